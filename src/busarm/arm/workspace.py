"""Where the arm can reach: grids computed with the vectorized IK, and a PNG picture of them.

Two views of one arm:

- :func:`workspace_grid`: the table cells (top view) where a top-down grasp (pitch -90)
  at a given height is reachable, from :meth:`ArmKinematics.ik_batch`;
- :func:`side_envelope`: the points of the vertical plane y = 0 (x forward, z up) that
  the tool point reaches at *any* pitch. This is exact, not a pitch scan: it is the same
  test as "``pitch_intervals`` is not empty", vectorized. The feasible pitches change
  only at the closed-form roots of the constraints (reach, joint limits, table), so each
  point is tested at the middle of every arc between its sorted roots.

:func:`render_workspace_png` draws both (matplotlib, Agg, imported only when called) and
writes the picture atomically, in the format its file name says (``PICTURE_FORMATS``).
Millimetres throughout.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import check_number
from busarm.arm.config import ArmConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError
from busarm.fileio import write_bytes_atomic

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

TOP_DOWN_PITCH_DEG = -90.0
MAX_GRID_CELLS = 4_000_000
"""Largest grid either view may have (memory and time); a smaller cell_mm is refused."""
_CHUNK_ROWS = 400_000
"""IK rows evaluated at once in the exact envelope test (bounds the temporaries)."""
_COARSE_PITCHES_DEG = np.arange(-180.0, 180.0, 22.5)
"""Pitches tried first: any hit proves a point reachable; the rest get the exact test."""
_ARC_EPS = 1e-12
"""Arcs narrower than this (radians) are ignored, as ``pitch_intervals`` does."""


@dataclass(frozen=True)
class WorkspaceSummary:
    """What :func:`render_workspace_png` drew, in numbers.

    The radii are the nearest and farthest reachable cell centres from the base axis, so
    they are within about one cell of the true edges; None when nothing is reachable.
    """

    path: Path
    grasp_z_mm: float
    cell_mm: float
    top_down_area_cm2: float
    min_radius_mm: float | None
    max_radius_mm: float | None
    envelope_area_cm2: float


def workspace_grid(
    kin: ArmKinematics, grasp_z_mm: float, cell_mm: float = 2.0, *,
    pitch_deg: float = TOP_DOWN_PITCH_DEG,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Top view: ``(xs, ys, mask)`` with ``mask[iy, ix]`` True where the tool point
    ``(xs[ix], ys[iy], grasp_z_mm)`` is reachable at ``pitch_deg`` (default top-down).

    Cell centres lie on multiples of ``cell_mm`` over +-``kin.max_reach_mm`` (the base
    axis is a centre). The wrist roll is free (kept at 0 where the limits allow).
    """
    z = check_number("grasp_z_mm", grasp_z_mm)
    pitch = check_number("pitch_deg", pitch_deg)
    cell = _cell(cell_mm)
    n = math.ceil(kin.max_reach_mm / cell)
    _check_size(cell, (2 * n + 1) ** 2)
    xs = np.asarray(np.arange(-n, n + 1) * cell, dtype=np.float64)
    ys = xs.copy()
    gx, gy = np.meshgrid(xs, ys)
    targets = np.empty((gx.size, 4))
    targets[:, 0] = gx.ravel()
    targets[:, 1] = gy.ravel()
    targets[:, 2] = z
    targets[:, 3] = pitch
    _, ok = kin.ik_batch(targets)
    return xs, ys, ok.reshape(gx.shape)


