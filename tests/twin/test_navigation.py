"""The navigation stack on the arena twin, through the real path, and its faults.

``Robot.open(RobotConfig(TwinSpec(arena=..., controller=BoardSettings())))`` drives the
chassis through the simulated controller board and reads the simulated A1's bytes; the
map is the robot's own (``build_map``, once for the module), then ``Navigator``
localises on it, plans and follows (busarm.apps.navigation.navigator), and ``TransportJob`` fetches
a block (busarm.apps.transport.job). The truth (the chassis's pose and speed, the arena's
geometry, what touched the chassis) is read only here, by the tests and their scan hooks
(a person carrying the robot, stepping in the way, unplugging the Lidar, a servo
browning out).

The arena is two small rooms: a partition from the south wall leaves one 0.8 m gap to
the east; a box waits in the east room's corner, to be moved into the way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from scipy.optimize import minimize
from scipy.spatial import cKDTree

from busarm.apps.navigation.explore import MapRun, build_map
from busarm.apps.navigation.navigator import Navigator, NavSettings
from busarm.apps.navigation.sensing import SensedScan
from busarm.apps.transport.job import TransportJob
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.errors import ConfigError, NavigationError
from busarm.lidar.rplidar import RplidarA1
from busarm.nav.map_files import OCCUPIED_THRESH
from busarm.nav.mapping import compose, inverse
from busarm.protocol import Request
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.sim.rplidar import SimRplidar
from busarm.sim.spec import BoardSettings
from busarm.sim.transport import SimTransport
from busarm.twin.arena import WALL_THICKNESS_M, Arena, ArenaBlock, Room, Solid, StartPose
from busarm.twin.arena_tasks import transport_points
from busarm.twin.mobile import MobileBase
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

pytestmark = pytest.mark.slow  # the mobile robot mapping and driving an arena

FloatArray = npt.NDArray[np.float64]

PARKED = (1.8, -0.8)
"""Where the movable box waits (the east room's south-east corner)."""
GAP = (0.6, 0.6)
"""The middle of the only way between the rooms."""
ARENA = Arena(room=Room(-1.0, 2.0, -1.0, 1.0),
              boxes=(Solid(0.6, -0.4, 0.2, 1.2, 0.3),  # the partition, y -1.0..0.2
                     Solid(*PARKED, 0.3, 0.3, 0.3)),
              start=StartPose(-0.4, 0.1, 20.0), name="two rooms")
MOVABLE = 1
"""The box the tests move (body ``box1``)."""
WEST_GOAL = Pose2D(-0.6, -0.6, math.radians(-90.0))
EAST_GOAL = Pose2D(1.4, 0.3, 0.0)
"""Arena frame: one in the start's room, one through the gap."""
EXPOSED_M = 0.1
"""A stretch of wall or box side with nothing else this near is in the Lidar's view."""


@dataclass
class Mapped:
    """The robot's own map of ARENA and where it really lies in the arena."""

    run: MapRun
    contacts: list[tuple[float, str]]
    placed: Pose2D
    """The map's frame in the arena: the rigid placement that fits the map's walls to the
    true ones best (nominally the start pose)."""

    def to_map(self, pose: Pose2D) -> Pose2D:
        return compose(inverse(self.placed), pose)

    def to_arena(self, pose: Pose2D) -> Pose2D:
        return compose(self.placed, pose)


def surface_distance_m(arena: Arena, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> FloatArray:
    """From each point (arena frame) to the nearest solid: a wall (its slab) or a box."""
    x, y = np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64)
    r = arena.room
    inside = np.minimum.reduce([x - r.x_min_m, r.x_max_m - x, y - r.y_min_m, r.y_max_m - y])
    out = np.where(inside >= 0.0, inside, np.maximum(-inside - WALL_THICKNESS_M, 0.0))
    for box in arena.boxes:
        assert box.yaw_deg == 0.0  # square to the room: the distance below is exact
        gap_x = np.maximum(np.abs(x - box.x_m) - box.size_x_m / 2, 0.0)
        gap_y = np.maximum(np.abs(y - box.y_m) - box.size_y_m / 2, 0.0)
        out = np.minimum(out, np.hypot(gap_x, gap_y))
    return np.asarray(out, dtype=np.float64)


def in_arena(placed: Pose2D, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    c, s = math.cos(placed.yaw_rad), math.sin(placed.yaw_rad)
    return (placed.x_m + c * points[:, 0] - s * points[:, 1],
            placed.y_m + s * points[:, 0] + c * points[:, 1])


def occupied_cells(run: MapRun) -> FloatArray:
    rows, cols = np.nonzero(run.grid.probability >= OCCUPIED_THRESH)
    return run.grid.spec.centres(rows, cols).reshape(-1, 2)


def best_placement(arena: Arena, cells: FloatArray, guess: Pose2D) -> Pose2D:
    """The map frame's pose in the arena that brings its occupied cells nearest the true
    surfaces (least squares, from ``guess``)."""
    def cost(v: FloatArray) -> float:
        x, y = in_arena(Pose2D(float(v[0]), float(v[1]), float(v[2])), cells)
        return float(np.mean(surface_distance_m(arena, x, y) ** 2))

    found = minimize(cost, np.array([guess.x_m, guess.y_m, guess.yaw_rad]),
                     method="Nelder-Mead", options={"xatol": 1e-5, "fatol": 1e-10})
    return Pose2D(float(found.x[0]), float(found.x[1]), float(found.x[2]))


def exposed_face_points(arena: Arena, step_m: float = 0.05) -> FloatArray:
    """Points every ``step_m`` along the room's walls and the boxes' sides that nothing
    else stands within EXPOSED_M of (not in a corner, nor a side against a wall)."""
    r = arena.room
    out: list[FloatArray] = []
    for k, solid in enumerate([None, *arena.boxes]):
        if solid is None:  # the walls, less the room's corners
            x0, x1, y0, y1 = r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m
            others = replace(arena, room=Room(-14.0, 14.0, -14.0, 14.0))
            trim = EXPOSED_M
        else:
            hx, hy = solid.size_x_m / 2, solid.size_y_m / 2
            x0, x1, y0, y1 = solid.x_m - hx, solid.x_m + hx, solid.y_m - hy, solid.y_m + hy
            others = replace(arena, boxes=arena.boxes[:k - 1] + arena.boxes[k:])
            trim = 0.0
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1], strict=True):
            length = math.dist((ax, ay), (bx, by))
            t = np.arange(trim, length - trim + 1e-9, step_m) / length
            x, y = ax + t * (bx - ax), ay + t * (by - ay)
            keep = surface_distance_m(others, x, y) >= EXPOSED_M
            out.append(np.column_stack([x[keep], y[keep]]))
    return np.concatenate(out)


