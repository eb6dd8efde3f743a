"""The arm over a surface, on the mobile base: what ``busarm.apps.transport.mobile_pick`` works in.

``Workspace(robot, surface)`` holds the arm's kinematics reaching down to the surface
(the arm's config keeps its tool above its own table, the deck), the block locator and
the grasp planner on the surface's plane, the chassis's footprint to keep the fingers
off, and the frames' conversions: the base frame (m, x ahead, y left, the origin on the
floor under the base's centre) and the arm's (mm, on the deck, ``ChassisConfig.arm``; a
surface ``height_m`` above the floor is at ``(height_m - arm.z_m) * 1000`` mm there).
It knows where straight-down grasps reach on the surface (``Reach``) and how the wrist
camera looks at it: look poses chosen from the kinematics and the hand-eye calibration
(``busarm.apps.pick_sort.look_poses``), pictures averaged and merged by ``TableView``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlanner
from busarm.apps.pick_sort.look_poses import look_pose
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.apps.pick_sort.table_view import TableView
from busarm.arm.kinematics import ArmKinematics
from busarm.base.config import ChassisConfig
from busarm.errors import ConfigError, UnreachableError
from busarm.perception.locate import BlockLocator, Sighting
from busarm.robot import Robot
from busarm.units import check_range, place_text

ImageArray = npt.NDArray[np.uint8]

SURVEY_CAMERA_MM = 420.0
SURVEY_TILT_DEG = 45.0
"""A survey's camera stands about this high over the surface, its axis at most this far
from straight down (farther it would see more of the room than of the surface)."""
CLOSE_CAMERA_MM = 250.0
CLOSE_TILT_DEG = 15.0
"""A closer look: the camera nearly straight over the block (the best located), this high."""
SURVEY_VIEWS = (("ahead", 0.33, 0.0, SURVEY_CAMERA_MM, SURVEY_TILT_DEG),
                ("left", 0.33, 60.0, SURVEY_CAMERA_MM, SURVEY_TILT_DEG),
                ("right", 0.33, -60.0, SURVEY_CAMERA_MM, SURVEY_TILT_DEG),
                ("near", 0.2, 0.0, CLOSE_CAMERA_MM, CLOSE_TILT_DEG))
"""Where ``look_for_blocks`` aims the camera: (name, metres from the arm's axis, bearing
degrees, the camera's height over the surface, its tilt). On the JetAuto's floor the look
ahead sees from its front (0.15 m from the arm's axis) to 0.55 m, 0.55 m wide across the
middle, but for the middle of its near edge, which the gripper hides: the near look
sees there."""
LOOK_FRAMES = 3
"""Pictures averaged per look."""
DECK_CLEAR_MM = 30.0
"""A held block passes this high over the deck; the tool keeps this high over it."""
FINGER_ROOM_MM = 5.0
"""Beyond a finger's pad and its clearance, room kept between a grasp and the chassis."""
WHEEL_WIDTH_SHARE = 0.45
"""A mecanum wheel is about this share of its diameter wide (the chassis's footprint
reaches past the track by half of it)."""
COMFORT_SHARE = 0.6
"""The comfortable reach lies this share of the way out along the straight-down grasps."""
RAISED_SHARE = 0.9
"""On a table, this share: the base stays as far back from the table's edge as it can."""
_REACHES: dict[tuple[object, ...], Reach] = {}
"""``Reach`` found before, by what decides it (the arm, the grasp planner, the chassis)."""


@dataclass(frozen=True)
class Surface:
    """Where blocks stand: the floor, or a table's top ``height_m`` above the floor."""

    name: str
    height_m: float

    def __post_init__(self) -> None:
        check_range("height_m", self.height_m, 0.0, 1.0, "m")


FLOOR = Surface("floor", 0.0)


@dataclass(frozen=True)
class BlockSeen:
    """A block the wrist camera saw: its colour, where it is (base frame, m), its yaw
    (deg, modulo 90), the picture it was seen in and whether it was seen whole."""

    color: str
    x_m: float
    y_m: float
    yaw_deg: float
    image: ImageArray = field(repr=False, compare=False)
    whole: bool = True


@dataclass(frozen=True)
class Reach:
    """Where the arm takes a block on a surface (arm frame, mm, straight ahead): straight
    down between ``down_mm`` (nearest, farthest); ``comfortable_mm`` is where fine
    alignment brings a block: well inside that, clear of the chassis."""

    down_mm: tuple[float, float]
    comfortable_mm: float


# ---------------------------------------------------------------------- the workspace


class Workspace:
    """The arm over one surface: kinematics that reach down to it, the locator and the
    grasp planner on its plane, the chassis to keep off, the frames' conversions."""

    def __init__(self, robot: Robot, surface: Surface,
                 colors: Sequence[str] | None = None) -> None:
        if robot.base is None:
            raise ConfigError("picking with the arm on the mobile base needs the base: open "
                              "the robot on a board:// port with a chassis")
        self.robot, self.arm, self.surface = robot, robot.arm, surface
        self.chassis: ChassisConfig = robot.base.config
        self.mount = self.chassis.arm
        self.settings = PickSortSettings(survey_frames=LOOK_FRAMES)
        self.z_mm = (surface.height_m - self.mount.z_m) * 1000.0
        self.kin = ArmKinematics.from_config(replace(self.arm.config, table_z_mm=self.z_mm))
        cal = robot.require_camera_calibration()
        self.cam2link = cal.hand_eye.cam2link
        self.locator = BlockLocator(self.kin, cal.intrinsics, cal.hand_eye,
                                    robot.locator(colors).detector, table_z_mm=self.z_mm)
        size = self.block_mm = self.locator.block_size_mm
        # Carried above the deck (the arm's base plane, z 0), or the usual carry height.
        self.travel_mm = max(self.settings.carry_mm, -self.z_mm + size + DECK_CLEAR_MM)
        self.planner = GraspPlanner(self.kin, self.z_mm, size, self.settings.approach_mm,
                                    self.travel_mm, pad_mm=self.arm.config.gripper.pad_mm)
        self.deck = _deck_mm(self.chassis)
        self.view = TableView(self.arm, robot.camera, self.locator, {}, [], self.settings,
                              lambda _: None)

    # ------------------------------------------------------------------ frames

    def to_arm_mm(self, x_m: float, y_m: float) -> tuple[float, float]:
        m = self.mount
        dx, dy = x_m - m.x_m, y_m - m.y_m
        c, s = math.cos(m.yaw_rad), math.sin(m.yaw_rad)
        return 1000.0 * (c * dx + s * dy), 1000.0 * (-s * dx + c * dy)

    def to_base_m(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        m = self.mount
        c, s = math.cos(m.yaw_rad), math.sin(m.yaw_rad)
        x, y = x_mm / 1000.0, y_mm / 1000.0
        return m.x_m + c * x - s * y, m.y_m + s * x + c * y

    def seen(self, sighting: Sighting, image: ImageArray) -> BlockSeen:
        loc = sighting.location
        x, y = self.to_base_m(loc.x_mm, loc.y_mm)
        yaw = (loc.yaw_deg + math.degrees(self.mount.yaw_rad) + 45.0) % 90.0 - 45.0
        return BlockSeen(sighting.color, x, y, yaw, image, sighting.whole)

    # ------------------------------------------------------------------ reach

    def reach(self) -> Reach:
        """Where straight-down grasps reach straight ahead, and the comfortable one;
        UnreachableError saying by how much if no grasp reaches the surface at all."""
        p = self.planner
        key = (self.arm.config.geometry, self.arm.config.limits_deg, p.table_z_mm, p.block_mm,
               p.approach_mm, p.carry_mm, p.pad_mm, p.margin_mm, self.deck.corners.tobytes(),
               self.surface.height_m > 0.0)
        if key not in _REACHES:
            _REACHES[key] = self._reach()
        return _REACHES[key]

    def _reach(self) -> Reach:
        radii = np.arange(60.0, self.kin.max_reach_mm, 5.0).tolist()
        down: list[float] = []
        other: list[float] = []
        for r in radii:
            try:
                plan = self.planner.plan(r, 0.0, 0.0)
            except UnreachableError:
                continue
            (down if plan.pitch_deg == -90.0 else other).append(r)
        if not down:
            raise UnreachableError(self._out_of_reach(bool(other)))
        lo, hi = min(down), max(down)
        # Clear of the chassis's front: half a block, a pad and its clearance, and room.
        front = (_ray_exit_mm(self.deck, 0.0) + self.block_mm / 2
                 + self.planner.pad_mm[0] + self.settings.finger_clearance_mm + FINGER_ROOM_MM)
        # On a table the base stays back from its edge (which it does not see): as far
        # out as straight down reaches well.
        share = COMFORT_SHARE if self.surface.height_m <= 0.0 else RAISED_SHARE
        comfortable = min(max(front, lo + share * (hi - lo)), hi)
        return Reach((lo, hi), comfortable)

    def _out_of_reach(self, tilted: bool) -> str:
        grasp = self.planner.grasp_z_mm
        lowest = _lowest_tool_mm(self.kin)
        where = (f"a block there is taken {-grasp:.0f} mm below the arm's base (which stands "
                 f"{self.mount.z_m * 1000:.0f} mm above the floor)" if grasp < 0 else
                 f"a block there is taken {grasp:.0f} mm above the arm's base")
        if tilted:
            return (f"the {self.surface.name} ({self.surface.height_m:.3f} m) is reached only "
                    f"tilted, never straight down: {where}")
        return (f"the {self.surface.name} ({self.surface.height_m:.3f} m) is out of the arm's "
                f"reach: {where}; within the joints' limits of {self.arm.config.name!r} its "
                f"fingertips go down to {abs(lowest):.0f} mm "
                f"{'below' if lowest < 0 else 'above'} its base")

    @contextlib.contextmanager
    def reaching(self) -> Iterator[None]:
        """The arm's moves allowed down to the surface while in the block (its config's
        table is the deck)."""
        kept = self.arm.kin
        self.arm.kin = self.kin
        try:
            yield
        finally:
            self.arm.kin = kept

    def rise_over_deck(self) -> None:
        """Straight up to the travel height first if the tool is lower (so that the joint
        move that follows sweeps over the deck and what stands on the surface)."""
        arm, s = self.arm, self.settings
        tool = arm.read_pose()
        up = self.z_mm + self.travel_mm
        if tool.z_mm < up - 1.0:
            try:
                arm.move_line(tool.x_mm, tool.y_mm, up, tool.pitch_deg, tool.roll_deg,
                              speed_mm_s=s.line_speed_mm_s)
            except UnreachableError:  # not straight up from here: nearly, joint by joint
                arm.move_to(tool.x_mm, tool.y_mm, up, tool.pitch_deg, tool.roll_deg,
                            speed_deg_s=s.joint_speed_deg_s / 2)

    # ------------------------------------------------------------------ looking

    def look_at(self, x_mm: float, y_mm: float, camera_mm: float, tilt_deg: float,
                bearing_deg: float | None = None) -> tuple[float, ...]:
        """Joints that aim the camera at (x, y) on the surface from about ``camera_mm``
        over it (``look_pose``), turned to ``bearing_deg`` (default the point's); tilted
        up to ``SURVEY_TILT_DEG`` if ``tilt_deg`` from straight down does not reach."""
        joints = None
        for tilt in sorted({tilt_deg, max(tilt_deg, SURVEY_TILT_DEG)}):  # nearer straight
            with contextlib.suppress(UnreachableError):  # down if it can be, else tilted
                joints = look_pose(self.kin, self.cam2link, self.z_mm,
                                   math.hypot(x_mm, y_mm), camera_mm, tilt, self.deck_clear_mm())
                break
        if joints is None:
            raise UnreachableError(f"no look pose aims the camera at {place_text((x_mm, y_mm))} "
                                   f"on the {self.surface.name}")
        bearing = math.degrees(math.atan2(y_mm, x_mm)) if bearing_deg is None else bearing_deg
        return self.arm.config.check_joints((bearing, *joints[1:]))

    def deck_clear_mm(self) -> tuple[float, float]:
        """(how far the deck reaches from the arm's axis at most, the tool's least height
        over it there): what a look pose keeps clear."""
        return float(np.max(np.hypot(*self.deck.corners.T))), DECK_CLEAR_MM

    def survey(self) -> list[BlockSeen]:
        """Every block seen ahead, left, right and near."""
        poses: list[Sequence[float]] = []
        for _, dist_m, bearing, camera_mm, tilt_deg in SURVEY_VIEWS:
            with contextlib.suppress(UnreachableError, ConfigError):  # a side not looked at
                poses.append(self.look_at(dist_m * 1000.0, 0.0, camera_mm, tilt_deg, bearing))
        if not poses:
            raise UnreachableError(f"no look pose aims the camera at the {self.surface.name}")
        self.view.survey_poses = poses
        self.rise_over_deck()
        found = self.view.survey()
        return [self.seen(s, _picture_of(s, self.view.last_survey)) for s in found]

    def look_closer(self, color: str | None, x_mm: float, y_mm: float) -> list[Sighting]:
        """Blocks of ``color`` (None: any) seen whole with the camera over (x, y), nearest
        first."""
        pose = self.look_at(x_mm, y_mm, CLOSE_CAMERA_MM, CLOSE_TILT_DEG)
        self.rise_over_deck()
        _, found = self.view.look(pose, fresh=True)
        self.view.seen = found
        same = [s for s in found if color in (None, s.color) and s.whole]
        return sorted(same, key=lambda s: math.hypot(s.location.x_mm - x_mm,
                                                     s.location.y_mm - y_mm))


def half_size_m(chassis: ChassisConfig) -> tuple[float, float]:
    """Half the chassis's length and width (its wheels included)."""
    r = chassis.wheel_diameter_m / 2
    return chassis.wheelbase_m / 2 + r, chassis.track_m / 2 + WHEEL_WIDTH_SHARE * r


def _deck_mm(chassis: ChassisConfig) -> Footprint:
    """The chassis's footprint in the arm's frame (mm)."""
    half_x, half_y = half_size_m(chassis)
    m = chassis.arm
    c, s = math.cos(m.yaw_rad), math.sin(m.yaw_rad)
    corners = [(sx * half_x - m.x_m, sy * half_y - m.y_m)
               for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return Footprint(np.array([(1000 * (c * x + s * y), 1000 * (-s * x + c * y))
                               for x, y in corners]))


def _ray_exit_mm(footprint: Footprint, bearing_deg: float) -> float:
    """How far from the arm's axis a ray on ``bearing_deg`` leaves ``footprint``."""
    u = np.array([math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg))])
    far = 0.0
    for r in np.arange(0.0, 2000.0, 1.0):
        if footprint.reaches(np.array([u * r]), 0.0):
            far = float(r)
        elif far:
            break
    return far


def _lowest_tool_mm(kin: ArmKinematics) -> float:
    """The lowest the tool point goes within the joints' limits (a grid, to a few mm)."""
    (_, _), (lo2, hi2), (lo3, hi3), (lo4, hi4), _ = kin.limits_deg
    q2, q3, q4 = np.meshgrid(np.arange(lo2, hi2 + 0.1, 2.0), np.arange(lo3, hi3 + 0.1, 2.0),
                             np.arange(lo4, hi4 + 0.1, 2.0), indexing="ij")
    zeros = np.zeros(q2.size)
    q = np.stack([zeros, q2.ravel(), q3.ravel(), q4.ravel(), zeros], axis=1)
    return float(kin.fk_matrix_batch(q)[:, 2, 3].min())


def _picture_of(sighting: Sighting,
                pictures: Sequence[tuple[ImageArray, list[Sighting]]]) -> ImageArray:
    for image, found in pictures:
        if any(f is sighting for f in found):
            return image
    return pictures[-1][0]


def xy_mm(sighting: Sighting) -> tuple[float, float]:
    return sighting.location.x_mm, sighting.location.y_mm


def m_text(xy: tuple[float, float]) -> str:
    """A place in the base frame as the messages say it: ``(0.41, -0.08) m``."""
    return f"({xy[0]:.2f}, {xy[1]:.2f}) m"




__all__ = ["FLOOR", "BlockSeen", "Reach", "Surface", "Workspace", "half_size_m", "m_text",
           "xy_mm"]
