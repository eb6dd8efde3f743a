"""``line-follow``: follow the taped floor loop with the wrist camera, stop for obstacles,
clear coloured blocks off the line (busarm.apps.line_follow.job).

Without ``--port`` it runs on a twin of its own in ``--arena`` (a seed or a file), its
camera calibration kept for the robot ``twin`` (made first if there is none, as
pick-sort's); on hardware (``--port board://... --lidar PORT --camera SOURCE``) the
calibration kept by ``busarm camera calibrate|handeye``, or ``--intrinsics`` and
``--hand-eye`` files. The report folder gets
``report.json`` and ``path.png`` (on the twin the arena from above with the true path
and the odometry's; on hardware the odometry's path), written atomically, also when the
run stops early.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import (
    ArmContext,
    JobNotDone,
    RangeType,
    Settings,
    calibration_options,
    calibration_store,
    check_writable,
    keeping_what_was_done,
    line_follow_hook,
    mobile_options,
    open_mobile_robot,
    pass_settings,
    view_options,
    watching,
)
from busarm.errors import ConfigError

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from busarm.apps.line_follow.job import LineFollowReport
    from busarm.robot import Robot

__all__ = [
    "COMMANDS",
    "DEFAULT_COLORS",
    "DEFAULT_REPORT",
    "line_follow",
    "parse_clear_colors",
]


DEFAULT_REPORT = "line-follow-report"
DEFAULT_COLORS = "red,green,blue"


def parse_clear_colors(text: str) -> list[str]:
    """--colors: block colours to clear (``none``: none); ConfigError naming one that is
    not a block colour of the shipped thresholds."""
    from busarm.perception.locate import NOT_BLOCK_COLORS
    from busarm.vision.color_thresholds import default_thresholds, parse_color_names

    if text.strip().lower() == "none":
        return []
    names = parse_color_names(text)
    allowed = [c for c in default_thresholds().names if c not in NOT_BLOCK_COLORS]
    bad = [c for c in names if c not in allowed]
    if bad:
        raise ConfigError(f"--colors {', '.join(bad)}: not a block colour; allowed: "
                          f"{', '.join(allowed)} (comma separated), or none")
    return names


@click.command("line-follow")
@click.option("--laps", default=1.0, show_default=True, metavar="N",
              type=RangeType("--laps", 0.05, 100.0, "laps"),
              help="How many times round the loop (a share of one too: 0.5 is half way; "
                   "before the first lap is done, by how far the base has turned).")
@click.option("--speed", "speed_m_s", default=0.2, show_default=True, metavar="M_S",
              type=RangeType("--speed", 0.01, 0.5, "m/s"),
              help="The speed along straight tape in m/s (slower in bends).")
@click.option("--colors", "colors_text", default=DEFAULT_COLORS, show_default=True,
              help="Block colours cleared off the line, comma separated; none: none.")
@click.option("--tape", default=None, metavar="COLOUR",
              help="The tape's colour: black, white, or a colour of the shipped thresholds "
                   "(red, green, blue, yellow)  [default: measured on the first look; the "
                   "robot starts on the tape facing along it]")
@click.option("--obstacle-wait", "obstacle_wait_s", default=30.0, show_default=True,
              type=RangeType("--obstacle-wait", 0.0, 3600.0, "s"),
              help="How long something in the base's way is waited for, in s.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False, path_type=Path),
              default=DEFAULT_REPORT, show_default=True, help="Folder for the run report.")
@click.option("--camera", "camera_src", default=None,
              help="With --port: the wrist camera's source  [default: the twin's]")
@calibration_options
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@view_options
@mobile_options
@pass_settings
def line_follow(settings: Settings, laps: float, speed_m_s: float, colors_text: str,
                tape: str | None, obstacle_wait_s: float, report_dir: Path, camera_src: str | None,
                intrinsics: Path | None, hand_eye: Path | None, config: str, as_json: bool,
                foxglove_port: int | None, mcap_file: Path | None, arena_spec: str,
                chassis: str | None, lidar_port: str | None) -> None:
    """Follow the floor loop with the wrist camera looking ahead: the Lidar stops the base
    for anything in its way (until it goes), and a coloured block on the line is picked
    and put aside. Prints its progress and a summary; writes a report folder (JSON, the
    path drawn). Exit code 0 when the laps are done and every block on the way was
    cleared, 1 when not. Without --port: a twin of its own in --arena."""
    from busarm.apps.line_follow.job import LineFollowJob
    from busarm.vision.tape_colour import check_tape

    colors = parse_clear_colors(colors_text)
    if tape is not None:
        check_tape(tape, "--tape")
    ac = ArmContext(settings, config, None)
    check_writable(report_dir / "report.json" if report_dir.is_dir() else report_dir)
    say = _sayer(settings)
    options: dict[str, Any] = {
        "config": ac.config, "needs": ("camera", "camera_calibration"),
        "intrinsics": intrinsics, "hand_eye": hand_eye}
    if intrinsics is None and hand_eye is None:
        options["calibration_store"] = calibration_store(settings, default="twin")
    if camera_src is not None:
        options["camera"] = camera_src
    wall_start = time.monotonic()
    with open_mobile_robot(settings, arena_spec, chassis, lidar_port, camera=True,
                           **options) as robot, \
            watching(settings, robot, foxglove_port, mcap_file) as view:
        job = LineFollowJob(robot, laps=laps, speed_m_s=speed_m_s, colors=colors,
                            obstacle_wait_s=obstacle_wait_s, progress=say, tape=tape,
                            on_step=line_follow_hook(view))
        with keeping_what_was_done(robot, lambda exc: "the report so far: "
                                   f"{_write(report_dir, job.report, robot)}"):
            say(f"{robot!r}: {laps:g} lap(s) of the line at {speed_m_s:g} m/s")
            report = job.run()
        path = _write(report_dir, report, robot)
        simulated = robot.clock.is_simulated
    if as_json:
        click.echo(json.dumps(json.loads(path.read_text()), indent=2))
    else:
        _print_summary(report, simulated, time.monotonic() - wall_start, report_dir)
    failed = [b for b in report.blocks if b.outcome == "failed"]
    if failed:
        raise JobNotDone(f"{len(failed)} block(s) on the line were not cleared (the reasons "
                         f"above, and in {report_dir}/report.json)")


def _sayer(settings: Settings) -> Any:
    def say(text: str) -> None:
        settings.err.print(text, highlight=False, markup=False, soft_wrap=True)
    return say


def _write(folder: Path, report: LineFollowReport, robot: Robot) -> Path:
    """report.json and path.png in ``folder`` (atomically); the path of report.json."""
    from busarm.fileio import write_text_atomic
    from busarm.vision.annotate import save_image

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot make the report folder {folder}: {exc.strerror}") from exc
    path = folder / "report.json"
    write_text_atomic(path, json.dumps(report.to_dict(), indent=2) + "\n", "report")
    save_image(folder / "path.png", _picture(report, robot))
    return path


def _picture(report: LineFollowReport, robot: Robot) -> npt.NDArray[np.uint8]:
    """On the twin, the arena from above with the true path and the odometry's (placed at
    the arena's start); on hardware, the odometry's path with the blocks and the stops."""
    from busarm.base.odometry import Pose2D
    from busarm.nav.mapping import compose

    title = f"line-follow: {report.laps_done:.2f} lap(s), {report.travelled_m:.2f} m"
    sim = robot.sim
    if sim is not None and sim.arena is not None and sim.base_pose() is not None:
        from busarm.twin.arena_picture import arena_picture

        s = sim.arena.start
        start = Pose2D(s.x_m, s.y_m, math.radians(s.yaw_deg))
        path = [compose(start, p) for p in report.path]
        return arena_picture(sim.twin, odometry_path=[(p.x_m, p.y_m) for p in path],
                             title=title)
    return _odometry_picture(report)


def _odometry_picture(report: LineFollowReport) -> npt.NDArray[np.uint8]:
    from busarm.nav.grid import GridSpec, OccupancyGrid
    from busarm.nav.map_picture import map_picture

    points = [(p.x_m, p.y_m) for p in report.path] or [(0.0, 0.0)]
    marks = {f"{i + 1} {b.color}": b.found_m for i, b in enumerate(report.blocks)}
    marks |= {f"stop {i + 1}": (s.at.x_m, s.at.y_m) for i, s in enumerate(report.stops)}
    xs = [x for x, _ in [*points, *marks.values()]]
    ys = [y for _, y in [*points, *marks.values()]]
    spec = GridSpec.covering(min(xs) - 0.5, max(xs) + 0.5, min(ys) - 0.5, max(ys) + 0.5, 0.02)
    return map_picture(OccupancyGrid(spec), path=points, marks=marks)


def _print_summary(report: LineFollowReport, simulated: bool, wall_s: float,
                   report_dir: Path) -> None:
    unit = "s of twin time" if simulated else "s"
    for s in report.stops:
        click.echo(f"stopped {s.seconds:.1f} s for something {s.obstacle_m[0]:.2f} m ahead"
                   + ("" if s.cleared else " (it stayed)"))
    for b in report.blocks:
        extra = f": {b.why}" if b.why else f", put {b.side} of the line"
        click.echo(f"{b.color:6s} block {b.outcome}{extra}")
    lateral = report.lateral_mm()
    offsets = ("no offset measured" if lateral is None else
               f"offset from the line median {lateral[0]:.1f} mm, max {lateral[1]:.1f} mm")
    loop = "" if report.loop_length_m is None else f" of a {report.loop_length_m:.2f} m loop"
    cleared = sum(b.ok for b in report.blocks)
    click.echo(f"followed {report.laps_done:.2f} lap(s){loop}, {report.travelled_m:.2f} m, "
               f"in {report.seconds:.1f} {unit} ({wall_s:.0f} s on this computer, with the "
               f"set-up); {offsets} (as the robot measured it); {cleared} block(s) cleared, "
               f"{len(report.stops)} stop(s) for obstacles; {report.tape or 'no'} tape"
               f"{' (measured)' if report.tape_measured else ''}. Report: {report_dir}/")


COMMANDS = [line_follow]
