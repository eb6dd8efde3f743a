"""The arm's servos in joint terms: the base of ``busarm.arm.arm.Arm``.

The servos are a ``ServoPort`` (busarm.bus.servo_port: the LX line, the controller
board, a robot served over Zenoh, or any other family's backend); their pulses are the
port's ``model``'s, so nothing here assumes a servo family's scale.

At connect each servo is checked (it answers; its stored offset is the calibration's)
and its pulse range is the joint's limits mapped through the calibration, rounded
inward, and narrowed to the servo's own stored angle limits. Then joint angles and
servo positions convert both ways, positions are read back, and targets are sent,
waited for, stopped and held. The motions themselves (joint moves, lines, the gripper,
action groups) are ``Arm``'s.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping, Sequence

from busarm.arm.calibration import Calibration
from busarm.arm.chain import Joints, Pose
from busarm.arm.config import ArmConfig, JointConfig
from busarm.arm.gripper import GripperState, gripper_state
from busarm.arm.kinematics import ArmKinematics
from busarm.bus.servo_port import ServoModel, ServoPort
from busarm.clock import Clock
from busarm.errors import (
    BusTimeoutError,
    CalibrationError,
    LimitError,
    UnreliableLineError,
)
from busarm.units import check_range

SETTLE_TIMEOUT_S = 1.0
"""How long settled_joints_deg waits for the servos to stand still after a move's end."""
SETTLE_POLL_S = 0.1
DEFAULT_TOLERANCE_DEG = 1.5
"""Position feedback is whole pulses (0.24 deg on LX servos), and a loaded servo settles
a pulse or two short; a wait within this counts as arrived."""


