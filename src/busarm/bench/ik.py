"""``busarm bench ik``: accuracy and speed of the closed-form arm IK, and its peers.

1. Accuracy: N seeded random joint vectors within the config's limits; each one's FK
   pose is a target. ``ik`` must return at least one solution and every solution it
   returns must reproduce the target 4x4 (``fk_matrix``) within ``POS_TOL_MM`` and
   ``ROT_TOL_DEG`` and lie within the limits. The same for ``ik_best`` and ``ik_batch``.
   Pure geometry (``check_table=False``): some random configurations put the tool under
   the table plane, which the table check would rightly refuse.
2. Just outside the envelope: N targets whose wrist point is ``OUTSIDE_MM`` beyond
   ``upper_arm + forearm`` from the shoulder axis (random bearing, pitch, elevation):
   ``ik`` and ``ik_batch`` must refuse all. Checked with the config's limits and with
   no joint limits and a free roll (so nothing but reach can refuse); in the latter,
   the same targets pulled ``OUTSIDE_MM`` inside must all be accepted.
3. Speed: per-call ``ik_best`` and ``ik`` over the same targets, each call timed alone
   with ``time.perf_counter_ns`` (GC off, after a warm-up); ``ik_batch`` on the targets
   tiled to ``batch_n`` rows, best of ``BATCH_REPEATS``.
4. Peers (optional, ``make bench-ik`` installs them): Robotics Toolbox ``ets().ik_LM``
   and ikpy ``inverse_kinematics(orientation_mode="all")`` on the first targets, timed
   the same way and verified the same way (busarm's FK of their joints): see
   ``busarm.bench.ik_peers``.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import FloatArray
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bench.common import machine_info
from busarm.errors import UnreachableError

__all__ = [
    "BATCH_REPEATS",
    "LIMIT_SLACK_DEG",
    "OUTSIDE_MM",
    "PEERS_HINT",
    "PEER_Q0_DEG",
    "POS_TOL_MM",
    "ROT_TOL_DEG",
    "TARGET_BATCH_PER_S",
    "TARGET_SINGLE_US",
    "WARM_UP",
    "Accuracy",
    "Batch",
    "IkBenchReport",
    "Outside",
    "PeerResult",
    "Timing",
    "check_accuracy",
    "check_outside",
    "in_limits",
    "outside_targets",
    "pose_errors",
    "random_joints",
    "run_ik_bench",
    "time_batch",
    "timer_overhead_ns",
    "timing_of",
]


POS_TOL_MM = 1e-3
ROT_TOL_DEG = 1e-3
LIMIT_SLACK_DEG = 1e-7
OUTSIDE_MM = 0.01
BATCH_REPEATS = 3
WARM_UP = 200
PEER_Q0_DEG = (0.0, -60.0, 60.0, -60.0, 0.0)
"""Common start for the iterative peers (within the limits, away from singularities)."""
TARGET_SINGLE_US = 5.0
TARGET_BATCH_PER_S = 3_000_000.0
PEERS_HINT = "IK peers not installed: `make bench-ik` installs them (pip install -e '.[ikbench]')"


@dataclass
class Accuracy:
    n: int
    seed: int
    check_table: bool
    failures: int
    """Targets where ``ik`` returned nothing, or any solution off the target or limits."""
    no_solution: int
    wrong_pose: int
    out_of_limits: int
    solutions: int
    worst_pos_mm: float
    worst_rot_deg: float
    best_failures: int
    batch_failures: int
    batch_worst_pos_mm: float
    batch_worst_rot_deg: float


@dataclass
class Outside:
    n: int
    margin_mm: float
    accepted_ik: int
    accepted_batch: int
    accepted_ik_no_limits: int
    accepted_batch_no_limits: int
    inside_accepted_no_limits: int
    """The same targets moved ``margin_mm`` inside: all must be accepted (``n``)."""


@dataclass
class Timing:
    name: str
    n: int
    median_us: float
    p90_us: float
    mean_us: float


@dataclass
class Batch:
    n: int
    repeats: int
    best_s: float
    solves_per_s: float
    all_ok: bool


@dataclass
class PeerResult:
    name: str
    version: str
    n: int
    median_us: float
    p90_us: float
    success: int
    claimed: int
    busarm_median_us: float
    """busarm ``ik_best`` median on the same targets."""
    ratio: float
    median_pos_mm: float
    median_rot_deg: float


@dataclass
class IkBenchReport:
    arm: str
    machine: dict[str, str]
    timing_method: str
    timer_overhead_ns: float
    accuracy: Accuracy
    outside: Outside
    single: list[Timing]
    batch: Batch
    peers: list[PeerResult] = field(default_factory=list)
    peers_note: str | None = None

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


# ------------------------------------------------------------------------ helpers


def pose_errors(t: FloatArray, target: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(position error mm, rotation angle deg) between stacks of 4x4 poses (..., 4, 4)."""
    pos = np.linalg.norm(t[..., :3, 3] - target[..., :3, 3], axis=-1)
    r = np.swapaxes(t[..., :3, :3], -1, -2) @ target[..., :3, :3]
    cos = (np.trace(r, axis1=-2, axis2=-1) - 1.0) / 2.0
    # Typed steps: one nested expression of these slices costs mypy seconds.
    rx: FloatArray = r[..., 2, 1] - r[..., 1, 2]
    ry: FloatArray = r[..., 0, 2] - r[..., 2, 0]
    rz: FloatArray = r[..., 1, 0] - r[..., 0, 1]
    skew = np.linalg.norm(np.stack([rx, ry, rz], axis=-1), axis=-1) / 2.0
    return pos, np.degrees(np.arctan2(skew, cos))  # exact near 0, unlike arccos


