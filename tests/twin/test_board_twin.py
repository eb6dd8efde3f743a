"""Pick-and-sort on the twin behind the simulated controller board (``board://twin``):
every move and read of the arm goes through the board's frames, and the result is
scored against the twin's ground truth."""

from __future__ import annotations

import math
from pathlib import Path

from busarm.apps.pick_sort.sorter import IN_BIN_MM, PickSorter
from busarm.bus.board_bus import BoardServoBus
from busarm.protocol import Command, Request
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.sim.board import SimBoard
from busarm.sim.spec import BoardSettings
from busarm.twin.spec import TwinSpec
from busarm.twin.transport import TwinTransport


def test_pick_sort_through_the_board_sorts_a_seeded_table(
        twin_calibration: tuple[Path, Path]) -> None:
    intrinsics, hand_eye = twin_calibration
    with Robot.open(RobotConfig(TwinSpec(seed=3, blocks=3, controller=BoardSettings()),
                                camera=CameraSpec(intrinsics=intrinsics,
                                                  hand_eye=hand_eye))) as robot:
        bus, twin = robot.arm.bus, robot.twin
        assert isinstance(bus, BoardServoBus) and twin is not None
        assert isinstance(bus.transport, TwinTransport)
        assert isinstance(bus.transport.bus, SimBoard)  # the host talks to the board only
        heard: list[Command] = []

        def tap(request: Request) -> None:
            heard.append(request.command)

        twin.bus.taps.append(tap)
        table = twin.blocks()
        report = PickSorter(robot).run()
        truth = twin.blocks()
        bins = robot.bins
    assert len(table) == 3
    assert report.totals()["sorted"] == 3, [b.to_dict() for b in report.blocks]
    for block in truth:
        bx, by = bins[block.color]
        assert math.hypot(block.x_mm - bx, block.y_mm - by) < IN_BIN_MM, block
    # The servos were moved by what the board sends them: MOVE_TIME_WRITE, never the
    # queued moves and MOVE_START of a plain LX line.
    assert Command.MOVE_TIME_WRITE in heard
    assert Command.MOVE_TIME_WAIT_WRITE not in heard and Command.MOVE_START not in heard
