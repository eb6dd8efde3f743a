"""``base drive | move-by | stop | odom``: the mecanum base on the controller board's wheel
motors (``--port board://...``), in m/s, deg/s, metres and degrees."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import click

from busarm.base.base import CONTROL_PERIOD_S, Base, BaseOdometry
from busarm.base.config import DEFAULT_CHASSIS, load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.cli.common import RangeType, Settings, pass_settings

__all__ = [
    "COMMANDS",
    "NEGATIVE_OK",
    "base",
    "chassis_option",
    "drive",
    "move_by",
    "odom",
    "stop",
]


chassis_option = click.option(
    "--chassis", default=DEFAULT_CHASSIS, show_default=True,
    help="The chassis config: a shipped name (jetauto) or a TOML file.")


@click.group()
def base() -> None:
    """The mobile base through the controller board (--port board://..., e.g. board://sim).

    Speeds beyond the chassis's limits are refused; the wheels stop at the end, on Ctrl+C,
    and whenever commands stop coming (the watchdog).
    """


@contextmanager
def _open_base(settings: Settings, chassis: str) -> Iterator[Base]:
    config = load_chassis_config(chassis)
    with settings.open_board() as link, Base(link, config) as the_base:
        yield the_base


def _odom_text(odom: BaseOdometry) -> str:
    p, t = odom.pose, odom.twist
    return (f"x {p.x_m:+.3f} m  y {p.y_m:+.3f} m  yaw {p.yaw_deg:+.1f} deg  "
            f"(moving {t.vx_m_s:+.3f} m/s, {t.vy_m_s:+.3f} m/s, "
            f"{math.degrees(t.wz_rad_s):+.1f} deg/s; odometry from {odom.source})")


NEGATIVE_OK = {"ignore_unknown_options": True}
"""-0.1 is a number here, not an option."""


@base.command(context_settings=NEGATIVE_OK)
@click.argument("vx", type=RangeType("vx", -10.0, 10.0, "m/s"))
@click.argument("vy", type=RangeType("vy", -10.0, 10.0, "m/s"))
@click.argument("wz_deg_s", metavar="WZ_DEG_S", type=RangeType("wz", -3600.0, 3600.0, "deg/s"))
@click.option("--time", "time_s", type=RangeType("time", 0.0, 600.0, "s"), default=1.0,
              show_default=True, help="How long to drive, in s (Ctrl+C stops sooner).")
@chassis_option
@pass_settings
def drive(settings: Settings, vx: float, vy: float, wz_deg_s: float, time_s: float,
          chassis: str) -> None:
    """Drive at VX m/s forward, VY m/s left, WZ_DEG_S deg/s counter-clockwise for --time
    seconds, then stop. Speeds beyond the chassis's limits are refused, nothing sent."""
    config = load_chassis_config(chassis)
    MecanumKinematics(config).check_limits(Twist(vx, vy, math.radians(wz_deg_s)))
    with _open_base(settings, chassis) as the_base:
        end = the_base.clock.now() + time_s
        command = the_base.command
        while the_base.clock.now() < end:
            command = the_base.drive(vx, vy, math.radians(wz_deg_s))
            the_base.clock.sleep(min(CONTROL_PERIOD_S, max(end - the_base.clock.now(), 0.0)))
        the_base.stop()
        the_base.wait_stopped()
        odom = the_base.odometry()
    settings.out.print(f"drove {time_s:g} s at vx {command.vx_m_s:+.3f} m/s, vy "
                       f"{command.vy_m_s:+.3f} m/s, wz {math.degrees(command.wz_rad_s):+.1f} "
                       f"deg/s (reached at the acceleration limits); wheels stopped")
    settings.out.print(_odom_text(odom))


@base.command("move-by", context_settings=NEGATIVE_OK)
@click.argument("dx", type=RangeType("dx", -100.0, 100.0, "m"))
@click.argument("dy", type=RangeType("dy", -100.0, 100.0, "m"))
@click.argument("dyaw_deg", metavar="DYAW_DEG", type=RangeType("dyaw", -3600.0, 3600.0, "deg"))
@chassis_option
@pass_settings
def move_by(settings: Settings, dx: float, dy: float, dyaw_deg: float, chassis: str) -> None:
    """Move DX m forward, DY m left and turn DYAW_DEG deg counter-clockwise on a smooth
    profile, closed on the odometry; ends stopped."""
    with _open_base(settings, chassis) as the_base:
        pose = the_base.move_by(dx, dy, math.radians(dyaw_deg))
        source = the_base.odometry_source
    settings.out.print(f"moved to x {pose.x_m:+.3f} m, y {pose.y_m:+.3f} m, yaw "
                       f"{pose.yaw_deg:+.1f} deg from the start (odometry from {source}); "
                       "wheels stopped")


@base.command()
@pass_settings
def stop(settings: Settings) -> None:
    """Every wheel motor to 0."""
    with settings.open_board() as link:
        link.stop_motors()
    settings.out.print("sent every wheel motor 0 rev/s")


@base.command()
@click.option("--time", "time_s", type=RangeType("time", 0.0, 60.0, "s"), default=0.5,
              show_default=True, help="How long to follow the odometry, in s.")
@chassis_option
@pass_settings
def odom(settings: Settings, time_s: float, chassis: str) -> None:
    """The odometry over --time seconds from now (the base is not driven)."""
    with _open_base(settings, chassis) as the_base:
        the_base.clock.sleep(time_s)
        reading = the_base.odometry()
    settings.out.print(_odom_text(reading))


COMMANDS = [base]
