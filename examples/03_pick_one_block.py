"""Pick one block and put it in the bin of its colour.

``PickSorter`` is the pick-and-sort job; here one cycle of it: look, choose, grasp,
carry, release. On the twin the block's true place is known, so the program checks it.
"""

from busarm import PickSorter, Robot, RobotConfig, TwinSpec

world = TwinSpec(seed=5, blocks=2)
robot_config = RobotConfig(world)  # its camera calibration kept as the commands keep it

with Robot.open(robot_config) as robot:
    sorter = PickSorter(robot)
    seen = sorter.survey()
    target = seen[0]
    where = target.location
    print(f"picking the {target.color} block seen at x {where.x_mm:.0f}, y {where.y_mm:.0f} mm")
    held, why_not, put_at, _plan = sorter.pick_and_place(target)
    robot.arm.home()
    print("held it" if held else f"did not hold it: {why_not}", "; put at", put_at)
    if robot.twin is not None:  # the twin's truth, which the job never reads
        bin_x, bin_y = robot.bins[target.color]
        miss_mm = min(((b.x_mm - bin_x) ** 2 + (b.y_mm - bin_y) ** 2) ** 0.5
                      for b in robot.twin.blocks() if b.color == target.color)
        print(f"truth: the {target.color} block is {miss_mm:.0f} mm from its bin's centre")