def side_envelope(
    kin: ArmKinematics, cell_mm: float = 2.0
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Side view: ``(rs, zs, mask)`` with ``mask[iz, ir]`` True where the tool point
    ``(x = rs[ir], y = 0, z = zs[iz])`` is reachable at some pitch (exactly:
    ``kin.pitch_intervals`` is not empty). Negative ``rs`` are behind the base.

    ``zs`` runs from the table (or the lowest reach) up to the highest reach.
    """
    cell = _cell(cell_mm)
    reach = kin.max_reach_mm
    h = kin.geometry.base_height_mm
    z_lo = h - reach
    if kin.table_z_mm is not None:
        z_lo = max(z_lo, kin.table_z_mm)
    n = math.ceil(reach / cell)
    nz = math.floor((h + reach - z_lo) / cell) + 1
    _check_size(cell, (2 * n + 1) * nz)
    rs = np.asarray(np.arange(-n, n + 1) * cell, dtype=np.float64)
    zs = np.asarray(z_lo + np.arange(nz) * cell, dtype=np.float64)
    gr, gz = np.meshgrid(rs, zs)
    mask = reachable_any_pitch(kin, gr.ravel(), np.zeros(gr.size), gz.ravel())
    return rs, zs, mask.reshape(gr.shape)


def reachable_any_pitch(
    kin: ArmKinematics, x_mm: npt.ArrayLike, y_mm: npt.ArrayLike, z_mm: npt.ArrayLike
) -> BoolArray:
    """For each tool point, whether some pitch reaches it (free wrist roll).

    The vectorized equivalent of ``bool(kin.pitch_intervals(x, y, z))``.
    """
    x, y, z = np.broadcast_arrays(
        np.asarray(x_mm, dtype=np.float64), np.asarray(y_mm, dtype=np.float64),
        np.asarray(z_mm, dtype=np.float64),
    )
    shape = x.shape
    x, y, z = x.ravel(), y.ravel(), z.ravel()
    out = np.zeros(x.size, dtype=bool)
    g = kin.geometry
    reach = g.upper_arm_mm + g.forearm_mm + g.wrist_to_tip_mm
    table = -math.inf if kin.table_z_mm is None else kin.table_z_mm
    candidate = np.isfinite(x) & np.isfinite(y) & np.isfinite(z) & (z >= table - 1e-9)
    # Beyond the stretched arm nothing can work (a margin keeps the rounding edge exact).
    candidate &= np.hypot(np.hypot(x, y), z - g.base_height_mm) <= reach + 1e-3
    idx = np.flatnonzero(candidate)
    if idx.size == 0:
        return out.reshape(shape)
    # Cheap first pass: a hit at any pitch proves the point reachable.
    hit = np.zeros(idx.size, dtype=bool)
    for p in _COARSE_PITCHES_DEG:
        rest = np.flatnonzero(~hit)
        if rest.size == 0:
            break
        hit[rest] = _ik_ok(kin, x[idx[rest]], y[idx[rest]], z[idx[rest]], np.full(rest.size, p))
    out[idx[hit]] = True
    idx = idx[~hit]
    if idx.size:
        out[idx] = _exact_any_pitch(kin, x[idx], y[idx], z[idx])
    return out.reshape(shape)


def render_workspace_png(
    config: ArmConfig, path: Path | str, *, grasp_height_mm: float = 15.0,
    cell_mm: float = 2.0,
) -> WorkspaceSummary:
    """Draw the top-down grasp area and the side reach envelope; write the picture
    atomically as PNG, JPEG, SVG or PDF by ``path``'s extension (``PICTURE_FORMATS``; any
    other is refused, naming them, before anything is computed).

    The grasp is at ``config.table_z_mm + grasp_height_mm`` (the tool point above the
    table, e.g. half a block's height). An existing file at ``path`` is replaced only
    once the picture is complete.
    """
    if not isinstance(config, ArmConfig):
        raise ConfigError(f"config must be an ArmConfig, got {type(config).__name__}")
    height = check_number("grasp_height_mm", grasp_height_mm)
    if height < 0:
        raise ConfigError(
            f"grasp_height_mm = {height:g} is below the table; give the height of the tool "
            "point above the table (>= 0 mm)"
        )
    cell = _cell(cell_mm)
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise ConfigError(
            f"cannot write workspace picture {path}: directory {directory} does not exist"
        )
    if path.is_dir():
        raise ConfigError(f"cannot write workspace picture {path}: it is a directory")
    fmt = picture_format(path)
    kin = ArmKinematics.from_config(config)
    grasp_z = config.table_z_mm + height
    xs, ys, top = workspace_grid(kin, grasp_z, cell)
    rs, zs, side = side_envelope(kin, cell)
    gx, gy = np.meshgrid(xs, ys)
    radii = np.hypot(gx, gy)[top]
    summary = WorkspaceSummary(
        path=path, grasp_z_mm=grasp_z, cell_mm=cell,
        top_down_area_cm2=float(top.sum()) * cell * cell / 100.0,
        min_radius_mm=float(radii.min()) if radii.size else None,
        max_radius_mm=float(radii.max()) if radii.size else None,
        envelope_area_cm2=float(side.sum()) * cell * cell / 100.0,
    )
    picture = _draw(config, kin, summary, (xs, ys, top), (rs, zs, side), fmt)
    write_bytes_atomic(path, picture, "workspace picture")
    return summary


# ---------------------------------------------------------------------- exact envelope


def _ik_ok(
    kin: ArmKinematics, x: FloatArray, y: FloatArray, z: FloatArray, pitch_deg: FloatArray
) -> BoolArray:
    ok = np.zeros(x.size, dtype=bool)
    for start in range(0, x.size, _CHUNK_ROWS):
        s = slice(start, start + _CHUNK_ROWS)
        ok[s] = kin.ik_batch(np.column_stack([x[s], y[s], z[s], pitch_deg[s]]))[1]
    return ok


def _cos_roots(
    roots: list[FloatArray], a: FloatArray | float, num: FloatArray, den: FloatArray
) -> None:
    """Append the two solutions q of ``den cos(q - a) = num`` (NaN where there are none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        k = num / den
        b = np.where((den > 0) & (np.abs(k) <= 1.0), np.arccos(np.clip(k, -1.0, 1.0)), np.nan)
    roots.extend((a + b, a - b))


def _exact_any_pitch(
    kin: ArmKinematics, x: FloatArray, y: FloatArray, z: FloatArray
) -> BoolArray:
    """``pitch_intervals`` non-empty, vectorized: the roots of ``_branch_arcs`` per point,
    from both branches in world pitch, then ``ik_batch`` at the middle of every arc."""
    g = kin.geometry
    a2, a3, L, h = g.upper_arm_mm, g.forearm_mm, g.wrist_to_tip_mm, g.base_height_mm
    lim = [(math.radians(lo), math.radians(hi)) for lo, hi in kin.limits_deg]
    r = np.hypot(x, y)
    zeta = z - h
    world: list[FloatArray] = [np.full(x.size, -math.pi)]  # one root always (no-root rows)
    for back in (False, True):
        rho = -r if back else r
        d = np.hypot(rho, zeta)
        phi = np.arctan2(zeta, rho)
        roots: list[FloatArray] = []
        radii = [a2 + a3, abs(a2 - a3)]
        for lim3 in lim[2]:
            if -math.pi < lim3 < math.pi:
                radii.append(math.sqrt(max(0.0, a2 * a2 + a3 * a3 + 2 * a2 * a3 * math.cos(lim3))))
        for radius in radii:
            _cos_roots(roots, phi, d * d + L * L - radius * radius, 2 * L * d)
        for c in lim[1]:  # shoulder limit: the elbow is fixed, |P - E - L u(q)| = a3
            px, pz = rho - a2 * math.cos(c), zeta + a2 * math.sin(c)
            pd = np.hypot(px, pz)
            _cos_roots(roots, np.arctan2(pz, px), pd * pd + L * L - a3 * a3, 2 * L * pd)
        for c in lim[3]:  # wrist pitch limit: |P - m u(q)| = a2
            mx, mz = L + a3 * math.cos(0.5 * math.pi + c), a3 * math.sin(0.5 * math.pi + c)
            m = math.hypot(mx, mz)
            _cos_roots(roots, phi - math.atan2(mz, mx), d * d + m * m - a2 * a2, 2 * d * m)
        if kin.table_z_mm is not None:  # the wrist above the table
            k = (z - kin.table_z_mm) / L
            s = np.where((k > -1.0) & (k < 1.0), np.arcsin(np.clip(k, -1.0, 1.0)), np.nan)
            roots.extend((s, math.pi - s))
        for q in roots:
            world.append(math.pi - q if back else q)
    p = np.stack(world, axis=1)
    p = np.where(np.isnan(p), np.nan, np.mod(p + math.pi, 2 * math.pi) - math.pi)
    p.sort(axis=1)  # NaN last; column 0 is a real root
    wrap = p[:, :1] + 2 * math.pi
    p = np.where(np.isnan(p), wrap, p)
    p = np.concatenate([p, wrap], axis=1)
    lo, hi = p[:, :-1], p[:, 1:]
    arcs = hi - lo > _ARC_EPS
    rows, cols = np.nonzero(arcs)
    mids = 0.5 * (lo[rows, cols] + hi[rows, cols])
    mids = np.degrees(np.mod(mids + math.pi, 2 * math.pi) - math.pi)
    ok = _ik_ok(kin, x[rows], y[rows], z[rows], mids)
    out = np.zeros(x.size, dtype=bool)
    out[rows[ok]] = True
    return out


# ---------------------------------------------------------------------- drawing


def _draw(
    config: ArmConfig, kin: ArmKinematics, summary: WorkspaceSummary,
    top: tuple[FloatArray, FloatArray, BoolArray], side: tuple[FloatArray, FloatArray, BoolArray],
    fmt: str = "png",
) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13.0, 6.2), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax_top, ax_side = fig.subplots(1, 2, width_ratios=(1.0, 1.25))
    _draw_top(ax_top, kin, summary, top)
    _draw_side(ax_side, config, kin, summary, top, side)
    fig.suptitle(f"{config.name}: workspace (cells of {summary.cell_mm:g} mm)", fontsize=13)
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt)
    return buf.getvalue()


