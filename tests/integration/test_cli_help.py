"""The command line's help in one style: defaults written one way (``[default: ...]``),
in one bracket with click's extras and no full stop after it, a range said once; every
number option with its unit (or plainly a count), metavars of one word naming the unit
and the same for an option on every command; placeholders named as the metavar shown;
every --config honouring $BUSARM_ARM and saying so; kept folders said with
$XDG_CONFIG_HOME; one name for a move's time, joint lists written either way everywhere;
the top-level help names the main job, and the README documents every simulator URL
parameter."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import click
from click.testing import CliRunner

from busarm.cli.main import cli
from busarm.robot import port_url

README = Path(__file__).resolve().parents[2] / "README.md"
UNIT = re.compile(r"\b(mm|deg|deg/s|mm/s|m|m/s|s|ms|V|C|Hz|bit/s|pixels|px|cm2|%|0\.\.1"
                  r"|probability)\b|\bfactor\b|seconds|frames/s")
COUNTS = {"--views", "--seed", "--scenes", "--workers", "--reads", "--scans", "--loops",
          "--frames", "--count", "--retries", "--blocks", "--pictures", "--placements", "--n",
          "--batch-n", "--distractors", "--camera-port", "--baud", "--http-port", "--tries",
          "--squares", "--laps", "--arenas", "--layouts", "--domain",
          "--drops"}
"""Number options that are counts, seeds, port numbers or ROS domain ids: no unit."""


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
    for name in port_url._SIM_KEYS:  # the keys a sim:// port takes
        assert re.search(rf"\| `{name}`|`{name}` \|| `{name}`,|, `{name}`", text), name


# ---------------------------------------------------------------------- one style (trial 3)


def _help_rows() -> Iterator[tuple[str, str, str]]:
    """(command, option, its help as rendered, unwrapped) for every option of every
    command, through the commands' own context (and so their help formatter)."""
    def walk(cmd: click.Command, path: str) -> Iterator[tuple[str, str, str]]:
        ctx = cmd.context_class(cmd, info_name=path, max_content_width=10_000,
                                terminal_width=10_000)
        rows = [line.strip() for line in cmd.get_help(ctx).splitlines()
                if line.startswith("  -")]
        for row in rows:
            term, _, text = row.partition("  ")
            yield path, term, text.strip()
        if isinstance(cmd, click.Group):
            for name, sub in cmd.commands.items():
                yield from walk(sub, f"{path} {name}")
    yield from walk(cli, "busarm")


EXTRAS = re.compile(r"\[(?:env var|default|required|-?[\d.]+<=x|x[<>]=)")


def test_an_options_extras_are_one_bracket_with_no_full_stop_after() -> None:
    rows = list(_help_rows())
    assert len(rows) > 150  # every command's options were rendered
    odd = [(path, term, text) for path, term, text in rows
           if len(EXTRAS.findall(text)) > 1 or re.search(r"\]\s*\.", text)
           or (EXTRAS.search(text) and not text.endswith("]"))]
    assert not odd, odd
    # Written in the text or click's own, a default and a range share one bracket.
    seed = next(text for path, term, text in rows
                if path == "busarm pick-sort" and term.startswith("--seed"))
    assert seed.endswith("[default: 0; 0<=x<=4294967295]"), seed


def test_a_range_is_said_once() -> None:
    twice = []
    for path, term, text in _help_rows():
        for lo, hi in re.findall(r"(-?\d+(?:\.\d+)?)\.\.(-?\d+(?:\.\d+)?)", text):
            for blo, bhi in re.findall(r"(-?[\d.]+)<=x<=(-?[\d.]+)", text):
                if float(lo) == float(blo) and float(hi) == float(bhi):
                    twice.append((path, term, text))
    assert not twice, twice


NUMBER_METAVARS = {"N", "S", "MS", "MM", "DEG", "DEG_S", "MM_S", "PX", "V", "C", "HZ", "FACTOR",
                   "FPS", "PROBABILITY", "M", "M_S"}
"""A number option's metavar: its unit, or N for a count (never NUMBER or INTEGER)."""
SAME_NAME_OTHER_MEANING = {"--pose": "a servo pose ID=DEG,... (`move`), or a named pose",
                           "--save": "a pose's NAME (`arm pose`), or a DIRECTORY",
                           "--speed": "the arm's DEG_S, or the base's M_S (`line-follow`)",
                           "--family": "the tables (`bench pick`), the rooms (`bench "
                                       "transport`), or the tape's colour (`bench line`)"}


def test_metavars_name_the_unit_and_agree_across_commands() -> None:
    numeric = (click.types.IntParamType, click.types.FloatParamType)
    metavars: dict[str, set[str]] = {}
    for path, p in _options():
        if p.is_flag:
            continue
        metavar = p.make_metavar()
        if p.nargs == 1 and (isinstance(p.type, numeric)
                             or type(p.type).__name__ == "RangeType"):
            unit = metavar.rsplit("_", 1)[-1]  # MAX_C: what it is, then its unit
            assert metavar in NUMBER_METAVARS or unit in NUMBER_METAVARS, (
                path, p.opts[-1], metavar)
        metavars.setdefault(p.opts[-1], set()).add(metavar)
    differ = {name: found for name, found in metavars.items() if len(found) > 1}
    assert set(differ) <= set(SAME_NAME_OTHER_MEANING), differ
    assert metavars["--pose"] == {"NAME", "ID=DEG,..."}, metavars["--pose"]


def test_help_names_placeholders_by_the_metavar_shown() -> None:
    stray = re.compile(r"\b(DIR|OUTPUT|INTERVAL)\b")  # words the help once used instead
    runner = CliRunner()

    def walk(cmd: click.Command, path: list[str]) -> Iterator[tuple[str, str]]:
        yield " ".join(path), runner.invoke(cli, [*path, "--help"]).output
        if isinstance(cmd, click.Group):
            for name, sub in cmd.commands.items():
                yield from walk(sub, [*path, name])
    found = [(path, stray.findall(text)) for path, text in walk(cli, []) if stray.search(text)]
    assert not found, found


def test_every_config_option_honours_busarm_arm_and_says_so() -> None:
    configs = [(path, text) for path, term, text in _help_rows()
               if term.startswith("--config") and not text.startswith("Same as")]
    assert len(configs) >= 8, configs  # arm, actions, camera, move, motor, pick-sort...
    assert all("[env var: BUSARM_ARM; default: jetauto_pro]" in text
               for _, text in configs), configs


def test_kept_folders_are_said_with_xdg_config_home() -> None:
    rows = [(path, term, text) for path, term, text in _help_rows() if "~/.config" in text]
    assert rows  # camera calibrate -o, camera handeye -o, vision locate --intrinsics
    assert all("$XDG_CONFIG_HOME/busarm/ROBOT/ (~/.config/busarm/ROBOT/ without it)" in text
               for _, _, text in rows), rows