def random_joints(kin: ArmKinematics, n: int, rng: np.random.Generator) -> FloatArray:
    lo = np.array([a for a, _ in kin.limits_deg])
    hi = np.array([b for _, b in kin.limits_deg])
    return rng.uniform(lo, hi, size=(n, 5))


def in_limits(kin: ArmKinematics, q_deg: FloatArray) -> npt.NDArray[np.bool_]:
    lo = np.array([a for a, _ in kin.limits_deg]) - LIMIT_SLACK_DEG
    hi = np.array([b for _, b in kin.limits_deg]) + LIMIT_SLACK_DEG
    ok: npt.NDArray[np.bool_] = np.all((q_deg >= lo) & (q_deg <= hi), axis=-1)
    return ok


def outside_targets(
    kin: ArmKinematics, n: int, rng: np.random.Generator, offset_mm: float,
) -> FloatArray:
    """(n, 5) poses (roll NaN = free) whose wrist point is ``upper_arm + forearm +
    offset_mm`` from the shoulder axis: random bearing, tool pitch and wrist elevation."""
    g = kin.geometry
    d = g.upper_arm_mm + g.forearm_mm + offset_mm
    L = g.wrist_to_tip_mm
    out = np.empty((0, 5))
    while out.shape[0] < n:
        m = 2 * n
        psi, p, e = rng.uniform(-math.pi, math.pi, size=(3, m))
        rho = d * np.cos(e) + L * np.cos(p)  # signed distance of the tool point from the axis
        z = g.base_height_mm + d * np.sin(e) + L * np.sin(p)
        keep = np.abs(rho) > 1e-3  # on the axis the bearing (and so the pitch) is undefined
        # The pose's pitch is measured facing away from the base through the tool point.
        pitch = np.where(rho >= 0.0, p, math.pi - p)
        x: FloatArray = rho * np.cos(psi)
        y: FloatArray = rho * np.sin(psi)
        wrapped: FloatArray = np.arctan2(np.sin(pitch), np.cos(pitch))
        rows = np.stack([x, y, z, np.degrees(wrapped), np.full(m, np.nan)], axis=1)
        out = np.concatenate([out, rows[keep]])
    return out[:n]


def _timed(call: Callable[..., object], args: Sequence[tuple[float, ...]]) -> list[int]:
    """Nanoseconds of each call, each timed alone, after a warm-up, with GC off."""
    for a in args[:WARM_UP]:
        call(*a)
    clock = time.perf_counter_ns
    times: list[int] = []
    append = times.append
    enabled = gc.isenabled()
    gc.disable()
    try:
        for a in args:
            t0 = clock()
            call(*a)
            append(clock() - t0)
    finally:
        if enabled:
            gc.enable()
    return times


def timer_overhead_ns() -> float:
    clock = time.perf_counter_ns
    samples = []
    for _ in range(10_000):
        t0 = clock()
        samples.append(clock() - t0)
    return float(np.median(samples))


def timing_of(name: str, times_ns: Sequence[int]) -> Timing:
    us = np.asarray(times_ns, dtype=np.float64) / 1000.0
    return Timing(name, len(us), round(float(np.median(us)), 3),
                  round(float(np.percentile(us, 90)), 3), round(float(us.mean()), 3))


# ------------------------------------------------------------------------ the bench


