"""``pick-sort``: the main job. Look at the table, sort every block into its colour's bin
(or, ``--by size``, its size class's bin; ``--by tag``, the bin its AprilTag's id goes to).

Without ``--port`` it runs on the twin (``--scene FILE`` or ``--seed N``; sorting by size,
a seeded table of blocks of every size class and trays named for them; by tag, a seeded
table of tagged blocks), with the
camera calibration kept for the robot (busarm.robot.calibration_store), made in the twin
first if there is none or it is stale, unless calibration files are given; on hardware
it needs the calibration (files, or kept by ``busarm camera calibrate|handeye``) and
``--bins``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.arm.config import ArmConfig
from busarm.cli.common import (
    DEFAULT_COLORS,
    ArmContext,
    JobNotDone,
    Settings,
    add_detail,
    calibration_options,
    calibration_store,
    check_writable,
    find_session,
    make_scene,
    parse_float_list,
    pass_settings,
    scene_options,
)
from busarm.cli.text import place
from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.apps.pick_sort.rules import SortRule
    from busarm.apps.pick_sort.sorter import RunReport
    from busarm.robot import Robot
    from busarm.twin.scene import Scene

__all__ = [
    "COMMANDS",
    "DEFAULT_REPORT",
    "parse_bins",
    "parse_survey",
    "pick_sort",
]


DEFAULT_REPORT = "pick-sort-report"


def _note_own_twin(settings: Settings, table: str) -> None:
    """Without --port pick-sort sorts a twin of its own, whatever server runs (a served
    twin's table and bins are not known here): said when one runs, with how to use it."""
    session = find_session()
    if session is None:
        return
    how = (f"; to sort the served table: busarm --port {session.port} pick-sort --camera "
           f"{session.camera} --bins 'COLOUR=X,Y;...' (the bins `twin serve` printed)"
           if session.kind == "twin" and session.camera else "")
    settings.err.print(f"note: pick-sort runs a twin of its own ({table}), not "
                       f"{session.describe()}{how}", highlight=False, markup=False,
                       soft_wrap=True)


def parse_bins(text: str) -> dict[str, tuple[float, float]]:
    """``red=33,187;green=33,-187`` -> {colour: (x, y) mm}."""
    bins: dict[str, tuple[float, float]] = {}
    for part in text.split(";"):
        if not part.strip():
            continue
        name, sep, xy = part.partition("=")
        values = parse_float_list(xy, f"bin {name.strip()} X,Y in mm") if sep else []
        if not sep or len(values) != 2 or not name.strip():
            raise ConfigError(f"--bins {part!r}: expected COLOUR=X,Y (mm), e.g. red=33,187")
        bins[name.strip()] = (values[0], values[1])
    if not bins:
        raise ConfigError("--bins is empty: expected COLOUR=X,Y;COLOUR=X,Y")
    return bins


def parse_survey(text: str, config: ArmConfig) -> list[tuple[float, ...]]:
    """``look,look@-45`` -> joint poses: poses named in the arm config, the base turned to
    the bearing (deg) after ``@`` if one is given."""
    poses = []
    for part in text.split(","):
        name, sep, bearing = part.strip().partition("@")
        pose = list(config.pose(name.strip()))
        if sep:
            (pose[0],) = parse_float_list(bearing, f"--survey {part.strip()!r}: the bearing")
        poses.append(config.check_joints(pose))
    return poses


@click.command("pick-sort")
@scene_options
@click.option("--camera", "camera_src", default=None,
              help="Camera source (on hardware: required)  [default: the twin's]")
@calibration_options
@click.option("--bins", "bins_text", default=None,
              help="Where each colour goes, COLOUR=X,Y;... in mm (by size: small=X,Y;"
                   "medium=X,Y;large=X,Y)  [default on the twin: its trays]")
@click.option("--by", "sort_by", type=click.Choice(["color", "size", "tag"]),
              default="color", show_default=True,
              help="Sort by colour (a bin per colour), by size class (small < 28 mm, "
                   "medium 28-37 mm, large > 37 mm: a bin named for each) or by the id of "
                   "the AprilTag (36h11) on each block's top (--tag-places).")
@click.option("--tag-places", "tag_places_text", default=None,
              help="With --by tag: which bin each tag id goes to, IDS=BIN;... (e.g. "
                   "'0,1=red;2-4=green')  [default: tag i to the i-th bin, round them]")
@click.option("--survey", "survey_text", default="look", show_default=True,
              help="Where the camera looks from: poses of the arm config, comma separated; "
                   "NAME@BEARING turns the base to BEARING deg (e.g. look@-40,look,look@40).")
@click.option("--order", type=click.Choice(["nearest", "colors"]), default="nearest",
              show_default=True,
              help="Which block next: the nearest, or by colour in --colors order (nearest "
                   "first within a colour).")
@click.option("--report", "report_dir", type=click.Path(file_okay=False, path_type=Path),
              default=DEFAULT_REPORT, show_default=True, help="Folder for the run report.")
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def pick_sort(settings: Settings, scene_file: Path | None, seed: int | None,
              blocks: int | None, colors: str | None, camera_src: str | None,
              intrinsics: Path | None, hand_eye: Path | None, bins_text: str | None,
              sort_by: str, tag_places_text: str | None, survey_text: str, order: str,
              report_dir: Path, config: str, as_json: bool) -> None:
    """Find the blocks, pick each and put it in its colour's bin, until the table is clear.

    Prints what happened to every block and the totals, and writes a report folder
    (JSON, the picture each pick started from, the table before and after, a GIF).
    Exit code 0 when every block was sorted or skipped for a reason it gives (bin full,
    out of reach, an unknown colour...), 1 when a block failed.
    """
    from busarm.apps.pick_sort.rules import SortRule, parse_tag_places
    from busarm.vision.color_thresholds import parse_color_names

    names = parse_color_names(colors or DEFAULT_COLORS)
    if tag_places_text is not None and sort_by != "tag":
        raise ConfigError(f"--tag-places is for --by tag (not --by {sort_by})")
    rule = SortRule(sort_by, parse_tag_places(tag_places_text) if tag_places_text else {})
    scene = None
    if scene_file is not None or seed is not None or blocks is not None or (
            not settings.port_given):
        scene = _scene_for(rule, scene_file, seed, blocks, colors)
    if not settings.port_given:
        _note_own_twin(settings, scene.source if scene is not None else "")
    bins_given = _bins_for(settings, bins_text, names, rule)
    ac = ArmContext(settings, config, None)
    survey_poses = parse_survey(survey_text, ac.config)
    check_writable(report_dir / "report.json" if report_dir.is_dir() else report_dir)
    wall_start = time.monotonic()
    store = calibration_store(settings, default="twin") if intrinsics is None and \
        hand_eye is None else None
    with settings.open_robot(default="twin", camera=camera_src, config=ac.config,
                             intrinsics=intrinsics, hand_eye=hand_eye, bins=bins_given,
                             scene=scene, calibration_store=store,
                             needs=("camera", "camera_calibration", "bins"),
                             progress=lambda text: None if " view " in text else
                             settings.err.print(text, highlight=False,
                                                soft_wrap=True)) as robot:
        simulated = robot.clock.is_simulated
        report, path = _run_job(settings, robot, report_dir, names, survey_poses, order, rule)
    if as_json:
        click.echo(json.dumps(json.loads(path.read_text()), indent=2))
    else:
        _print_summary(report, simulated, time.monotonic() - wall_start, report_dir)
    failed = report.totals()["failed"]
    if failed:  # skipped ones (bin full, out of reach...) were left by design
        raise JobNotDone(f"{failed} block(s) failed to be sorted (the reasons above, and in "
                         f"{report_dir}/report.json)")


def _scene_for(rule: SortRule, scene_file: Path | None, seed: int | None, blocks: int | None,
               colors: str | None) -> Scene:
    """The twin's table: a scene file, or seeded: by size, a table of every size class
    with trays named for them (busarm.twin.lookalike.sized_scene); by tag, tagged blocks
    (``tagged_scene``)."""
    if rule.by == "color" or scene_file is not None:
        return make_scene(scene_file, seed, blocks, None if scene_file else colors)
    from busarm.twin.lookalike import sized_scene, tagged_scene

    if rule.by == "tag":
        if colors is not None:
            raise ConfigError("--colors: the seeded table for --by tag has blocks of its own "
                              "colours (give --scene for others)")
        return tagged_scene(seed or 0, blocks)
    if blocks is not None:
        raise ConfigError(f"--blocks {blocks}: the seeded table for --by size has 4-6 blocks "
                          "of its own (choose them with --seed, or give --scene)")
    return sized_scene(seed or 0)


def _bins_for(settings: Settings, bins_text: str | None, names: list[str],
              rule: SortRule) -> dict[str, tuple[float, float]] | None:
    """The bins --bins gives (None: the robot's): refused if none is one the rule sorts
    into; a bin it does not is warned of."""
    bins_given = parse_bins(bins_text) if bins_text is not None else None
    if bins_given is None:
        return None
    if rule.by == "color":
        others = [c for c in bins_given if c not in names]
        sorting = f"the colours to sort ({', '.join(names)}; --colors chooses them)"
        if not set(bins_given) & set(names):
            raise ConfigError(f"--bins has no bin for {sorting}: "
                              + (f"{', '.join(others)} is not one of them; " if others else "")
                              + "give COLOUR=X,Y for at least one of them")
    else:
        used = rule.places(bins_given, names)  # ConfigError if none is one it sorts into
        others = [c for c in bins_given if c not in used]
        sorting = f"the places sorting by {rule.by} uses ({', '.join(used)})"
    if others:  # a typo, or a colour left out of --colors: said, not silently ignored
        settings.err.print(f"warning: --bins {', '.join(others)}: not one of {sorting}; "
                           "no block goes there", highlight=False, markup=False,
                           soft_wrap=True)
    return bins_given


def _run_job(settings: Settings, robot: Robot, report_dir: Path, names: list[str],
             survey_poses: list[tuple[float, ...]], order: str, rule: SortRule
             ) -> tuple[RunReport, Path]:
    """Sort the table with ``robot``: the report and its file. A stop's one line also
    says what the gripper holds and where the report is."""
    from busarm.apps.pick_sort.job import PickJob
    from busarm.apps.pick_sort.settings import PickSortSettings

    job = PickJob(robot, report_dir, colors=names, survey_poses=survey_poses,
                  settings=PickSortSettings(order=order), rule=rule,
                  progress=lambda text: settings.err.print(text, highlight=False))
    try:
        return job.run()
    except BaseException as exc:
        # What the gripper holds and where the report is join the one line that
        # reports the stop (with each servo's torque, read back: busarm.cli.main).
        for note in job.notes:
            add_detail(exc, note)
        raise


def _print_summary(report: RunReport, simulated: bool, wall_s: float,
                   report_dir: Path) -> None:
    for b in report.blocks:
        where = place(b.found_mm)
        extra = f": {b.reason}" if b.reason else f", {b.attempts} attempt(s), {b.seconds:.1f} s"
        into = f" into {b.place}" if b.outcome == "sorted" and b.place != b.color else ""
        click.echo(f"{b.color:7s} at {where:18s} {b.outcome}{into}{extra}")
    t = report.totals()
    unit = "s of twin time" if simulated else "s"
    moved = f", moved {t['moved']}" if t["moved"] else ""
    cycle = ("no block sorted to time a cycle" if t["median_cycle_s"] is None else
             f"median cycle {t['median_cycle_s']} {unit} per block")
    click.echo(f"sorted {t['sorted']}, failed {t['failed']}, skipped {t['skipped']}{moved}; "
               f"{cycle}; {t['seconds']} {unit} in all ({wall_s:.0f} s on this computer, "
               f"with the set-up). Report: {report_dir}/")


COMMANDS = [pick_sort]
