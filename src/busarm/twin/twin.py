"""The digital twin: MuJoCo physics of the arm, table, blocks and camera, coupled to the
servo simulator so that the same code drives it through the same bytes as a real arm.

The coupling, every control tick (``CONTROL_PERIOD_S``), under the simulated bus's lock:

- each ``SimServo`` is advanced to now; where its firmware model says the horn should
  be (its commanded motion: speed limits, offsets, faults, MOVE_STOP) becomes the target
  of the joint's position actuator, whose torque is limited to the servo's stall torque;
  an unloaded servo (torque off, a fault) gives no torque at all;
- physics steps up to now;
- the simulated joint angles become what POS_READ reports (``SimServo.horn_sensor``), so a
  gripper closing on a block stalls short of closed and a loaded joint sags as it would;
- each actuator's torque, as a fraction of stall torque, heats its servo model
  (``SimServo.external_effort``).

Time is the twin's ``clock``. A real-time twin (``realtime=True``: ``twin serve``, programs
in other processes) follows the wall clock: a background thread keeps physics up to date,
and every render first catches up. Otherwise (``--port twin`` in this process, benchmarks,
tests) it is a ``SimClock``: physics steps whenever anyone waits on that clock (the bus
driver for a reply, the arm for a move), as fast as the CPU allows, and every time the
programs above report is in simulated seconds. Blocks
settle for ``SETTLE_S`` of simulated time before the clock starts, so a seeded scene
looks the same every time. Such a twin does not see ``time.sleep``: a program that waits
so, then reads it, is warned once (``busarm.clock.FrozenClockWarning``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType

import numpy as np
import numpy.typing as npt

from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import ArmConfig, deck_mounted, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.base.config import ChassisConfig, load_chassis_config
from busarm.clock import WALL_CLOCK, Clock, SimClock
from busarm.errors import ConfigError, TwinError
from busarm.protocol import Command, Request
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams
from busarm.twin.arena import Arena
from busarm.twin.arena_model import build_arena_mjcf, floor_texture
from busarm.twin.boards import board2base, check_boards_fit, scene_textures
from busarm.twin.lens import LensSpec
from busarm.twin.lidar import LidarNoise
from busarm.twin.mobile import MobileBase, SlipModel
from busarm.twin.model import (
    AS_BUILT_MOUNT_ERROR,
    GRIPPER_KP_NM_PER_RAD,
    GRIPPER_TORQUE_NM,
    JOINT_TORQUE_NM,
    M_PER_MM,
    SERVO_KP_NM_PER_RAD,
    SERVO_KV_NM_S_PER_RAD,
    TwinModelSpec,
    build_mjcf,
)
from busarm.twin.mujoco_gl import Renderers, import_mujoco
from busarm.twin.rendering import LIVE_DENSITY, ImageArray, TwinRendering, live_render_size
from busarm.twin.scene import Block, Scene, random_scene

__all__ = [
    "CONTROL_PERIOD_S",
    "EFFORT_STEP",
    "LIVE_DENSITY",
    "MAX_CATCH_UP_S",
    "SETTLE_S",
    "BlockState",
    "FloatArray",
    "ImageArray",
    "Twin",
]


FloatArray = npt.NDArray[np.float64]

CONTROL_PERIOD_S = 0.004
SETTLE_S = 0.4
MAX_CATCH_UP_S = 0.25
"""At most this much simulated time per tick: after a longer stall (a debugger, a loaded
machine) the twin's clock slips rather than integrating seconds in one go."""
EFFORT_STEP = 0.05


@dataclass(frozen=True)
class BlockState:
    """Where a block really is (ground truth, mm and degrees, base frame)."""

    index: int
    color: str
    x_mm: float
    y_mm: float
    z_mm: float
    yaw_deg: float
    size_mm: float
    is_upright: bool


def _twin_clock(realtime: bool, clock: SimClock | None) -> Clock:
    """The wall clock for a real-time twin, else ``clock`` or a new SimClock."""
    if realtime and clock is not None:
        raise ConfigError("a real-time twin follows the wall clock: give a SimClock "
                          "only with realtime=False")
    return WALL_CLOCK if realtime else (clock or SimClock(step_s=CONTROL_PERIOD_S))


