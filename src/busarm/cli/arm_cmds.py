"""``arm``: the arm in millimetres and joint degrees (action groups: ``actions_cmds``).

``arm fk``, ``arm ik``, ``arm urdf`` and ``arm workspace`` need no bus: they work from
the arm config alone. Everything else opens ``--port`` and checks the arm's servos
(and the calibration) before it moves anything.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click
from rich.table import Table

from busarm.arm.arm import DEFAULT_SPEED_DEG_S, Arm
from busarm.arm.calibration import (
    PLAUSIBLE_ERROR_DEG,
    Calibration,
    far_from_reference,
    save_calibration,
    solve_calibration,
)
from busarm.arm.chain import Pose
from busarm.arm.config import ArmConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.arm.motion import PROFILE_NAMES
from busarm.arm.named_poses import check_savable_name, poses_file, save_pose
from busarm.cli import text
from busarm.cli.common import (
    NUMBER_ARGS,
    ArmContext,
    RangeType,
    Settings,
    angle_list,
    arm_options,
    check_gap_mm,
    gap_report,
    hold_where_it_stands,
    joints_in,
    joints_to_move,
    parse_gripper_target,
    pass_arm,
    pass_settings,
    robot_folder,
    target_in,
    torque_text,
)
from busarm.errors import CalibrationError, ConfigError
from busarm.protocol.lx_units import DEG_PER_PULSE

__all__ = [
    "COMMANDS",
    "DEFAULT_CALIBRATION_OUT",
    "DEG",
    "DURATION",
    "JOINT_SPEED",
    "LINE_SPEED",
    "MM",
    "arm",
    "calibrate",
    "fk",
    "gripper",
    "home",
    "ik",
    "ik_batch",
    "move_joints",
    "move_to",
    "pose",
    "urdf",
    "workspace",
]


MM = RangeType("coordinate", -2000.0, 2000.0, "mm")
DEG = RangeType("angle", -360.0, 360.0, "deg")
JOINT_SPEED = RangeType("speed", 0.1, 1000.0, "deg/s")
LINE_SPEED = RangeType("speed", 0.1, 1000.0, "mm/s")
DURATION = RangeType("duration", 0.0, 30.0, "s")
DEFAULT_CALIBRATION_OUT = "arm-calibration.json"


@click.group()
@arm_options
@pass_settings
@click.pass_context
def arm(ctx: click.Context, settings: Settings, config: str, calibration: str | None) -> None:
    """The arm: pose, kinematics, moves in mm, calibration, URDF and workspace.

    Joint angles are the model's (degrees; all servos at 500 pulses = straight up, joints
    2 and 4 then read -90); positions are the tool point in mm in the base frame (x
    forward, z up from the base plane); pitch -90 points the tool straight down.
    """
    ctx.obj = ArmContext(settings, config, calibration)


# ---------------------------------------------------------------------- output helpers


def _pose_dict(pose: Pose) -> dict[str, float]:
    return {
        "x_mm": _json_number(pose.x_mm), "y_mm": _json_number(pose.y_mm),
        "z_mm": _json_number(pose.z_mm), "pitch_deg": _json_number(pose.pitch_deg),
        "roll_deg": _json_number(pose.roll_deg),
    }


def _json_number(value: float, digits: int = 3) -> float:
    """``value`` rounded for JSON (mm and deg to 3 decimals), never ``-0.0``."""
    return round(value, digits) + 0.0


def _joints_dict(config: ArmConfig, joints: Sequence[float]) -> dict[str, float]:
    return {j.name: _json_number(a) for j, a in zip(config.joints, joints, strict=True)}


def _pose_text(pose: Pose) -> str:
    return text.pose(pose.x_mm, pose.y_mm, pose.z_mm, pose.pitch_deg, pose.roll_deg)


def _joints_text(config: ArmConfig, joints: Sequence[float]) -> str:
    return text.joints((j.name for j in config.joints), joints)


def _emit(settings: Settings, as_json: bool, data: object, text: str) -> None:
    if as_json:
        click.echo(json.dumps(data))
    else:
        settings.out.print(text, highlight=False, markup=False)


# ---------------------------------------------------------------------- model-only


@arm.command(context_settings=NUMBER_ARGS)
@click.argument("joints", nargs=-1, callback=angle_list(DEG))
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--batch", is_flag=True,
              help="Read JSON lines from stdin, each [j1..j5] or {\"joints_deg\": ...} as "
                   "`arm pose --json` prints it; print one JSON line each.")
@click.option("--matrix", is_flag=True, help="Also print the 4x4 tool2base transform (mm).")
@pass_arm
def fk(ac: ArmContext, joints: tuple[float, ...], as_json: bool, batch: bool,
       matrix: bool) -> None:
    """Forward kinematics: the tool pose for five joint angles (deg). No bus needed."""
    kin = ac.kin
    if batch:
        if joints:
            raise ConfigError("give joint angles or --batch, not both")
        _batch(lambda item: _fk_item(ac.config, kin, item))
        return
    q = ac.config.check_joints(joints)
    pose = kin.fk(q)
    data: dict[str, Any] = {"joints_deg": _joints_list(q), "pose": _pose_dict(pose)}
    lines = [_pose_text(pose)]
    if matrix:
        m = kin.fk_matrix(q)
        data["tool2base"] = [[_json_number(v, 6) for v in row] for row in m.tolist()]
        lines += ["  ".join(f"{text.number(v, 4):>10}" for v in row) for row in m.tolist()]
    _emit(ac.settings, as_json, data, "\n".join(lines))


def _fk_item(config: ArmConfig, kin: ArmKinematics, item: object) -> dict[str, Any]:
    q = joints_in(item, config)
    return {"joints_deg": _joints_list(q), "pose": _pose_dict(kin.fk(q))}


def _joints_list(joints: Sequence[float]) -> list[float]:
    return [_json_number(a) for a in joints]


@arm.command(context_settings=NUMBER_ARGS)
@click.argument("x", type=MM)
@click.argument("y", type=MM)
@click.argument("z", type=MM)
@click.option("--pitch", type=DEG, help="Tool pitch in deg (-90 = straight down); "
              "without it the feasible pitch nearest the config's preferred one is chosen.")
@click.option("--roll", type=DEG, help="Wrist roll in deg  [default: 0]")
@click.option("--all", "all_solutions", is_flag=True, help="Every solution, not just the first.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@pass_arm
def ik(ac: ArmContext, x: float, y: float, z: float, pitch: float | None, roll: float | None,
       all_solutions: bool, as_json: bool) -> None:
    """Inverse kinematics: joint angles for a tool point in mm. No bus needed.

    For many targets use `busarm arm ik-batch` (JSON lines on stdin).
    """
    result = _ik_item(ac.config, ac.kin, {"x": x, "y": y, "z": z, "pitch": pitch, "roll": roll},
                      all_solutions)
    if as_json:
        click.echo(json.dumps(result))
        return
    out = ac.settings.out
    for q in result["solutions"]:
        out.print(_joints_text(ac.config, q.values()), highlight=False)
    out.print(f"pitch {text.quantity(result['pitch_deg'], 'deg')}"
              + ("" if pitch is not None else " (chosen: free pitch)"), highlight=False)


@arm.command("ik-batch")
@click.option("--all", "all_solutions", is_flag=True, help="Every solution per target.")
@pass_arm
def ik_batch(ac: ArmContext, all_solutions: bool) -> None:
    """IK for JSON lines on stdin: {"x":..,"y":..,"z":..[,"pitch":..][,"roll":..]}.

    Also takes x_mm ... roll_deg, or the lines `arm fk --json` prints. One JSON line out
    per line in: the solution(s), or {"error": ...} for that target (the exit code is
    then 3). No bus needed.
    """
    kin = ac.kin
    _batch(lambda item: _ik_item(ac.config, kin, item, all_solutions))


def _ik_item(config: ArmConfig, kin: ArmKinematics, item: object,
             all_solutions: bool) -> dict[str, Any]:
    x, y, z, pitch, roll = target_in(item)
    if pitch is None:
        q, chosen = kin.ik_free_pitch(
            x, y, z, roll, preferred_pitch_deg=config.preferred_pitch_deg
        )
        sols = [q]
        if all_solutions:
            sols = kin.ik(x, y, z, chosen, roll) or sols
    else:
        chosen = float(pitch)
        sols = [kin.ik_best(x, y, z, pitch, roll)]
        if all_solutions:
            sols = kin.ik(x, y, z, pitch, roll)
    return {
        "target": {"x_mm": _json_number(x), "y_mm": _json_number(y), "z_mm": _json_number(z),
                   "pitch_deg": None if pitch is None else _json_number(pitch),
                   "roll_deg": None if roll is None else _json_number(roll)},
        "pitch_deg": _json_number(chosen),
        "solutions": [_joints_dict(config, q) for q in sols],
    }


def _batch(solve: Callable[[object], dict[str, Any]]) -> None:
    """JSON lines in, JSON lines out; a bad line gives an error line and exit code 3."""
    failed = 0
    for n, line in enumerate(sys.stdin, start=1):
        if not line.strip():
            continue
        try:
            try:
                item = json.loads(line)
            except ValueError:  # the decoder's "Expecting value: ..." is for programmers
                raise ConfigError(f"line {n} is not JSON") from None
            click.echo(json.dumps(solve(item)))
        except (ValueError, ConfigError) as exc:  # KinematicsError is a ValueError
            failed += 1
            reason = getattr(exc, "reason", None)
            click.echo(json.dumps({"line": n, "error": str(exc), "reason": reason}))
    if failed:
        click.echo(f"error: {failed} line(s) failed", err=True)
        sys.exit(3)


@arm.command()
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Write to this file (atomically) instead of stdout.")
@pass_arm
def urdf(ac: ArmContext, output: Path | None) -> None:
    """The arm's URDF (metres, radians), generated from the config. No bus needed."""
    from busarm.arm.urdf import urdf_from_config, write_urdf

    if output is None:
        click.echo(urdf_from_config(ac.config), nl=False)
        return
    write_urdf(ac.config, output)
    ac.settings.err.print(f"wrote {output}", highlight=False)


