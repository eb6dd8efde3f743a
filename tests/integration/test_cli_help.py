"""The command line's help in one style: defaults written one way (``[default: ...]``),
every number option with its unit (or plainly a count), metavars of one word, one name
for a move's time, joint lists written either way everywhere; the top-level help names
the main job, and the README documents every simulator URL parameter."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import click
from click.testing import CliRunner

from busarm.cli.main import cli
from busarm.sim import transport

README = Path(__file__).resolve().parents[2] / "README.md"
UNIT = re.compile(r"\b(mm|deg|deg/s|mm/s|s|ms|V|C|bit/s|pixels|px|cm2|%|0\.\.1|probability)\b"
                  r"|\bfactor\b|seconds|frames/s")
COUNTS = {"--views", "--seed", "--scenes", "--workers", "--reads", "--scans", "--loops",
          "--frames", "--count", "--retries", "--blocks", "--pictures", "--placements", "--n",
          "--batch-n", "--distractors", "--camera-port", "--baud", "--http-port", "--tries"}
"""Number options that are counts, seeds or port numbers: no unit to give."""


def _options() -> Iterator[tuple[str, click.Option]]:
    def walk(cmd: click.Command, path: str) -> Iterator[tuple[str, click.Option]]:
        for p in cmd.params:
            if isinstance(p, click.Option) and not p.hidden:
                yield path, p
        if isinstance(cmd, click.Group):
            for name, sub in cmd.commands.items():
                yield from walk(sub, f"{path} {name}")
    yield from walk(cli, "busarm")


def test_defaults_are_written_one_way() -> None:
    odd = [(path, p.opts[0], p.help) for path, p in _options()
           if p.help and re.search(r"\(default|;\s*default|\bdefault \d", p.help)]
    assert not odd, odd


def test_number_options_say_their_unit_or_are_counts() -> None:
    numeric = (click.types.IntParamType, click.types.FloatParamType)
    missing = [(path, p.opts[0], p.help) for path, p in _options()
               if not p.is_flag and (isinstance(p.type, numeric)
                                     or type(p.type).__name__ == "RangeType")
               and p.opts[-1] not in COUNTS and not UNIT.search(p.help or "")]
    assert not missing, missing


def test_metavars_read_as_one_argument() -> None:
    spaced = [(path, p.opts[0], p.make_metavar()) for path, p in _options()
              if p.nargs == 1 and " " in p.make_metavar()]
    assert not spaced, spaced


def test_a_moves_time_is_time_everywhere() -> None:
    names = {opt for _, p in _options() for opt in p.opts}
    assert "--duration" not in names and "--time-ms" not in names
    assert "--time" in names


def test_joint_lists_are_taken_with_commas_or_spaces() -> None:
    runner = CliRunner(mix_stderr=False)
    spaced = runner.invoke(cli, ["arm", "fk", "0", "-60", "0", "-90", "0"])
    commas = runner.invoke(cli, ["arm", "fk", "0,-60,0,-90,0"])
    assert spaced.exit_code == commas.exit_code == 0, (spaced.stderr, commas.stderr)
    assert spaced.stdout == commas.stdout and "z 571.5 mm" in spaced.stdout
    bad = runner.invoke(cli, ["arm", "fk", "0,-60,x,-90,0"])
    assert bad.exit_code == 2 and "'x' is not a number" in bad.stderr


def test_the_top_level_help_names_the_main_job() -> None:
    result = CliRunner().invoke(cli, ["--help"])
    assert "busarm pick-sort --seed 3 --blocks 5" in " ".join(result.output.split())


def test_the_readme_documents_every_simulator_url_parameter() -> None:
    text = README.read_text(encoding="utf-8")
    assert "busarm.sim.transport" not in text  # the user reads the README, not the source
    for name in transport._KNOWN:
        assert re.search(rf"\| `{name}`|`{name}` \|| `{name}`,|, `{name}`", text), name
