"""What busarm says and does about the robot is true (issue 13, third trial's items 1-4, 7).

- A tool point inside the arm's base (the keep-out cylinder of the arm config) is refused
  by every solver and by ``arm move-to``/``arm ik``/``arm ik-batch``, nothing sent, while
  blocks 90 mm or more from the base stay reachable.
- The gripper's state (``busarm.arm.gripper``): stalled on a block after a close is
  *holding*, said so by ``arm pose`` (its JSON too), not "open"; limp, it holds nothing;
  closed and open carry millimetres, and the open width is one the range accepts.
- ``sim://?state=FILE`` keeps each horn's position between runs, as its README row says.
- ``arm calibrate`` refuses (``--yes``) or asks about a joint far from the reference pose;
  nothing is written to the servos unless ``--force``.
- A ``twin serve``'s camera is a twin's (its server tells its lens and mount), so the
  calibration kept for the twin is used with it; ``pick-sort`` without --port says that it
  runs a twin of its own, and how to sort the served one.

The CLI runs in this process through click's runner, on simulated servos of the test's
own on their simulated clock (``in_process_port``: their truth is then inspected), or at a
``twin serve`` run as its own process (wall-clock time), found without --port through the
test's runtime folder and talked to over its pty and its camera's socket.
"""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.arm.config import load_arm_config
from busarm.arm.gripper import gripper_state
from busarm.arm.kinematics import ArmKinematics
from busarm.cli.main import cli
from busarm.errors import UnreachableError
from busarm.protocol import Command
from busarm.sim.bus import WireTiming
from conftest import ListeningSim, in_process_port, not_crashed, process_env, wait_for

CONFIG = load_arm_config()
GRIPPER_ID = CONFIG.gripper.servo_id
MARGIN = ("--timeout-margin-ms", "1000")
"""For a command at a served twin's pty (wall-clock time) on a computer that may be busy:
a reply heard late is not what these tests are about. The most the driver takes: a twin
serve simulates its physics in the same process as it answers, and starved of CPU beside
other programs has been heard to fall silent for more than 3 x 200 ms."""


def _arm(monkeypatch: pytest.MonkeyPatch, block: bool) -> tuple[str, ListeningSim]:
    sim = ListeningSim.with_ids(timing=WireTiming(enabled=False))
    assert isinstance(sim, ListeningSim)
    if block:
        sim.put_block_in_gripper()
    return in_process_port(monkeypatch, sim), sim


@pytest.fixture
def sim_arm(monkeypatch: pytest.MonkeyPatch) -> tuple[str, ListeningSim]:
    """The arm's six simulated servos (the port commands open them by, and the servos)."""
    return _arm(monkeypatch, block=False)


@pytest.fixture
def sim_arm_with_block(monkeypatch: pytest.MonkeyPatch) -> tuple[str, ListeningSim]:
    """The same, a 3 cm block between the gripper's fingers."""
    return _arm(monkeypatch, block=True)


Env = dict[str, str | None]
"""Variables for a command in this process: None removes one for the call."""


