"""Offline protocol tools: ``decode`` bytes into frames, ``encode`` a request. No bus."""

from __future__ import annotations

import re

import click

from busarm.cli.common import ServoIdType, parse_int
from busarm.errors import ConfigError, ProtocolError
from busarm.protocol import Command, FrameParser, decode_message, describe, encode_request

_SEPARATORS = re.compile(r"\\x|(?<![0-9a-fA-F])0[xX]|[\s,:;]+")


def parse_hex(texts: tuple[str, ...] | list[str]) -> bytes:
    """Bytes from hex text: spaces, commas, colons and 0x or \\x prefixes are ignored.

    Raises ConfigError naming the first bad character, or an odd digit count.
    """
    digits = _SEPARATORS.sub("", " ".join(texts))
    bad = re.search(r"[^0-9a-fA-F]", digits)
    if bad:
        raise ConfigError(f"not hex: {bad.group()!r} in {' '.join(texts)!r}")
    if len(digits) % 2:
        raise ConfigError(f"odd number of hex digits ({len(digits)}): bytes need two each")
    return bytes.fromhex(digits)


def decode_lines(data: bytes) -> list[str]:
    """One line per frame found in ``data``, then a summary of what was skipped."""
    parser = FrameParser()
    frames = parser.feed(data) + parser.flush()
    lines: list[str] = []
    for frame in frames:
        try:
            text = describe(decode_message(frame), frame.servo_id)
        except ProtocolError as exc:
            text = f"not a valid message: {exc}"
        lines.append(f"{frame.hex()}  {text}")
    summary = f"{len(frames)} frame(s) in {len(data)} byte(s)"
    if parser.skipped_bytes:
        summary += f"; {parser.skipped_bytes} byte(s) skipped (not part of a valid frame)"
    if parser.checksum_failures:
        summary += f"; {parser.checksum_failures} candidate frame(s) with a bad checksum"
    return [*lines, summary]


@click.command()
@click.argument("hex_text", metavar="HEX...", nargs=-1, required=True)
def decode(hex_text: tuple[str, ...]) -> None:
    """Find and explain every frame in HEX (spaces, commas and 0x optional).

    Example: busarm decode 55 55 01 07 01 f4 01 e8 03 16. Garbage between frames
    is skipped and counted, as are candidates with a bad checksum.
    """
    for line in decode_lines(parse_hex(hex_text)):
        click.echo(line)


@click.command(context_settings={"ignore_unknown_options": True})
@click.argument("command_name", metavar="COMMAND")
@click.argument("servo_id", metavar="ID", type=ServoIdType(allow_broadcast=True))
@click.argument("args", metavar="[ARGS]...", nargs=-1)
def encode(command_name: str, servo_id: int, args: tuple[str, ...]) -> None:
    """Print the bytes of a request: COMMAND (name or number) to ID (0..254).

    ARGS are in wire units (pulses, ms, mV), e.g. busarm encode MOVE_TIME_WRITE 1 500 1000.
    """
    command = Command.parse(command_name)
    values = [parse_int(a, f"{command.name} parameter") for a in args]
    click.echo(encode_request(servo_id, command, *values).hex(" "))


COMMANDS = [decode, encode]