@pytest.fixture(scope="module")
def mapped() -> Mapped:
    """ARENA explored and mapped by the robot itself from its start (about 8 s)."""
    with Robot.open(RobotConfig(TwinSpec(arena=ARENA, controller=BoardSettings()),
                                camera=CameraSpec(calibrate=False))) as robot:
        twin = twin_of(robot)
        run = build_map(robot, time_limit_s=120.0)
        contacts = list(mobile(twin).contacts)
    s = ARENA.start
    start = Pose2D(s.x_m, s.y_m, math.radians(s.yaw_deg))
    return Mapped(run, contacts, best_placement(ARENA, occupied_cells(run), start))


# ---------------------------------------------------------------------- the twin's truth

def twin_of(robot: Robot) -> Twin:
    assert robot.twin is not None
    return robot.twin


def mobile(twin: Twin) -> MobileBase:
    assert twin.mobile is not None
    return twin.mobile


def true_pose(robot: Robot) -> Pose2D:
    """Where the chassis really is (arena frame)."""
    twin = twin_of(robot)
    twin.sync()
    with twin.lock:
        return mobile(twin).pose(twin.data)


def true_speed_m_s(robot: Robot) -> float:
    twin = twin_of(robot)
    twin.sync()
    with twin.lock:
        vx, vy, _wz = mobile(twin).speed(twin.data)
    return math.hypot(vx, vy)


def contacts(robot: Robot) -> list[str]:
    return [name for _, name in mobile(twin_of(robot)).contacts]


def teleport(robot: Robot, pose: Pose2D) -> None:
    """A person lifts the robot and puts it down at ``pose`` (arena frame)."""
    twin_of(robot).put_base(pose.x_m, pose.y_m, pose.yaw_rad)