@arm.command()
@click.option("--png", "png", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Picture to write (top view of the top-down grasp area, side reach): "
                   ".png, .jpg, .svg or .pdf.")
@click.option("--grasp-height", type=RangeType("height", 0.0, 300.0, "mm"), default=15.0,
              show_default=True, help="Tool point height above the table for the top view, in mm.")
@click.option("--cell", type=RangeType("cell", 0.5, 20.0, "mm"), default=2.0, show_default=True,
              help="Grid cell size in mm.")
@pass_arm
def workspace(ac: ArmContext, png: Path, grasp_height: float, cell: float) -> None:
    """A picture of where the arm reaches: the table for a top-down grasp, and the side."""
    from busarm.arm.workspace import render_workspace_png

    s = render_workspace_png(ac.config, png, grasp_height_mm=grasp_height, cell_mm=cell)
    reach = ("nowhere" if s.min_radius_mm is None or s.max_radius_mm is None else
             f"{text.number(s.min_radius_mm, 0)}-{text.number(s.max_radius_mm, 0)} mm from "
             f"the base axis, {text.quantity(s.top_down_area_cm2, 'cm2', 0)}")
    ac.settings.out.print(
        f"wrote {png}: straight down at {text.quantity(s.grasp_z_mm, 'mm', 0)} over the table "
        f"the arm reaches {reach}; its side envelope covers "
        f"{text.quantity(s.envelope_area_cm2, 'cm2', 0)} ({text.quantity(s.cell_mm, 'mm')} "
        "cells)", highlight=False, soft_wrap=True)


