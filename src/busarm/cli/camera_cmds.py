"""``camera calibrate | handeye``: calibrate the wrist camera with the arm moving it.

On the twin (``--port twin``) both run without a person: the twin lays the board on
its table and its camera takes the pictures. On hardware they ask before each picture
(``--yes`` does not ask). ``camera calibrate --images DIR`` calibrates from pictures
taken any other way, without an arm. Without ``-o`` they write to the robot's kept
calibration (busarm.robot.calibration_store), which ``pick-sort`` and ``vision locate``
then use; each file records what it was made for.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import (
    ArmContext,
    Settings,
    arm_options,
    calibration_store,
    check_writable,
    pass_arm,
    pass_settings,
)
from busarm.errors import CalibrationError, ConfigError

if TYPE_CHECKING:
    from busarm.robot.calibration_store import CalibrationStore, MadeFor

__all__ = [
    "COMMANDS",
    "INTRINSIC_BOARDS",
    "calibrate",
    "camera",
    "handeye",
]


INTRINSIC_BOARDS = ("chessboard", "charuco")

def _confirm(yes: bool, on_twin: bool) -> Any:
    """Asks before each picture on hardware (None: take them all)."""
    if yes or on_twin:
        return None
    if not sys.stdin.isatty():
        raise ConfigError("no terminal to ask on before each picture: add --yes to take "
                          "them all without asking")

    def ask(i: int, n: int) -> bool:
        answer = click.prompt(f"view {i + 1}/{n}: Enter to take the picture, s to skip",
                              default="", show_default=False)
        return str(answer).strip().lower() != "s"

    return ask


def _board_at(text: str) -> tuple[float, float]:
    from busarm.cli.common import parse_float_list

    values = parse_float_list(text, "board centre X,Y in mm")
    if len(values) != 2:
        raise ConfigError(f"--board-at takes X,Y in mm, got {text!r}")
    return values[0], values[1]


@click.group()
@arm_options
@pass_settings
@click.pass_context
def camera(ctx: click.Context, settings: Settings, config: str, calibration: str | None) -> None:
    """Calibrate the wrist camera: intrinsics (lens), then hand-eye (where it sits)."""
    ctx.obj = ArmContext(settings, config, calibration)


def _progress(settings: Settings) -> Any:
    def show(i: int, n: int, view: Any) -> None:
        seen = "board found" if view.observation is not None else "no board"
        settings.err.print(f"view {i + 1}/{n}: {seen}", highlight=False)
    return show


def _take_pictures(ac: ArmContext, board: str, board_at: str, views: int, seed: int,
                   camera_src: str | None, yes: bool, store: CalibrationStore, *,
                   intrinsics: Any = None, intrinsics_file: Path | None = None
                   ) -> tuple[list[Any], MadeFor]:
    """Plan the views of ``board``, then move the arm through them taking pictures;
    everything is checked before the arm moves (kept ``intrinsics`` too: they must be
    this camera's), and it ends at home. Also what the pictures' calibration is for."""
    from busarm.arm.camera_mount import CameraMount
    from busarm.robot.calibration_store import MadeFor
    from busarm.robot.camera_calibration import calibration_views, capture_views
    from busarm.twin.boards import BOARD_SPECS, board2base, calibration_board

    settings = ac.settings
    spec = BOARD_SPECS[board]
    centre = _board_at(board_at)
    where = board2base(calibration_board(board, centre), ac.config.table_z_mm)
    poses = calibration_views(ac.kin, spec, where, views, intrinsics_guess=intrinsics,
                              seed=seed, mount=CameraMount.from_config(ac.config.camera))
    with settings.open_robot(camera=camera_src, config=ac.config,
                             arm_calibration=ac.calibration(), calibrate=False, board=board,
                             needs=("camera",)) as robot:
        source = robot.camera
        confirm = _confirm(yes, robot.is_twin)
        if not robot.is_twin:
            settings.err.print(f"Lay the {spec.describe()} flat with its centre at "
                               f"({centre[0]:g}, {centre[1]:g}) mm, its long side across the "
                               "arm's front; it must not move.", highlight=False)
        made_for = MadeFor.for_camera(store.robot, source, ac.config, robot.twin)
        if intrinsics_file == store.intrinsics_path:
            store.load_intrinsics(made_for)  # StaleCalibration saying why
        if intrinsics is not None and (source.width_px, source.height_px) != (
                intrinsics.width_px, intrinsics.height_px):
            raise ConfigError(f"{intrinsics_file} is for {intrinsics.width_px}x"
                              f"{intrinsics.height_px} pictures; {source.name} gives "
                              f"{source.width_px}x{source.height_px}")
        taken = capture_views(robot.arm, source, poses, spec, confirm=confirm,
                              progress=_progress(settings))
        robot.arm.move_joints(ac.config.pose("home"))
    return taken, made_for


def _output(given: Path | None, kept: Path, store: CalibrationStore) -> Path:
    """Where to write: the file given, else the robot's kept one (its folder made)."""
    if given is None:
        store.make_folder()
    output = given if given is not None else kept
    check_writable(output)
    return output


@camera.command()
@click.option("--camera", "camera_src", default=None,
              help="Camera source (/dev/video0, a folder, twin...)  [default: the twin's]")
@click.option("--board", type=click.Choice(INTRINSIC_BOARDS), default="chessboard",
              show_default=True, help="The printed board to look at.")
@click.option("--model", type=click.Choice(["pinhole", "fisheye"]), default="pinhole",
              show_default=True, help="Lens model: pinhole (OpenCV k1..k3) or fisheye.")
@click.option("--views", type=click.IntRange(6, 60), default=20, show_default=True,
              help="Pictures to take.")
@click.option("--board-at", "board_at", default="210,0", show_default=True,
              help="Where the board's centre lies on the table, X,Y in mm (base frame).")
@click.option("--images", type=click.Path(file_okay=False, exists=True, path_type=Path),
              help="Calibrate from the pictures in this folder instead (no arm).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the view plan.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Where to write the intrinsics (JSON)  [default: kept for this robot, "
                   "camera.json in $XDG_CONFIG_HOME/busarm/ROBOT/ (~/.config/busarm/ROBOT/ "
                   "without it)]")
@click.option("--yes", is_flag=True, help="Do not ask before each picture (hardware).")
@pass_arm
def calibrate(ac: ArmContext, camera_src: str | None, board: str, model: str, views: int,
              board_at: str, images: Path | None, seed: int, output: Path | None,
              yes: bool) -> None:
    """Find the camera's intrinsics and lens distortion from pictures of a board.

    The arm takes the camera through views of the board from many angles, then the
    calibration is written to FILE (busarm.camera_intrinsics, version 1).
    """
    from busarm.robot.calibration_store import MadeFor
    from busarm.robot.camera_calibration import intrinsics_from_views
    from busarm.twin.boards import BOARD_SPECS
    from busarm.vision.calibration import calibrate_intrinsics, find_board, save_intrinsics
    from busarm.vision.camera import EndOfFrames, open_camera

    spec = BOARD_SPECS[board]
    store = calibration_store(ac.settings)
    output = _output(output, store.intrinsics_path, store)
    if images is not None:
        with open_camera(str(images)) as source:
            observations, size = [], (source.width_px, source.height_px)
            while True:
                try:
                    frame = source.read()
                except EndOfFrames:
                    break
                observations.append(find_board(frame.image, spec))
        result = calibrate_intrinsics(observations, size, model)
        made_for = MadeFor.of(store.robot, size, ac.config)
    else:
        taken, made_for = _take_pictures(ac, board, board_at, views, seed, camera_src, yes,
                                         store)
        result = intrinsics_from_views(taken, model)
    save_intrinsics(output, result, board=spec.describe(), made_for=made_for.intrinsics())
    i = result.intrinsics
    click.echo(f"wrote {output}: {i.describe()}; reprojection rms {result.rms_px:.3f} px over "
               f"{len(result.per_view_rms_px)} views")
    if output == store.intrinsics_path:
        ac.settings.err.print(f"next, where the camera sits: `{store.command('handeye')}`",
                              highlight=False, soft_wrap=True)


@camera.command()
@click.option("--intrinsics", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              default=None,
              help="The camera's intrinsics, from `busarm camera calibrate`  [default: the "
                   "ones kept for this robot]")
@click.option("--camera", "camera_src", default=None,
              help="Camera source (/dev/video0, twin...)  [default: the twin's]")
@click.option("--views", type=click.IntRange(4, 60), default=16, show_default=True,
              help="Pictures to take.")
@click.option("--board-at", "board_at", default="210,0", show_default=True,
              help="Where the tag board's centre lies on the table, X,Y in mm.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
              help="Seed of the view plan.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Where to write the hand-eye calibration (JSON)  [default: kept for this "
                   "robot, hand_eye.json in $XDG_CONFIG_HOME/busarm/ROBOT/ "
                   "(~/.config/busarm/ROBOT/ without it)]")
@click.option("--yes", is_flag=True, help="Do not ask before each picture (hardware).")
@pass_arm
def handeye(ac: ArmContext, intrinsics: Path | None, camera_src: str | None, views: int,
            board_at: str, seed: int, output: Path | None, yes: bool) -> None:
    """Find where the camera sits on the wrist from pictures of a fixed AprilTag board.

    The arm looks at the board (tag36h11 grid) from many poses; the camera's pose on the
    wrist-pitch link is solved from the *measured* joints and written to FILE
    (busarm.hand_eye, version 1).
    """
    from busarm.robot.camera_calibration import hand_eye_from_views
    from busarm.vision.calibration import load_intrinsics, save_hand_eye

    store = calibration_store(ac.settings)
    if intrinsics is None:
        if not store.intrinsics_path.is_file():
            raise ConfigError(f"no camera intrinsics are kept for robot {store.robot!r} "
                              f"(looked for {store.intrinsics_path}): make them first with "
                              f"`{store.command('calibrate')}`, or give --intrinsics FILE")
        intrinsics = store.intrinsics_path
    output = _output(output, store.hand_eye_path, store)
    try:
        intr = load_intrinsics(intrinsics)
    except CalibrationError as exc:
        if intrinsics != store.intrinsics_path:
            raise
        raise ConfigError(f"{exc}; make them again with `{store.command('calibrate')}`"
                          ) from None
    taken, made_for = _take_pictures(ac, "tags", board_at, views, seed, camera_src, yes, store,
                                     intrinsics=intr, intrinsics_file=intrinsics)
    result = hand_eye_from_views(taken, intr)
    save_hand_eye(output, result, made_for=made_for.hand_eye())
    t = result.cam2link[:3, 3]
    click.echo(
        f"wrote {output}: camera at ({t[0]:.1f}, {t[1]:.1f}, {t[2]:.1f}) mm on the "
        f"{result.link} link (+-{result.translation_std_mm:.2f} mm); reprojection rms "
        f"{result.rms_px:.3f} px over {len(result.views_used)} views")


COMMANDS = [camera]