class ArmServos:
    """An arm config's servos on a ServoPort, commanded and read in joint degrees."""

    def __init__(
        self,
        bus: ServoPort,
        config: ArmConfig,
        calibration: Calibration | None = None,
        *,
        check: bool = True,
    ) -> None:
        self.bus = bus
        self.model: ServoModel = bus.model
        """The servos' position scale (the port's): what the arm's pulses are."""
        self.clock: Clock = bus.clock
        """Every wait of the arm's is on its bus's clock (simulated time on a twin)."""
        self.config = config
        self.kin = ArmKinematics.from_config(config)
        self.calibration = calibration or Calibration.identity(config)
        self.calibration.check_against(config)
        self._sw = {c.servo_id: c.software_offset_deg for c in self.calibration.joints}
        self._lock = threading.RLock()
        # Pulse limits per servo: the joint limits mapped through the calibration and
        # rounded inward, so a rounded command can never land outside a limit.
        self._pulse_limits: dict[int, tuple[int, int]] = {}
        for j in config.joints:
            self._pulse_limits[j.servo_id] = self._joint_pulse_limits(j)
        g = config.gripper
        self._pulse_limits[g.servo_id] = (g.min_pulses, g.max_pulses)
        if check:
            self._check_servos()
        for sid, (lo, hi) in self._pulse_limits.items():
            bus.set_limits_deg(sid, self.model.deg_from_pulses(lo),
                               self.model.deg_from_pulses(hi))

    # ------------------------------------------------------------------ checks

    def _joint_pulse_limits(self, j: JointConfig) -> tuple[int, int]:
        a = self.pulses_exact(j, j.min_deg)
        b = self.pulses_exact(j, j.max_deg)
        lo, hi = math.ceil(min(a, b) - 1e-9), math.floor(max(a, b) + 1e-9)
        lo, hi = max(lo, self.model.min_pulses), min(hi, self.model.max_pulses)
        if lo >= hi:
            raise CalibrationError(
                f"{j.name}: with its calibration the joint range maps outside the servo"
            )
        return lo, hi

    def _check_servos(self) -> None:
        """Every servo answers; stored offsets match the calibration; narrow the pulse
        limits to each servo's own stored angle limits."""
        for j in self.config.joints:
            cal = next(c for c in self.calibration.joints if c.servo_id == j.servo_id)
            try:
                offset_deg = self.bus.read_offset_deg(j.servo_id)
                lo_deg, hi_deg = self.bus.read_angle_limits_deg(j.servo_id)
            except UnreliableLineError:
                raise  # not "does not answer": it may, late (the driver's words)
            except BusTimeoutError as exc:
                raise BusTimeoutError(
                    f"{j.name} (servo {j.servo_id}) does not answer: check the cable, the "
                    f"power and the ID (`busarm scan`)",
                    servo_id=j.servo_id, command=exc.command, timeout_s=exc.timeout_s,
                ) from exc
            if abs(offset_deg - cal.hardware_offset_deg) > 1e-6:
                raise CalibrationError(
                    f"{j.name} (servo {j.servo_id}) has a stored offset of {offset_deg:+.2f} deg "
                    f"but the calibration says {cal.hardware_offset_deg:+.2f} deg: was the servo "
                    f"replaced or re-zeroed? Run `busarm arm calibrate`"
                )
            self._narrow(j.servo_id, lo_deg, hi_deg)
        g = self.config.gripper
        try:
            lo_deg, hi_deg = self.bus.read_angle_limits_deg(g.servo_id)
        except UnreliableLineError:
            raise
        except BusTimeoutError as exc:
            raise BusTimeoutError(
                f"the gripper (servo {g.servo_id}) does not answer",
                servo_id=g.servo_id, command=exc.command, timeout_s=exc.timeout_s,
            ) from exc
        self._narrow(g.servo_id, lo_deg, hi_deg)

    def _narrow(self, servo_id: int, lo_deg: float, hi_deg: float) -> None:
        lo, hi = self._pulse_limits[servo_id]
        m = self.model
        slo = round(lo_deg / m.deg_per_pulse) + m.center_pulses
        shi = round(hi_deg / m.deg_per_pulse) + m.center_pulses
        nlo, nhi = max(lo, slo), min(hi, shi)
        if nlo >= nhi:
            raise LimitError(
                f"servo {servo_id}'s stored angle limits {slo}..{shi} pulses leave nothing of "
                f"its configured range {lo}..{hi}: widen them with `busarm limits`"
            )
        self._pulse_limits[servo_id] = (nlo, nhi)

    # ------------------------------------------------------------------ conversions

    @property
    def pulse_limits(self) -> dict[int, tuple[int, int]]:
        """Each servo's allowed positions (pulses): its joint's limits, the gripper's range."""
        return dict(self._pulse_limits)

    def pulses_exact(self, joint: JointConfig, angle_deg: float) -> float:
        """The (fractional) servo position for a joint angle, with the calibration."""
        servo_deg = joint.servo_deg_from_angle_deg(angle_deg) + self._sw[joint.servo_id]
        return self.model.pulses_exact(servo_deg)

    def joint_deg_from_servo_deg(self, joint: JointConfig, servo_deg: float) -> float:
        return joint.angle_deg_from_servo_deg(servo_deg - self._sw[joint.servo_id])

    def servo_pulses(self, joints_deg: Sequence[float]) -> dict[int, int]:
        """Servo positions for joint angles; LimitError before anything is sent if any
        joint is outside its limits or would leave its servo's range."""
        angles = self.config.check_joints(joints_deg)
        out = {}
        for j, a in zip(self.config.joints, angles, strict=True):
            p = self.pulses_exact(j, a)
            lo, hi = self._pulse_limits[j.servo_id]
            # Within the joint limits the exact value is within [lo, hi] up to the
            # inward rounding of the limits; clamping moves it by under one pulse.
            if not lo - 1.0 <= p <= hi + 1.0:
                raise LimitError(
                    f"{j.name} = {a:.2f} deg needs servo {j.servo_id} at {p:.0f} pulses, outside "
                    f"its limits {lo}..{hi} pulses (servo angle limits or calibration)"
                )
            out[j.servo_id] = min(max(round(p), lo), hi)
        return out

    def joints_from_pulses(self, pulses: Mapping[int, float]) -> Joints:
        """Joint angles for servo positions (calibrated)."""
        a = [
            self.joint_deg_from_servo_deg(j, self.model.deg_from_pulses(pulses[j.servo_id]))
            for j in self.config.joints
        ]
        return (a[0], a[1], a[2], a[3], a[4])

    # ------------------------------------------------------------------ reading

    def read_joints_deg(self) -> Joints:
        """The measured joint angles (one position read per joint)."""
        with self._lock:
            pulses = {
                j.servo_id: self.bus.read_position_pulses(j.servo_id) for j in self.config.joints
            }
        return self.joints_from_pulses(pulses)

    def read_pose(self) -> Pose:
        """The tool pose from the measured joints."""
        return self.kin.fk(self.read_joints_deg())

    def read_gripper_pulses(self) -> int:
        return self.bus.read_position_pulses(self.config.gripper.servo_id)

    def read_gripper_state(self) -> GripperState:
        """Open, closed or holding (``busarm.arm.gripper``), from the gripper's position,
        the position it was last told and its torque, read back."""
        sid = self.config.gripper.servo_id
        position = self.bus.read_position_pulses(sid)
        target = self.bus.last_target_pulses(sid)
        return gripper_state(self.config.gripper, position, target, self.bus.read_torque(sid))

    # ------------------------------------------------------------------ sending

    def command_joints(self, joints_deg: Sequence[float], duration_s: float) -> None:
        """Send joint targets to arrive in ``duration_s``, reading nothing and not waiting
        (a caller that streams small steps and knows where the arm is: a jog). Joint
        limits are checked; the caller keeps each step within the joints' speeds."""
        check_range("duration_s", duration_s, 0.0, self.model.max_move_s, "s")
        self._send_pulses(self.servo_pulses(joints_deg), duration_s)

    def _send_pulses(self, pulses: Mapping[int, int], duration_s: float) -> None:
        targets = {sid: self.model.deg_from_pulses(p) for sid, p in pulses.items()}
        self.bus.sync_move_deg(targets, duration_s)

    def wait(
        self,
        joints_deg: Sequence[float],
        *,
        tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
        timeout_s: float | None = None,
    ) -> Joints:
        """Wait until the measured joints are within ``tolerance_deg`` of ``joints_deg``.

        Default timeout: the end of the last commanded move plus 2 s. Raises
        MotionTimeoutError naming the joints that did not arrive.
        """
        target = self.config.check_joints(joints_deg)
        servo_targets = {
            j.servo_id: self.model.deg_from_pulses(self.pulses_exact(j, a))
            for j, a in zip(self.config.joints, target, strict=True)
        }
        # Joint and servo degrees differ only by sign and offset: the tolerance carries over.
        positions = self.bus.wait_until_reached(
            servo_targets, tolerance_deg=tolerance_deg, timeout_s=timeout_s
        )
        return self.joints_from_pulses(
            {sid: deg / self.model.deg_per_pulse + self.model.center_pulses
             for sid, deg in positions.items()}
        )

    def settled_joints_deg(self, *, timeout_s: float = SETTLE_TIMEOUT_S,
                           poll_s: float = SETTLE_POLL_S) -> Joints:
        """The measured joints once the last commanded move has ended and the servos
        stand still (two reads ``poll_s`` apart within a pulse), or ``timeout_s`` after
        its end: where the arm stays, as a later read finds it. A ``wait`` returns within
        tolerance, while the servos may still be closing the last degree or two."""
        check_range("poll_s", poll_s, 0.001, 1.0, "s")
        end_s = self.bus.move_end_s(j.servo_id for j in self.config.joints)
        self.clock.sleep(max(end_s - self.clock.now(), 0.0))
        deadline = self.clock.now() + timeout_s
        last = self.read_joints_deg()
        while self.clock.now() < deadline:
            self.clock.sleep(poll_s)
            now = self.read_joints_deg()
            if max(abs(a - b) for a, b in zip(now, last, strict=True)) <= self.model.deg_per_pulse:
                return now
            last = now
        return last

    def stop(self) -> None:
        """Stop every servo where it is and hold it (MOVE_STOP)."""
        self.bus.emergency_stop()

    def hold_here(self) -> list[int]:
        """Torque on where each servo stands (a move to its present position), so that
        nothing jumps. Servos found outside their limits are left limp (never commanded
        outside them); returns their IDs."""
        limp = []
        for sid in self.config.servo_ids:
            position = self.bus.read_position_pulses(sid)
            lo, hi = self._pulse_limits[sid]
            if lo <= position <= hi:
                self.bus.move_deg(sid, self.model.deg_from_pulses(position), 0.0)
            else:
                limp.append(sid)
        return limp

    def set_torque(self, enabled: bool) -> None:
        """Torque on (hold) or off (limp: the arm falls under its own weight) for all servos."""
        for sid in self.config.servo_ids:
            self.bus.set_torque(sid, enabled)

    def _guarded(self, action: Callable[[], None]) -> None:
        """Run a motion; on any exception stop and hold the arm, then re-raise."""
        try:
            action()
        except BaseException:
            self.bus.emergency_stop()
            raise


__all__ = ["DEFAULT_TOLERANCE_DEG", "ArmServos"]
