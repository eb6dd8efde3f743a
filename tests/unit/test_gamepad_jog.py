"""The gamepad teleoperator (busarm.learn.gamepad) through a real pipe carrying Linux
joystick events: a stick held turns its joint at a rate in proportion, for as long as it
is held (on an injected clock), within the joints' limits; a stick inside the dead zone,
or let go, holds still; buttons close and open the gripper and Start goes back."""

from __future__ import annotations

import math
import os
import struct

import pytest

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.learn.gamepad import GamepadJog

ARM = load_arm_config()
EVENT = struct.Struct("<IhBB")


def _send(fd: int, *events: tuple[int, int, int]) -> None:
    os.write(fd, b"".join(EVENT.pack(0, value, kind, number) for kind, number, value in events))


def test_a_held_stick_turns_its_joint_until_let_go() -> None:
    r, w = os.pipe()
    now = [0.0]
    try:
        with GamepadJog(ARM, fd=r, speed_deg_s=40.0, gripper_mm_s=20.0,
                        clock=lambda: now[0]) as pad:
            def hold(seconds: float) -> dict[str, float]:  # read every 0.1 s meanwhile
                for _ in range(round(seconds / 0.1)):
                    now[0] += 0.1
                    pad.read()
                return pad.read()

            _send(w, (0x82, 0, 0), (0x82, 1, 0))  # the state on opening: sticks centred
            start = pad.read()
            _send(w, (0x02, 0, 16384))  # left stick half right: base_yaw + 20 deg/s
            pad.read()
            moved = hold(0.5)
            assert moved["base_yaw.pos"] - start["base_yaw.pos"] == pytest.approx(
                math.radians(10.0), rel=1e-3)
            _send(w, (0x02, 0, 2000))  # inside the dead zone: held still from now on
            pad.read()
            assert hold(0.5)["base_yaw.pos"] == pytest.approx(moved["base_yaw.pos"], abs=1e-3)
            _send(w, (0x01, 0, 1))  # A held: the gripper closes at 20 mm/s
            pad.read()
            assert hold(0.5)["gripper.gap_mm"] == pytest.approx(start["gripper.gap_mm"] - 10)
            _send(w, (0x01, 0, 0), (0x02, 1, -32767))  # A let go; left stick up: shoulder -
            pad.read()
            now[0] += 100.0  # a stall: moved as if 0.2 s had passed, never further
            assert pad.read()["shoulder_pitch.pos"] == pytest.approx(
                start["shoulder_pitch.pos"] + math.radians(40.0 * 0.2), rel=1e-3)
            for _ in range(100):  # held for long: stops at the joint's limit
                now[0] += 0.2
                pad.read()
            assert pad.read()["shoulder_pitch.pos"] == pytest.approx(
                math.radians(ARM.joints[1].max_deg))
            _send(w, (0x01, 7, 1))  # Start: back where it began
            pad.read()
            assert pad.read()["base_yaw.pos"] == pytest.approx(start["base_yaw.pos"])
    finally:
        os.close(w)
        os.close(r)


def test_a_missing_gamepad_is_named() -> None:
    with pytest.raises(ConfigError, match="/dev/input/js9"):
        GamepadJog(ARM, device="/dev/input/js9").open()
