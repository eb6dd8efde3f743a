"""Drive the mobile base and read the Lidar: metres, radians and seconds.

The twin's mobile robot stands in a seeded room (``family="arena"``); its wheels are on
the simulated controller board (``controller``), as on the real robot. Wait with
``robot.clock.sleep``: on the twin the robot's time is simulated and passes only as the
program waits on its clock (``time.sleep`` would leave it standing still).
"""

import math

from busarm import BoardSettings, CameraSpec, Robot, RobotConfig, TwinSpec

world = TwinSpec(family="arena", seed=3, controller=BoardSettings())
with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot:
    base, lidar, clock = robot.base, robot.lidar, robot.clock
    assert base is not None and lidar is not None
    scan = lidar.read_scan()
    print(f"{scan!r}; nearest (m, rad): {scan.nearest()}")
    start = clock.now()
    while clock.now() - start < 2.0:  # 0.15 m/s ahead for 2 s
        base.drive(0.15, 0.0, 0.0)  # again within the watchdog's timeout, or it stops
        clock.sleep(0.1)
    base.stop()
    print("odometry after 2 s:", base.odometry().pose)
    base.move_by(0.0, 0.0, math.pi / 2)  # turn a quarter on the spot
    print("odometry after the turn:", base.odometry().pose)
