"""Workspace grids agree with the scalar IK; the PNG is written atomically; bad input fails."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from busarm.arm import workspace
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.arm.workspace import (
    reachable_any_pitch,
    render_workspace_png,
    side_envelope,
    workspace_grid,
)
from busarm.errors import ConfigError, UnreachableError

JETAUTO = load_arm_config("jetauto_pro")
MODIFIED = dataclasses.replace(
    JETAUTO,
    geometry=dataclasses.replace(
        JETAUTO.geometry, base_height_mm=160.0, upper_arm_mm=105.0, forearm_mm=142.5,
        wrist_mm=0.0, tool_mm=88.3,
    ),
    table_z_mm=-20.0,
)
_LIMITS = [(-90, 90), (-150, -30), (-30, 100), (-150, 0), (-120, 120)]
CONSTRAINED = dataclasses.replace(  # narrow, asymmetric limits: every root kind matters
    JETAUTO,
    joints=tuple(
        dataclasses.replace(j, min_deg=lo, max_deg=hi)
        for j, (lo, hi) in zip(JETAUTO.joints, _LIMITS, strict=True)
    ),
    geometry=dataclasses.replace(JETAUTO.geometry, upper_arm_mm=100.0),
)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _edge_cells(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Cells with a 4-neighbour of the other kind: where a wrong answer would show first."""
    edge = np.zeros_like(mask)
    dy = mask[:-1] != mask[1:]
    dx = mask[:, :-1] != mask[:, 1:]
    edge[:-1] |= dy
    edge[1:] |= dy
    edge[:, :-1] |= dx
    edge[:, 1:] |= dx
    return edge


def _sample(mask: npt.NDArray[np.bool_], n_random: int, seed: int) -> npt.NDArray[np.intp]:
    rng = np.random.default_rng(seed)
    edge = np.flatnonzero(_edge_cells(mask).ravel())
    random = rng.choice(mask.size, size=n_random, replace=False)
    return np.union1d(edge, random)


@pytest.mark.parametrize("config", [JETAUTO, MODIFIED], ids=["jetauto", "modified"])
def test_top_down_grid_agrees_with_ik_best(config: ArmConfig) -> None:
    kin = ArmKinematics.from_config(config)
    z = config.table_z_mm + 15.0
    xs, ys, mask = workspace_grid(kin, z, 2.0)
    assert xs[0] == -xs[-1] and 0.0 in xs and np.array_equal(xs, ys)
    assert mask.shape == (ys.size, xs.size) and mask.any() and not mask.all()
    gx, gy = np.meshgrid(xs, ys)
    cells = _sample(mask, 400, 1)
    assert cells.size > 1000
    for i in cells:
        try:
            kin.ik_best(float(gx.flat[i]), float(gy.flat[i]), z, -90.0)
            reachable = True
        except UnreachableError:
            reachable = False
        assert reachable == mask.flat[i], (gx.flat[i], gy.flat[i])


@pytest.mark.parametrize(
    "config", [JETAUTO, MODIFIED, CONSTRAINED], ids=["jetauto", "modified", "constrained"]
)
def test_side_envelope_is_pitch_intervals_non_empty(config: ArmConfig) -> None:
    kin = ArmKinematics.from_config(config)
    rs, zs, mask = side_envelope(kin, 5.0)
    assert mask.shape == (zs.size, rs.size) and mask.any()
    assert zs[0] == config.table_z_mm or zs[0] > config.table_z_mm
    gr, gz = np.meshgrid(rs, zs)
    for i in _sample(mask, 150, 2):
        expected = bool(kin.pitch_intervals(float(gr.flat[i]), 0.0, float(gz.flat[i])))
        assert expected == mask.flat[i], (gr.flat[i], gz.flat[i])


def test_exact_test_alone_matches_pitch_intervals() -> None:
    # Without the coarse first pass, on random points in 3-D (both branches, any bearing).
    for config in (JETAUTO, CONSTRAINED):
        kin = ArmKinematics.from_config(config)
        pts = np.random.default_rng(3).uniform([-450, -450, -20], [450, 450, 650], (600, 3))
        exact = workspace._exact_any_pitch(kin, pts[:, 0], pts[:, 1], pts[:, 2])
        full = reachable_any_pitch(kin, pts[:, 0], pts[:, 1], pts[:, 2])
        expected = np.array([bool(kin.pitch_intervals(*p)) for p in pts])
        assert 100 < expected.sum() < 550
        np.testing.assert_array_equal(exact, expected)
        np.testing.assert_array_equal(full, expected)