def busarm(*args: str, env: Env | None = None, input: str | None = None) -> Result:
    """``busarm ARGS`` in this process (click's runner), with ``env`` set for the call."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args), env=env, input=input,
                                              prog_name="busarm")


def run(*args: str, port: str, input: str | None = None) -> Result:
    return busarm("--port", port, *args, input=input)




def ok(result: Result) -> str:
    not_crashed(result)
    assert result.exit_code == 0, (result.stdout, result.stderr)
    return str(result.stdout)


def one_error(result: Result, code: int) -> str:
    """Exactly one ``error:`` line on stderr (no crash), and exit code ``code``."""
    not_crashed(result)
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = [line for line in result.stderr.strip().splitlines()
             if not line.startswith("note: no --port given")]  # which arm: not an error
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return str(lines[0])


# ---------------------------------------------------------------------- 1: the base


def test_every_solver_refuses_a_tool_point_inside_the_base() -> None:
    kin = ArmKinematics.from_config(CONFIG)
    radius_mm, top_mm = CONFIG.base_keepout_mm
    assert (radius_mm, top_mm) == (70.0, 197.4)  # the shipped config's, as documented
    for x, y, z in ((0, 0, 0), (50, 0, 0), (0, -69, 100), (40, 40, 150)):
        assert kin.in_base(x, y, z)
        assert kin.pitch_intervals(x, y, z) == []
        assert kin.ik(x, y, z, -90.0) == []
        joints, fine = kin.ik_batch([[x, y, z, -90.0], [x, y, z, -120.0]])
        assert not fine.any() and np.isnan(joints).all()
        with pytest.raises(UnreachableError) as info:
            kin.ik_free_pitch(x, y, z)
        assert info.value.reason == "base"
        assert f"{math.hypot(x, y):.1f} mm from its axis" in str(info.value)
    # Pure geometry (no table, no base) still solves it: the rule is the world's.
    assert ArmKinematics.from_config(CONFIG, check_table=False).ik_free_pitch(50, 0, 0)
    # Blocks stand 90 mm or more from the axis (the twin's scene rule): every one reachable
    # at the heights a grasp uses, on every side the base turns to.
    for bearing in np.radians(np.arange(-120.0, 121.0, 30.0)):
        for grasp_z_mm in (0.0, 15.0, 30.0):
            kin.ik_free_pitch(90 * math.cos(bearing), 90 * math.sin(bearing), grasp_z_mm)
    # Above the shoulder the axis is free again (the straight-up pose is there).
    assert not kin.in_base(0, 0, top_mm + 1) and kin.ik(0, 0, 629.4, 90.0)


def test_move_to_and_ik_inside_the_base_are_refused_and_nothing_moves(
        sim_arm: tuple[str, ListeningSim]) -> None:
    port, sim = sim_arm
    for target in (("0", "0", "0"), ("50", "0", "0")):
        line = one_error(run("arm", "move-to", *target, port=port), 1)
        x = float(target[0])
        assert (f"target ({x:.1f}, 0.0, 0.0) mm at any pitch is inside the arm's base: "
                f"{x:.1f} mm from its axis; below z 197.4 mm the tool point must stay 70 mm "
                "or more from the axis") in line, line
        assert "stopped" not in line  # nothing was written, so nothing to stop
    one_error(run("arm", "move-to", "0", "0", "0", "--line", port=port), 1)
    assert "inside the arm's base" in one_error(run("arm", "ik", "0", "0", "0", port=port), 1)
    batch = run("arm", "ik-batch", port=port,
                input='{"x": 30, "y": 0, "z": 10}\n{"x": 200, "y": 0, "z": 30}\n')
    rows = [json.loads(line) for line in batch.stdout.splitlines()]
    assert rows[0]["reason"] == "base" and "inside the arm's base" in rows[0]["error"]
    assert "error" not in rows[1], rows[1]
    assert sim.writes() == []  # not one byte that moves anything
    sim.advance()
    assert [s.position_pulses for s in sim.servos] == [500] * 6
    # Just outside it, and a block's place at 90 mm, are not refused.
    assert "at x" in ok(run("arm", "move-to", "100", "0", "0", port=port))


# ---------------------------------------------------------------------- 2: the gripper


def test_the_gripper_state_rule() -> None:
    g = CONFIG.gripper  # open 200, closed 700, margin 20 pulses, 0.1875 mm a pulse
    assert gripper_state(g, 544, 700).state == "holding"
    assert gripper_state(g, 544, 700, torque_on=False).state == "open"  # limp: holds nothing
    assert gripper_state(g, 544, 544).state == "open"
    assert gripper_state(g, 690, 700).state == "closed"
    assert gripper_state(g, 700, 700).gap_mm == 0.0
    assert gripper_state(g, 300, 200).state == "open"  # opening, stopped short: not holding
    assert gripper_state(g, 197, 200).gap_mm == g.widest_gap_mm == 93.75  # never wider
    # A light hold (Arm.grip eases to a few pulses inside where the fingers stopped).
    assert gripper_state(g, 541, 544).state == "holding"
    assert gripper_state(g, 543, 544).state == "open"  # 1 pulse: within the accuracy
    assert gripper_state(g, 685, 688).state == "closed"  # the fingers met: on nothing


def test_arm_pose_says_the_gripper_holds_the_block_it_stalled_on(
        sim_arm_with_block: tuple[str, ListeningSim]) -> None:
    port, sim = sim_arm_with_block
    assert "gripper holding an object: 30.0 mm apart (540 pulses, 160 short of closed)" in ok(
        run("arm", "gripper", "close", port=port))
    sim.advance()
    assert sim.servo(GRIPPER_ID).position_pulses == 540  # the truth: stalled on the block
    # Then eased to a hold 3 pulses inside the block (busarm.arm.gripper): still holding.
    assert ("gripper holding something 30.0 mm wide (540 pulses; told 543, stopped 3 "
            "short)") in ok(run("arm", "pose", port=port))
    data = json.loads(ok(run("arm", "pose", "--json", port=port)))
    assert (data["gripper_state"], data["gripper_pulses"], data["gripper_gap_mm"]) == (
        "holding", 540, 30.0)
    # Limp, the fingers hold nothing (they only rest on the block): not "holding".
    ok(run("torque", "off", str(GRIPPER_ID), port=port))
    assert "gripper open 30.0 mm (540 pulses, torque off)" in ok(run("arm", "pose", port=port))
    # Told to close to 10 mm, it stops on the block again: holding, said so.
    assert ("gripper holding something: stopped at 30.0 mm apart (540 pulses), short of "
            "the 10.0 mm asked") in ok(run("arm", "gripper", "10mm", port=port))


def test_open_and_closed_gripper_in_mm_and_the_range_that_agrees(
        sim_arm: tuple[str, ListeningSim]) -> None:
    port, sim = sim_arm
    ok(run("arm", "gripper", "close", port=port))
    assert "gripper closed 0.0 mm (700 pulses)" in ok(run("arm", "pose", port=port))
    opened = ok(run("arm", "gripper", "open", port=port))
    match = re.search(r"gripper open ([\d.]+) mm \((\d+) pulses\)", opened)
    assert match is not None, opened
    sim.advance()
    assert int(match.group(2)) == round(sim.servo(GRIPPER_ID).position_pulses)
    widest = one_error(run("arm", "gripper", "94mm", port=port), 2)
    assert re.search(r"gripper gap = 94(\.0)? mm is out of range 0\.\.93\.8 mm", widest), widest
    assert float(match.group(1)) <= 93.8  # what it reports is within what it accepts
    assert "gripper at 93.8 mm apart" in ok(run("arm", "gripper", "93.8mm", port=port))


# ---------------------------------------------------------------------- 3: sim state


def test_the_sim_state_file_keeps_positions_between_runs(tmp_path: Path) -> None:
    state = tmp_path / "servos.json"
    port = f"sim://?state={state}"
    moved = run("move", "1", "30", "--wait", port=port)  # each run opens the port anew
    assert moved.exit_code == 0 and "reached: 1 at +29" in moved.stdout, moved.stderr
    record = next(s for s in json.loads(state.read_text())["servos"] if s["id"] == 1)
    assert record["position_pulses"] == pytest.approx(500 + 30 / 0.24, abs=4)
    again = run("arm", "pose", "--json", port=port)
    assert again.exit_code == 0, again.stderr
    assert json.loads(again.stdout)["joints_deg"]["base_yaw"] == pytest.approx(-30.0, abs=1.0)
    assert ok(run("arm", "pose", "--json", port="sim")).count('"base_yaw": 0.0') == 1


# ---------------------------------------------------------------------- 4: calibrate


def _far_from_upright(port: str) -> None:
    ok(run("arm", "move-joints", "0", "-60", "79", "-90", "0", port=port))


def test_calibrate_yes_refuses_a_pose_far_from_the_reference(
        sim_arm: tuple[str, ListeningSim], tmp_path: Path) -> None:
    port, sim = sim_arm
    _far_from_upright(port)
    out = tmp_path / "cal.json"
    line = one_error(run("arm", "calibrate", "--yes", "--out", str(out), port=port), 2)
    assert ("calibration not written: shoulder_pitch (servo 2) reads -60.0 deg, the reference "
            "pose has -90 deg: 30.0 deg off; elbow_pitch (servo 3) reads 79.0 deg, the "
            "reference pose has 0 deg: 79.0 deg off: more than 20 deg") in line, line
    assert "give --force if it is" in line and "holding position (torque on)" in line
    assert not out.exists()
    assert Command.ANGLE_OFFSET_ADJUST not in sim.writes()
    assert [s.stored_fields()["offset_pulses"] for s in sim.servos] == [0] * 6
    # A person is told and asked (default no): nothing written, exit 0.
    asked = run("arm", "calibrate", "--out", str(out), port=port, input="y\n\n")
    assert asked.exit_code == 0, asked.stderr
    assert "warning: shoulder_pitch (servo 2) reads -60.0 deg" in asked.stderr
    assert "Write it anyway? [y/N]" in asked.stderr
    assert "calibration declined: nothing written" in asked.stdout
    assert not out.exists() and Command.ANGLE_OFFSET_ADJUST not in sim.writes()
    # --force writes it (the arm may really be there, with horns far off).
    forced = ok(run("arm", "calibrate", "--yes", "--force", "--out", str(out), port=port))
    assert f"wrote {out}" in forced and out.exists()
    assert sim.servo(2).stored_fields()["offset_pulses"] == -125  # saved in the servo


# ---------------------------------------------------------------------- 7: twin serve


def _keep_true_twin_calibration(config_home: Path, lens_name: str = "wide") -> Path:
    """The twin's kept calibration, made from its truth (the lens, the as-built mount)
    as `camera calibrate`/`handeye` would keep it, without their minute of CPU."""
    from busarm.arm.camera_mount import CameraMount
    from busarm.robot.calibration_store import MadeFor
    from busarm.twin.camera import TwinOptics
    from busarm.twin.lens import LENSES
    from busarm.twin.model import AS_BUILT_MOUNT_ERROR
    from busarm.vision.calibration import (
        CameraIntrinsics,
        HandEyeResult,
        save_hand_eye,
        save_intrinsics,
    )

    lens = LENSES[lens_name]
    mount = CameraMount.from_config(CONFIG.camera).offset(*AS_BUILT_MOUNT_ERROR)
    made_for = MadeFor.of("twin", (lens.width_px, lens.height_px), CONFIG,
                          TwinOptics(lens, mount))
    intrinsics = CameraIntrinsics("pinhole", lens.width_px, lens.height_px,
                                  lens.camera_matrix, lens.dist_coeffs)
    folder = config_home / "busarm" / "twin"
    folder.mkdir(parents=True)
    save_intrinsics(folder / "camera.json", intrinsics, made_for=made_for.intrinsics())
    save_hand_eye(folder / "hand_eye.json",
                  HandEyeResult(mount.cam2link, np.eye(4), 0.1, (0.1,), (0,), intrinsics),
                  made_for=made_for.hand_eye())
    return folder


TWIN_REASON = ("`busarm twin serve` as its own process (wall-clock time), found by commands "
               "run in this process without --port")




class TwinServe:
    """``busarm twin serve`` in its own process (its servos' pty, its camera's URL)."""

    def __init__(self, env: Env, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "busarm", "twin", "serve", *args], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env=process_env(env),
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        assert self.proc.stdout is not None and self.proc.stderr is not None
        self.port = self.proc.stdout.readline().strip()
        self.camera = self.proc.stdout.readline().strip()
        assert self.port.startswith("/dev/") and self.camera.startswith("twin://127.0.0.1:")
        self.banner = [self.proc.stderr.readline().strip() for _ in range(2)]
        runtime = Path(str(env["BUSARM_RUNTIME_DIR"]))
        assert wait_for(lambda: bool(list(runtime.glob("twin-*.json"))), timeout_s=30), \
            "twin serve did not announce itself"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
        self.proc.communicate(timeout=30)


@pytest.fixture
def twin_serve(tmp_path: Path) -> Iterator[tuple[TwinServe, Env, Path]]:
    """A twin serve (seed 3, 2 blocks) in a runtime folder of this test's own, the
    variables of commands that find it (set for a command in this process, None removed;
    its process gets them on top of this one's environment), and the twin's kept (true)
    calibration."""
    env: Env = {"BUSARM_PORT": None, "BUSARM_ARM": None,
                "BUSARM_RUNTIME_DIR": str(tmp_path / "run"),
                "XDG_CONFIG_HOME": str(tmp_path), "COLUMNS": "200"}
    folder = _keep_true_twin_calibration(tmp_path)
    serve = TwinServe(env, "--seed", "3", "--blocks", "2")
    try:
        yield serve, env, folder
    finally:
        serve.stop()


@pytest.mark.wallclock(TWIN_REASON)
def test_a_served_twins_camera_uses_the_calibration_kept_for_the_twin(
        twin_serve: tuple[TwinServe, Env, Path], tmp_path: Path) -> None:
    from busarm.twin.scene import random_scene

    serve, env, folder = twin_serve
    bins = "red=66.69,183.24;green=66.69,-183.24;blue=-66.69,183.24"
    assert serve.banner[1] == (f"bins: {bins} (busarm --port {serve.port} pick-sort --camera "
                               f"{serve.camera} --bins '{bins}')")
    for args in ((), ("--camera", serve.camera)):
        located = busarm("vision", "locate", "--json", *args, *MARGIN, env=env)
        not_crashed(located)
        assert located.exit_code == 0, located.stderr
        assert f"using the camera calibration kept in {folder}/" in located.stderr
        seen = {(b["color"], round(b["x_mm"]), round(b["y_mm"]))
                for b in json.loads(located.stdout)["blocks"]}
        truth = random_scene(3, 2).blocks
        assert len(seen) == len(truth)
        for block in truth:  # where the served twin's blocks really are
            assert any(c == block.color and math.hypot(x - block.x_mm, y - block.y_mm) < 5
                       for c, x, y in seen), (seen, truth)
    # pick-sort without --port: its own twin, said so, with how to sort the served one.
    sorted_own = busarm("pick-sort", "--blocks", "0", "--report", str(tmp_path / "r"),
                        env=env)
    not_crashed(sorted_own)
    assert sorted_own.exit_code == 0, sorted_own.stderr
    assert (f"note: pick-sort runs a twin of its own (seed 0), not the arm of `busarm twin "
            f"serve` (pid {serve.proc.pid}) on {serve.port}; to sort the served table: busarm "
            f"--port {serve.port} pick-sort --camera {serve.camera} --bins") \
        in sorted_own.stderr


@pytest.mark.wallclock(TWIN_REASON)
def test_a_calibration_for_another_lens_is_stale_for_a_served_twin(
        twin_serve: tuple[TwinServe, Env, Path]) -> None:
    _, env, folder = twin_serve
    record = json.loads((folder / "camera.json").read_text())
    record["meta"]["made_for"]["twin_lens"]["distortion"][0] = -0.1
    (folder / "camera.json").write_text(json.dumps(record))
    line = one_error(busarm("vision", "locate", *MARGIN, env=env), 2)
    assert "it was made for a twin lens with fx 473.45 px, k1 -0.1, this is the twin's " \
           "'wide' lens (twin://?lens=wide)" in line, line
