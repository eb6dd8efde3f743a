"""The ``busarm`` group: global options, command registry and error handling.

Every expected failure ends as one line on stderr, ``error: ...``, and an exit code
(``busarm.cli.exits``). Ctrl+C ends as one line ``interrupted: ...`` and 130. Either
line says what the servos were left doing, read back, if anything was written to them
(``busarm.cli.stopping``). Output whose reader went away (``busarm ... | head``) ends
quietly with 141, as Unix tools do. No tracebacks.
"""

from __future__ import annotations

import contextlib
import ctypes
import inspect
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn, TextIO

import click

from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S
from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.cli import (
    actions_cmds,
    arm_cmds,
    base_cmds,
    bench_games_cmd,
    board_cmds,
    bus_cmds,
    camera_cmds,
    config_cmds,
    dashboard_cmd,
    demo,
    help_style,
    learn_cmds,
    lidar_cmds,
    line_follow_cmd,
    locate_cmd,
    map_cmds,
    motor_cmd,
    option_places,
    pick_cmd,
    poses_cmd,
    proto_cmds,
    robot_cmds,
    ros_cmds,
    samples_cmd,
    servo_cmds,
    sim_cmds,
    stack_cmd,
    track_cmd,
    transport_cmd,
    twin_cmds,
    view_cmds,
    vision_cmds,
)
from busarm.cli.bench_cmd import bench
from busarm.cli.bench_learn_cmd import bench_teleop
from busarm.cli.common import Settings, report_line, unwritten_text
from busarm.cli.exits import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OUTPUT_CLOSED
from busarm.cli.stopping import Terminated, new_command, servos_note, stop_on_termination
from busarm.errors import BusArmError, ConfigError
from busarm.version import __version__

__all__ = [
    "EXIT_BUS_ERROR",
    "INPUT_ENDED",
    "BusArmGroup",
    "cli",
    "main",
]


EXIT_BUS_ERROR = EXIT_FAILED
INPUT_ENDED = ("the input ended (end of file) before the question was answered: run it at a "
               "terminal, or with --yes")


class _OutputClosed(Exception):
    """stdout's reader went away (raised from the BrokenPipeError, past click's own
    handling of it, which would exit 1)."""


def _fail(message: str, code: int, exc: BaseException | None = None) -> NoReturn:
    click.echo(f"error: {report_line(exc, message)}", err=True)
    sys.exit(code)


def _interrupted(exc: BaseException, message: str = "interrupted") -> NoReturn:
    """Ctrl+C: one line, what the servos were left doing, exit code 130; SIGTERM or
    SIGHUP the same, saying which, with 128 + its number (143, 129), as a shell reports a
    program it ended."""
    signalled = _terminated(exc)
    if signalled is not None:
        message = str(signalled) if message == "interrupted" else message
    elif sys.stderr.isatty():
        click.echo(err=True)  # off the line where the terminal echoed ^C
    click.echo(report_line(exc, message, unwritten=unwritten_text()), err=True)
    sys.exit(EXIT_INTERRUPTED if signalled is None else 128 + signalled.signum)


def _terminated(exc: BaseException) -> Terminated | None:
    """The SIGTERM or SIGHUP ``exc`` came of, if it did."""
    found = _of(exc, Terminated)
    return found if isinstance(found, Terminated) else None


def _output_closed(exc: BaseException) -> NoReturn:
    """The reader of stdout went away: end quietly, as Unix tools do; only if the servos
    were stopped for it is that said (on stderr)."""
    # Nothing more reaches the pipe, not even the flush at exit (no real stdout in tests).
    with contextlib.suppress(OSError, ValueError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    if servos_note(exc) is not None:
        click.echo(f"error: {report_line(exc, 'the output was closed (broken pipe)')}", err=True)
    sys.exit(EXIT_OUTPUT_CLOSED)


def _by(exc: BaseException, kind: type[BaseException]) -> bool:
    """Whether ``exc`` is, or came of, a ``kind`` (click turns an EOF at a prompt into its
    Abort; rich turns a broken pipe into SystemExit)."""
    return _of(exc, kind) is not None


def _of(exc: BaseException, kind: type[BaseException]) -> BaseException | None:
    """The ``kind`` that ``exc`` is or came of, if any."""
    seen: BaseException | None = exc
    met: set[int] = set()
    while seen is not None and id(seen) not in met:
        if isinstance(seen, kind):
            return seen
        met.add(id(seen))
        seen = seen.__cause__ or seen.__context__
    return None


def _of_ctrl_c(exc: BaseException) -> bool:
    """Whether ``exc`` came of a Ctrl+C: a KeyboardInterrupt in its chain, or the
    ctypes.ArgumentError it turns into in a C call's arguments (MuJoCo's OpenGL calls)."""
    return _by(exc, KeyboardInterrupt) or (
        isinstance(exc, ctypes.ArgumentError) and "KeyboardInterrupt" in str(exc))


def _show_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int,
    file: TextIO | None = None, line: str | None = None,
) -> None:
    click.echo(f"warning: {message}", err=True)