def _edge_radius(kin: ArmKinematics, z: float, bearing: float, lo: float, hi: float) -> float:
    """Bisect the top-down reachability edge along a ray with the scalar IK."""

    def ok(r: float) -> bool:
        try:
            kin.ik_best(r * math.cos(bearing), r * math.sin(bearing), z, -90.0)
        except UnreachableError:
            return False
        return True

    inside = ok(lo)
    assert inside != ok(hi)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if ok(mid) == inside:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def test_summary_numbers_and_png(tmp_path: Path) -> None:
    path = tmp_path / "workspace.png"
    summary = render_workspace_png(JETAUTO, path)
    assert summary.path == path and summary.grasp_z_mm == 15.0 and summary.cell_mm == 2.0
    assert summary.min_radius_mm is not None and summary.max_radius_mm is not None
    # The ring's edges, from the scalar IK along several bearings (front and over the back).
    kin = ArmKinematics.from_config(JETAUTO)
    inner = [_edge_radius(kin, 15.0, b, 50.0, 200.0) for b in (0.0, 1.0, 2.5, math.pi)]
    outer = [_edge_radius(kin, 15.0, b, 200.0, 400.0) for b in (0.0, 1.0, 2.5, math.pi)]
    # ... and in closed form. The wrist is L above the tool point, dz = -10.4 mm below the
    # shoulder axis. Inner edge: the elbow at its 120 deg limit puts the wrist 130 mm from
    # the shoulder axis. Outer edge: not the stretched arm (which would point 2.3 deg down)
    # but the shoulder at its 0 deg limit (upper arm horizontal), the forearm reaching down.
    g = JETAUTO.geometry
    a2, a3 = g.upper_arm_mm, g.forearm_mm
    dz = 15.0 + g.wrist_to_tip_mm - g.base_height_mm
    assert dz < 0 and JETAUTO.joint("shoulder_pitch").max_deg == 0.0
    r_in = math.sqrt(a2**2 + a3**2 + 2 * a2 * a3 * math.cos(math.radians(120)) - dz**2)
    r_out = a2 + math.sqrt(a3**2 - dz**2)
    np.testing.assert_allclose(inner, r_in, atol=1e-6)
    np.testing.assert_allclose(outer, r_out, atol=1e-6)
    assert 100 < r_in < 150 and 240 < r_out < 270
    cell_diag = 2.0 * math.sqrt(2)
    assert r_in <= summary.min_radius_mm <= r_in + cell_diag
    assert r_out - cell_diag <= summary.max_radius_mm <= r_out
    ring_cm2 = math.pi * (r_out**2 - r_in**2) / 100.0
    assert summary.top_down_area_cm2 == pytest.approx(ring_cm2, rel=0.01)
    assert 2000 < summary.envelope_area_cm2 < math.pi * kin.max_reach_mm**2 / 100
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE) and len(data) > 10_000
    import matplotlib.image

    image = matplotlib.image.imread(path)
    assert image.shape == (620, 1300, 4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["workspace.png"]


def test_existing_file_replaced_only_on_success(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "ws.png"
    path.write_bytes(b"old picture")
    from matplotlib.figure import Figure

    def broken_savefig(*args: object, **kwargs: object) -> None:
        raise RuntimeError("renderer exploded")

    with monkeypatch.context() as m:
        m.setattr(Figure, "savefig", broken_savefig)
        with pytest.raises(RuntimeError, match="exploded"):
            render_workspace_png(JETAUTO, path, cell_mm=8.0)
    assert path.read_bytes() == b"old picture"

    def broken_fsync(p: Path) -> None:
        raise OSError(28, "No space left on device")

    with monkeypatch.context() as m:
        m.setattr("busarm.fileio._fsync_file", broken_fsync)
        with pytest.raises(ConfigError, match="cannot write workspace picture .*No space"):
            render_workspace_png(JETAUTO, path, cell_mm=8.0)
    assert path.read_bytes() == b"old picture"
    assert [p.name for p in tmp_path.iterdir()] == ["ws.png"]

    render_workspace_png(JETAUTO, path, cell_mm=8.0)
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    assert [p.name for p in tmp_path.iterdir()] == ["ws.png"]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cell_mm": -2.0}, r"cell_mm = -2 must be > 0"),
        ({"cell_mm": 0}, r"cell_mm = 0 must be > 0"),
        ({"cell_mm": math.nan}, r"cell_mm = nan must be finite"),
        ({"cell_mm": "2"}, r"cell_mm must be a number"),
        ({"cell_mm": 0.1}, r"cell_mm = 0.1 gives \d+ grid cells"),
        ({"grasp_height_mm": math.nan}, r"grasp_height_mm = nan must be finite"),
        ({"grasp_height_mm": math.inf}, r"grasp_height_mm = inf must be finite"),
        ({"grasp_height_mm": -5.0}, r"grasp_height_mm = -5 is below the table"),
    ],
)
def test_bad_arguments(tmp_path: Path, kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        render_workspace_png(JETAUTO, tmp_path / "ws.png", **kwargs)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_bad_paths_and_config(tmp_path: Path) -> None:
    missing = tmp_path / "no" / "such" / "dir" / "ws.png"
    with pytest.raises(ConfigError, match=r"directory .*dir does not exist"):
        render_workspace_png(JETAUTO, missing)
    with pytest.raises(ConfigError, match="is a directory"):
        render_workspace_png(JETAUTO, tmp_path)
    with pytest.raises(ConfigError, match="must be an ArmConfig"):
        render_workspace_png("jetauto_pro", tmp_path / "ws.png")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []
    kin = ArmKinematics.from_config(JETAUTO)
    with pytest.raises(ConfigError, match="grasp_z_mm = nan must be finite"):
        workspace_grid(kin, math.nan, 2.0)
    with pytest.raises(ConfigError, match="cell_mm = -1 must be > 0"):
        side_envelope(kin, -1.0)


def test_nothing_reachable_is_drawn_too(tmp_path: Path) -> None:
    summary = render_workspace_png(JETAUTO, tmp_path / "ws.png", grasp_height_mm=400.0,
                                   cell_mm=10.0)
    assert summary.top_down_area_cm2 == 0.0
    assert summary.min_radius_mm is None and summary.max_radius_mm is None
    assert (tmp_path / "ws.png").read_bytes().startswith(PNG_SIGNATURE)


def test_import_stays_light() -> None:
    code = (
        "import sys, busarm.arm, busarm.arm.workspace, busarm.arm.urdf; "
        "print(sorted(m for m in ('matplotlib', 'yourdfpy', 'trimesh') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "[]"