# ---------------------------------------------------------------------- on the bus


@arm.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--save", "save_name", metavar="NAME",
              help="Also keep these joint angles as pose NAME (see `busarm arm poses`).")
@pass_arm
def pose(ac: ArmContext, as_json: bool, save_name: str | None) -> None:
    """The measured joint angles, the tool pose and the gripper position."""
    if save_name is not None:
        check_savable_name(ac.config, save_name)  # before the bus: a built-in name fails
    with ac.open() as a:
        q = a.read_joints_deg()
        p = a.kin.fk(q)
        grip = a.read_gripper_state()
    if save_name is not None:
        folder = robot_folder(ac.settings.robot_key())
        replaced = save_pose(folder, ac.config, save_name, q)
        ac.settings.err.print(f"{'replaced' if replaced else 'saved'} pose {save_name!r} in "
                              f"{poses_file(folder)}", highlight=False, markup=False,
                              soft_wrap=True)
    data = {"joints_deg": _joints_dict(ac.config, q), "pose": _pose_dict(p),
            "gripper_pulses": grip.position_pulses,
            "gripper_gap_mm": _json_number(grip.gap_mm), "gripper_state": grip.state}
    _emit(ac.settings, as_json, data,
          f"{_joints_text(ac.config, q)}\n{_pose_text(p)}\n"
          f"gripper {text.gripper(grip)}")


