"""``stack``: the tag-stacking game. The blocks with AprilTags on their tops are stacked at
one place in tag-id order, the lowest at the bottom (busarm.apps.stack.job).

Without ``--port`` it runs on a twin of its own: a seeded table of tagged blocks
(``--seed``, ``--blocks``; busarm.twin.lookalike.tagged_scene), its camera calibration kept
for the robot ``twin`` (made first if there is none, as pick-sort's). On hardware the
calibration kept by ``busarm camera calibrate|handeye``, or ``--intrinsics`` and
``--hand-eye`` files.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import click

from busarm.cli.common import (
    ArmContext,
    JobNotDone,
    RangeType,
    Settings,
    calibration_options,
    calibration_store,
    keeping_what_was_done,
    parse_float_list,
    pass_settings,
)
from busarm.errors import ConfigError

__all__ = [
    "COMMANDS",
    "parse_at",
    "parse_tag_ids",
    "stack",
]


def parse_at(text: str) -> tuple[float, float]:
    """``200,-40`` -> (x, y) mm; ConfigError otherwise."""
    values = parse_float_list(text, "--at X,Y in mm")
    if len(values) != 2:
        raise ConfigError(f"--at {text!r}: expected X,Y in mm, e.g. 160,0")
    return values[0], values[1]


def parse_tag_ids(text: str) -> list[int]:
    """``0,1,2`` -> tag ids (checked by busarm.apps.stack.job.check_ids)."""
    from busarm.apps.stack.job import check_ids

    out = []
    for part in text.replace(" ", ",").split(","):
        if not part:
            continue
        try:
            out.append(int(part))
        except ValueError:
            raise ConfigError(f"--tags {text!r}: {part!r} is not a tag id (0..586)") from None
    ids = check_ids(out)
    assert ids is not None
    return ids


@click.command("stack")
@click.option("--at", "at_text", default=None, metavar="X,Y",
              help="Where the tower stands, in mm  [default: a free place within easy reach]")
@click.option("--tags", "ids_text", default=None, metavar="ID,ID,...",
              help="The tag ids to stack, lowest at the bottom  [default: every tag seen]")
@click.option("--max-height", "max_height_mm", default=None, metavar="MM",
              type=RangeType("--max-height", 10.0, 1000.0, "mm"),
              help="Stop before the tower grows taller than this, in mm  [default: as tall "
                   "as the arm reaches over]")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="The twin's seeded table of tagged blocks (without --port).")
@click.option("--blocks", type=click.IntRange(3, 5), default=None,
              help="Tagged blocks on the twin's table  [default: 3-5, from the seed]")
@click.option("--camera", "camera_src", default=None,
              help="Camera source (on hardware: required)  [default: the twin's]")
@calibration_options
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def stack(settings: Settings, at_text: str | None, ids_text: str | None,
          max_height_mm: float | None, seed: int, blocks: int | None, camera_src: str | None,
          intrinsics: Path | None, hand_eye: Path | None, config: str, as_json: bool) -> None:
    """Stack the blocks with AprilTags on their tops at one place, in tag-id order (the
    lowest at the bottom): each found and measured by its tag, set on the tower, and the
    tower looked at after each one (a block off its axis by more than 4 mm is placed
    again). Stops cleanly before a block the arm cannot set on the tower. Prints the
    tower's order, each block's placement error as looked at and the height. Exit code 1
    when a block could not be stacked."""
    from busarm.apps.stack.job import StackJob, check_place
    from busarm.apps.stack.settings import StackSettings

    ids = parse_tag_ids(ids_text) if ids_text is not None else None
    at = parse_at(at_text) if at_text is not None else None
    ac = ArmContext(settings, config, None)
    scene = None
    if not settings.port_given:
        from busarm.twin.lookalike import tagged_scene

        scene = tagged_scene(seed, blocks)
    if at is not None:  # refused before anything is opened, where the table is known
        check_place(ac.kin, ac.config.table_z_mm, at,
                    table=scene.table if scene is not None else None,
                    bins={b.color: (b.x_mm, b.y_mm) for b in scene.bins} if scene else None)
    job_settings = StackSettings(max_height_mm=max_height_mm)
    store = calibration_store(settings, default="twin") if intrinsics is None and \
        hand_eye is None else None

    def say(text: str) -> None:
        settings.err.print(text, highlight=False, markup=False, soft_wrap=True)

    wall_start = time.monotonic()
    with settings.open_robot(default="twin", camera=camera_src, config=ac.config,
                             intrinsics=intrinsics, hand_eye=hand_eye, scene=scene,
                             calibration_store=store, needs=("camera", "camera_calibration"),
                             progress=say) as robot:
        job = StackJob(robot, ids=ids, at_mm=at, settings=job_settings, progress=say)
        with keeping_what_was_done(robot, lambda exc: "the report so far: "
                                   + job.report.text()):
            report = job.run()
        simulated = robot.clock.is_simulated
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=2))
    else:
        unit = "s of twin time" if simulated else "s"
        click.echo(f"{report.text()}; {report.seconds:.1f} {unit} "
                   f"({time.monotonic() - wall_start:.0f} s on this computer, with the set-up)")
    if report.end == "failed":
        raise JobNotDone(f"the tower is not complete: {report.why}")


COMMANDS = [stack]
