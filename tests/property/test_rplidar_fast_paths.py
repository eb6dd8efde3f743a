"""The RPLIDAR codec's fast paths against the plain definitions they replace (hypothesis).

``pack_nodes`` packs many nodes at once (a simulated A1 sends thousands a second) and
``NodeParser.feed`` reads the buffer in place: each must give exactly the bytes and the
nodes of the per-node definitions (``Node`` fields to bytes by hand; a 5-byte window
copied, checked by ``is_node`` and decoded by ``decode_node``), noise and all.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.errors import ConfigError
from busarm.protocol.rplidar import (
    NODE_SIZE,
    Node,
    NodeParser,
    decode_node,
    is_node,
    pack_nodes,
)

fields = st.tuples(st.booleans(), st.integers(0, 63), st.integers(0, 0x7FFF),
                   st.integers(0, 0xFFFF))


def reference_bytes(start: bool, quality: int, angle_q6: int, distance_q2: int) -> bytes:
    """A node's five bytes as the A1's protocol document lays them out."""
    s = int(start)
    return (bytes((quality << 2 | (1 - s) << 1 | s,)) + (angle_q6 << 1 | 1).to_bytes(2, "little")
            + distance_q2.to_bytes(2, "little"))


def reference_feed(buf: bytearray, data: bytes) -> tuple[list[Node], int]:
    """NodeParser.feed as first written: a copied window per position."""
    buf += data
    out: list[Node] = []
    skipped = i = 0
    while len(buf) - i >= NODE_SIZE:
        window = bytes(buf[i:i + NODE_SIZE])
        if is_node(window):
            out.append(decode_node(window))
            i += NODE_SIZE
        else:
            i += 1
            skipped += 1
    del buf[:i]
    return out, skipped


@given(st.lists(fields, max_size=40))
def test_packed_nodes_are_each_nodes_bytes_in_turn(nodes: list[tuple[bool, int, int, int]]) -> None:
    packed = pack_nodes(nodes)
    assert packed == b"".join(reference_bytes(*n) for n in nodes)
    assert packed == b"".join(Node(*n).encode() for n in nodes)
    parser = NodeParser()
    assert parser.feed(packed) == [Node(*n) for n in nodes]
    assert parser.skipped_bytes == 0


@pytest.mark.parametrize("bad", [(True, 64, 0, 0), (False, 0, 0x8000, 0), (False, 0, 0, 0x10000),
                                 (False, -1, 0, 0), (False, 0, -1, 0)])
def test_a_field_out_of_range_is_refused(bad: tuple[bool, int, int, int]) -> None:
    with pytest.raises(ConfigError, match="node out of range"):
        pack_nodes([(True, 10, 5, 5), bad])
    with pytest.raises(ConfigError, match="node out of range"):
        Node(*bad).encode()


@given(st.lists(st.binary(max_size=23), max_size=8))
def test_the_parser_reads_any_bytes_as_the_copying_parser_did(pieces: list[bytes]) -> None:
    parser, buf = NodeParser(), bytearray()
    skipped = 0
    for piece in pieces:
        want, skip = reference_feed(buf, piece)
        skipped += skip
        assert parser.feed(piece) == want
        assert parser.skipped_bytes == skipped