def _extent(a: FloatArray, b: FloatArray, cell: float) -> tuple[float, float, float, float]:
    """The image extent of a grid of cell centres ``a`` by ``b``."""
    return (float(a[0]) - cell / 2, float(a[-1]) + cell / 2,
            float(b[0]) - cell / 2, float(b[-1]) + cell / 2)


def _draw_top(
    ax: Axes, kin: ArmKinematics, summary: WorkspaceSummary,
    top: tuple[FloatArray, FloatArray, BoolArray],
) -> None:
    """(a) The top view: the top-down grasp area and its radii round the base axis."""
    from matplotlib.patches import Circle

    xs, ys, mask = top
    # NaN cells are drawn transparent
    ax.imshow(np.where(mask, 1.0, np.nan), extent=_extent(xs, ys, summary.cell_mm),
              origin="lower", cmap="Greens", vmin=0.0, vmax=1.6, interpolation="nearest")
    if summary.min_radius_mm is not None and summary.max_radius_mm is not None:
        for radius in (summary.min_radius_mm, summary.max_radius_mm):
            ax.add_patch(Circle((0.0, 0.0), radius, fill=False, ls="--", lw=0.8,
                                color="tab:green"))
        reach = (f"r = {summary.min_radius_mm:.0f}–{summary.max_radius_mm:.0f} mm from the "
                 f"base axis, {summary.top_down_area_cm2:.0f} cm²")
    else:
        reach = "nowhere reachable"
    ax.plot([0.0], [0.0], marker="+", ms=14, mew=2, color="black")
    ax.annotate("base", (0.0, 0.0), xytext=(6, 6), textcoords="offset points")
    ax.set_title(
        f"Top-down grasp (pitch −90°) at z = {summary.grasp_z_mm:g} mm\n{reach}", fontsize=11
    )
    span = (summary.max_radius_mm or kin.max_reach_mm) + 40.0
    ax.set_xlim(-span, span)
    ax.set_ylim(-span, span)
    ax.set_xlabel("x (mm), forward at base yaw 0")
    ax.set_ylabel("y (mm)")
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3, alpha=0.5)


