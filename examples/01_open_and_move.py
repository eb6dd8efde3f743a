"""Open the robot and move its arm: a named pose, a point on the table, one joint.

Runs on the twin (the simulated robot) as it is; on your robot give its port
(``python 01_open_and_move.py /dev/ttyUSB0``) or its robot file (``... robot.toml``,
which ``busarm robot init`` writes).
"""

import sys

from busarm import Robot, load_robot_file

given = sys.argv[1] if len(sys.argv) > 1 else "twin"
description = load_robot_file(given)[0] if given.endswith(".toml") else given

with Robot.open(description) as robot:  # leaving by an error stops and holds the arm
    arm = robot.arm
    print(robot)
    robot.move_to_pose("look")  # the arm config's named poses: home, look, ...
    print("joints (deg):", [round(q, 1) for q in arm.read_joints_deg()])
    arm.move_to(150.0, 50.0, 60.0, pitch_deg=-90.0)  # the gripper above a point, in mm
    print("gripper at:", arm.read_pose())
    joints = list(arm.read_joints_deg())
    joints[0] -= 20.0  # turn the base 20 degrees
    arm.move_joints(joints)
    arm.home()
    print(f"done in {robot.clock.now():.2f} s of the robot's time")
