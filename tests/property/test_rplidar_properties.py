"""Properties of the RPLIDAR A1 codec (hypothesis).

What resynchronisation can guarantee: the protocol's only framing is the start flag S
with its inverse and the check bit, so noise can look like a node (1 in 8 random
windows do). The guarantee tested here: when no 5-byte window starting in the noise's
last 4 bytes passes those checks (true when each of those bytes has its two low bits
equal), every node after the noise is recovered, exactly and in order, whatever the
noise before them and however the stream is split into reads.
"""

from __future__ import annotations

import contextlib
import math

from hypothesis import given
from hypothesis import strategies as st

from busarm.errors import ProtocolError
from busarm.protocol.rplidar import (
    Node,
    NodeParser,
    RequestParser,
    decode_descriptor,
    decode_health,
    decode_info,
    decode_node,
    find_descriptor,
    node_from_si,
)

wire_nodes = st.builds(Node, st.booleans(), st.integers(0, 63), st.integers(0, 0x7FFF),
                       st.integers(0, 0xFFFF))
# A byte whose two low bits are equal: S == not-S, so no node can start on it.
no_start_bytes = st.integers(0, 255).map(lambda b: (b & 0xFC) | (0b11 if b & 1 else 0))


def feed_in_pieces(parser: NodeParser, data: bytes, cuts: list[int]) -> list[Node]:
    out: list[Node] = []
    start = 0
    for cut in [*sorted(c % (len(data) + 1) for c in cuts), len(data)]:
        out += parser.feed(data[start:cut])
        start = max(start, cut)
    return out


@given(wire_nodes)
def test_nodes_round_trip(node: Node) -> None:
    assert decode_node(node.encode()) == node


@given(st.lists(wire_nodes, max_size=40), st.lists(st.integers(0, 400), max_size=8))
def test_a_clean_stream_is_decoded_exactly_however_it_is_split(
    nodes: list[Node], cuts: list[int]
) -> None:
    stream = b"".join(n.encode() for n in nodes)
    assert feed_in_pieces(NodeParser(), stream, cuts) == nodes


@given(st.binary(max_size=60), st.lists(no_start_bytes, min_size=4, max_size=4),
       st.lists(wire_nodes, min_size=1, max_size=30), st.lists(st.integers(0, 400), max_size=6))
def test_nodes_after_noise_are_all_recovered(
    noise: bytes, guard: list[int], nodes: list[Node], cuts: list[int]
) -> None:
    stream = noise + bytes(guard) + b"".join(n.encode() for n in nodes)
    parser = NodeParser()
    got = feed_in_pieces(parser, stream, cuts)
    assert got[len(got) - len(nodes):] == nodes
    # Whatever came of the noise took at least its 5 bytes each.
    assert 5 * (len(got) - len(nodes)) + parser.skipped_bytes == len(noise) + 4


@given(st.floats(0.0, 2 * math.pi, exclude_max=True), st.floats(0.001, 16.0))
def test_si_values_quantise_within_half_a_wire_unit(angle_rad: float, distance_m: float) -> None:
    node = node_from_si(False, 0, angle_rad, distance_m)
    error_deg = abs(math.remainder(math.degrees(angle_rad) - node.angle_q6 / 64.0, 360.0))
    assert error_deg <= 1 / 128 + 1e-9
    assert abs(node.distance_m - distance_m) <= 0.000125 + 1e-12


@given(st.binary(max_size=200))
def test_arbitrary_bytes_raise_nothing_but_protocol_errors(data: bytes) -> None:
    NodeParser().feed(data)
    RequestParser().feed(data)
    find_descriptor(data)
    for decode in (decode_node, decode_info, decode_health, decode_descriptor):
        for chunk in (data, data[:5], data[:3], data[:7], data[:20]):
            with contextlib.suppress(ProtocolError):
                decode(chunk)