def move_box(robot: Robot, x_m: float, y_m: float) -> None:
    """The movable box steps to (x, y) (arena frame), square to the room."""
    twin = twin_of(robot)
    with twin.lock:
        mocap = int(twin.model.body(f"box{MOVABLE}").mocapid[0])
        twin.data.mocap_pos[mocap] = (x_m, y_m, 0.0)
        twin.data.mocap_quat[mocap] = (1.0, 0.0, 0.0, 0.0)
        twin.mujoco.mj_forward(twin.model, twin.data)


def simulated_lidar(robot: Robot) -> SimRplidar:
    """The simulated A1 behind ``robot.lidar``'s bytes."""
    assert robot.lidar is not None and isinstance(robot.lidar.source, RplidarA1)
    transport = robot.lidar.source.transport
    assert isinstance(transport, SimTransport)
    assert isinstance(transport.bus, SimRplidar)
    return transport.bus


def off_by(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    """(distance m, heading difference deg) between two poses."""
    return (math.dist((a.x_m, a.y_m), (b.x_m, b.y_m)),
            abs(math.degrees(wrap_rad(a.yaw_rad - b.yaw_rad))))


@contextmanager
def robot_at(start: Pose2D | None = None, arena: Arena = ARENA,
             calibration: tuple[Path, Path] | None = None) -> Iterator[Robot]:
    """The robot standing at ``start`` (arena frame; default the arena's start); its
    camera calibrated by ``calibration``'s files if given."""
    if start is not None:
        arena = replace(arena, start=StartPose(start.x_m, start.y_m, start.yaw_deg))
    intrinsics, hand_eye = calibration if calibration is not None else (None, None)
    camera = CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye, calibrate=False)
    with Robot.open(RobotConfig(TwinSpec(arena=arena, controller=BoardSettings()),
                                camera=camera)) as robot:
        yield robot


ScanHook = Callable[[Navigator, SensedScan], None]


def navigator(robot: Robot, mapped: Mapped, settings: NavSettings | None = None,
              on_scan: Callable[[Robot, Navigator], None] | None = None, *,
              localised: bool = True) -> Navigator:
    """A navigator on the module's map, localised near the truth (as a person says where
    the robot stands) if ``localised``; ``on_scan(robot, nav)`` after every scan."""
    hook: ScanHook | None = None
    if on_scan is not None:
        def hook(nav: Navigator, _sensed: SensedScan) -> None:
            on_scan(robot, nav)
    nav = Navigator(robot, mapped.run.grid, settings=settings, on_scan=hook)
    if localised:
        nav.localize(mapped.to_map(true_pose(robot)))
    return nav


# ---------------------------------------------------------------------- the map

def test_exploring_maps_the_walls_and_boxes_where_they_are_touching_nothing(
        mapped: Mapped) -> None:
    run = mapped.run
    assert run.finished.startswith("explored"), run.finished
    assert mapped.contacts == []
    # The map's frame is where the base started (to the odometry's and matching's error).
    s = ARENA.start
    start = Pose2D(s.x_m, s.y_m, math.radians(s.yaw_deg))
    frame_m, frame_deg = off_by(mapped.placed, start)
    assert frame_m < 0.02 and frame_deg < 1.5, (frame_m, frame_deg)
    # Every occupied cell lies on a true surface: no phantom obstacle, no doubled wall.
    cells = occupied_cells(run)
    x, y = in_arena(mapped.placed, cells)
    error_m = surface_distance_m(ARENA, x, y)
    assert float(error_m.max()) <= 0.03, np.percentile(error_m, [50, 95, 100])
    # And every surface in view is on the map (an empty map would pass the above).
    faces = exposed_face_points(ARENA)
    near_m, _ = cKDTree(np.column_stack([x, y])).query(faces)
    assert len(faces) > 150
    assert float(np.mean(near_m <= 0.03)) >= 0.95, faces[near_m > 0.03]


# ---------------------------------------------------------------------- localisation

