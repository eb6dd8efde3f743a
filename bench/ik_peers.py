"""IK peers side by side with busarm: ``busarm bench ik --peers`` plus the caveat check.

Runs the same comparison as ``busarm bench ik --peers`` (Robotics Toolbox
``ets().ik_LM`` and ikpy ``inverse_kinematics(orientation_mode="all")`` against
busarm's closed form, on the same FK-generated targets, verified with busarm's FK),
then shows why the bench calls ``robot.ets().ik_LM`` and not ``robot.ik_LM``: in
roboticstoolbox-python 1.5.0 the ``DHRobot`` wrapper strips ``robot.tool`` from the
target although ``robot.ets()`` already ends with it, so the tool counts twice.

Run (peers from ``pip install -e '.[ikbench]'``, or ``make bench-ik``):
    python bench/ik_peers.py [--n 1000] [--n-ikpy 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bench_ik import (
    PEER_Q0_DEG,
    POS_TOL_MM,
    ROT_TOL_DEG,
    build_rtb,
    pose_errors,
    random_joints,
    run_ik_bench,
)


def robot_ik_lm_caveat(n: int, seed: int) -> dict[str, int]:
    """Successes of ``robot.ik_LM`` with and without ``tool=eye(4)`` on n targets."""
    kin = ArmKinematics.from_config(load_arm_config(), check_table=False)
    robot = build_rtb(kin)
    q = random_joints(kin, n, np.random.default_rng(seed))
    targets = kin.fk_matrix_batch(q)
    out = {}
    for label, kw in (("robot.ik_LM", {}), ("robot.ik_LM tool=eye(4)", {"tool": np.eye(4)})):
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="targets for Robotics Toolbox")
    ap.add_argument("--n-ikpy", type=int, default=100, help="targets for ikpy (first N)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    report = run_ik_bench(n=max(args.n, 10), batch_n=100_000, seed=args.seed, peers=True,
                          n_rtb=args.n, n_ikpy=args.n_ikpy)
    if report.peers_note:
        raise SystemExit(report.peers_note)
    for p in report.peers:
        print(json.dumps(p.__dict__))
    caveat = robot_ik_lm_caveat(min(args.n, 100), args.seed)
    print(f"robot.ik_LM caveat (successes of {min(args.n, 100)}): {caveat}")


if __name__ == "__main__":
    main()
