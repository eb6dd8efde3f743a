"""``demo``: the simulated arm on a pseudo-terminal, scanned and moved through poses.

Every byte goes through a real pty, as it would to a USB adapter: the demo runs the
same driver code as a real arm.
"""

from __future__ import annotations

import time

import click
from rich.console import Console
from rich.live import Live
from rich.table import Table

from busarm.bus.driver import ServoBus
from busarm.cli.common import SPEED, Settings, pass_settings
from busarm.cli.render import scan_report, scan_with_progress, state_table
from busarm.protocol import MAX_SERVO_ID

# Joint angles in deg for servos 1 (base), 2 (shoulder), 3 (elbow), 4 (wrist),
# 5 (wrist rotation) and 10 (gripper).
POSES: list[tuple[str, dict[int, float]]] = [
    ("reach forward", {1: 0.0, 2: -35.0, 3: 60.0, 4: 40.0, 5: 0.0, 10: 25.0}),
    ("turn left, open gripper", {1: 60.0, 2: -10.0, 3: 30.0, 4: -20.0, 5: 45.0, 10: -20.0}),
    ("turn right, close gripper", {1: -60.0, 2: 20.0, 3: -30.0, 4: 30.0, 5: -45.0, 10: 25.0}),
    ("look up", {1: -20.0, 2: 30.0, 3: -50.0, 4: -40.0, 5: 0.0, 10: 0.0}),
    ("home", {1: 0.0, 2: 0.0, 3: 0.0, 4: 0.0, 5: 0.0, 10: 0.0}),
]
REFRESH_S = 0.1


@click.command()
@click.option("--speed", type=SPEED, metavar="DEG_S", default=35.0, show_default=True,
              help="Top joint speed in deg/s.")
@click.option("--poses", "n_poses", type=click.IntRange(1, len(POSES)), default=len(POSES),
              hidden=True, help="How many poses to go through (tests use 1).")
@click.option("--no-timing", is_flag=True, hidden=True,
              help="Simulate without wire timing (faster, for tests).")
@pass_settings
def demo(settings: Settings, speed: float, n_poses: int, no_timing: bool) -> None:
    """Scan and move a simulated arm (servos 1-5, gripper 10) over a pseudo-terminal.

    Ignores --port: it starts its own simulator. Takes about 15 s.
    """
    from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
    from busarm.sim.pty import PtyServer

    out = settings.out
    timing = WireTiming(settings.baudrate, enabled=not no_timing)
    sim = SimBus.with_ids(ARM_SERVO_IDS, timing=timing)
    with PtyServer(sim) as server:
        out.print(f"simulated arm on pseudo-terminal [bold]{server.path}[/bold]")
        with settings.open_bus(server.path) as bus:
            result = scan_with_progress(bus, range(MAX_SERVO_ID + 1), settings.err)
            scan_report(bus, result, out, MAX_SERVO_ID + 1)
            for name, pose in POSES[:n_poses]:
                targets = {sid: a for sid, a in pose.items() if sid in result.found}
                if not targets:
                    continue
                duration = bus.sync_move_deg(targets, speed_deg_s=speed)
                out.print(f"pose [bold]{name}[/bold]: moving together over {duration:.1f} s")
                _follow(bus, targets, duration, out)
                bus.wait_until_reached(targets, timeout_s=duration + 2.0)
            counters = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in bus.stats.items())
        out.print(f"done ({counters})")


def _follow(bus: ServoBus, targets: dict[int, float], duration_s: float, out: Console) -> None:
    """Show a live table of the moving servos until ``duration_s`` has passed.

    Output that is not a terminal gets only the last table.
    """
    end = time.monotonic() + duration_s

    def table() -> Table:
        return state_table(bus, targets, targets=targets)

    def wait() -> None:
        time.sleep(min(REFRESH_S, max(end - time.monotonic(), 0.0)))

    if not out.is_terminal:
        while time.monotonic() < end:
            wait()
        out.print(table())
        return
    with Live(table(), console=out, auto_refresh=False) as live:
        while time.monotonic() < end:
            wait()
            live.update(table(), refresh=True)


COMMANDS = [demo]
