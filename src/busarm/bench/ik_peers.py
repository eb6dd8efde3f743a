"""IK peers beside busarm's closed form: Robotics Toolbox ``ets().ik_LM`` and ikpy
``inverse_kinematics(orientation_mode="all")``, on the same FK-generated targets, timed
like busarm and verified with busarm's FK. ``busarm bench ik --peers`` runs them
(``make bench-ik`` installs them: ``pip install -e '.[ikbench]'``).

Run as a script, it reruns that comparison and then shows why the bench calls
``robot.ets().ik_LM`` and not ``robot.ik_LM``: in roboticstoolbox-python 1.5.0 the
``DHRobot`` wrapper strips ``robot.tool`` from the target although ``robot.ets()``
already ends with it, so the tool counts twice::

    python -m busarm.bench.ik_peers [--n 1000] [--n-ikpy 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import io
import json
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import FloatArray
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bench.ik import (
    PEER_Q0_DEG,
    POS_TOL_MM,
    ROT_TOL_DEG,
    PeerResult,
    in_limits,
    pose_errors,
    random_joints,
    run_ik_bench,
    timing_of,
)

__all__ = [
    "Solver",
    "build_ikpy",
    "build_rtb",
    "main",
    "robot_ik_lm_caveat",
    "run_peers",
]


Solver = Callable[[npt.ArrayLike], tuple[FloatArray, bool]]
"""A peer's IK of a 4x4 target in mm: joints in radians, and whether it claims success."""


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "?"


def build_rtb(kin: ArmKinematics) -> Any:
    """The arm as a Robotics Toolbox ``DHRobot`` of ``RevoluteMDH`` links, in metres."""
    rtb = importlib.import_module("roboticstoolbox")  # optional, untyped

    links = [
        rtb.RevoluteMDH(alpha=alpha, a=a / 1000.0, d=d / 1000.0,
                        qlim=np.radians([lo, hi]))
        for (alpha, a, d), (lo, hi) in zip(kin.dh_table(), kin.limits_deg, strict=True)
    ]
    tool = np.eye(4)
    tool[2, 3] = kin.geometry.tool_mm / 1000.0
    return rtb.DHRobot(links, tool=tool, name="busarm5")


def build_ikpy(config: ArmConfig) -> Any:
    """The arm as an ikpy chain, from busarm's own URDF."""
    ikpy_chain = importlib.import_module("ikpy.chain")  # optional, untyped

    from busarm.arm.urdf import BASE_LINK, urdf_from_config

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ikpy warns about the fixed origin/tool links
        return ikpy_chain.Chain.from_urdf_file(
            io.StringIO(urdf_from_config(config)), base_elements=[BASE_LINK],
            active_links_mask=[False, True, True, True, True, True, False], name="busarm5",
        )


def _m(t_mm: npt.ArrayLike) -> FloatArray:
    t = np.array(t_mm, dtype=np.float64)
    t[:3, 3] /= 1000.0
    return t


def _check_same_arm(robot_ets: Any, chain: Any, q_deg: FloatArray, target_t: FloatArray) -> None:
    """Both peers must model the same arm: FK against busarm's on the first targets."""
    for qd, t in zip(q_deg[:20], target_t[:20], strict=True):
        qr = np.radians(qd)
        for peer_t in (robot_ets.fkine(qr).A, chain.forward_kinematics([0.0, *qr, 0.0])):
            p = np.array(peer_t, dtype=np.float64)
            p[:3, 3] *= 1000.0
            if float(np.abs(p - t).max()) > 1e-6:
                raise RuntimeError("peer FK differs from busarm's: not the same arm")


def _time_peer(
    kin: ArmKinematics, name: str, dist: str, solve: Solver, targets: FloatArray,
    busarm_ns: Sequence[int],
) -> PeerResult:
    """Each solve timed alone (after 5 warm-up solves), then verified with busarm's FK."""
    for t in targets[:5]:
        solve(t)
    ns: list[int] = []
    qs = np.empty((len(targets), 5))
    claimed = 0
    clock = time.perf_counter_ns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, t in enumerate(targets):
            t0 = clock()
            qr, flag = solve(t)
            ns.append(clock() - t0)
            qs[i] = np.degrees(qr)
            claimed += flag
    pos, rot = pose_errors(kin.fk_matrix_batch(qs), targets)
    ok = (pos <= POS_TOL_MM) & (rot <= ROT_TOL_DEG) & in_limits(kin, qs)
    tm = timing_of(name, ns)
    ref = float(np.median(np.asarray(busarm_ns[: len(targets)]))) / 1000.0
    return PeerResult(
        name, f"{dist} {_version(dist)}", len(targets), tm.median_us, tm.p90_us,
        int(ok.sum()), claimed, round(ref, 3), round(tm.median_us / ref, 1),
        float(np.median(pos)), float(np.median(rot)),
    )


