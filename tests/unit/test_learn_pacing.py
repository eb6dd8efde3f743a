"""Frames paced on the robot's clock (busarm.learn.frames.next_frame): each waits until
its time; a frame more than a period late is not caught up on with frames back to back."""

from __future__ import annotations

import pytest

from busarm.clock import SimClock
from busarm.learn.frames import next_frame


def test_frames_wait_for_their_time_and_do_not_catch_up_after_a_stall() -> None:
    clock = SimClock()
    t0 = clock.now()
    due = next_frame(t0, 0.05, clock)
    assert due == pytest.approx(t0 + 0.05) and clock.now() == pytest.approx(t0 + 0.05)
    clock.sleep(0.03)  # a frame's work took 30 ms: the next is still on time
    due = next_frame(due, 0.05, clock)
    assert clock.now() == pytest.approx(t0 + 0.10) and due == pytest.approx(t0 + 0.10)
    clock.sleep(0.2)  # a stall of four frames: the next frame is now, then a period on
    due = next_frame(due, 0.05, clock)
    assert due == pytest.approx(t0 + 0.30) and clock.now() == pytest.approx(t0 + 0.30)
    due = next_frame(due, 0.05, clock)
    assert clock.now() == pytest.approx(t0 + 0.35)
