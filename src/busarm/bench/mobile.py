"""``busarm bench mobile``: the mobile twin's odometry, Lidar and speed, against its truth.

Everything runs through ``Robot.open("board://twin?...")``: the base through the simulated
controller board's bytes, the Lidar through the A1's. The twin's ground truth (where the
chassis really is, what the Lidar's rays really hit) is read only here, never by the code
under test.

- Odometry: a 2 m square driven by ``move_by`` (four sides, four 90 degree turns) in an
  empty room with the slip model on, once per seed; the odometry's final pose (encoders +
  IMU) against the twin's, as a share of the 8 m driven and in degrees.
- Lidar: scans of a seeded arena with the robot standing: every beam against a noise-free
  ray cast at its bearing, with the noise model off (the A1's wire quantisation only) and
  on (residuals in units of the model's sigma; dropouts counted).
- Real time: the base driving, the arm moving, the wrist camera at 10 frames per
  simulated second (captured at their instants, drawn in a thread of their own while
  physics goes on, as a camera exposes while the robot moves: busarm.twin.camera_stream),
  the Lidar read scan after scan: simulated seconds per wall second until the last frame
  is drawn,
  and the Lidar's and the camera's rates in simulated time; with the camera drawn as a
  stream (no antialiasing: what a line follower or the dashboard reads), then as
  vision's pictures (four samples a pixel).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from busarm.base.odometry import wrap_rad
from busarm.bench.common import machine_info
from busarm.nav.mapping import compose
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.arena import Arena, Room, StartPose
from busarm.twin.camera_stream import CameraStream
from busarm.twin.lidar import LidarNoise, TwinLidarWorld
from busarm.twin.spec import TwinSpec

SIDE_M = 2.0
STILL_S = 1.0
"""The base stands still this long first: the gyro's bias is learnt while still."""
TARGET_POSITION_SHARE = 0.03
TARGET_HEADING_DEG = 3.0
TARGET_LIDAR_M = 0.01
TARGET_LIDAR_HZ = 10.0
TARGET_REALTIME = 5.0
CAMERA_FPS = 10.0


@dataclass
class SquareRun:
    seed: int
    driven_m: float
    position_error_m: float
    heading_error_deg: float
    odometry_end: tuple[float, float, float]
    true_end: tuple[float, float, float]
    worst_corner_share: float = 0.0
    """The largest error at a corner over the distance driven to it: the drift along the
    way (a closed square hands much of it back by the end)."""

    @property
    def position_share(self) -> float:
        return self.position_error_m / self.driven_m


@dataclass
class LidarAccuracy:
    seed: int = 0
    scans: int = 0
    beams: int = 0
    max_error_m: float = math.nan
    """Noise model off: the largest |measured - ray-cast truth|."""
    noisy_beams: int = 0
    sigma_ratio: float = math.nan
    """Noise model on: the residuals' RMS over the model's sigma (1 = as modelled)."""
    dropout_share: float = math.nan


@dataclass
class RealTimeRun:
    live: bool = True
    """The camera drawn as a stream (no antialiasing), or as vision's pictures."""
    sim_s: float = 0.0
    wall_s: float = 0.0
    scans: int = 0
    frames: int = 0
    lidar_hz: float = 0.0
    camera_fps: float = 0.0

    @property
    def factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.nan


@dataclass
class MobileBenchReport:
    machine: dict[str, str]
    squares: list[SquareRun] = field(default_factory=list)
    lidar: LidarAccuracy = field(default_factory=LidarAccuracy)
    realtime: RealTimeRun = field(default_factory=RealTimeRun)
    realtime_vision: RealTimeRun = field(default_factory=lambda: RealTimeRun(live=False))
    picture: str | None = None

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for run, data in zip(self.squares, out["squares"], strict=True):
            data["position_share"] = run.position_share
        out["realtime"]["factor"] = self.realtime.factor
        out["realtime_vision"]["factor"] = self.realtime_vision.factor
        return out


def square_arena(seed: int) -> Arena:
    """An empty 5 x 5 m room, the robot at (-1, -1) facing +x (the noise seeded)."""
    return Arena(Room(-2.5, 2.5, -2.5, 2.5), start=StartPose(-1.0, -1.0, 0.0),
                 name="empty room", seed=seed, source=f"empty room, seed {seed}")


def run_square(seed: int, picture: Path | None = None) -> SquareRun:
    """One 2 m square with the slip model on; its end by odometry and by the twin."""
    with Robot.open(RobotConfig(TwinSpec(arena=square_arena(seed), controller=BoardSettings()),
                                camera=CameraSpec(calibrate=False))) as robot:
        base, twin = robot.base, robot.twin
        assert base is not None and twin is not None and twin.mobile is not None
        robot.clock.sleep(STILL_S)
        start = twin.mobile.pose(twin.data)
        corners = [(start.x_m, start.y_m)]
        worst = 0.0
        for side in range(4):
            base.move_by(SIDE_M, 0.0, 0.0)
            base.move_by(0.0, 0.0, math.pi / 2)
            believed = compose(start, base.odometry().pose)
            corners.append((believed.x_m, believed.y_m))
            truth = twin.mobile.pose(twin.data)
            off = math.dist(corners[-1], (truth.x_m, truth.y_m))
            worst = max(worst, off / (SIDE_M * (side + 1)))
        odom = base.odometry().pose
        true = twin.mobile.pose(twin.data).relative_to(start)
        if picture is not None:
            from busarm.twin.arena_picture import arena_picture
            from busarm.vision.annotate import save_image

            save_image(picture, arena_picture(
                twin, odometry_path=corners,
                title=f"2 m square by move_by, slip on (seed {seed})"))
    heading = math.degrees(abs(wrap_rad(odom.yaw_rad - true.yaw_rad)))
    return SquareRun(seed, 4 * SIDE_M, math.hypot(odom.x_m - true.x_m, odom.y_m - true.y_m),
                     heading, (odom.x_m, odom.y_m, odom.yaw_deg),
                     (true.x_m, true.y_m, true.yaw_deg), worst)