def test_localisation_tracks_the_base_while_it_drives(mapped: Mapped) -> None:
    errors: list[tuple[float, float]] = []
    with robot_at() as robot:
        def note(robot: Robot, nav: Navigator) -> None:
            if nav.trips:  # while going (localised)
                errors.append(off_by(nav.pose, mapped.to_map(true_pose(robot))))

        nav = navigator(robot, mapped, on_scan=note)
        for goal in (WEST_GOAL, EAST_GOAL):
            assert nav.go_to(mapped.to_map(goal)).ok
        assert contacts(robot) == []
    position_m = [e[0] for e in errors]
    heading_deg = [e[1] for e in errors]
    assert len(errors) > 100  # every scan of some 20 s of driving
    assert max(position_m) <= 0.03, np.percentile(position_m, [50, 95, 100])
    assert max(heading_deg) <= 2.0, np.percentile(heading_deg, [50, 95, 100])


def test_global_localisation_finds_a_carried_robot_within_10_s(mapped: Mapped) -> None:
    with robot_at() as robot:
        teleport(robot, Pose2D(1.3, 0.5, math.radians(-150.0)))  # into the other room
        robot.clock.sleep(0.3)  # put down
        nav = navigator(robot, mapped, NavSettings(localize_limit_s=10.0), localised=False)
        began = robot.clock.now()
        estimate = nav.localize(None)
        took_s = robot.clock.now() - began
        position_m, heading_deg = off_by(estimate.pose, mapped.to_map(true_pose(robot)))
        assert contacts(robot) == []
    assert took_s <= 10.0
    assert position_m <= 0.05 and heading_deg <= 3.0, (position_m, heading_deg, took_s)


def test_a_robot_kidnapped_mid_trip_stops_or_recovers_touching_nothing(
        mapped: Mapped) -> None:
    kidnapped: list[Pose2D] = []

    def kidnap(robot: Robot, nav: Navigator) -> None:
        if not kidnapped and len(nav.trips) == 1 and len(nav.trips[0].path) == 15:
            to = Pose2D(-0.5, 0.6, math.radians(60.0))
            teleport(robot, to)
            kidnapped.append(to)

    goal = mapped.to_map(WEST_GOAL)
    with robot_at() as robot:
        nav = navigator(robot, mapped, on_scan=kidnap)
        try:
            nav.go_to(goal)
            nav.settle(goal)
        except NavigationError as exc:  # a clean stop: the base stands, and says why
            assert "the base is stopped" in str(exc)
            robot.clock.sleep(0.3)
            assert true_speed_m_s(robot) < 0.005
        else:  # recovered: it went on from where it really was, to the goal
            position_m, heading_deg = off_by(mapped.to_map(true_pose(robot)), goal)
            assert position_m <= 0.03 and heading_deg <= 2.0, (position_m, heading_deg)
        assert kidnapped
        assert contacts(robot) == []


def test_a_robot_shoved_mid_trip_finds_itself_again_and_arrives(mapped: Mapped) -> None:
    shoved: list[Pose2D] = []

    # A person bumps it 0.25 m aside 1.6 s into the trip. (Where the bump lands decides
    # whether the scans stop fitting: on some stretches of this room half of them still
    # fit, and the filter finds itself without stopping. 1.6 s in, at the speed the base
    # drives now, it is past them.)
    def shove(robot: Robot, nav: Navigator) -> None:
        if not shoved and len(nav.trips) == 1 and len(nav.trips[0].path) == 16:
            here = true_pose(robot)
            to = compose(here, Pose2D(0.0, 0.25, math.radians(8.0)))
            teleport(robot, to)
            shoved.append(to)

    goal = mapped.to_map(WEST_GOAL)
    with robot_at() as robot:
        nav = navigator(robot, mapped, on_scan=shove)
        trip = nav.go_to(goal)
        nav.settle(goal)
        assert shoved and trip.relocalised >= 1, trip  # the scans stopped fitting: found again
        position_m, heading_deg = off_by(mapped.to_map(true_pose(robot)), goal)
        assert position_m <= 0.03 and heading_deg <= 2.0, (position_m, heading_deg)
        assert contacts(robot) == []


# ---------------------------------------------------------------------- going places

