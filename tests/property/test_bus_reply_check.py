"""The hot path's whole-reply checksum test (busarm.bus.bus_core) against the protocol's
own: for any reply with the LX header, the low byte of the sum of all its bytes is
``_SUM_OK`` exactly when its checksum byte is right."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from busarm.bus.bus_core import _SUM_OK
from busarm.protocol import Frame
from busarm.protocol.commands import HEADER


def protocol_check(data: bytes) -> bool:
    n = len(data)
    return data[n - 1] == (~sum(data[2 : n - 1])) & 0xFF


@given(st.integers(0, 253), st.integers(0, 255), st.binary(min_size=0, max_size=7))
def test_a_valid_reply_sums_to_the_constant(servo_id: int, command: int, params: bytes) -> None:
    data = Frame(servo_id, command, params).to_bytes()
    assert data.startswith(HEADER)
    assert protocol_check(data)
    assert sum(data) & 0xFF == _SUM_OK


@given(st.binary(min_size=4, max_size=12))
def test_the_sum_agrees_with_the_checksum_on_any_bytes(body: bytes) -> None:
    data = HEADER + body
    assert (sum(data) & 0xFF == _SUM_OK) == protocol_check(data)