def run_lidar_accuracy(seed: int, scans: int) -> LidarAccuracy:
    """The Lidar against ray-cast truth, noise model off and on (robot standing)."""
    out = LidarAccuracy(seed=seed, scans=scans)
    errors: list[float] = []
    normalised: list[float] = []
    dropped = total = 0
    for noisy in (False, True):
        world = TwinSpec(family="arena", seed=seed, lidar_noise=None if noisy else False,
                         controller=BoardSettings())
        with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot:
            assert robot.lidar is not None and robot.twin is not None
            truth = TwinLidarWorld(robot.twin, LidarNoise.none())
            model = robot.twin.lidar_noise
            for _ in range(scans):
                scan = robot.lidar.read_scan(1.0)
                expected = truth.true_ranges(scan.angles_rad)
                seen = np.isfinite(expected)
                got = scan.ranges_m[seen]
                if not noisy:
                    errors += list(np.abs(got - expected[seen])[np.isfinite(got)])
                    out.beams += int(seen.sum())
                    continue
                total += int(seen.sum())
                dropped += int((~np.isfinite(got)).sum())
                ok = np.isfinite(got)
                sigma = model.sigma_m + model.sigma_share * expected[seen][ok]
                normalised += list((got[ok] - expected[seen][ok]) / sigma)
    out.max_error_m = float(max(errors)) if errors else math.nan
    out.noisy_beams = total
    out.sigma_ratio = float(np.sqrt(np.mean(np.square(normalised)))) if normalised else math.nan
    out.dropout_share = dropped / total if total else math.nan
    return out


def run_realtime(seed: int, seconds: float, *, live: bool = True) -> RealTimeRun:
    """Drive, move the arm, capture the camera at 10 fps (drawn meanwhile: a
    ``CameraStream``) and read the Lidar, for ``seconds``; the wall time runs until the
    last frame is drawn. ``live``: frames drawn as a stream is (a line follower's, the
    dashboard's: no antialiasing); else as vision's pictures are."""
    out = RealTimeRun(live=live)
    with Robot.open(RobotConfig(
            TwinSpec(family="arena", seed=seed, controller=BoardSettings()),
            camera=CameraSpec(calibrate=False))) as robot:
        base, lidar, arm, twin = robot.base, robot.lidar, robot.arm, robot.twin
        assert base is not None and lidar is not None and twin is not None
        poses = [arm.config.pose("look"), arm.config.pose("home")]
        clock = robot.clock
        stream = CameraStream(twin, live=live)
        stream.capture()  # the renderer is made before the clock starts
        stream.drain()
        wall0, sim0 = time.perf_counter(), clock.now()
        next_frame, next_move, k = sim0, sim0, 0
        stamps: list[float] = []
        while clock.now() - sim0 < seconds:
            now = clock.now()
            base.drive(0.05, 0.0, 0.5)
            if now >= next_move:
                arm.command_joints(poses[k % 2], 1.5)
                k, next_move = k + 1, now + 2.0
            while next_frame <= now:
                stream.capture()
                out.frames += 1
                next_frame += 1.0 / CAMERA_FPS
            stamps.append(lidar.read_scan(1.0).stamp_s)
            out.scans += 1
        out.sim_s = clock.now() - sim0
        stream.drain()  # every frame drawn before the clock stops
        out.wall_s = time.perf_counter() - wall0
        stream.close()
        base.stop()
    # Revolutions a second from the scans' own start times (a count over the run would
    # include the part of a revolution the run began in).
    out.lidar_hz = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 1 else 0.0
    out.camera_fps = out.frames / out.sim_s
    return out


def run_mobile_bench(*, squares: int = 3, scans: int = 20, seconds: float = 20.0,
                     seed: int = 0, picture: Path | None = None,
                     progress: Progress = quiet) -> MobileBenchReport:
    report = MobileBenchReport(machine_info())
    for k in range(squares):
        progress(f"odometry: square {k + 1} of {squares}")
        report.squares.append(run_square(seed + k, picture if k == 0 else None))
    report.picture = str(picture) if picture is not None else None
    progress(f"Lidar: {scans} scans, noise off and on")
    report.lidar = run_lidar_accuracy(seed, scans)
    progress(f"real time: {seconds:g} simulated s of driving, arm, camera and Lidar")
    report.realtime = run_realtime(seed, seconds)
    progress(f"real time again, the camera drawn as vision's pictures ({seconds:g} s)")
    report.realtime_vision = run_realtime(seed, seconds, live=False)
    return report


__all__ = [
    "LidarAccuracy",
    "MobileBenchReport",
    "RealTimeRun",
    "SquareRun",
    "run_lidar_accuracy",
    "run_mobile_bench",
    "run_realtime",
    "run_square",
    "square_arena",
]
