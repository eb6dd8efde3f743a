"""Record what the robot observes, while it moves, to a log: one line of JSON a step.

``robot.get_observation()`` reads every part once, each stamped on the robot's clock;
``as_dict()`` is the flat form (``shoulder_pitch.pos`` in rad, ``base.x`` in m...) that
datasets take. Cameras are left out here (``cameras=False``): a picture costs a render.
"""

import json

from busarm import Action, BoardSettings, CameraSpec, Robot, RobotConfig, TwinSpec, Twist

world = TwinSpec(family="arena", seed=3, controller=BoardSettings())
with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot, \
        open("observations.jsonl", "w", encoding="utf-8") as log:
    for step in range(20):
        robot.send_action(Action(base=Twist(0.1, 0.0, 0.2)))  # m/s, m/s, rad/s; checked
        robot.clock.sleep(0.1)
        seen = robot.get_observation(cameras=False, scan=step % 5 == 0)
        flat = {k: v for k, v in seen.as_dict().items() if isinstance(v, float | int)}
        log.write(json.dumps({"t": seen.t_s, **flat}) + "\n")
    print(seen)
print("wrote observations.jsonl")