def test_go_to_reaches_its_goals_within_3_cm_touching_nothing(mapped: Mapped) -> None:
    with robot_at() as robot:
        nav = navigator(robot, mapped)
        with pytest.raises(ConfigError, match=r"go_to: goal = \(0\.5, 0\.2, 0\.0\); give a Pose2D"):
            nav.go_to((0.5, 0.2, 0.0))  # type: ignore[arg-type]
        assert nav.trips == []
        for goal in (EAST_GOAL, WEST_GOAL):
            on_map = mapped.to_map(goal)
            trip = nav.go_to(on_map)
            nav.settle(on_map)
            position_m, heading_deg = off_by(mapped.to_map(true_pose(robot)), on_map)
            assert trip.ok and trip.why == "arrived"
            assert position_m <= 0.03 and heading_deg <= 2.0, (goal, position_m, heading_deg)
        assert contacts(robot) == []


def ahead_on_plan(nav: Navigator, distance_m: float) -> tuple[float, float]:
    """The point ``distance_m`` along the trip's latest plan from where the base is."""
    path = nav.trips[-1].plans[-1]
    here = (nav.pose.x_m, nav.pose.y_m)
    left = distance_m
    for a, b in zip([here, *path[1:]], path[1:], strict=False):
        step = math.dist(a, b)
        if step >= left:
            t = left / step
            return a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
        left -= step
    return path[-1]


def test_a_box_stepping_onto_the_path_is_driven_around(mapped: Mapped) -> None:
    start = Pose2D(-0.7, -0.6, math.radians(90.0))
    goal = Pose2D(-0.7, 0.7, math.radians(90.0))
    stepped: list[tuple[float, float]] = []

    def step_in(robot: Robot, nav: Navigator) -> None:
        trip = nav.trips[-1] if nav.trips else None
        if stepped or trip is None or not trip.plans or len(trip.path) < 5:
            return
        # Its near side 0.6 m ahead on the path (the box is 0.3 m square).
        x, y = ahead_on_plan(nav, 0.75)
        spot = mapped.to_arena(Pose2D(x, y, 0.0))
        move_box(robot, spot.x_m, spot.y_m)
        stepped.append((spot.x_m, spot.y_m))

    with robot_at(start) as robot:
        nav = navigator(robot, mapped, on_scan=step_in)
        trip = nav.go_to(mapped.to_map(goal))
        nav.settle(mapped.to_map(goal))
        position_m, _ = off_by(true_pose(robot), goal)
        assert contacts(robot) == []
    assert stepped
    assert trip.ok and position_m <= 0.03
    assert len(trip.plans) >= 2  # planned again, with the box in it
    # The way driven went round the box: its near side kept off the chassis's disc.
    box_x, box_y = stepped[0]
    path = [mapped.to_arena(p) for p in trip.path]
    clear_m = min(max(abs(p.x_m - box_x), abs(p.y_m - box_y)) for p in path) - 0.15
    assert clear_m >= 0.15, clear_m


@dataclass
class Stepped:
    """When the box stepped into the gap (and out), and the truth at each moment."""

    at_s: list[float] = field(default_factory=list)
    base: list[Pose2D] = field(default_factory=list)
    speed_m_s: list[float] = field(default_factory=list)


def gap_blocker(mapped: Mapped, *, for_s: float | None
                ) -> tuple[Callable[[Robot, Navigator], None], Stepped]:
    """A scan hook putting the box in the gap when the base is about 0.6 m from its near
    side (and back in its corner ``for_s`` later, if given)."""
    stepped = Stepped()

    def hook(robot: Robot, nav: Navigator) -> None:
        here = mapped.to_arena(nav.pose)
        now = robot.clock.now()
        steps = len(stepped.at_s)
        if steps == 0 and nav.trips and math.dist((here.x_m, here.y_m), GAP) < 0.9:
            move_box(robot, *GAP)
        elif steps == 1 and for_s is not None and now - stepped.at_s[0] >= for_s:
            move_box(robot, *PARKED)
        else:
            return
        stepped.at_s.append(now)
        stepped.base.append(true_pose(robot))
        stepped.speed_m_s.append(true_speed_m_s(robot))

    return hook, stepped


NEAR_SIDE_X_M = GAP[0] - 0.15
"""The box's near side, in the gap."""