class Twin(TwinRendering):
    """A physically simulated arm, table, blocks and camera behind a simulated servo bus.

    ``twin.bus`` is the ``SimBus`` to talk to (``--port twin`` wraps it in a transport);
    ``render_camera()`` gives the arm camera's image through its lens.
    """

    def __init__(
        self,
        config: ArmConfig | None = None,
        scene: Scene | None = None,
        *,
        lens: LensSpec | None = None,
        mount: CameraMount | None = None,
        start_joints_deg: Sequence[float] | None = None,
        gripper_pulses: int | None = None,
        realtime: bool = True,
        clock: SimClock | None = None,
        timing: WireTiming | None = None,
        echo: bool = False,
        arena: Arena | None = None,
        chassis: ChassisConfig | None = None,
        slip: SlipModel | None = None,
    ) -> None:
        self.mujoco = import_mujoco()
        self.config = config if config is not None else load_arm_config()
        if arena is not None:  # the arm stands on the mobile base's deck
            self.config = deck_mounted(self.config)
        if arena is not None and scene is not None:
            raise ConfigError("a twin has an arena (the mobile robot) or a table scene, not both")
        self.arena = arena
        """The mobile robot's arena (None: the arm on a table)."""
        self.chassis = chassis if chassis is not None or arena is None else load_chassis_config()
        self.scene = scene if scene is not None else Scene() if arena else random_scene(0)
        self.lens = lens if lens is not None else LensSpec()
        self.mount = mount if mount is not None else CameraMount.from_config(
            self.config.camera).offset(*AS_BUILT_MOUNT_ERROR)
        self.kin = ArmKinematics.from_config(self.config, check_table=False)
        start, grip = self._start_pose(start_joints_deg, gripper_pulses)
        self._build_model()
        self._lock = threading.RLock()
        self._renderers = Renderers(self.mujoco)
        self._closed = False
        self.slipped_s = 0.0
        self.physics_hooks: list[Callable[[float, float], None]] = []
        """Called as ``hook(t_s, chunk_s)`` under the twin's lock before each physics chunk
        (``t_s``: the simulation's time, ``chunk_s``: how long the chunk lasts): what moves
        on the twin's own clock and is not a servo (busarm.twin.mover's hand)."""
        self._find_parts()

        # Start: arm at rest in the start pose, servos holding it, blocks settled.
        self.lidar_noise = LidarNoise()
        """What the twin's Lidar adds to the truth (busarm.twin.lidar)."""
        self.mobile = None if arena is None or self.chassis is None else MobileBase(
            self.model, self.data, self.chassis, arena.start, slip, seed=arena.seed or 0)
        """The base's coupling to a simulated board (an arena twin only)."""
        self._settle(start, grip)
        self.realtime = realtime
        self.clock: Clock = _twin_clock(realtime, clock)
        self._t0 = self.clock.now()
        self.servos = self._power_servos(start, grip)
        self.bus = SimBus(self.servos, timing=timing or WireTiming(), echo=echo, clock=self.clock)
        self._read_sensors()
        self._start_physics()

    def _start_pose(self, joints_deg: Sequence[float] | None,
                    gripper_pulses: int | None) -> tuple[tuple[float, ...], int]:
        """The start pose's joint angles and gripper pulses, checked."""
        cfg = self.config
        if joints_deg is None:
            # Looking down at the table, so a fresh twin's camera sees the blocks.
            joints_deg = cfg.pose("look" if "look" in cfg.poses_deg else "home")
        start = cfg.check_joints(joints_deg)
        grip = cfg.gripper.open_pulses if gripper_pulses is None else gripper_pulses
        cfg.gripper.check_pulses(grip)
        return start, grip

    def _build_model(self) -> None:
        """The world's MJCF (``mjcf``), compiled with its assets (board prints, an
        arena's floor) into ``model`` and ``data``."""
        cfg = self.config
        board_textures = scene_textures(self.scene, cfg.table_z_mm)
        check_boards_fit(self.scene, cfg.table_z_mm)
        width, height, fovy = self.lens.render_geometry()
        spec = TwinModelSpec(self.mount, fovy, (width, height), textures=tuple(board_textures))
        assets = {name: data for name, data, _w, _h, _pose in board_textures}
        if self.arena is None or self.chassis is None:
            self.mjcf = build_mjcf(cfg, self.scene, spec)
        else:
            self.mjcf = build_arena_mjcf(cfg, self.chassis, self.arena, spec)
            assets.update([floor_texture(self.arena)])
        try:
            self.model = self.mujoco.MjModel.from_xml_string(self.mjcf, assets)
        except ValueError as exc:
            raise TwinError(f"MuJoCo rejected the generated model: {exc}") from exc
        self.data = self.mujoco.MjData(self.model)
        self._render_size = (width, height)
        self._fovy_deg = fovy
        self._live_render_size = live_render_size(width, height)

    def _find_parts(self) -> None:
        """The model's addresses of the joints, actuators and bodies the coupling uses."""
        m, cfg, n_blocks = self.model, self.config, len(self.scene.blocks)
        self._joint_qpos = [m.joint(j.name).qposadr[0] for j in cfg.joints]
        self._joint_act = [m.actuator(j.name).id for j in cfg.joints]
        self._finger_qpos = m.joint("finger_left").qposadr[0]
        self._finger_right_qpos = m.joint("finger_right").qposadr[0]
        self._grip_act = m.actuator("gripper").id
        self._block_body = [m.body(f"block{i}").id for i in range(n_blocks)]
        self._block_qpos = [m.joint(f"block{i}").qposadr[0] for i in range(n_blocks)]
        self._block_dof = [m.joint(f"block{i}").dofadr[0] for i in range(n_blocks)]
        self._link4 = m.body("link4").id
        self._torque = [JOINT_TORQUE_NM] * len(cfg.joints) + [GRIPPER_TORQUE_NM]
        self._acts = [*self._joint_act, self._grip_act]
        self._kp = [SERVO_KP_NM_PER_RAD] * len(cfg.joints) + [GRIPPER_KP_NM_PER_RAD]
        self._loaded = [True] * len(self._acts)
        # Each joint's last commanded angle (rad) and when (None while limp), for the ramp
        # and the servo's rate term.
        self._last_cmd: list[tuple[float, float] | None] = [None] * len(cfg.joints)
        # What every control tick reads, looked up once: a tick often steps physics only
        # once or twice, so its own bookkeeping would otherwise cost more than the physics.
        self._dt = float(m.opt.timestep)
        self._chunk = max(1, round(CONTROL_PERIOD_S / self._dt))
        self._ctrl = self.data.ctrl
        self._qpos = self.data.qpos
        self._actuator_force = self.data.actuator_force
        self._grip_gear = float(m.actuator_gear[self._grip_act, 0])
        self._to_angle = [j.angle_deg_from_pulses for j in cfg.joints]
        self._to_pulses = [j.pulses_from_angle_deg for j in cfg.joints]

    def _settle(self, start: Sequence[float], grip: float) -> None:
        """The arm at rest in the start pose, the servos holding it, then ``SETTLE_S`` of
        physics for the blocks to settle; the simulated time starts at 0 after that."""
        mj, m, d = self.mujoco, self.model, self.data
        for adr, act, angle in zip(self._joint_qpos, self._joint_act, start, strict=True):
            d.qpos[adr] = math.radians(angle)
            d.ctrl[act] = math.radians(angle)
        half_gap = self._half_gap_m(grip)
        d.qpos[self._finger_qpos] = d.qpos[self._finger_right_qpos] = half_gap
        d.ctrl[self._grip_act] = self._grip_ctrl(half_gap)
        mj.mj_forward(m, d)
        mj.mj_step(m, d, nstep=round(SETTLE_S / m.opt.timestep))
        d.time = 0.0

    def _power_servos(self, start: Sequence[float], grip: float) -> list[SimServo]:
        """The simulated servos, powered on and holding the start pose, as after the
        vendor's start-up move; each senses its joint in the physics."""
        cfg = self.config
        servos: list[SimServo] = []
        for j, angle in zip(cfg.joints, start, strict=True):
            servos.append(SimServo(j.servo_id, params=ServoParams.arm_35kg(),
                                   position_pulses=j.pulses_from_angle_deg(angle), now=self._t0))
        servos.append(SimServo(cfg.gripper.servo_id, params=ServoParams.gripper(),
                               position_pulses=float(grip), now=self._t0))
        self._sensed = [s.physical_pulses for s in servos]
        for k, servo in enumerate(servos):
            servo.handle(Request(servo.servo_id, Command.MOVE_TIME_WRITE,
                                 (round(servo.physical_pulses), 0)), self._t0)
            servo.horn_sensor = self._sensor(k)
        return servos

    def _start_physics(self) -> None:
        """Physics follows the clock: stepped by a SimClock's waits, else by a thread."""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        if isinstance(self.clock, SimClock):
            self.clock.attach(self._tick)
            # A program that waits with time.sleep finds the twin where it left it: told
            # once (busarm.clock.FrozenClockWarning), not left to wonder.
            self.clock.warn_when_frozen("the twin")
        else:
            self._thread = threading.Thread(target=self._run, name="busarm-twin", daemon=True)
            self._thread.start()

    # ------------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Stop the physics thread and free the renderers."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        if isinstance(self.clock, SimClock):
            self.clock.detach(self._tick)
        self.release_renderers()
        self._renderers.forget_others()

    @property
    def lock(self) -> threading.RLock:
        """Held while physics steps: hold it to read ``data`` consistently."""
        return self._lock

    @property
    def is_closed(self) -> bool:
        return self._closed

    def __enter__(self) -> Twin:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ coupling

    def _half_gap_m(self, gripper_pulses: float) -> float:
        return self.config.gripper.gap_mm_at(gripper_pulses) / 2 * M_PER_MM

    def _pulses_from_half_gap(self, half_gap_m: float) -> float:
        closed = self.config.gripper.closed_pulses
        sign = 1.0 if closed >= self.config.gripper.open_pulses else -1.0
        return closed - sign * half_gap_m / M_PER_MM * 2 / self.config.gripper.gap_mm_per_pulse

    def _grip_ctrl(self, half_gap_m: float) -> float:
        return self._grip_gear * half_gap_m

    def _sensor(self, k: int) -> Callable[[], float]:
        return lambda: self._sensed[k]

    def _read_sensors(self) -> None:
        qpos, sensed = self._qpos, self._sensed
        for k, (to_pulses, adr) in enumerate(zip(self._to_pulses, self._joint_qpos,
                                                 strict=True)):
            sensed[k] = to_pulses(math.degrees(qpos[adr]))
        sensed[-1] = self._pulses_from_half_gap(float(qpos[self._finger_qpos]))

    def _set_loaded(self, k: int, loaded: bool) -> None:
        if self._loaded[k] == loaded:
            return
        self._loaded[k] = loaded
        act = self._acts[k]
        kp = self._kp[k] if loaded else 0.0
        self.model.actuator_gainprm[act, 0] = kp
        self.model.actuator_biasprm[act, 1] = -kp
        if act in self._joint_act:
            self.model.actuator_biasprm[act, 2] = -SERVO_KV_NM_S_PER_RAD if loaded else 0.0

    def _tick(self) -> None:
        """Bring physics up to the clock, following the servos' commands."""
        d, dt = self.data, self._dt
        motors = None if self.mobile is None else self.mobile.read_wheels(self.clock.now())
        with self.bus.lock, self._lock:
            now = self.clock.now()
            behind = now - self._t0 - d.time
            if behind < dt:
                return
            if behind > MAX_CATCH_UP_S:
                self.slipped_s += behind - MAX_CATCH_UP_S
                self._t0 += behind - MAX_CATCH_UP_S
                behind = MAX_CATCH_UP_S
            steps = int(behind / dt + 1e-9)
            ramps = self._joint_ramps(now, steps)
            if self.mobile is not None:
                self.mobile.before_physics(d, now, motors)
            grip = self.servos[-1]
            grip.advance(now)
            self._ctrl[self._grip_act] = self._grip_ctrl(self._half_gap_m(grip.physical_pulses))
            self._set_loaded(len(self.servos) - 1, grip.is_loaded)
            self._step_physics(steps, ramps)
            self._read_sensors()
            if self.mobile is not None:
                self.mobile.after_physics(d)
            self._feel_efforts()

    def _joint_ramps(self, now: float, steps: int) -> list[tuple[int, float, float, float]]:
        """Each arm servo advanced to ``now``, and its joint's command ramp over the
        coming ``steps``: (actuator, start, target, rate lead), all rad."""
        ramps = []
        span_s = steps * self._dt
        last_cmd, loaded_now = self._last_cmd, self._loaded
        for k, (servo, to_angle, act) in enumerate(zip(self.servos, self._to_angle,
                                                       self._joint_act, strict=False)):
            servo.advance(now)
            target = math.radians(to_angle(servo.physical_pulses))
            loaded = servo.is_loaded
            # A limp servo re-seeds its target from the horn when it takes the load again
            # (the firmware model does): no ramp from where it was before.
            last = last_cmd[k]
            last_cmd[k] = (now, target) if loaded else None
            start, rate = target, 0.0
            if last is not None and steps > 0:
                start = last[1]
                rate = (target - start) / span_s
            # Firmware moves are uniform in time, so the command is ramped across the
            # physics steps (a long tick, after a stall, is not one jump). The
            # actuator damps the joint's speed (kv); a servo's D term acts on the
            # error's rate instead, so the commanded speed is fed forward.
            ramps.append((act, start, target, rate * SERVO_KV_NM_S_PER_RAD / SERVO_KP_NM_PER_RAD))
            if loaded != loaded_now[k]:
                self._set_loaded(k, loaded)
        return ramps

    def _step_physics(self, steps: int, ramps: list[tuple[int, float, float, float]]) -> None:
        """``steps`` physics steps in chunks of a control period, the joints' commands
        ramped across them and the physics hooks run before each chunk."""
        mj, m, d, dt, ctrl = self.mujoco, self.model, self.data, self._dt, self._ctrl
        hooks = self.physics_hooks
        done = 0
        while done < steps:
            n = min(self._chunk, steps - done)
            done += n
            for act, start, end, lead in ramps:
                ctrl[act] = start + (end - start) * done / steps + lead
            for hook in hooks:
                hook(float(d.time), n * dt)
            mj.mj_step(m, d, nstep=n)

    def _feel_efforts(self) -> None:
        """Each loaded servo's actuator torque, as a share of its stall torque (in
        ``EFFORT_STEP`` steps), becomes the load its heat model feels."""
        forces = self._actuator_force.tolist()
        for servo, loaded, act, torque in zip(self.servos, self._loaded, self._acts,
                                              self._torque, strict=True):
            if not loaded:
                continue
            effort = min(1.0, abs(forces[act]) / torque)
            effort = round(effort / EFFORT_STEP) * EFFORT_STEP
            if effort != servo.external_effort:
                servo.external_effort = effort

    def _run(self) -> None:
        while not self._stop.wait(CONTROL_PERIOD_S):
            self._tick()

    def step(self, duration_s: float) -> None:
        """Advance a twin made with ``realtime=False`` by ``duration_s`` of simulated time
        (as any wait on ``twin.clock`` does)."""
        if not self.clock.is_simulated:
            raise ConfigError("step() is for a twin made with realtime=False; "
                              "a real-time twin follows the wall clock")
        if not (math.isfinite(duration_s) and 0 <= duration_s <= 3600):
            raise ConfigError(f"duration_s = {duration_s!r} is out of range 0..3600")
        self.clock.sleep(duration_s)

    def sync(self) -> None:
        """Catch physics up with the clock now (before reading or rendering)."""
        self._tick()

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since the twin started: the clock's, less any slip."""
        return float(self.data.time)

    # ------------------------------------------------------------------ ground truth

    def joints_deg(self) -> tuple[float, ...]:
        """The simulated joint angles (ground truth, not quantised to pulses)."""
        with self._lock:
            return tuple(math.degrees(self.data.qpos[a]) for a in self._joint_qpos)

    def servo_pulses_in_step(self) -> tuple[list[int], list[float]]:
        """Every servo's (arm joints, then the gripper) position as POS_READ would report
        it (logical pulses) and its firmware's setpoint, at the physics' present: for a
        hook in ``physics_hooks``, which runs between physics steps, where the bus cannot
        be read."""
        t = self._t0 + float(self.data.time)
        read = [j.pulses_from_angle_deg(math.degrees(self.data.qpos[a]))
                for j, a in zip(self.config.joints, self._joint_qpos, strict=True)]
        read.append(self._pulses_from_half_gap(float(self.data.qpos[self._finger_qpos])))
        return ([round(p - s.offset_pulses) for p, s in zip(read, self.servos, strict=True)],
                [s.setpoint_pulses_at(t) for s in self.servos])

    def finger_gap_mm(self) -> float:
        with self._lock:
            return 2 * float(self.data.qpos[self._finger_qpos]) / M_PER_MM

    def link2base(self) -> FloatArray:
        """The wrist-pitch link's frame (DH frame 4) in the base frame, mm (ground truth)."""
        with self._lock:
            return self._body_pose_mm(self._link4)

    def board2base(self, index: int = 0) -> FloatArray:
        """Where board ``index`` of the scene lies: its own frame in the base frame (mm)."""
        return board2base(self.scene.boards[index], self.config.table_z_mm)

    def cam2base(self) -> FloatArray:
        """The arm camera's pose (OpenCV axes, mm) in the base frame: ground truth."""
        return self.link2base() @ self.mount.cam2link

    def _body_pose_mm(self, body: int) -> FloatArray:
        out = np.eye(4)
        out[:3, :3] = self.data.xmat[body].reshape(3, 3)
        out[:3, 3] = self.data.xpos[body] / M_PER_MM
        return out

    def blocks(self) -> list[BlockState]:
        """Every block's true pose."""
        out = []
        with self._lock:
            for i, (block, body) in enumerate(zip(self.scene.blocks, self._block_body,
                                                  strict=True)):
                pose = self._body_pose_mm(body)
                r = pose[:3, :3]
                # Yaw of whichever face points up, folded into (-45, 45] for a cube.
                up_axis = int(np.argmax(np.abs(r[2, :])))
                side = r[:, (up_axis + 1) % 3]
                yaw = math.degrees(math.atan2(side[1], side[0]))
                yaw = (yaw + 45.0) % 90.0 - 45.0
                out.append(BlockState(
                    i, block.color, float(pose[0, 3]), float(pose[1, 3]),
                    float(pose[2, 3]), yaw, block.size_mm,
                    bool(abs(r[2, up_axis]) > math.cos(math.radians(10)))))
        return out

    def distractor_positions_mm(self) -> list[tuple[float, float, float]]:
        """Where each of the scene's distractors (things that are not blocks) really is:
        (x, y, z) of its body, mm, base frame (ground truth)."""
        out = []
        with self._lock:
            for i in range(len(self.scene.distractors)):
                p = self._body_pose_mm(self.model.body(f"distractor{i}").id)[:3, 3]
                out.append((float(p[0]), float(p[1]), float(p[2])))
        return out

    def put_base(self, x_m: float, y_m: float, yaw_rad: float) -> None:
        """A person lifts the mobile robot and puts it down here (arena frame), at rest:
        its odometry is not told (its gyro feels the turn, as a real one would)."""
        if self.mobile is None:
            raise TwinError("this twin has no mobile base (open it with an arena)")
        mj, model, data = self.mujoco, self.model, self.data
        with self.lock:
            for name, value in (("chassis_x", x_m), ("chassis_y", y_m), ("chassis_yaw", yaw_rad)):
                joint = model.joint(name)
                data.qpos[int(joint.qposadr[0])] = value
                data.qvel[int(joint.dofadr[0])] = 0.0
            mj.mj_forward(model, data)

    def place_block(self, index: int, x_mm: float, y_mm: float, yaw_deg: float = 0.0,
                    z_mm: float | None = None) -> None:
        """Put block ``index`` at (x, y), standing on the table unless ``z_mm`` is given
        (a hand moving it: fault injection, benchmarks). It starts at rest."""
        self.place_blocks({index: (x_mm, y_mm, yaw_deg, z_mm)})

    def place_blocks(
        self, poses: dict[int, tuple[float, float, float, float | None]],
    ) -> None:
        """Move several blocks at once, ``{index: (x, y, yaw, z or None)}``, in one physics
        instant, so none is ever put inside another's old place. Checked before any moves."""
        checked = []
        for index, (x_mm, y_mm, yaw_deg, z_mm) in poses.items():
            if isinstance(index, bool) or not isinstance(index, int) or not (
                    0 <= index < len(self.scene.blocks)):
                raise ConfigError(f"block index {index!r} is out of range "
                                  f"0..{len(self.scene.blocks) - 1}")
            for name, v in (("x_mm", x_mm), ("y_mm", y_mm), ("yaw_deg", yaw_deg)):
                if not math.isfinite(v):
                    raise ConfigError(f"{name} = {v!r} must be finite")
            block: Block = self.scene.blocks[index]
            if not self.scene.table.contains(x_mm, y_mm, block.radius_mm):
                raise ConfigError(f"block {index} at ({x_mm:g}, {y_mm:g}) mm is off the table")
            z = (self.config.table_z_mm + block.size_mm / 2) if z_mm is None else z_mm
            if not math.isfinite(z):
                raise ConfigError(f"z_mm = {z_mm!r} must be finite")
            half = math.radians(yaw_deg) / 2
            checked.append((index, (x_mm * M_PER_MM, y_mm * M_PER_MM, z * M_PER_MM,
                                    math.cos(half), 0.0, 0.0, math.sin(half))))
        with self._lock:
            for index, qpos in checked:
                adr, dof = self._block_qpos[index], self._block_dof[index]
                self.data.qpos[adr:adr + 7] = qpos
                self.data.qvel[dof:dof + 6] = 0.0
            self.mujoco.mj_forward(self.model, self.data)
