"""Look at the table with the wrist camera and say where each block is (mm, arm frame).

On the twin, its camera calibration is made the first time (a few seconds) and kept in
your configuration folder; on your robot, calibrate it once with ``busarm camera
calibrate`` and ``busarm camera handeye``.
"""

from busarm import Robot, RobotConfig, TwinSpec

world = TwinSpec(seed=3, blocks=4)
robot_config = RobotConfig(world)  # its camera calibration kept as the commands keep it

with Robot.open(robot_config) as robot:
    robot.move_to_pose("look")
    frame = robot.camera.read()
    joints = robot.arm.read_joints_deg()  # where the camera was when it took the picture
    for block in robot.locator().locate(frame.image, joints):
        where = block.location
        print(f"{block.color:>6} block at x {where.x_mm:6.1f} mm, y {where.y_mm:6.1f} mm")