def run_peers(
    kin: ArmKinematics, q_deg: FloatArray, target_t: FloatArray, busarm_ns: Sequence[int],
    n_rtb: int, n_ikpy: int, config: ArmConfig | None = None,
) -> list[PeerResult]:
    """Time and verify the peers on the first targets; raises ImportError if missing."""
    robot = build_rtb(kin)
    chain = build_ikpy(config if config is not None else load_arm_config())
    ets = robot.ets()  # ends with the tool; robot.ik_LM would strip the tool again (1.5.0)
    _check_same_arm(ets, chain, q_deg, target_t)

    q0 = np.radians(PEER_Q0_DEG)
    init = [0.0, *q0, 0.0]

    def rtb_solve(t: npt.ArrayLike) -> tuple[FloatArray, bool]:
        sol = ets.ik_LM(_m(t), q0=q0, ilimit=30, slimit=100, tol=1e-14)
        return np.asarray(sol.q, dtype=np.float64), bool(sol.success)

    def ikpy_solve(t: npt.ArrayLike) -> tuple[FloatArray, bool]:
        tm = _m(t)
        full = chain.inverse_kinematics(target_position=tm[:3, 3],
                                        target_orientation=tm[:3, :3],
                                        orientation_mode="all", initial_position=init)
        return np.asarray(full[1:6], dtype=np.float64), True  # ikpy has no success flag

    peers: tuple[tuple[str, str, Solver, int], ...] = (
        ("RTB ets().ik_LM", "roboticstoolbox-python", rtb_solve, n_rtb),
        ("ikpy inverse_kinematics", "ikpy", ikpy_solve, n_ikpy),
    )
    return [_time_peer(kin, name, dist, solve, target_t[:m], busarm_ns)
            for name, dist, solve, m in peers]


# ------------------------------------------------------------------------ the caveat


def robot_ik_lm_caveat(n: int, seed: int) -> dict[str, int]:
    """Successes of ``robot.ik_LM`` with and without ``tool=eye(4)`` on n targets."""
    kin = ArmKinematics.from_config(load_arm_config(), check_table=False)
    robot = build_rtb(kin)
    q = random_joints(kin, n, np.random.default_rng(seed))
    targets = kin.fk_matrix_batch(q)
    out = {}
    options: tuple[tuple[str, dict[str, Any]], ...] = (
        ("robot.ik_LM", {}), ("robot.ik_LM tool=eye(4)", {"tool": np.eye(4)}))
    for label, kw in options:
        ok = 0
        for t in targets:
            tm = t.copy()
            tm[:3, 3] /= 1000.0
            sol = robot.ik_LM(tm, q0=np.radians(PEER_Q0_DEG), ilimit=30, slimit=100, tol=1e-14,
                              **kw)
            pos, rot = pose_errors(kin.fk_matrix(np.degrees(sol.q))[None], t[None])
            ok += int(pos[0] <= POS_TOL_MM and rot[0] <= ROT_TOL_DEG)
        out[label] = ok
    return out


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        description="IK peers side by side with busarm, plus the robot.ik_LM caveat check.")
    ap.add_argument("--n", type=int, default=1000, help="targets for Robotics Toolbox")
    ap.add_argument("--n-ikpy", type=int, default=100, help="targets for ikpy (first N)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    report = run_ik_bench(n=max(args.n, 10), batch_n=100_000, seed=args.seed, peers=True,
                          n_rtb=args.n, n_ikpy=args.n_ikpy)
    if report.peers_note:
        raise SystemExit(report.peers_note)
    for p in report.peers:
        print(json.dumps(asdict(p)))
    caveat = robot_ik_lm_caveat(min(args.n, 100), args.seed)
    print(f"robot.ik_LM caveat (successes of {min(args.n, 100)}): {caveat}")


if __name__ == "__main__":
    main()