def _draw_side(
    ax: Axes, config: ArmConfig, kin: ArmKinematics, summary: WorkspaceSummary,
    top: tuple[FloatArray, FloatArray, BoolArray], side: tuple[FloatArray, FloatArray, BoolArray],
) -> None:
    """(b) The side view: the reach envelope, the table, the grasp line and the home pose."""
    xs, ys, mask = top
    rs, zs, env = side
    ax.imshow(np.where(env, 1.0, np.nan), extent=_extent(rs, zs, summary.cell_mm),
              origin="lower", cmap="Blues", vmin=0.0, vmax=1.8, interpolation="nearest")
    if kin.table_z_mm is not None:
        ax.axhline(kin.table_z_mm, color="saddlebrown", lw=2, label="table")
    row = mask[int(np.argmin(np.abs(ys)))]  # y = 0 row of the top view
    seg = np.where(row, summary.grasp_z_mm, np.nan)
    ax.plot(xs, seg, color="tab:green", lw=4, solid_capstyle="butt",
            label=f"top-down grasp at z = {summary.grasp_z_mm:g} mm")
    home = config.poses_deg.get("home")
    if home is not None:
        _draw_home(ax, kin, home)
    ax.set_title(
        f"Reach envelope in the plane y = 0, any pitch ({summary.envelope_area_cm2:.0f} cm²)\n"
        "exact: the feasible-pitch set is not empty (closed-form arcs, no pitch scan)",
        fontsize=11,
    )
    ax.set_xlabel("x (mm); negative = behind the base (reached over the back)")
    ax.set_ylabel("z (mm)")
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3, alpha=0.5)
    if kin.table_z_mm is not None:  # show the table line below the grid
        ax.set_ylim(bottom=min(float(zs[0]), kin.table_z_mm) - 30.0)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)


