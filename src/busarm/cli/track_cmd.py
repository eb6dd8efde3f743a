"""``track``: the colour-tracking game. The arm looks down at the table and keeps a block of
one colour centred in the wrist camera while it is slid about (busarm.apps.track.job).

Without ``--port`` it runs on a twin of its own: a table with the block to track (and
blocks of other colours out of its way), its camera calibration kept for the robot
``twin`` (made first if there is none, as pick-sort's); ``--twin-mover`` has the twin's
hand slide the block (busarm.twin.mover), for the twin only. On hardware the calibration
kept by ``busarm camera calibrate|handeye``, or ``--intrinsics`` and ``--hand-eye``
files, and a person's hand.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import (
    DEFAULT_COLORS,
    ArmContext,
    RangeType,
    Settings,
    calibration_options,
    calibration_store,
    keeping_what_was_done,
    pass_settings,
)
from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.apps.track.job import TrackReport
    from busarm.robot import Robot
    from busarm.twin.mover import BlockMover

__all__ = [
    "COMMANDS",
    "report_text",
    "track",
]


@click.command("track")
@click.option("--color", "color", required=True, type=click.Choice(DEFAULT_COLORS.split(",")),
              help="The colour of the block to keep centred.")
@click.option("--seconds", default=None, metavar="S",
              type=RangeType("--seconds", 0.1, 86400.0, "s"),
              help="Stop after this long, in s  [default: until the block leaves the view or "
                   "the reach]")
@click.option("--fps", "frame_rate_hz", default=15.0, show_default=True,
              type=RangeType("--fps", 1.0, 60.0, "frames/s"),
              help="Frames a second looked at (a real camera's own rate if slower).")
@click.option("--lost-frames", default=15, show_default=True, type=click.IntRange(1, 1000),
              help="The block not seen for this many frames running (at --fps frames/s) "
                   "has left the view: stop.")
@click.option("--twin-mover", "mover_kind", default=None,
              type=click.Choice(["circle", "eight", "walk"]),
              help="On the twin: its hand slides the block along a circle, a figure-eight "
                   "or a seeded smooth walk  [default: the block stays put]")
@click.option("--speed-mm-s", "speed_mm_s", default=50.0, show_default=True,
              type=RangeType("--speed-mm-s", 0.0, 200.0, "mm/s"),
              help="With --twin-mover: how fast the hand slides the block, in mm/s.")
@click.option("--seed", "mover_seed", default=0, show_default=True,
              type=click.IntRange(0, 2**32 - 1),
              help="With --twin-mover walk: the walk's seed.")
@click.option("--camera", "camera_src", default=None,
              help="Camera source (on hardware: required)  [default: the twin's]")
@calibration_options
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def track(settings: Settings, color: str, seconds: float | None, frame_rate_hz: float,
          lost_frames: int, mover_kind: str | None, speed_mm_s: float, mover_seed: int,
          camera_src: str | None, intrinsics: Path | None, hand_eye: Path | None,
          config: str, as_json: bool) -> None:
    """Keep a block of --color centred in the wrist camera, looking down at the table,
    while it is slid about: until --seconds are up or the block leaves the view or the
    arm's reach (the arm then holds where it is). Prints the share of frames within 40 px
    of the centre, the pixel error's median and p95, and the latency from a frame to
    its command. Without --port: a twin of its own (--twin-mover slides the block)."""
    from busarm.apps.track.job import TrackJob, TrackSettings, check_color

    color = check_color(color)
    job_settings = TrackSettings(frame_rate_hz=frame_rate_hz, seconds=seconds,
                                 lost_frames=lost_frames)
    scene = None
    path = None
    if mover_kind is not None:
        _check_on_twin(settings)
        from busarm.twin.mover import named_path

        path = named_path(mover_kind, mover_seed)
    if not settings.port_given:
        from busarm.twin.mover import DEFAULT_CENTRE_MM, track_scene

        start = DEFAULT_CENTRE_MM if path is None else path.at(0.0)[:2]
        scene = track_scene(color, (start[0], start[1]))
    ac = ArmContext(settings, config, None)
    store = calibration_store(settings, default="twin") if intrinsics is None and \
        hand_eye is None else None
    say = _sayer(settings)
    wall_start = time.monotonic()
    with settings.open_robot(default="twin", camera=camera_src, config=ac.config,
                             intrinsics=intrinsics, hand_eye=hand_eye, scene=scene,
                             calibration_store=store, needs=("camera", "camera_calibration"),
                             progress=say) as robot:
        job = TrackJob(robot, color, settings=job_settings, progress=say)
        mover = None if path is None else _mover(robot, color, path, speed_mm_s)
        with keeping_what_was_done(robot, lambda exc: "the report so far: "
                                   + report_text(job.report)):
            report = job.run()
        if mover is not None:
            mover.detach()
        simulated = robot.clock.is_simulated
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=2))
    else:
        unit = "s of twin time" if simulated else "s"
        click.echo(f"{report_text(report)}; {report.seconds:.1f} {unit} "
                   f"({time.monotonic() - wall_start:.0f} s on this computer, with the set-up)")


def _check_on_twin(settings: Settings) -> None:
    """--twin-mover is the twin's hand: refused, before anything is opened, on any other
    robot."""
    from busarm.twin.spec import TwinSpec

    if settings.port_given or settings.on_robot_file:
        world = settings.world()
        if not isinstance(world, TwinSpec) or world.mobile:
            raise ConfigError(f"--twin-mover slides a block on the twin's table; {world.name} "
                              "is not a twin in this process: slide the block by hand")


def _mover(robot: Robot, color: str, path: Any, speed_mm_s: float) -> BlockMover:
    """The twin's hand on the first block of ``color``, started now."""
    from busarm.twin.mover import BlockMover

    twin = robot.twin
    if twin is None:
        raise ConfigError("--twin-mover slides a block on the twin's table; this robot is "
                          "not a twin: slide the block by hand")
    index = next((i for i, b in enumerate(twin.scene.blocks) if b.color == color), None)
    if index is None:
        raise ConfigError(f"the twin's table has no {color} block for --twin-mover to slide")
    return BlockMover(twin, path, speed_mm_s, index=index, start_after_s=1.0).attach()


def report_text(report: TrackReport) -> str:
    """The report on one line: frames, share centred, pixel errors, latency, why it
    stopped."""
    err, lat = report.error_stats_px(), report.latency_stats_s()
    errors = "never seen" if err is None else (f"error median {err[0]:.1f} px, p95 "
                                               f"{err[1]:.1f} px")
    latency = "no command sent" if lat is None else (f"latency frame -> command median "
                                                     f"{lat[0] * 1000:.1f} ms, p95 "
                                                     f"{lat[1] * 1000:.1f} ms")
    return (f"{report.frames} frames, {report.within() * 100:.1f}% within 40 px of the "
            f"centre, {errors}, {latency}; stopped: {report.why or 'not started'}")


def _sayer(settings: Settings) -> Any:
    def say(text: str) -> None:
        settings.err.print(text, highlight=False, markup=False, soft_wrap=True)
    return say


COMMANDS = [track]
