"""``demo``: the simulated arm on a pseudo-terminal: scanned, then a Cartesian
pick-and-place with the tool path printed.

Every byte goes through a real pty, as it would to a USB adapter: the demo runs the
same driver and arm code as a real arm.
"""

from __future__ import annotations

import click
from rich.table import Table

from busarm.arm.arm import Arm
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import Pose
from busarm.arm.motion import LinePath
from busarm.cli.common import Settings, pass_settings, scan_report, scan_with_progress
from busarm.cli.text import number
from busarm.protocol import MAX_SERVO_ID

PICK = (200.0, -110.0)
PLACE = (190.0, 120.0)
ABOVE_MM = 80.0
"""Approach and carry height of the tool point above the table."""
GRASP_MM = 15.0
"""Tool point height when gripping a 3 cm block (the vendor descends to 1.5 cm)."""
PLACE_MM = 25.0


@click.command()
@click.option("--no-timing", is_flag=True, hidden=True,
              help="Simulate without wire timing (faster, for tests).")
@click.option("--line-speed", type=click.FloatRange(10.0, 300.0), default=120.0,
              show_default=True, help="Peak tool speed of the straight moves, mm/s.")
@pass_settings
def demo(settings: Settings, no_timing: bool, line_speed: float) -> None:
    """Pick and place a block with the simulated arm over a pseudo-terminal.

    Ignores --port: it starts its own simulator (servos 1-5 and gripper 10, a 3 cm
    block between the fingers). Prints the tool path measured from the servos.
    Takes about 30 s.
    """
    from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
    from busarm.sim.pty import PtyServer

    out = settings.out
    timing = WireTiming(settings.baudrate, enabled=not no_timing)
    sim = SimBus.with_ids(ARM_SERVO_IDS, timing=timing)
    sim.put_block_in_gripper()
    with PtyServer(sim) as server:
        out.print(f"simulated arm on pseudo-terminal [bold]{server.path}[/bold]")
        with settings.open_bus(server.path) as bus:
            result = scan_with_progress(bus, range(MAX_SERVO_ID + 1), settings.err)
            scan_report(bus, result, out, MAX_SERVO_ID + 1)
            arm = Arm(bus, load_arm_config())
            path = Table(title="tool path (measured: servo positions through FK)",
                         title_justify="left")
            for col in ("step", "t (s)", "x (mm)", "y (mm)", "z (mm)", "pitch", "off line (mm)"):
                path.add_column(col, justify="right")
            t0 = arm.clock.now()

            def row(step: str, off: float | None = None) -> None:
                p = arm.read_pose()
                path.add_row(step, number(arm.clock.now() - t0), *_pose_cells(p),
                             "" if off is None else number(off, 2))

            def line(step: str, x: float, y: float, z: float) -> None:
                start = arm.clock.now() - t0
                rec = arm.move_line(x, y, z, -90.0, 0.0, speed_mm_s=line_speed, record=True)
                segment = LinePath(arm.kin.fk(rec.commanded_deg[0]), arm.kin.fk(
                    rec.commanded_deg[-1]))
                points = [arm.kin.fk(q) for _, q in rec.measured]
                every = max(1, len(points) // 4)
                for k in range(every, len(points) - 1, every):
                    p = points[k]
                    path.add_row("", number(start + rec.measured[k][0]), *_pose_cells(p), "")
                row(step, float(segment.distance_mm(points).max()))

            arm.home()
            row("home")
            arm.open_gripper()
            arm.move_to(*PICK, ABOVE_MM, -90.0, 0.0)
            row("above the block")
            line("down to grasp", *PICK, GRASP_MM)
            grip = arm.grip()
            state = "holding the block" if grip.is_holding else "closed on nothing"
            path.add_row(f"grip: {state}", "", "", "", "", "", "")
            line("lift", *PICK, ABOVE_MM)
            line("carry", *PLACE, ABOVE_MM)
            line("lower", *PLACE, PLACE_MM)
            arm.open_gripper()
            path.add_row("release", "", "", "", "", "", "")
            line("retreat", *PLACE, ABOVE_MM)
            arm.home()
            row("home")
            out.print(path)
            counters = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in bus.stats.items())
        out.print(f"done in {arm.clock.now() - t0:.1f} s ({counters})")


def _pose_cells(p: Pose) -> list[str]:
    """x, y, z (mm) and pitch (deg) of a table row, one decimal, never ``-0.0``."""
    return [number(v) for v in (p.x_mm, p.y_mm, p.z_mm, p.pitch_deg)]


COMMANDS = [demo]