def _draw_home(ax: Axes, kin: ArmKinematics, home: tuple[float, ...]) -> None:
    """The arm's links at the home pose, seen in the plane of its base yaw."""
    frames = kin.frames(home)
    bearing = math.radians(home[0])
    pts = [np.zeros(3)] + [f[:3, 3] for f in frames]
    r_pts = [p[0] * math.cos(bearing) + p[1] * math.sin(bearing) for p in pts]
    z_pts = [p[2] for p in pts]
    ax.plot(r_pts, z_pts, "-o", color="black", lw=2.5, ms=4,
            label=f"home pose {tuple(round(v) for v in home)}°")
    ax.plot(r_pts[-1:], z_pts[-1:], marker="*", ms=12, color="crimson", ls="none",
            label="tool point")


# ---------------------------------------------------------------------- checks

PICTURE_FORMATS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg", ".svg": "svg", ".pdf": "pdf"}
"""The picture's format by its file's extension (matplotlib's name for it)."""


def picture_format(path: Path | str) -> str:
    """The format ``path``'s extension names; ConfigError naming the allowed ones."""
    suffix = Path(path).suffix.lower()
    if suffix not in PICTURE_FORMATS:
        raise ConfigError(f"cannot write workspace picture {path}: extension "
                          f"{suffix or '(none)'!r} is not one of {', '.join(PICTURE_FORMATS)}")
    return PICTURE_FORMATS[suffix]


def _cell(cell_mm: object) -> float:
    cell = check_number("cell_mm", cell_mm)
    if cell <= 0:
        raise ConfigError(f"cell_mm = {cell:g} must be > 0 (grid cell size in mm)")
    return cell


def _check_size(cell: float, cells: int) -> None:
    if cells > MAX_GRID_CELLS:
        raise ConfigError(
            f"cell_mm = {cell:g} gives {cells} grid cells, more than {MAX_GRID_CELLS}; "
            "use larger cells"
        )


__all__ = [
    "MAX_GRID_CELLS",
    "PICTURE_FORMATS",
    "WorkspaceSummary",
    "picture_format",
    "reachable_any_pitch",
    "render_workspace_png",
    "side_envelope",
    "workspace_grid",
]
