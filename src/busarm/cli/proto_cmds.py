"""Offline protocol tools: ``decode`` bytes into frames, ``encode`` a request. No bus."""

from __future__ import annotations

import re

import click

from busarm.cli.common import ServoIdType, parse_int
from busarm.errors import ConfigError, ProtocolError
from busarm.protocol import (
    SPECS,
    Command,
    Frame,
    FrameParser,
    checksum,
    decode_message,
    describe,
    encode_request,
)
from busarm.protocol.board import BoardFrameParser
from busarm.protocol.board.describe import describe_board_frame

__all__ = [
    "COMMANDS",
    "decode",
    "decode_lines",
    "encode",
    "parse_hex",
]


_SEPARATORS = re.compile(r"\\x|(?<![0-9a-fA-F])0[xX]|[\s,:;]+")


def parse_hex(texts: tuple[str, ...] | list[str]) -> bytes:
    """Bytes from hex text, each token on its own: ``1 3`` is 01 03, never 0x13.

    Tokens are separated by spaces, commas, colons or a 0x / \\x prefix. A token of one or
    two digits is one byte; a longer one is a run of bytes, two digits each
    (``5555010312``). Raises ConfigError naming the first bad character, or a token with
    an odd digit count.
    """
    out = bytearray()
    for line in texts:
        for token in _SEPARATORS.split(line):
            if not token:
                continue
            bad = re.search(r"[^0-9a-fA-F]", token)
            if bad:
                raise ConfigError(f"not hex: {bad.group()!r} in {line!r}")
            if len(token) == 1:
                token = "0" + token
            elif len(token) % 2:
                raise ConfigError(
                    f"{token!r} has an odd number of hex digits ({len(token)}): give each byte "
                    "as two digits, or separate the bytes with spaces"
                )
            out += bytes.fromhex(token)
    return bytes(out)


def decode_lines(data: bytes) -> tuple[list[str], int]:
    """One line per frame found in ``data`` and per candidate with a bad checksum (with the
    checksum it should have), in the order they occur, then a summary; and the number of
    valid frames."""
    bad: list[bytes] = []
    parser = FrameParser(on_bad_checksum=bad.append)
    frames = parser.feed(data) + parser.flush()
    board = BoardFrameParser()  # the controller board's frames (AA 55 ...), if any
    board_frames = board.feed(data) + board.flush()
    entries = _placed(data, [(f.to_bytes(), _explain(f)) for f in frames])
    entries += _placed(data, [(f.to_bytes(), describe_board_frame(f)) for f in board_frames])
    at = 0
    for raw in bad:
        at = data.find(raw, at)
        entries.append((at, f"{raw.hex(' ')}  {_bad_checksum(raw)}"))
        at += 1
    summary = f"{len(frames)} frame(s) in {len(data)} byte(s)"
    if board_frames:
        summary = (f"{len(frames)} servo frame(s) and {len(board_frames)} controller-board "
                   f"frame(s) in {len(data)} byte(s)")
    elif parser.skipped_bytes:  # (the board's frames are bytes the servos' parser skips)
        summary += f"; {parser.skipped_bytes} byte(s) skipped (not part of a valid frame)"
    if parser.checksum_failures:
        summary += f"; {parser.checksum_failures} candidate frame(s) with a bad checksum"
    lines = [text for _, text in sorted(entries, key=lambda e: e[0])] + [summary]
    return lines, len(frames) + len(board_frames)


def _placed(data: bytes, found: list[tuple[bytes, str]]) -> list[tuple[int, str]]:
    """Each found frame's bytes and words as a line, with where in ``data`` it starts."""
    entries: list[tuple[int, str]] = []
    at = 0
    for raw, words in found:
        at = data.find(raw, at)
        entries.append((at, f"{raw.hex(' ')}  {words}"))
        at += len(raw)
    return entries


def _explain(frame: Frame) -> str:
    try:
        return describe(decode_message(frame), frame.servo_id)
    except ProtocolError as exc:
        return f"not a valid message: {exc}"


def _bad_checksum(raw: bytes) -> str:
    """A candidate frame whose checksum fails: the checksum it has, the one it should
    have, and what it would be with the right one."""
    frame = Frame(raw[2], raw[4], raw[5:-1])
    return (f"bad checksum {raw[-1]:#04x}, expected {checksum(raw[2:-1]):#04x} "
            f"(with the right one: {_explain(frame)})")


@click.command()
@click.argument("hex_text", metavar="HEX...", nargs=-1, required=True)
def decode(hex_text: tuple[str, ...]) -> None:
    """Find and explain every frame in HEX, or in standard input with `-`.

    Each token is its own byte(s): `1 3` is 01 03; a run without spaces such as
    5555010312 is two digits per byte; commas, colons and 0x are optional. Example:
    busarm decode 55 55 01 07 01 f4 01 e8 03 16. Garbage between frames is skipped and
    counted; a candidate with a bad checksum is shown with the checksum it should have.
    The controller board's frames (AA 55 ...) are found and explained too. Exit code 1
    when no valid frame is found.
    """
    if "-" in hex_text:
        if len(hex_text) > 1:
            raise click.UsageError("give the hex as arguments or `-` (standard input), not both")
        hex_text = tuple(click.get_text_stream("stdin").read().splitlines())
    data = parse_hex(hex_text)
    lines, found = decode_lines(data)
    for line in lines:
        click.echo(line)
    if not found:
        raise ProtocolError(f"no valid frame in {len(data)} byte(s)")


def _command_list() -> str:
    """The commands and their ARGS, for `encode --help` (kept as lines by click's \\b)."""
    lines = ["\b", "COMMAND (name or number) and its ARGS:"]
    for c in Command:
        args = ", ".join(f"{f.name} {f.lo}..{f.hi}" for f in SPECS[c].request if f.kind != "null")
        lines.append(f"  {c.name + f' ({c.value})':<26}{args}".rstrip())
    return "\n".join(lines)


@click.command(context_settings={"ignore_unknown_options": True}, epilog=_command_list())
@click.argument("command_name", metavar="COMMAND")
@click.argument("servo_id", metavar="ID", type=ServoIdType(allow_broadcast=True))
@click.argument("args", metavar="[ARGS]...", nargs=-1)
def encode(command_name: str, servo_id: int, args: tuple[str, ...]) -> None:
    """Print the bytes of a request: COMMAND (name or number) to ID (0..254).

    ARGS are in wire units (pulses, ms, mV), e.g. busarm encode MOVE_TIME_WRITE 1 500 1000;
    the commands and their ARGS are listed below.
    """
    command = Command.parse(command_name)
    values = [parse_int(a, f"{command.name} parameter") for a in args]
    click.echo(encode_request(servo_id, command, *values).hex(" "))


COMMANDS = [decode, encode]
