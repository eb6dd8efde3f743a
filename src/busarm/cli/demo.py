"""``demo``: the simulated arm on a pseudo-terminal: scanned, then a Cartesian
pick-and-place with the tool path printed.

Every byte goes through a real pty, as it would to a USB adapter: the demo runs the
same driver and arm code as a real arm.
"""

from __future__ import annotations

import click
from rich.table import Table

from busarm.arm.arm import Arm
from busarm.arm.chain import Pose
from busarm.arm.config import load_arm_config
from busarm.arm.motion import LinePath
from busarm.cli.common import Settings, pass_settings, scan_report, scan_with_progress
from busarm.cli.text import number
from busarm.protocol import MAX_SERVO_ID

__all__ = [
    "ABOVE_MM",
    "COMMANDS",
    "GRASP_MM",
    "PICK",
    "PLACE",
    "PLACE_MM",
    "demo",
]


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
    from busarm.clock import WALL_CLOCK
    from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
    from busarm.sim.pty import PtyServer

    out = settings.out
    timing = WireTiming(settings.baudrate, enabled=not no_timing)
    sim = SimBus.with_ids(ARM_SERVO_IDS, timing=timing, clock=WALL_CLOCK)
    sim.put_block_in_gripper()
    with PtyServer(sim) as server:
        out.print(f"simulated arm on pseudo-terminal [bold]{server.path}[/bold]")
        with settings.open_bus(server.path) as bus:
            result = scan_with_progress(bus, range(MAX_SERVO_ID + 1), settings.err)
            scan_report(bus, result, out, MAX_SERVO_ID + 1)
            arm = Arm(bus, load_arm_config())
            path = _ToolPath(arm, line_speed)
            _pick_and_place(arm, path)
            out.print(path.table)
            counters = ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in bus.stats.items())
        out.print(f"done in {arm.clock.now() - path.t0:.1f} s ({counters})")


class _ToolPath:
    """The table of the tool path, measured from the servos: a row per step, and rows
    along each straight move with how far the tool strayed from the line."""

    def __init__(self, arm: Arm, line_speed: float) -> None:
        self.arm, self.line_speed = arm, line_speed
        self.table = Table(title="tool path (measured: servo positions through FK)",
                           title_justify="left")
        for col in ("step", "t (s)", "x (mm)", "y (mm)", "z (mm)", "pitch", "off line (mm)"):
            self.table.add_column(col, justify="right")
        self.t0 = arm.clock.now()

    def row(self, step: str, off: float | None = None) -> None:
        """Where the tool is now, read back."""
        p = self.arm.read_pose()
        self.table.add_row(step, number(self.arm.clock.now() - self.t0), *_pose_cells(p),
                           "" if off is None else number(off, 2))

    def note(self, step: str) -> None:
        """A step that moves no joint (the gripper's)."""
        self.table.add_row(step, "", "", "", "", "", "")

    def line(self, step: str, x: float, y: float, z: float) -> None:
        """A straight move of the tool, pointing down, to x, y, z mm."""
        arm = self.arm
        start = arm.clock.now() - self.t0
        rec = arm.move_line(x, y, z, -90.0, 0.0, speed_mm_s=self.line_speed, record=True)
        segment = LinePath(arm.kin.fk(rec.commanded_deg[0]), arm.kin.fk(
            rec.commanded_deg[-1]))
        points = [arm.kin.fk(q) for _, q in rec.measured]
        every = max(1, len(points) // 4)
        for k in range(every, len(points) - 1, every):
            p = points[k]
            self.table.add_row("", number(start + rec.measured[k][0]), *_pose_cells(p), "")
        self.row(step, float(segment.distance_mm(points).max()))


def _pick_and_place(arm: Arm, path: _ToolPath) -> None:
    """The block from PICK to PLACE, from home to home, each step in ``path``."""
    arm.home()
    path.row("home")
    arm.open_gripper()
    arm.move_to(*PICK, ABOVE_MM, -90.0, 0.0)
    path.row("above the block")
    path.line("down to grasp", *PICK, GRASP_MM)
    grip = arm.grip()
    path.note(f"grip: {'holding the block' if grip.is_holding else 'closed on nothing'}")
    path.line("lift", *PICK, ABOVE_MM)
    path.line("carry", *PLACE, ABOVE_MM)
    path.line("lower", *PLACE, PLACE_MM)
    arm.open_gripper()
    path.note("release")
    path.line("retreat", *PLACE, ABOVE_MM)
    arm.home()
    path.row("home")


def _pose_cells(p: Pose) -> list[str]:
    """x, y, z (mm) and pitch (deg) of a table row, one decimal, never ``-0.0``."""
    return [number(v) for v in (p.x_mm, p.y_mm, p.z_mm, p.pitch_deg)]


COMMANDS = [demo]
