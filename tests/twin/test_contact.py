"""Guarded lines on the twin, through the real path (Robot -> Arm -> bus bytes -> servo
models -> MuJoCo): free lines at pick-and-sort speeds never trip; fingers landing on a
block trip within a bounded time of the touch (MuJoCo's contacts on the twin's clock),
and the arm backs off to where the line started, holding.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from busarm.apps.pick_sort.sorter import PickSortSettings
from busarm.errors import ConfigError, ContactError
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

PICK_SORT_MM_S = PickSortSettings().line_speed_mm_s
SPEEDS_MM_S = (120.0, PICK_SORT_MM_S)
APPROACH_Z_MM = 60.0
GRASP_Z_MM = 15.0
AWAY_MM = (-150.0, 300.0)
"""Where the block waits while it is not wanted (on the table, clear of arm and bins)."""
MAX_DELAY_S = 0.15


@pytest.fixture(scope="module")
def robot() -> Iterator[Robot]:
    with Robot.open(RobotConfig(TwinSpec(seed=3, blocks=1),
                                camera=CameraSpec(calibrate=False))) as r:
        yield r


class FirstTouch:
    """The twin clock's time when block 0 first touches anything but the table."""

    def __init__(self, twin: Twin) -> None:
        self.twin = twin
        self.block = twin.model.geom("block0").id
        self.table = twin.model.geom("table").id
        self.at_s: float | None = None
        self.geom = ""

    def __call__(self) -> None:
        if self.at_s is not None:
            return
        d = self.twin.data
        for i in range(d.ncon):
            pair = {int(d.contact[i].geom1), int(d.contact[i].geom2)}
            if self.block in pair and self.table not in pair:
                self.at_s = self.twin.clock.now()
                other = (pair - {self.block}).pop()
                self.geom = self.twin.model.geom(other).name
                return


def _tool_mm(robot: Robot) -> tuple[float, float, float]:
    p = robot.arm.read_pose()
    return p.x_mm, p.y_mm, p.z_mm


def test_free_lines_at_pick_sort_speeds_never_trip(robot: Robot) -> None:
    arm = robot.arm
    assert robot.twin is not None
    robot.twin.place_block(0, *AWAY_MM)
    lines = worst = 0.0
    for x, y, pitch in ((150, -100, -90), (150, 100, -90), (200, 0, -90), (230, -60, -90),
                        (260, 80, -45), (280, -20, -45)):
        for speed, profile in [*((v, "min_jerk") for v in SPEEDS_MM_S), (200.0, "time_optimal")]:
            arm.move_to(x, y, APPROACH_Z_MM + 15, pitch, 0.0, speed_deg_s=180.0)
            low = GRASP_Z_MM if pitch == -90 else 40.0  # a tilted pad's corner is lower
            aside = (x, y + (40 if y <= 0 else -40), APPROACH_Z_MM)
            for target in ((x, y, low), (x, y, APPROACH_Z_MM + 15), aside):
                move = arm.move_line_guarded(*target, pitch, 0.0, speed_mm_s=speed,
                                             profile=profile)
                lines += 1
                worst = max(worst, move.worst_lag_fraction)
                assert move.late_s < 1e-3, "the readings delayed a waypoint"
                # Arrived (within the joints' tolerance); a stretched arm sags a little.
                assert math.dist(_tool_mm(robot), target) < 3.0
    print(f"{lines:.0f} free lines: the worst lag was {worst:.2f} of the allowance")
    assert lines >= 20 and worst < 0.6


@pytest.mark.parametrize(("speed_mm_s", "profile"),
                         [*((speed, "min_jerk") for speed in SPEEDS_MM_S),
                          (200.0, "time_optimal")])  # pick-and-sort's descent
@pytest.mark.parametrize("landing", ["fingers_closed", "one_finger"])
def test_fingers_landing_on_a_block_trip_and_the_arm_backs_off(
        robot: Robot, landing: str, speed_mm_s: float, profile: str) -> None:
    arm, twin, clock = robot.arm, robot.twin, robot.clock
    assert twin is not None
    x, y = (190.0, -40.0) if landing == "one_finger" else (210.0, 50.0)
    twin.place_block(0, *AWAY_MM)
    if landing == "one_finger":
        arm.open_gripper(gap_mm=50.0)
    else:
        arm.grip()
    arm.move_to(x, y, APPROACH_Z_MM, -90.0, 0.0, speed_deg_s=180.0)
    clock.sleep(0.3)  # the arm stops ringing
    start = _tool_mm(robot)
    # Under the tool point, or under one finger pad (30 mm out along the closing axis).
    side = arm.kin.fk_matrix(arm.read_joints_deg())[:3, 1]
    out_mm = 30.0 if landing == "one_finger" else 0.0
    twin.place_block(0, start[0] + out_mm * side[0], start[1] + out_mm * side[1], 0.0)
    clock.sleep(0.1)
    touch = FirstTouch(twin)
    clock.attach(touch)
    try:
        with pytest.raises(ContactError) as caught:
            arm.move_line_guarded(x, y, GRASP_Z_MM, -90.0, 0.0, speed_mm_s=speed_mm_s,
                                  profile=profile)
    finally:
        clock.detach(touch)
    e = caught.value
    assert touch.at_s is not None and touch.geom.startswith("finger"), touch.geom
    delay_s = e.detected_s - touch.at_s
    print(f"{landing} at {speed_mm_s:g} mm/s: touched at {touch.at_s:.3f} s, detected "
          f"{delay_s * 1000:.0f} ms later; {e}")
    assert 0.0 < delay_s < MAX_DELAY_S
    names = [j.name for j in arm.config.joints]
    assert e.joint in names and e.joint in str(e) and e.lag_deg > 1.0
    assert e.backed_off and "backed off" in str(e)
    top_mm = twin.scene.blocks[0].size_mm
    assert top_mm - 4.0 < e.tool_mm[2] < top_mm + 2.0, e.tool_mm
    assert abs(e.along_mm - (start[2] - e.tool_mm[2])) < 2.0
    assert math.dist(_tool_mm(robot), start) < 2.0
    assert all(arm.bus.read_torque(j.servo_id) for j in arm.config.joints)  # holding


def test_bad_input_is_refused_before_any_byte(robot: Robot) -> None:
    before = robot.clock.now()  # any bus traffic moves the twin's clock (wire timing)
    for bad in ({"speed_mm_s": 0.0}, {"profile": "jerky"}, {"z_mm": math.nan}):
        args = {"x_mm": 200.0, "y_mm": 0.0, "z_mm": GRASP_Z_MM} | bad
        with pytest.raises(ConfigError):
            robot.arm.move_line_guarded(**args)  # type: ignore[arg-type]
    assert robot.clock.now() == before
