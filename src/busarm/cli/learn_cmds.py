"""``record`` and ``rollout``: busarm's demonstrations as LeRobot datasets, and LeRobot
policies on busarm's robots (busarm.learn; docs/lerobot.md).

LeRobot and PyTorch are not part of busarm's install: these commands run from the
environment ``make lerobot`` makes (``.venv-lerobot/bin/busarm``), and say so elsewhere.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from busarm.cli.common import RangeType, Settings, describe_robot, pass_settings
from busarm.errors import ConfigError

__all__ = [
    "COMMANDS",
    "record",
    "rollout",
]

TASKS = ("one-block", "table")


@click.command("record")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--expert", type=click.Choice(["pick-sort"]), default=None,
              help="Busarm's own expert on seeded twin tables (pick-and-sort's planner).")
@click.option("--leader", "leader_port", default=None, metavar="PORT",
              help="A leader arm (torque off, moved by hand) on this port drives the robot.")
@click.option("--teleop", type=click.Choice(["dashboard", "keyboard", "gamepad"]),
              default=None, help="A person drives the robot from the dashboard's jog, this "
                                 "terminal's keys or a gamepad (--gamepad).")
@click.option("--gamepad", "gamepad_device", default="/dev/input/js0", show_default=True,
              help="The gamepad's joystick device (--teleop gamepad).")
@click.option("--task", type=click.Choice(TASKS), default="one-block", show_default=True,
              help="The expert's task: one block to its bin, or a whole table.")
@click.option("--episodes", type=click.IntRange(1, 100_000), default=10, show_default=True,
              help="How many episodes to record.")
@click.option("--seed", type=click.IntRange(0, 999_999), default=0, show_default=True,
              help="The expert's first table (episode i: table SEED+i; from 1,000,000 the "
                   "tables are kept for evaluation).")
@click.option("--workers", type=click.IntRange(1, 64), default=1, show_default=True,
              help="Expert episodes side by side, in this many processes.")
@click.option("--fps", type=RangeType("--fps", 1.0, 100.0, "frames/s"), default=20.0,
              show_default=True, help="The episodes' frames a second, in frames/s.")
@click.option("--episode-s", type=RangeType("--episode-s", 0.5, 3600.0, "s"), default=10.0,
              show_default=True, help="A person's episode's length.")
@click.option("--text", default=None, help="The task in words (a person's episodes).")
@click.option("--cameras", default="wrist", show_default=True,
              help="Cameras whose pictures a person's episodes keep (comma separated; "
                   "'' for none).")
@click.option("--keep-failed", is_flag=True,
              help="Keep the expert's failed episodes (never marked next.success).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def record(settings: Settings, out: Path, expert: str | None, leader_port: str | None,
           teleop: str | None, gamepad_device: str, task: str, episodes: int, seed: int,
           workers: int, fps: float, episode_s: float, text: str | None, cameras: str,
           keep_failed: bool, as_json: bool) -> None:
    """Record demonstrations into a new LeRobotDataset at OUT (a folder): busarm's expert
    on seeded twin tables (--expert pick-sort, many side by side), or a person driving
    the robot (--leader PORT, --teleop dashboard|keyboard; on --port, default a real-time
    twin). Without one of these, ``busarm record OUT`` records an MCAP file for
    Foxglove."""
    chosen = [name for name, v in (("--expert", expert), ("--leader", leader_port),
                                   ("--teleop", teleop)) if v is not None]
    if len(chosen) != 1:
        raise ConfigError("give one of --expert pick-sort, --leader PORT, --teleop "
                          f"dashboard|keyboard|gamepad (got {', '.join(chosen) or 'none'})")
    ctx = click.get_current_context()
    theirs = ("task", "seed", "workers", "keep_failed") if expert is None else (
        "episode_s", "text", "cameras", "gamepad_device")
    opts = {p.name: p.opts[0] for p in ctx.command.params}
    given = [opts[n] for n in theirs
             if ctx.get_parameter_source(n) is click.core.ParameterSource.COMMANDLINE]
    if given:
        raise ConfigError(f"{', '.join(given)}: not for {chosen[0]} (the expert's: --task, "
                          "--seed, --workers, --keep-failed; a person's: --episode-s, "
                          "--text, --cameras, --gamepad)")
    if expert is not None:
        from busarm.learn.record import record_expert

        report = record_expert(out, task=task, episodes=episodes, seed=seed, fps=round(fps),
                               workers=workers, keep_failed=keep_failed,
                               progress=_say(settings))
        click.echo(json.dumps(report.to_dict(), indent=2) if as_json else report.text())
        return
    _record_person(settings, out, leader_port, (teleop, gamepad_device), episodes, round(fps),
                   episode_s, text or "a person's demonstration",
                   [c for c in cameras.split(",") if c], as_json)


def _say(settings: Settings) -> Any:
    def say(line: str) -> None:
        settings.err.print(line, highlight=False, markup=False, soft_wrap=True)
    return say


def _description(settings: Settings, realtime: bool) -> Any:
    """The robot of --port (or --robot), a real-time twin without one."""
    from busarm.twin.spec import TwinSpec

    if settings.on_robot_file:
        return settings.robot_description()
    world = settings.world() if settings.port_given else TwinSpec(realtime=realtime)
    return describe_robot(world, settings.line())


def _record_person(settings: Settings, out: Path, leader_port: str | None,
                   teleop: tuple[str | None, str], episodes: int, fps: int, episode_s: float,
                   text: str,
                   cameras: list[str], as_json: bool) -> None:
    from busarm.learn.dataset import DatasetWriter
    from busarm.learn.features import Features
    from busarm.learn.frames import FrameRobot
    from busarm.learn.human import record_teleop

    say = _say(settings)
    frames = FrameRobot(_description(settings, realtime=True), fps=fps, cameras=cameras)
    features = Features.of(frames.config, fps=fps, task_state=False, cameras=[
        (role, *frames.camera_sizes[role]) for role in cameras])
    try:  # a leader or a terminal that is not there: the writer leaves nothing behind
        with DatasetWriter(out, features) as writer, \
                _source(frames, leader_port, teleop, say) as source:
            done = record_teleop(frames, source, writer, episodes=episodes,
                                 episode_s=episode_s, text=text, progress=say)
    finally:
        frames.close()
    kept = {"root": str(out), "episodes": len(done), "frames": sum(len(e.states) for e in done),
            "fps": fps, "worst_late_ms": round(1000 * max(e.worst_late_s for e in done), 1)}
    click.echo(json.dumps(kept, indent=2) if as_json else
               f"{kept['episodes']} episodes ({kept['frames']} frames at {fps} fps) in {out}")


@contextmanager
def _source(frames: Any, leader_port: str | None, teleop: tuple[str | None, str], say: Any
            ) -> Iterator[Any]:
    """What drives the robot: a leader arm, the keyboard, a gamepad, or the dashboard
    (served on the robot here while recording; None: the action kept is where the jog
    told the arm)."""
    kind, device = teleop
    if leader_port is not None:
        from busarm.learn.leader import LeaderArm

        with LeaderArm(leader_port, config=frames.config) as leader:
            yield leader.read
        return
    if kind == "gamepad":
        from busarm.learn.gamepad import GamepadJog

        say("gamepad: the sticks and the d-pad turn the joints, A/B close/open, Start back")
        with GamepadJog(frames.config, device=device) as pad:
            frames.open()
            pad.begin_at(dict(zip(frames.motors, frames.state().tolist(), strict=True)))
            yield pad.read
        return
    if kind == "keyboard":
        from busarm.learn.keyboard import KeyboardJog

        if not sys.stdin.isatty():
            raise ConfigError("--teleop keyboard reads this terminal's keys: run it in one")
        say("keys: q/a w/s e/d r/f t/g jog the joints, o/c open/close, h back to the start")
        with KeyboardJog(frames.config) as jog:
            frames.open()
            jog.begin_at(dict(zip(frames.motors, frames.state().tolist(), strict=True)))
            yield jog.read
        return
    with _dashboard(frames.open(), say):
        yield lambda: None


@contextmanager
def _dashboard(robot: Any, say: Any) -> Iterator[None]:
    from busarm.dashboard.access import Access
    from busarm.dashboard.feeds import robot_feeds
    from busarm.dashboard.server import ServerThread
    from busarm.dashboard.service import RobotService

    service = RobotService(robot).start()
    http = ServerThread(service, Access.for_bind("127.0.0.1"), robot_feeds(robot, 10)).start()
    say(f"dashboard: open {http.url} to drive the robot (its Stop and e-stop are in charge)")
    try:
        yield
    finally:
        http.stop()
        service.close()


@click.command("rollout")
@click.option("--policy", "policy_path", required=True,
              type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="A trained policy's folder (lerobot-train's .../pretrained_model).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1_000_000,
              show_default=True, help="Without --port: the twin's table (a held-out one).")
@click.option("--task", type=click.Choice(TASKS), default="one-block", show_default=True,
              help="Without --port: the task whose table is set (one block, or a table).")
@click.option("--seconds", type=RangeType("--seconds", 0.5, 3600.0, "s"), default=15.0,
              show_default=True, help="At most this long, on the robot's clock.")
@click.option("--fps", type=RangeType("--fps", 1.0, 100.0, "frames/s"), default=None,
              help="The policy's pace, in frames/s  [default: its training data's]")
@click.option("--cameras", default=None,
              help="Cameras the policy sees, comma separated  [default: those its "
                   "inputs name]")
@click.option("--dashboard", "with_dashboard", is_flag=True,
              help="Serve the dashboard on the robot meanwhile (its Stop and e-stop end it).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def rollout(settings: Settings, policy_path: Path, seed: int, task: str, seconds: float,
            fps: float | None, cameras: str | None, with_dashboard: bool,
            as_json: bool) -> None:
    """Let a policy trained with LeRobot drive the robot (--port; default the twin on a
    held-out table): it looks first, then the policy acts each frame, every action
    clipped to the limits; on a twin the end is judged on the twin's truth."""
    from busarm.learn.features import DEFAULT_FPS
    from busarm.learn.frames import FrameRobot
    from busarm.learn.policy import LoadedPolicy, policy_fps
    from busarm.learn.rollout import rollout as run
    from busarm.learn.tasks import task_scene
    from busarm.twin.spec import TwinSpec

    policy = LoadedPolicy(policy_path)
    rate = round(fps) if fps else policy_fps(policy_path, DEFAULT_FPS)
    if settings.port_given or settings.on_robot_file:
        description = _description(settings, realtime=with_dashboard)
    else:
        description = describe_robot(TwinSpec(scene=task_scene(task, seed),
                                              realtime=with_dashboard), settings.line())
    roles = [c for c in cameras.split(",") if c] if cameras is not None else policy.cameras
    frames = FrameRobot(description, fps=rate, cameras=roles)
    say = _say(settings)
    try:
        robot = frames.open()
        if with_dashboard:
            with _dashboard(robot, say):
                report = run(frames, policy, seconds=seconds, progress=say)
        else:
            report = run(frames, policy, seconds=seconds, progress=say)
    finally:
        frames.close()
    click.echo(json.dumps(report.to_dict(), indent=2) if as_json else report.text())


COMMANDS = [rollout]
"""``record`` is added by busarm.cli.main beside the Foxglove recording of the same name
(the demonstrators' options choose it)."""
