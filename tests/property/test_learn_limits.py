"""A policy's action clipped to the limits (busarm.learn.limits), as properties: whatever
it asks (huge, negative, not a number), what is sent is within every joint's limits and
the gripper's travel, no joint steps further from its setpoint (where it was last told to
go, less what that move has still to go) than its servo turns in one frame, nor leads
where it was read by more than a few frames; a value already within every limit is sent
as asked, and the count of changed values is right."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.learn.limits import LEAD_FRAMES, SPEED_MARGIN, ActionLimits

ARM = load_arm_config()
LIMITS = ActionLimits.of(ARM, 20)
N = len(LIMITS.names)
anything = st.floats(allow_nan=True, allow_infinity=True, width=64)


def _measured(fractions: list[float]) -> np.ndarray:
    return np.array([lo + f * (hi - lo) for lo, hi, f in
                     zip(LIMITS.low, LIMITS.high, fractions, strict=True)])


@given(st.lists(anything, min_size=N, max_size=N),
       st.lists(st.floats(0.0, 1.0), min_size=N, max_size=N),
       st.one_of(st.none(), st.lists(st.floats(-2.0, 2.0), min_size=N, max_size=N)),
       st.floats(0.0, 0.2))
def test_what_is_sent_is_within_every_limit(asked: list[float], where: list[float],
                                            lead: list[float] | None, since_s: float) -> None:
    measured = _measured(where)
    top = np.array([SPEED_MARGIN * math.radians(j.max_speed_deg_s) / 20 for j in ARM.joints])
    # where the arm was last told to go: within LEAD_FRAMES frames' turn of the reading
    heading = None if lead is None else np.clip(
        measured + np.append(top * np.array(lead[:-1]), 10.0 * lead[-1]) * LEAD_FRAMES / 2,
        LIMITS.low, LIMITS.high)
    out, changed = LIMITS.clip(asked, measured, heading, since_s=since_s)
    assert np.all(np.isfinite(out))
    assert np.all(out >= np.asarray(LIMITS.low) - 1e-12)
    assert np.all(out <= np.asarray(LIMITS.high) + 1e-12)
    # each joint's step within what its servo turns in a frame, from its setpoint: the
    # heading, less what the last move (told since_s ago) has still to go
    start = measured if heading is None else heading
    share = 1.0 if heading is None else min(1.0, since_s / LIMITS.frame_s)
    assert np.all(np.abs(out - start)[:-1] <= share * top + 1e-12)
    assert np.all(np.abs(out - measured)[:-1] <= LEAD_FRAMES * top + 1e-12)
    kept = [a if math.isfinite(a) else s for a, s in zip(asked, start, strict=True)]
    differs = [not math.isfinite(a) or abs(o - k) > 1e-9
               for a, o, k in zip(asked, out, kept, strict=True)]
    assert changed == sum(differs)


@given(st.lists(st.floats(0.0, 1.0), min_size=N, max_size=N),
       st.lists(st.floats(-1.0, 1.0), min_size=N, max_size=N))
def test_an_action_within_the_limits_is_sent_as_asked(where: list[float],
                                                      toward: list[float]) -> None:
    measured = _measured(where)
    step = np.array([s if math.isfinite(s) else 10.0 for s in LIMITS.max_step]) * 0.99
    asked = np.clip(measured + step * np.array(toward), LIMITS.low, LIMITS.high)
    out, changed = LIMITS.clip(asked, measured)
    assert changed == 0 and np.allclose(out, asked, rtol=0, atol=1e-12)


def test_a_wrong_length_is_refused_by_name() -> None:
    with pytest.raises(ConfigError, match="an action has 6 values"):
        LIMITS.clip([0.0] * 5, [0.0] * 6)
    with pytest.raises(ConfigError, match="fps"):
        ActionLimits.of(ARM, 0)
    flat = LIMITS.flat(np.zeros(N))
    assert flat["min_duration_s"] == pytest.approx(0.05) and len(flat) == N + 1
