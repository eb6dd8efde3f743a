"""The keyboard teleoperator (busarm.learn.keyboard) through a real pseudo-terminal: keys
typed at the terminal jog the target, a pair per joint, kept within the joints' limits;
the terminal is put in cbreak mode while it is open and restored after."""

from __future__ import annotations

import math
import os
import termios

import pytest

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.learn.keyboard import KeyboardJog

ARM = load_arm_config()


def test_keys_jog_the_target_within_the_limits() -> None:
    master, slave = os.openpty()
    try:
        before = termios.tcgetattr(slave)
        with KeyboardJog(ARM, fd=slave, step_deg=5.0, gripper_step_mm=4.0) as jog:
            assert termios.tcgetattr(slave)[3] & termios.ICANON == 0  # cbreak: key by key
            start = jog.read()
            assert start["base_yaw.pos"] == pytest.approx(math.radians(ARM.pose("look")[0]))
            os.write(master, b"qqqAwxc")  # three left, one right (any case), up, ?, close
            now = jog.read()
            assert now["base_yaw.pos"] == pytest.approx(start["base_yaw.pos"]
                                                        + math.radians(10.0))
            assert now["shoulder_pitch.pos"] == pytest.approx(start["shoulder_pitch.pos"]
                                                             + math.radians(5.0))
            assert now["gripper.gap_mm"] == pytest.approx(start["gripper.gap_mm"] - 4.0)
            assert jog.presses == 6
            os.write(master, b"q" * 200)  # held down: stops at the joint's limit
            assert jog.read()["base_yaw.pos"] == pytest.approx(math.radians(ARM.joints[0].max_deg))
            os.write(master, b"h")
            assert jog.read() == start
        assert termios.tcgetattr(slave) == before
    finally:
        os.close(master)
        os.close(slave)


def test_a_bad_step_is_refused_by_name() -> None:
    with pytest.raises(ConfigError, match="step_deg"):
        KeyboardJog(ARM, fd=0, step_deg=0.0)