def _move_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--time", "duration", type=DURATION, metavar="S",
                     help="Move time in s, all joints together (instead of --speed).")(f)
    return click.option(
        "--speed", type=JOINT_SPEED, metavar="DEG_S",
        help=f"Fastest joint speed in deg/s  [default: {DEFAULT_SPEED_DEG_S:g}]",
    )(f)


def _check_pace(speed: float | None, duration: float | None) -> None:
    """--speed and --time both set how long a move takes: one of them, before the bus."""
    if speed is not None and duration is not None:
        raise click.UsageError("give --time or --speed, not both")


@arm.command("move-to", context_settings=NUMBER_ARGS)
@click.argument("x", type=MM)
@click.argument("y", type=MM)
@click.argument("z", type=MM)
@click.option("--pitch", type=DEG,
              help="Tool pitch in deg  [default: free: the first that reaches]")
@click.option("--roll", type=DEG, help="Wrist roll in deg  [default: the present roll]")
@click.option("--line", is_flag=True, help="Straight tool line (streamed IK), not a joint move.")
@click.option("--line-speed", type=LINE_SPEED, default=80.0, show_default=True,
              help="Peak tool speed of a --line move, mm/s.")
@click.option("--profile", type=click.Choice(list(PROFILE_NAMES)), default="min_jerk",
              show_default=True, help="Speed profile of a --line move.")
@_move_options
@pass_arm
def move_to(ac: ArmContext, x: float, y: float, z: float, pitch: float | None,
            roll: float | None, line: bool, line_speed: float, profile: str,
            speed: float | None, duration: float | None) -> None:
    """Move the tool point to X Y Z mm (checked in full before anything moves)."""
    _check_pace(speed, duration)
    with ac.open() as a:
        start = a.read_joints_deg()
        # Plan first: an unreachable target fails here, with the arm untouched.
        target, chosen = a.solve(x, y, z, pitch, roll, current_deg=start)
        if line:
            a.move_line(x, y, z, chosen, roll, speed_mm_s=line_speed, duration_s=duration,
                        profile=profile)
        else:
            a.move_joints(target, speed_deg_s=speed, duration_s=duration)
        q = a.settled_joints_deg()  # where it stays, not where the wait let go
    ac.settings.out.print(f"at {_pose_text(a.kin.fk(q))}", highlight=False)


@arm.command("move-joints", context_settings=NUMBER_ARGS)
@click.argument("joints", nargs=-1, callback=angle_list(DEG))
@click.option("--pose", "pose_name", metavar="NAME",
              help="A named pose instead of angles (`busarm arm poses` lists them).")
