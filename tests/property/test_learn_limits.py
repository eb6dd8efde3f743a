"""A policy's action clipped to the limits (busarm.learn.limits), as properties: whatever
it asks (huge, negative, not a number), what is sent is within every joint's limits and
the gripper's travel, no joint steps further from where it was read than its servo turns
in one frame, a value already within every limit is sent as asked, and the count of
changed values is right."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.learn.limits import SPEED_MARGIN, ActionLimits

ARM = load_arm_config()
LIMITS = ActionLimits.of(ARM, 20)
N = len(LIMITS.names)
anything = st.floats(allow_nan=True, allow_infinity=True, width=64)


def _measured(fractions: list[float]) -> np.ndarray:
    return np.array([lo + f * (hi - lo) for lo, hi, f in
                     zip(LIMITS.low, LIMITS.high, fractions, strict=True)])


@given(st.lists(anything, min_size=N, max_size=N),
       st.lists(st.floats(0.0, 1.0), min_size=N, max_size=N))
def test_what_is_sent_is_within_every_limit(asked: list[float], where: list[float]) -> None:
    measured = _measured(where)
    out, changed = LIMITS.clip(asked, measured)
    assert np.all(np.isfinite(out))
    assert np.all(out >= np.asarray(LIMITS.low) - 1e-12)
    assert np.all(out <= np.asarray(LIMITS.high) + 1e-12)
    steps = np.abs(out - measured)[:-1]
    top = [SPEED_MARGIN * math.radians(j.max_speed_deg_s) / 20 for j in ARM.joints]
    assert np.all(steps <= np.asarray(top) + 1e-12)
    differs = [not (math.isfinite(a) and abs(o - a) <= 1e-9) for a, o in zip(asked, out,
                                                                                strict=True)]
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
    with pytest.raises(ValueError, match="an action has 6 values"):
        LIMITS.clip([0.0] * 5, [0.0] * 6)
    with pytest.raises(ConfigError, match="fps"):
        ActionLimits.of(ARM, 0)
    flat = LIMITS.flat(np.zeros(N))
    assert flat["min_duration_s"] == pytest.approx(0.05) and len(flat) == N + 1
