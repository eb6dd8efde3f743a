"""A jog's release racing the control thread: once MOVE_STOP has gone out, no jog
target planned just before it may follow (the arm would move on after the stop).

The service is not started: the test takes its control ticks itself, on the simulated
arm, and makes the release arrive while a step is being planned.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from busarm.dashboard.jog import JogPlan, JogStep
from busarm.dashboard.protocol import parse_request
from busarm.dashboard.service import RobotService
from busarm.protocol import Command, Request
from busarm.robot import Robot, RobotConfig
from busarm.sim.spec import SimSpec
from busarm.sim.transport import SimTransport

MOVES = {Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE, Command.MOVE_START}


def test_a_release_during_a_jog_step_sends_no_target_after_the_stop(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    robot = Robot.open(RobotConfig(SimSpec()))
    service = RobotService(robot, folder=tmp_path / "robot")
    transport = robot.arm.bus.transport
    assert isinstance(transport, SimTransport)
    seen: list[Request] = []
    transport.bus.taps.append(seen.append)
    names = tuple(j.name for j in robot.config.joints)

    def send(text: str) -> None:
        service.handle("p1", parse_request(text, names))

    try:
        service.subscribe("p1", lambda _: None)
        send('{"type": "jog", "joint": "base_yaw", "direction": 1}')
        send('{"type": "heartbeat"}')
        service._tick()
        assert any(r.command in MOVES for r in seen), "the jog did not move"

        plan = JogPlan.step

        def released_meanwhile(self: JogPlan, *args: object, **kwargs: object) -> JogStep:
            send('{"type": "jog_stop"}')  # the page's release, from the server's thread
            return plan(self, *args, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr(JogPlan, "step", released_meanwhile)
        seen.clear()
        send('{"type": "heartbeat"}')
        service._tick()
        commands = [r.command for r in seen]
        assert Command.MOVE_STOP in commands
        last_stop = len(commands) - 1 - commands[::-1].index(Command.MOVE_STOP)
        assert not MOVES & set(commands[last_stop:]), commands
    finally:
        service.close()
        robot.close()