@click.option("--json", "json_source", metavar="FILE|-",
              help="The joints from JSON, as `busarm arm pose --json` prints it (- = stdin).")
@_move_options
@pass_arm
def move_joints(ac: ArmContext, joints: tuple[float, ...], pose_name: str | None,
                json_source: str | None, speed: float | None, duration: float | None) -> None:
    """Move to five joint angles (deg), a named pose or JSON joints; all joints start and
    arrive together. Everything is checked before anything moves."""
    _check_pace(speed, duration)
    joints = joints_to_move(ac.config, ac.settings.robot_key(), joints, pose_name, json_source)
    with ac.open() as a:
        took = a.move_joints(joints, speed_deg_s=speed, duration_s=duration)
        q = a.settled_joints_deg()
    to = f" to pose {pose_name!r}" if pose_name is not None else ""
    ac.settings.out.print(f"moved{to} in {took:.2f} s: {_joints_text(ac.config, q)}",
                          highlight=False)


@arm.command()
@_move_options
@pass_arm
def home(ac: ArmContext, speed: float | None, duration: float | None) -> None:
    """Go to the config's home pose."""
    _check_pace(speed, duration)
    with ac.open() as a:
        a.move_joints(ac.config.pose("home"), speed_deg_s=speed, duration_s=duration)
        p = a.kin.fk(a.settled_joints_deg())
    ac.settings.out.print(f"home: {_pose_text(p)}", highlight=False)


@arm.command(context_settings=NUMBER_ARGS)
@click.argument("what", metavar="open|close|GAPmm")
@pass_arm
def gripper(ac: ArmContext, what: str) -> None:
    """Open the gripper, close it and tell whether it holds something, or open (or close)
    it to a gap between the fingers in mm: `busarm arm gripper 25` (or 25mm)."""
    action = parse_gripper_target(what)
    if isinstance(action, float):
        gap_mm = check_gap_mm(ac.config, action)
        with ac.open() as a:
            pos = a.open_gripper(gap_mm=gap_mm)
        ac.settings.out.print(gap_report(ac.config, gap_mm, pos), highlight=False, soft_wrap=True)
        return
    with ac.open() as a:
        if action == "open":
            a.open_gripper()
            ac.settings.out.print(f"gripper {text.gripper(a.read_gripper_state())}",
                                  highlight=False)
            return
        result = a.grip()
    state = "holding an object" if result.is_holding else "closed on nothing"
    gap_mm = ac.config.gripper.gap_mm_at(result.position_pulses)
    ac.settings.out.print(
        f"gripper {state}: {text.quantity(gap_mm, 'mm')} apart ({result.position_pulses} "
        f"pulses, {result.short_of_closed_pulses} short of closed)", highlight=False,
    )


@arm.command()
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path),
              default=DEFAULT_CALIBRATION_OUT, show_default=True, help="Calibration file to write.")
@click.option("--pose", "pose_name", default="upright", show_default=True,
              metavar="NAME",
              help="Reference pose (a pose of the config) the arm is put in.")
@click.option("--software-only", is_flag=True,
              help="Do not write the servos' offsets; keep every correction in the file.")
@click.option("--yes", is_flag=True,
              help="Non-interactive: the arm is already in the reference pose; no questions.")
@click.option("--force", is_flag=True,
              help=f"Write even if a joint reads more than {PLAUSIBLE_ERROR_DEG:g} deg from "
                   "the reference pose (else --yes refuses, and a person is asked).")