def test_a_box_in_the_only_way_is_waited_for_until_it_goes(mapped: Mapped) -> None:
    hook, stepped = gap_blocker(mapped, for_s=3.0)
    with robot_at(Pose2D(-0.3, 0.5, 0.0)) as robot:
        nav = navigator(robot, mapped, on_scan=hook)
        trip = nav.go_to(mapped.to_map(EAST_GOAL))
        assert contacts(robot) == []
        position_m, _ = off_by(true_pose(robot), EAST_GOAL)
    assert len(stepped.at_s) == 2  # stepped in, and away 3 s later
    # When it went, the base stood waiting short of it (its front 0.15 m ahead).
    assert stepped.base[1].x_m < NEAR_SIDE_X_M - 0.15 - 0.05, stepped.base
    assert stepped.speed_m_s[1] < 0.005
    assert trip.ok and position_m <= 0.05
    assert trip.waited_s > 1.0


def test_a_box_that_stays_in_the_only_way_ends_the_trip_saying_so(mapped: Mapped) -> None:
    hook, stepped = gap_blocker(mapped, for_s=None)
    with robot_at(Pose2D(-0.3, 0.5, 0.0)) as robot:
        nav = navigator(robot, mapped, NavSettings(obstacle_wait_s=2.0), on_scan=hook)
        with pytest.raises(NavigationError, match=r"(no free route|something in the way) "
                                                  r"for 2 s; the base is stopped"):
            nav.go_to(mapped.to_map(EAST_GOAL))
        gave_up_s = robot.clock.now()
        robot.clock.sleep(0.3)
        assert true_speed_m_s(robot) < 0.005
        assert contacts(robot) == []
        here = true_pose(robot)
    assert stepped.at_s and gave_up_s - stepped.at_s[0] >= 2.0
    assert here.x_m < NEAR_SIDE_X_M - 0.15  # its front short of the box's near side


# ---------------------------------------------------------------------- faults

def test_a_lidar_that_stops_sending_stops_the_base(mapped: Mapped) -> None:
    silenced: list[float] = []

    def unplug(robot: Robot, nav: Navigator) -> None:
        if not silenced and nav.trips and len(nav.trips[-1].path) == 10:
            simulated_lidar(robot).go_silent()
            silenced.append(robot.clock.now())

    with robot_at() as robot:
        nav = navigator(robot, mapped, on_scan=unplug)
        with pytest.raises(NavigationError, match=r"the Lidar sent no scan for 1 s .*the "
                                                  r"base is stopped"):
            nav.go_to(mapped.to_map(EAST_GOAL))
        assert silenced
        assert robot.clock.now() - silenced[0] < 1.5  # noticed within the scan timeout
        robot.clock.sleep(0.3)
        assert true_speed_m_s(robot) < 0.005
        assert contacts(robot) == []


def test_a_servo_that_stops_answering_in_the_pick_ends_the_job_not_delivered(
        mapped: Mapped, twin_calibration: tuple[Path, Path]) -> None:
    block_at = (-0.3, -0.5)
    arena = replace(ARENA, blocks=(ArenaBlock("red", *block_at),))
    stands, _index, _spot = transport_points(arena, Pose2D())  # arena frame
    pick = stands.get("pick").pose
    points, _, _ = transport_points(arena, mapped.placed)  # the map's frame
    silenced: list[Request] = []
    picking: list[str] = []
    heard: list[Request] = []

    def progress(line: str) -> None:
        if line.startswith("pick"):
            picking.append(line)  # from here on, count the requests

    with robot_at(compose(pick, Pose2D(-0.1, 0.05, math.radians(10.0))), arena,
                  twin_calibration) as robot:
        twin = twin_of(robot)

        def brown_out_later(request: Request) -> None:
            # Some way into the pick: the elbow's supply drops under 6 V and it answers
            # nothing more.
            if picking and not silenced:
                heard.append(request)
                if len(heard) > 60:
                    twin.servos[2].supply_mv = 5000
                    silenced.append(request)

        twin.bus.taps.append(brown_out_later)
        job = TransportJob(robot, mapped.run.grid, points, "pick", "place",
                           progress=progress)
        report = job.run(mapped.to_map(true_pose(robot)))
        robot.clock.sleep(0.3)
        speed_m_s = true_speed_m_s(robot)
        touched = contacts(robot)
    assert silenced, report.to_dict()
    assert not report.delivered
    assert "servo 3" in report.why, report.why
    failed = [p for p in report.phases if not p.ok]
    assert [p.name for p in failed] == ["pick"] and "servo 3" in failed[0].detail
    assert report.to_dict()["delivered"] is False
    assert speed_m_s < 0.005
    assert touched == []
