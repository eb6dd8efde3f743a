"""Build a map of the room by exploring it, then drive to a point on the map.

``build_map`` explores with the Lidar until no frontier is left; ``Navigator`` localises
on the map (starting from where the exploration ended), plans around what it knows and
follows the path. The map is saved as ROS
map_server files (``room.yaml`` and ``room.pgm``).
"""

from busarm import (
    BoardSettings,
    CameraSpec,
    Navigator,
    Pose2D,
    Robot,
    RobotConfig,
    TwinSpec,
    build_map,
    save_map,
)

world = TwinSpec(family="arena", seed=3, controller=BoardSettings())
with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot:
    run = build_map(robot, time_limit_s=240.0)
    print(f"mapped in {run.seconds:.0f} s of the robot's time ({run.finished}): {run.grid!r}")
    save_map("room.yaml", run.grid)
    navigator = Navigator(robot, run.grid)
    navigator.localize(run.poses[-1])  # where the exploration left it (map frame)
    trip = navigator.go_to(Pose2D(0.0, 0.0, 0.0))  # back to where the map began
    print(trip)