def check_accuracy(
    kin: ArmKinematics, poses: FloatArray, target_t: FloatArray, seed: int,
) -> Accuracy:
    """``ik``, ``ik_best`` and ``ik_batch`` on FK poses, checked against their 4x4 targets."""
    n = len(poses)
    args = [tuple(float(v) for v in row) for row in poses]
    no_sol = wrong = out_lim = 0
    failed = np.zeros(n, dtype=bool)
    worst_pos = worst_rot = 0.0
    all_sols: list[tuple[float, ...]] = []
    owner: list[int] = []
    for i, a in enumerate(args):
        sols = kin.ik(*a)
        if not sols:
            no_sol += 1
            failed[i] = True
        all_sols.extend(sols)
        owner.extend([i] * len(sols))
    n_sols = len(all_sols)
    if all_sols:
        s = np.asarray(all_sols)
        idx = np.asarray(owner)
        pos, rot = pose_errors(kin.fk_matrix_batch(s), target_t[idx])
        bad_pose = (pos > POS_TOL_MM) | (rot > ROT_TOL_DEG)
        bad_lim = ~in_limits(kin, s)
        wrong = int(np.unique(idx[bad_pose]).size)
        out_lim = int(np.unique(idx[bad_lim]).size)
        failed[idx[bad_pose | bad_lim]] = True
        worst_pos, worst_rot = float(pos.max()), float(rot.max())

    best_fail = 0
    best = np.full((n, 5), np.nan)
    for i, a in enumerate(args):
        try:
            best[i] = kin.ik_best(*a)
        except UnreachableError:
            best_fail += 1
    ok_b = ~np.isnan(best).any(axis=1)
    pos_b, rot_b = pose_errors(kin.fk_matrix_batch(np.where(ok_b[:, None], best, 0.0)), target_t)
    best_fail += int((ok_b & ((pos_b > POS_TOL_MM) | (rot_b > ROT_TOL_DEG))).sum())

    bq, bok = kin.ik_batch(poses)
    pos_q, rot_q = pose_errors(kin.fk_matrix_batch(np.where(bok[:, None], bq, 0.0)), target_t)
    batch_bad = ~bok | (pos_q > POS_TOL_MM) | (rot_q > ROT_TOL_DEG) | ~in_limits(kin, bq)
    return Accuracy(
        n, seed, False, int(failed.sum()), no_sol, wrong, out_lim, n_sols,
        worst_pos, worst_rot, best_fail, int(batch_bad.sum()),
        float(pos_q[bok].max(initial=0.0)), float(rot_q[bok].max(initial=0.0)),
    )


def check_outside(kin: ArmKinematics, n: int, seed: int) -> Outside:
    """``n`` targets just beyond full stretch must all be refused, the same ones just
    inside (no joint limits, free roll) all accepted."""
    free = ArmKinematics(kin.geometry, [(-180.0, 180.0)] * 5, table_z_mm=None)
    outside_t = outside_targets(kin, n, np.random.default_rng(seed + 1), OUTSIDE_MM)
    inside_t = outside_targets(kin, n, np.random.default_rng(seed + 1), -OUTSIDE_MM)

    def accepted(k: ArmKinematics, t: FloatArray) -> int:
        return sum(1 for row in t if k.ik(*(float(v) for v in row[:4])))

    return Outside(
        n, OUTSIDE_MM,
        accepted(kin, outside_t), int(kin.ik_batch(outside_t)[1].sum()),
        accepted(free, outside_t), int(free.ik_batch(outside_t)[1].sum()),
        accepted(free, inside_t),
    )


def time_batch(kin: ArmKinematics, poses: FloatArray, batch_n: int) -> Batch:
    """``ik_batch`` on ``poses`` tiled to ``batch_n`` rows: best of ``BATCH_REPEATS``."""
    reps = -(-batch_n // len(poses))
    big = np.tile(poses, (reps, 1))[:batch_n]
    kin.ik_batch(big[: min(batch_n, 10_000)])  # warm-up
    times = []
    all_ok = True
    for _ in range(BATCH_REPEATS):
        t0 = time.perf_counter()
        _, ok = kin.ik_batch(big)
        times.append(time.perf_counter() - t0)
        all_ok = all_ok and bool(ok.all())
    best_s = min(times)
    return Batch(batch_n, BATCH_REPEATS, round(best_s, 4), round(batch_n / best_s, 1), all_ok)


def run_ik_bench(
    config: ArmConfig | None = None, *, n: int = 10_000, batch_n: int = 1_000_000,
    seed: int = 0, peers: bool = False, n_rtb: int = 1000, n_ikpy: int = 100,
) -> IkBenchReport:
    """Accuracy, refusal just outside the envelope, and speed; the peers if asked."""
    cfg = config if config is not None else load_arm_config()
    kin = ArmKinematics.from_config(cfg, check_table=False)
    rng = np.random.default_rng(seed)
    q = random_joints(kin, n, rng)
    target_t = kin.fk_matrix_batch(q)
    poses = kin.fk_batch(q)
    args = [tuple(float(v) for v in row) for row in poses]

    accuracy = check_accuracy(kin, poses, target_t, seed)
    outside = check_outside(kin, n, seed)

    overhead = timer_overhead_ns()
    best_ns = _timed(kin.ik_best, args)
    all_ns = _timed(kin.ik, args)
    single = [timing_of("ik_best", best_ns), timing_of("ik (all solutions)", all_ns)]
    batch = time_batch(kin, poses, batch_n)

    report = IkBenchReport(
        arm=cfg.name, machine=machine_info(),
        timing_method=("each call timed alone with time.perf_counter_ns (timer overhead "
                       "included), GC disabled, after a warm-up; batch: wall time, best of "
                       f"{BATCH_REPEATS}"),
        timer_overhead_ns=overhead, accuracy=accuracy, outside=outside, single=single,
        batch=batch,
    )
    if peers:
        try:
            from busarm.bench.ik_peers import run_peers

            report.peers = run_peers(kin, q, target_t, best_ns, n_rtb, n_ikpy, cfg)
        except ImportError as exc:
            report.peers_note = f"{PEERS_HINT} ({exc})"
    return report
