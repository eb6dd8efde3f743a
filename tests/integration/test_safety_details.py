"""Details found by a new user's review: noisy scans, default waits, broadcast ID reads,
faults named in motion timeouts, and the simulator's power-off state.

Scans and broadcast reads on a noisy or shared LX line are the LX wire's own; the tests
of the bus's calls also run behind the simulated controller board on a pty (``way``).
In-process (``SimSpec`` included) the servos are on a simulated clock, so a long move
waited for costs only CPU; behind the board on a pty they are on the wall clock."""

from __future__ import annotations

from pathlib import Path

import pytest

from busarm.bus.driver import ServoBus
from busarm.clock import WALL_CLOCK
from busarm.errors import BusConflictError, ConfigError, MotionTimeoutError
from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
from busarm.sim.spec import SimSpec
from conftest import BOARD_WAY, sim_bus_on


@pytest.fixture(params=["inproc", BOARD_WAY])
def way(request: pytest.FixtureRequest) -> str:
    """The simulated servos in-process, or behind the simulated controller board on a pty."""
    return str(request.param)


def sim_for(way: str, ids: list[int], **kwargs: object) -> SimBus:
    """Simulated servos for ``way``: on a simulated clock in-process, on the wall clock
    behind the board on a pty (a pty serves in wall-clock time)."""
    return SimBus.with_ids(ids, clock=WALL_CLOCK if way == BOARD_WAY else None,
                           **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_noisy_line_is_not_reported_as_duplicate_ids(seed: int) -> None:
    bus = ServoBus.open(SimSpec(corrupt=0.05, seed=seed))
    result = bus.scan()
    assert result.conflicts == []
    assert set(result.found) <= set(ARM_SERVO_IDS)
    assert len(result.found) >= 4  # a few may be lost to the noise; none is invented


def test_real_duplicates_are_still_reported() -> None:
    bus = ServoBus.open(SimSpec(ids=(1, 3, 3, 5)))
    result = bus.scan()
    assert result.found == [1, 5]
    assert result.conflicts == [3]


def test_broadcast_id_read_with_several_servos_is_a_conflict() -> None:
    bus = ServoBus.open(SimSpec())
    with pytest.raises(BusConflictError, match="more than one servo"):
        bus.read_id()
    assert ServoBus.open(SimSpec(ids=(7,))).read_id() == 7


def test_default_wait_covers_the_whole_commanded_move() -> None:
    # Longer than any fixed default would allow: the wait follows the move. (In-process
    # only, on the simulated clock: the bookkeeping is ServoBus's, the same behind the
    # board, where a second run would cost another 5.5 s of wall-clock time.)
    bus = ServoBus.open(SimSpec(ids=(3,)))
    t0 = bus.clock.now()
    bus.move_deg(3, 20.0, 5.5)
    positions = bus.wait_until_reached({3: 20.0})
    assert abs(positions[3] - 20.0) <= 1.0
    assert bus.clock.now() - t0 >= 5.0


def test_motion_timeout_names_a_servo_that_unloaded(way: str) -> None:
    with sim_bus_on(sim_for(way, [2]), way) as bus:
        bus.write_vin_limits_v(2, 11.5, 11.9)  # the simulated supply is 11.1 V
        bus.move_deg(2, 30.0, 0.3)
        with pytest.raises(MotionTimeoutError, match="servo 2 .*torque off"):
            bus.wait_until_reached({2: 30.0}, timeout_s=0.5)


def test_power_off_keeps_where_the_horns_are(tmp_path: Path, way: str) -> None:
    state = tmp_path / "servos.json"
    sim = sim_for(way, [1, 2], state_file=state, timing=WireTiming(enabled=False))
    with sim_bus_on(sim, way, echo="off") as bus:
        bus.move_deg(1, 45.0, 0.2)
        bus.wait_until_reached({1: 45.0}, tolerance_deg=0.3)
    sim.power_off()
    again = sim_for(way, [1, 2], state_file=state)
    with sim_bus_on(again, way, echo="off") as bus:
        assert bus.read_position_deg(1) == pytest.approx(45.0, abs=0.3)
        assert bus.read_position_deg(2) == pytest.approx(0.0, abs=0.3)


def test_state_file_in_a_missing_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        SimBus.with_ids([1], state_file=tmp_path / "nope" / "servos.json")
