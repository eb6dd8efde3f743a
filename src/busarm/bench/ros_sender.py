"""A ROS 2 node in a process of its own that sends one joint trajectory, says so, and
stays connected until it is killed: the sender whose link ``busarm bench ros`` (and its
tests) drop mid-trajectory.

``python -m busarm.bench.ros_sender ENDPOINT JOINT DEG SECONDS``: connect to ENDPOINT,
send JOINT to DEG in SECONDS on /joint_trajectory, print ``sent``, wait.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from busarm.bus.zenoh_session import open_session
from busarm.ros import messages as m
from busarm.ros.node import RosNode

__all__ = [
    "main",
    "one_point_trajectory",
]


def one_point_trajectory(joint: str, deg: float, seconds: float) -> object:
    """A JointTrajectory taking ``joint`` to ``deg`` in ``seconds``."""
    point = m.message_class("trajectory_msgs/msg/JointTrajectoryPoint")
    duration = m.message_class("builtin_interfaces/msg/Duration")
    empty = np.zeros(0)
    return m.message_class(m.JOINT_TRAJECTORY)(
        header=m.header(0.0, ""), joint_names=[joint], points=[point(
            positions=np.radians([deg]), velocities=empty, accelerations=empty,
            effort=empty, time_from_start=duration(sec=int(seconds),
                                                   nanosec=round(seconds % 1 * 1e9)))])


def main(argv: list[str]) -> None:
    endpoint, joint, deg, seconds = argv[0], argv[1], float(argv[2]), float(argv[3])
    session = open_session(connect=[endpoint])
    node = RosNode(session, "sender")
    publisher = node.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.5)  # the bridge hears of this publisher before its first message
    publisher.publish(one_point_trajectory(joint, deg, seconds))
    print("sent", flush=True)
    time.sleep(3600)


if __name__ == "__main__":
    main(sys.argv[1:])
