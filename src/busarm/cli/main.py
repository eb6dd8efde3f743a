"""The ``busarm`` group: global options, command registry and error handling.

Every expected failure ends as one line on stderr, ``error: ...``, and an exit code:
2 for bad input (usage errors, ConfigError), 1 for bus errors (timeouts, garbled
replies, a port that cannot be opened), 130 when interrupted. No tracebacks.
"""

from __future__ import annotations

import logging
import sys
import warnings
from collections.abc import Sequence
from typing import Any, NoReturn, TextIO

import click

from busarm import __version__
from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S
from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.cli import (
    arm_cmds,
    bus_cmds,
    camera_cmds,
    config_cmds,
    demo,
    locate_cmd,
    pick_cmd,
    proto_cmds,
    servo_cmds,
    sim_cmds,
    twin_cmds,
    vision_cmds,
)
from busarm.cli.bench_cmd import bench
from busarm.cli.common import STOPPED, Settings, servos_stopped
from busarm.errors import BusArmError, ConfigError

EXIT_BUS_ERROR = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130


def _fail(message: str, code: int, exc: BaseException | None = None) -> NoReturn:
    if exc is not None and servos_stopped(exc):
        message = f"{message}: {STOPPED}"
    click.echo(f"error: {message}", err=True)
    sys.exit(code)


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
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            try:
                rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            except click.ClickException as exc:
                _fail(exc.format_message(), exc.exit_code, exc)
            except click.Abort as exc:
                _fail("interrupted", EXIT_INTERRUPTED, exc)
            except ConfigError as exc:
                _fail(str(exc), EXIT_BAD_INPUT, exc)
            except BusArmError as exc:
                _fail(str(exc) or type(exc).__name__, EXIT_BUS_ERROR, exc)
            except BrokenPipeError:  # `busarm decode ... | head`
                sys.exit(0)
        if not standalone_mode:
            return rv
        sys.exit(rv if isinstance(rv, int) else 0)


@click.group(cls=BusArmGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="busarm")
@click.option(
    "--port", envvar="BUSARM_PORT", default="sim", show_default=True, show_envvar=True,
    help="Serial port: a device path (/dev/ttyUSB0, COM3), a pyserial URL (socket://host:port, "
         "loop://), the simulator: 'sim' or 'sim://?ids=1,2,3&echo=1&timing=0', or the "
         "digital twin: 'twin' or 'twin://?seed=3&blocks=6'.",
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
    help="Slack in ms added to each reply deadline (which is derived from the baud rate).",
)
@click.option(
    "--retries", type=click.IntRange(0, 10), default=DEFAULT_RETRIES, show_default=True,
    help="How many times a read is retried after a timeout or a garbled reply.",
)
@click.option("-v", "--verbose", is_flag=True, help="Log bus details (echo detection) to stderr.")
@click.pass_context
def cli(
    ctx: click.Context, port: str, baudrate: int, echo: str, timeout_margin_ms: float,
    retries: int, verbose: bool,
) -> None:
    """Drive LX-protocol serial bus servos (a JetAuto Pro style arm: IDs 1-5 and 10).

    Angles are in degrees from each servo's mid-point (-120..120), times in seconds,
    voltages in volts, temperatures in deg C. Try `busarm demo` for a simulated arm.
    """
    if verbose:
        logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    ctx.obj = Settings(
        port=port, baudrate=baudrate, echo=echo, timeout_margin_ms=timeout_margin_ms,
        retries=retries,
        port_given=ctx.get_parameter_source("port") is not click.core.ParameterSource.DEFAULT,
    )


for _module in (
    bus_cmds, servo_cmds, config_cmds, proto_cmds, sim_cmds, arm_cmds, twin_cmds, camera_cmds,
    vision_cmds, pick_cmd, demo,
):
    for _command in _module.COMMANDS:
        cli.add_command(_command)

cli.add_command(bench)
# `vision locate` needs the arm; the rest of `vision` does not.
vision_cmds.vision.add_command(locate_cmd.locate)


def main() -> None:
    """Entry point of the ``busarm`` script."""
    cli.main(prog_name="busarm")


if __name__ == "__main__":
    main()
