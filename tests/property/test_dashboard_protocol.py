"""The dashboard's request parser: any text a page sends gives one typed request or one
RequestError naming what is wrong, never another exception; valid requests round-trip."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.dashboard.protocol import (
    JOG_AXES,
    Jog,
    RequestError,
    message,
    parse_request,
)

JOINTS = ("base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch", "wrist_roll")
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=4),
    max_leaves=12)


@given(st.text(max_size=300) | st.binary(max_size=300))
def test_any_text_is_a_request_or_a_request_error(text: str | bytes) -> None:
    try:
        parse_request(text, JOINTS)
    except RequestError as exc:
        assert str(exc)


@given(st.sampled_from(["jog", "torque", "record", "pick_sort", "drive", "move_pose",
                        "gripper", "estop", "play"]),
       st.dictionaries(st.sampled_from(["joint", "axis", "direction", "speed", "servo", "on",
                                        "action", "name", "duration_ms", "colors", "order",
                                        "take_over", "group"]), json_values, max_size=4))
def test_any_fields_of_a_known_type_are_a_request_or_a_request_error(
        kind: str, fields: dict[str, object]) -> None:
    try:
        parse_request(json.dumps({"type": kind, **fields}), JOINTS)
    except RequestError as exc:
        assert kind in str(exc) or "JSON" in str(exc)


@given(st.sampled_from(JOINTS) | st.sampled_from(JOG_AXES), st.sampled_from([1, -1]),
       st.floats(0.05, 1.0))
def test_valid_jogs_round_trip(target: str, direction: int, speed: float) -> None:
    key = "axis" if target in JOG_AXES else "joint"
    request = parse_request(json.dumps({"type": "jog", key: target, "direction": direction,
                                        "speed": speed}), JOINTS)
    assert isinstance(request, Jog)
    assert getattr(request, key) == target
    assert (request.direction, request.speed) == (direction, speed)


def test_server_messages_are_strict_json() -> None:
    text = message("state", x=float("nan"), y=[float("inf"), 1.5], z={"w": -float("inf")})

    def refuse(name: str) -> None:
        raise ValueError(name)

    assert json.loads(text, parse_constant=refuse) == {"type": "state", "x": None,
                                                       "y": [None, 1.5], "z": {"w": None}}


@pytest.mark.parametrize("speed", [True, "1", float("nan"), 0.0, 1.01])
def test_jog_speeds_out_of_range_name_the_range(speed: object) -> None:
    with pytest.raises(RequestError, match=r"speed = .*; allowed: a number 0.05..1"):
        parse_request(json.dumps({"type": "jog", "joint": "base_yaw", "direction": 1,
                                  "speed": speed}), JOINTS)