class BusArmGroup(click.Group):
    """A click group that turns every expected error into one ``error:`` line."""

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        new_command()
        restore = stop_on_termination()
        try:
            return self._main(args, prog_name, complete_var, standalone_mode, **extra)
        finally:
            restore()

    def _main(self, args: Sequence[str] | None, prog_name: str | None,
              complete_var: str | None, standalone_mode: bool, **extra: Any) -> Any:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            try:
                rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
                sys.stdout.flush()  # here, not at exit, where a closed pipe is not caught
            except click.ClickException as exc:
                said = option_places.explain(exc, self, sys.argv[1:] if args is None else args)
                # One style: ours end without a full stop, so click's do too.
                _fail(said[:-1] if said.endswith(".") and not said.endswith("..") else said,
                      exc.exit_code, exc)
            except click.Abort as exc:
                if _by(exc, EOFError):  # not a Ctrl+C: stdin ended at a prompt
                    click.echo(err=True)  # off the prompt's line
                    _fail(INPUT_ENDED, EXIT_BAD_INPUT, exc)
                # A command may say where it was: Abort("interrupted at frame 3 of 7").
                _interrupted(exc, str(exc) or "interrupted")
            except ConfigError as exc:
                _fail(str(exc), EXIT_BAD_INPUT, exc)
            except BusArmError as exc:
                _fail(str(exc) or type(exc).__name__, EXIT_BUS_ERROR, exc)
            except (_OutputClosed, BrokenPipeError) as exc:  # `busarm decode ... | head`
                _output_closed(exc)
        if not standalone_mode:
            return rv
        sys.exit(rv if isinstance(rv, int) else 0)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:  # as click's Abort, without click's blank line
            raise click.Abort from exc
        except (BrokenPipeError, SystemExit) as exc:
            if _by(exc, BrokenPipeError):
                raise _OutputClosed from exc
            raise
        except (click.Abort, click.ClickException):
            raise  # (an Abort saying where it was interrupted keeps its words)
        except Exception as exc:
            if _of_ctrl_c(exc):  # a Ctrl+C inside a C call comes wrapped (ctypes)
                raise click.Abort from exc
            raise


@click.group(cls=BusArmGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="busarm")
@click.option(
    "--port", envvar="BUSARM_PORT", default="sim", show_default=True, show_envvar=True,
    help="Serial port (here or after the command): a device path (/dev/ttyUSB0, COM3), a "
         "pyserial URL (socket://host:port, "
         "loop://), the simulator: 'sim' or 'sim://?ids=1,2,3&echo=1&timing=0', or the "
         "digital twin: 'twin' or 'twin://?seed=3&blocks=6'. Without it: the arm of a "
         "running `busarm sim serve` or `twin serve`, else a simulated arm for one command.",
)
@click.option(
    "--baud", "baudrate", type=click.IntRange(1200, 4_000_000), default=DEFAULT_BAUDRATE,
    show_default=True, help="Baud rate in bit/s (LX servos use 115200).",
)
@click.option(
    "--echo", type=click.Choice(["on", "off", "auto"]), default="auto", show_default=True,
    help="Whether the adapter echoes what it sends: one-wire/resistor adapters do (on), "
         "direction-switching boards such as the BusLinker do not (off); auto probes once.",
)
@click.option(
    "--timeout-margin-ms", type=click.FloatRange(0.0, 1000.0),
    default=DEFAULT_TIMEOUT_MARGIN_S * 1000.0, show_default=True,
    envvar="BUSARM_TIMEOUT_MARGIN_MS", show_envvar=True,
    help="Slack in ms added to each reply deadline (which is derived from the baud rate); "
         "raise it on a computer busy with other work, which may hear replies late.",
)
@click.option(
    "--retries", type=click.IntRange(0, 10), default=DEFAULT_RETRIES, show_default=True,
    help="How many times a read is retried after a timeout or a garbled reply.",
)
@click.option(
    "--robot", "robot_file", envvar="BUSARM_ROBOT", show_envvar=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="A robot file (`busarm robot init` writes one): the whole robot, its port, arm, "
         "base, Lidar, camera and bins, instead of --port and the part options.",
)
@click.option("-v", "--verbose", is_flag=True, help="Log bus details (echo detection) to stderr.")
@click.pass_context
def cli(
    ctx: click.Context, port: str, baudrate: int, echo: str, timeout_margin_ms: float,
    retries: int, robot_file: Path | None, verbose: bool,
) -> None:
    """Drive a JetAuto Pro style arm of LX-protocol bus servos (IDs 1-5 and 10), on
    hardware, the simulator or the digital twin.

    The main job, on the twin: `busarm pick-sort --seed 3 --blocks 5` (what `make demo`
    runs). A tour of the simulated arm: `busarm demo`. Angles are in degrees, lengths in
    mm, times in seconds, voltages in volts, temperatures in deg C.
    """
    if verbose:
        option_places.log_verbosely()
    ctx.obj = Settings(
        port=port, baudrate=baudrate, echo=echo, timeout_margin_ms=timeout_margin_ms,
        retries=retries,
        port_given=ctx.get_parameter_source("port") is not click.core.ParameterSource.DEFAULT,
        port_from_env=ctx.get_parameter_source("port") is click.core.ParameterSource.ENVIRONMENT,
        robot_file=robot_file,
    )


