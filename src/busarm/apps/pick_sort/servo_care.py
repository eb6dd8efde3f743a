"""Looking after the servos during a long job: a pause while one is too hot, a clean stop
when the supply is too low for them."""

from __future__ import annotations

from collections.abc import Callable

from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.arm import Arm
from busarm.errors import ServoFaultError

__all__ = ["rest_while_hot"]


def rest_while_hot(arm: Arm, settings: PickSortSettings,
                   progress: Callable[[str], None] = lambda _: None) -> None:
    """Pause while a servo is hotter than ``settings.pause_above_c`` (arm at home, gripper
    open) until every one is below ``resume_below_c``; ServoFaultError if a supply reads
    below ``min_supply_v``, or if the servos are still hot after ``max_pause_s``."""
    s, clock = settings, arm.clock
    deadline = clock.now() + s.max_pause_s
    paused = False
    while True:
        states = arm.bus.read_states(arm.config.servo_ids)
        low = [st for st in states if st.vin_v < s.min_supply_v]
        if low:
            raise ServoFaultError(
                f"servo {low[0].servo_id} reads {low[0].vin_v:.2f} V, below "
                f"{s.min_supply_v:g} V: charge or change the battery", low[0].servo_id)
        hot = max(states, key=lambda st: st.temp_c)
        limit = s.resume_below_c if paused else s.pause_above_c
        if hot.temp_c < limit:
            if paused:
                progress(f"servos cool again ({hot.temp_c} C): going on")
            return
        if not paused:
            progress(f"servo {hot.servo_id} at {hot.temp_c} C: pausing until every "
                     f"servo is below {s.resume_below_c:g} C")
            arm.open_gripper()
            arm.move_joints(arm.config.pose("home"), speed_deg_s=s.joint_speed_deg_s)
            paused = True
        if clock.now() > deadline:
            raise ServoFaultError(f"servo {hot.servo_id} still at {hot.temp_c} C after "
                                  f"{s.max_pause_s:g} s of rest", hot.servo_id)
        clock.sleep(2.0)
