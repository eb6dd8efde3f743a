"""The dashboard's mobile requests (``transport``, ``line_follow``): any fields give one
typed request or one RequestError naming the request, the field and what is allowed;
valid ones round-trip."""

from __future__ import annotations

import json

from hypothesis import given
from hypothesis import strategies as st

from busarm.dashboard.protocol import (
    LAPS_RANGE,
    LINE_SPEED_RANGE_M_S,
    NAME_CHARS,
    LineFollow,
    NavTransport,
    RequestError,
    parse_request,
)

JOINTS = ("base_yaw", "shoulder_pitch")
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=4),
    max_leaves=12)
names = st.text(NAME_CHARS, min_size=1, max_size=64)


@given(st.sampled_from(["transport", "line_follow"]),
       st.dictionaries(st.sampled_from(["pick", "place", "color", "laps", "speed_m_s",
                                        "colors", "other"]), json_values, max_size=4))
def test_any_fields_are_a_request_or_an_error_naming_it(kind: str,
                                                       fields: dict[str, object]) -> None:
    try:
        request = parse_request(json.dumps({"type": kind, **fields}), JOINTS)
    except RequestError as exc:
        assert str(exc).startswith(f"{kind}: ")
    else:
        assert isinstance(request, NavTransport if kind == "transport" else LineFollow)


@given(names, names, st.none() | names)
def test_valid_transports_round_trip(pick: str, place: str, color: str | None) -> None:
    fields = {"pick": pick, "place": place, **({} if color is None else {"color": color})}
    try:
        request = parse_request(json.dumps({"type": "transport", **fields}), JOINTS)
    except RequestError as exc:
        assert pick == place
        assert str(exc) == (f"transport: pick and place are both {pick!r}; give two "
                            "different points")
        return
    assert request == NavTransport("transport", pick, place, color)


@given(st.floats(*LAPS_RANGE), st.floats(*LINE_SPEED_RANGE_M_S),
       st.lists(names, max_size=8))
def test_valid_line_follows_round_trip(laps: float, speed_m_s: float,
                                       colors: list[str]) -> None:
    request = parse_request(json.dumps({"type": "line_follow", "laps": laps,
                                        "speed_m_s": speed_m_s, "colors": colors}), JOINTS)
    assert request == LineFollow("line_follow", laps, speed_m_s, tuple(colors))


@given(st.floats(allow_nan=False, allow_infinity=False).filter(
    lambda v: not LAPS_RANGE[0] <= v <= LAPS_RANGE[1]))
def test_laps_out_of_range_are_refused_with_the_range(laps: float) -> None:
    try:
        parse_request(json.dumps({"type": "line_follow", "laps": laps}), JOINTS)
    except RequestError as exc:
        text = str(exc)
        assert text.startswith("line_follow: laps = ")
        assert text.endswith("; allowed: a number 0.05..100")
    else:
        raise AssertionError(f"laps {laps} accepted")