class _RecordEither(click.Command):
    """``record``: the robot's channels into an MCAP file for Foxglove (view_cmds), or,
    given who demonstrates (--expert, --leader, --teleop), demonstrations into a LeRobot
    dataset (learn_cmds): one verb, the command chosen by those options."""

    DEMONSTRATORS = ("--expert", "--leader", "--teleop")

    def __init__(self, mcap: click.Command, dataset: click.Command) -> None:
        super().__init__("record", help=mcap.help, short_help=(
            "Record the robot: an MCAP file for Foxglove, or (--expert, --leader, "
            "--teleop) demonstrations as a LeRobot dataset."))
        self.mcap, self.dataset = mcap, dataset
        mcap.help = inspect.cleandoc(mcap.help or "") + (
            "\n\nWith --expert, --leader or --teleop it records demonstrations into a "
            "LeRobot dataset instead: busarm record OUT --expert pick-sort --help.")

    def make_context(self, info_name: str | None, args: list[str],
                     parent: click.Context | None = None, **extra: Any) -> click.Context:
        demonstrated = any(a.split("=", 1)[0] in self.DEMONSTRATORS for a in args)
        chosen = self.dataset if demonstrated else self.mcap
        return chosen.make_context(info_name, args, parent=parent, **extra)

    def invoke(self, ctx: click.Context) -> Any:
        assert ctx.command is not self
        return ctx.command.invoke(ctx)


for _module in (
    bus_cmds, servo_cmds, config_cmds, proto_cmds, sim_cmds, arm_cmds, actions_cmds, twin_cmds,
    camera_cmds, vision_cmds, pick_cmd, demo, motor_cmd, dashboard_cmd, board_cmds, base_cmds,
    lidar_cmds, map_cmds, line_follow_cmd, transport_cmd, ros_cmds, robot_cmds, view_cmds,
    track_cmd, stack_cmd, learn_cmds,
):
    for _command in _module.COMMANDS:
        cli.add_command(_command)

cli.add_command(_RecordEither(view_cmds.record, learn_cmds.record))
cli.add_command(bench)
bench.add_command(bench_games_cmd.bench_track)
bench.add_command(bench_games_cmd.bench_stack)
bench.add_command(bench_teleop)
# `vision locate` needs the arm; the rest of `vision` does not.
vision_cmds.vision.add_command(locate_cmd.locate)
# `arm poses` and `actions list` are kept out of arm_cmds and actions_cmds.
arm_cmds.arm.add_command(poses_cmd.poses)
actions_cmds.actions.add_command(samples_cmd.samples_list)
# Last, once every command is in: `busarm arm pose --port twin`, `busarm --config X arm pose`.
option_places.accept_everywhere(cli)
option_places.name_numbers(cli)
help_style.apply(cli)


def main() -> None:
    """Entry point of the ``busarm`` script."""
    try:
        cli.main(prog_name="busarm")
    except KeyboardInterrupt as exc:  # outside a command: starting up or ending
        _interrupted(exc)


if __name__ == "__main__":
    main()