@pass_arm
def calibrate(ac: ArmContext, out_path: Path, pose_name: str, software_only: bool,
              yes: bool, force: bool) -> None:
    """Measure each joint's zero: torque off, put the arm in the reference pose, confirm.

    Errors within +-30 deg go into the servo's own offset (saved in the servo);
    the rest into the calibration file. Then use it with --calibration FILE.
    """
    settings = ac.settings
    reference = ac.config.pose(pose_name)
    with ac.open(check=False) as a:
        a.set_torque(False)
        if not yes:
            settings.err.print(
                f"Torque is off. Move the arm by hand to the [bold]{pose_name}[/bold] pose "
                f"({_joints_text(ac.config, reference)}), hold it still."
            )
            if not click.confirm("Is the arm in that pose?", default=True, err=True):
                _declined(a, settings, out_path)
                return
        measured = {}
        present = {}
        for j in ac.config.joints:
            measured[j.servo_id] = a.bus.read_position_deg(j.servo_id)
            present[j.servo_id] = round(a.bus.read_offset_deg(j.servo_id) / DEG_PER_PULSE)
        cal = solve_calibration(ac.config, reference, measured, present,
                                use_hardware_offset=not software_only)
        table = Table(title=f"calibration of {ac.config.name}", title_justify="left")
        for col in ("joint", "servo", "read (deg)", "servo offset (deg)", "software (deg)"):
            table.add_column(col, justify="right")
        for j, c in zip(ac.config.joints, cal.joints, strict=True):
            table.add_row(j.name, str(j.servo_id), f"{measured[j.servo_id]:+.2f}",
                          f"{c.hardware_offset_deg:+.2f}", f"{c.software_offset_deg:+.3f}")
        settings.out.print(table)
        if not force and not _plausible(a, settings, cal, pose_name, yes):
            _declined(a, settings, out_path)
            return
        if not yes and not click.confirm(f"Write the servo offsets and {out_path}?",
                                         default=True, err=True):
            _declined(a, settings, out_path)
            return
        for c in cal.joints:
            if present[c.servo_id] != c.hardware_offset_pulses:
                a.bus.adjust_offset_deg(c.servo_id, c.hardware_offset_deg)
                a.bus.save_offset(c.servo_id)
        for c in cal.joints:  # read back: the servo must hold what we wrote
            got = round(a.bus.read_offset_deg(c.servo_id) / DEG_PER_PULSE)
            if got != c.hardware_offset_pulses:
                raise ConfigError(
                    f"servo {c.servo_id} kept offset {got} pulses, not "
                    f"{c.hardware_offset_pulses}: calibration not written"
                )
        save_calibration(out_path, cal)
        hold_where_it_stands(a, settings)
    settings.out.print(f"wrote {out_path}; use it with `busarm arm --calibration {out_path} ...`"
                       f" or BUSARM_CALIBRATION={out_path}", highlight=False)


def _plausible(a: Arm, settings: Settings, cal: Calibration, pose_name: str,
               yes: bool) -> bool:
    """Whether to go on with a calibration some joint of which reads farther from the
    reference pose than a horn's mounting can be off: --yes refuses (CalibrationError,
    the arm holding where it stands), a person is asked (default no)."""
    far = far_from_reference(a.config, cal)
    if not far:
        return True
    what = (f"{'; '.join(far)}: more than {PLAUSIBLE_ERROR_DEG:g} deg, so the arm is likely "
            f"not in the {pose_name} pose")
    if yes:
        hold_where_it_stands(a, settings)
        raise CalibrationError(f"calibration not written: {what}; put it in that pose, or "
                               "give --force if it is")
    settings.err.print(f"warning: {what}", highlight=False, markup=False, soft_wrap=True)
    return click.confirm("Write it anyway?", default=False, err=True)


def _declined(a: Arm, settings: Settings, out_path: Path) -> None:
    """A "no" to a calibration prompt: nothing is written, and the arm (limp for the
    measurement) holds where it stands again; said as read back."""
    hold_where_it_stands(a, settings)
    settings.out.print(f"calibration declined: nothing written (the servos' offsets and "
                       f"{out_path} are unchanged); {torque_text(a.bus, a.config.servo_ids)}",
                       highlight=False, markup=False, soft_wrap=True)


COMMANDS = [arm]
