"""The robot behind the dashboard: one control thread, one job at a time, one driver.

The control thread runs every ``period_s`` (25 Hz): it reads the robot's live values
(busarm.robot.state), takes the jog one step on (busarm.dashboard.jog) and hands the
state to every page. A job (a move to a named pose, the gripper, an action group,
pick-and-sort, and on a mobile robot transport and line following: busarm.dashboard.mobile)
runs in its own thread; a jog and a job never run together. A stop or an e-stop on a
mobile robot stops the wheels too (the halt latches them: ``BoardServoBus.halt``).

Stopping, by its strength:

- ``jog_stop`` (a key released, the page lost focus) and a lost heartbeat (none from the
  driver for ``JOG_HOLD_S``): MOVE_STOP to the jogged servos, which hold there.
- ``stop``: the job is cancelled and every servo holds (MOVE_STOP); nothing is latched.
- ``estop``, from any page, even one that only watches: the bus is halted
  (``ServoBus.halt``: MOVE_STOP to every servo, holding, and every later write refused, in
  every thread), the job is cancelled; only ``rearm`` from the driver lets the robot move
  again. The driver's page closing stops everything too, as ``stop`` does.

Every request is checked before anything is sent (the protocol's fields, then the arm's
own limits and speeds, the same checks as the command line); a refusal raises
RequestError or a BusArmError with the reason, and the robot is left as it was.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from busarm.apps.pick_sort.rules import SortRule
from busarm.arm.action_samples import read_group_or_sample, sample_names
from busarm.arm.named_poses import find_pose, list_poses, save_pose
from busarm.dashboard import jobs
from busarm.dashboard.group_recorder import GroupRecorder
from busarm.dashboard.jog import JogPlan
from busarm.dashboard.mobile import MobileJobs, MobileSetup
from busarm.dashboard.protocol import (
    BaseDrive,
    Drive,
    Gripper,
    Jog,
    LineFollow,
    Localise,
    Named,
    NamePoint,
    NavTransport,
    PickSort,
    Record,
    Request,
    RequestError,
    Torque,
    message,
)
from busarm.dashboard.sensing import LiveScans
from busarm.dashboard.teleop import BaseTeleop, base_limits
from busarm.errors import BusArmError, HaltedError
from busarm.fileio import robot_folder
from busarm.robot import Robot
from busarm.robot.state import StateReader

__all__ = [
    "CONTROL_PERIOD_S",
    "JOB_STOP_WAIT_S",
    "JOG_HOLD_S",
    "LOG_LINES",
    "MOBILE_JOBS",
    "WATCH_PERIOD_S",
    "Publish",
    "RobotService",
]


log = logging.getLogger(__name__)

CONTROL_PERIOD_S = 0.04
"""The control thread's period: state and jog steps at 25 Hz."""
JOG_HOLD_S = 0.3
"""A jog goes on this long after the driver's last heartbeat or jog message."""
WATCH_PERIOD_S = 0.01
"""How often the deadman looks at the driver's last heartbeat."""
JOB_STOP_WAIT_S = 5.0
"""How long a stop waits for a cancelled job's thread to end before saying so."""
LOG_LINES = 200
MOBILE_JOBS = ("transport", "line follow", "localise")

Publish = Callable[[str], None]


@dataclass
class _Job:
    name: str
    thread: threading.Thread
    cancel: threading.Event = field(default_factory=threading.Event)
    progress: str = ""


class RobotService:
    """The dashboard's robot: ``handle`` a page's requests, ``subscribe`` to what it says.

    ``folder``: the robot's folder (saved poses; action groups recorded here are kept in
    its ``actions/``); ``reports``: where the jobs' reports go; ``mobile``: the named
    points and map for transport (busarm.dashboard.mobile).
    """

    def __init__(self, robot: Robot, *, folder: Path | None = None,
                 reports: Path = Path("dashboard-reports"),
                 period_s: float = CONTROL_PERIOD_S, mobile: MobileSetup | None = None) -> None:
        self.robot, self.arm = robot, robot.arm
        self.folder = folder if folder is not None else robot_folder(robot.robot_key)
        self.reports = reports
        self.mobile = MobileJobs(robot, mobile, reports)
        self.period_s = period_s
        self.reader = StateReader(robot.arm)
        self.names = tuple(j.name for j in robot.config.joints)
        self._lock = threading.RLock()
        # Held while a jog target is sent and while a jog is ended: a stop's MOVE_STOP is
        # never followed by a target the control thread planned just before it.
        self._jog_io = threading.Lock()
        self._subscribers: dict[str, Publish] = {}
        self.driver: str | None = None
        self._heard = 0.0  # when the driver was last heard from (time.monotonic)
        self._jog: JogPlan | None = None
        self._jog_target: tuple[float, ...] | None = None
        self._job: _Job | None = None
        self.recorder = GroupRecorder(robot.arm, self.folder, self.log)
        self._rearm_after: str | None = None  # a stop's halt, lifted when its job ends
        self.log_lines: collections.deque[dict[str, Any]] = collections.deque(maxlen=LOG_LINES)
        self.last_state: dict[str, Any] = {}
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="busarm-dashboard", daemon=True)
        # The deadman has its own thread: a control period slowed by the bus or the CPU
        # does not delay the stop of a jog whose heartbeat is gone.
        self._watchdog = threading.Thread(target=self._watch, name="busarm-dashboard-deadman",
                                          daemon=True)
        self.teleop = BaseTeleop(robot.base, self.log) if robot.base is not None else None
        self.scans = self._live_scans()

    def _live_scans(self) -> LiveScans | None:
        robot = self.robot
        if robot.lidar is None or robot.base is None:
            return None
        return LiveScans(robot.lidar, robot.base.config.lidar,
                         publish=lambda fields: self.publish("scan", **fields),
                         watched=lambda: bool(self._subscribers),
                         busy=lambda: self._job is not None, idle=self.mobile.show_idle)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> RobotService:
        self._thread.start()
        self._watchdog.start()
        if self.scans is not None:
            self.scans.start()
        return self

    def close(self) -> None:
        """Stop whatever moves (holding), end the control thread."""
        if self._closed.is_set():
            return
        self.stop("the dashboard is closing", who=None)
        self._closed.set()
        if self.scans is not None:
            self.scans.close()
        for thread in (self._thread, self._watchdog):
            if thread.is_alive():
                thread.join(timeout=2)

    # ------------------------------------------------------------------ pages

    def subscribe(self, client: str, publish: Publish) -> str:
        """Add a page (``publish`` gets every message as JSON text); its welcome message.
        The first page becomes the driver if there is none."""
        with self._lock:
            if self.driver is None:
                self.driver, self._heard = client, time.monotonic()
                self.log(f"page {client} drives")  # before it listens: in its welcome's log
            self._subscribers[client] = publish
            return message("welcome", client=client, role=self._role(client),
                           robot=self.describe(), log=list(self.log_lines))

    def unsubscribe(self, client: str) -> None:
        """A page left; if it drove, everything stops (holding) and the seat is free."""
        with self._lock:
            self._subscribers.pop(client, None)
            drove = self.driver == client
            if drove:
                self.driver = None
        if drove:
            self.stop(f"the driver's page ({client}) closed", who=None)

    def _role(self, client: str) -> str:
        return "driver" if self.driver == client else "watcher"

    def describe(self) -> dict[str, Any]:
        """What a page needs to draw the controls: joints, limits, poses, groups."""
        cfg = self.robot.config
        return {
            "name": cfg.name, "port": self.robot.port, "twin": self.robot.is_twin,
            "joints": [{"name": j.name, "servo_id": j.servo_id, "min_deg": j.min_deg,
                        "max_deg": j.max_deg} for j in cfg.joints],
            "servo_ids": list(cfg.servo_ids), "gripper_id": cfg.gripper.servo_id,
            "poses": [p.name for p in list_poses(self.folder, cfg)],
            "groups": self.group_names(), "cameras": sorted(self.robot.cameras),
            "colors": ["red", "green", "blue", "yellow"],
            "mobile": self.mobile.describe(),
            "base": base_limits(self.robot.base) if self.robot.base is not None else None,
            "bins": sorted(self.robot.bins),
        }

    def group_names(self) -> list[str]:
        saved = sorted(p.stem for p in (self.folder / "actions").glob("*.d6a"))
        return [*saved, *(n for n in sample_names() if n not in saved)]

    def publish(self, kind: str, **fields: Any) -> None:
        text = message(kind, **fields)
        with self._lock:
            targets = list(self._subscribers.values())
        for send in targets:
            send(text)

    def log(self, text: str, level: str = "info") -> None:
        entry = {"t": round(time.time(), 3), "level": level, "text": text}
        self.log_lines.append(entry)
        getattr(log, "warning" if level == "error" else level, log.info)(text)
        self.publish("log", **entry)

    # ------------------------------------------------------------------ requests

    def handle(self, client: str, request: Request) -> None:
        """Carry out ``request`` from ``client``; RequestError or BusArmError if refused."""
        kind = request.type
        if kind == "estop":  # anyone may stop the robot
            self.estop(f"e-stop from page {client}")
            return
        if kind == "base_stop":  # a stop is never wrong: from a page that just lost the seat
            self._stop_base("released")
            return
        with self._lock:
            if client == self.driver:
                self._heard = time.monotonic()
        if kind == "heartbeat":
            return
        if kind == "drive":
            assert isinstance(request, Drive)
            self._take_seat(client, request.take_over)
            return
        if client != self.driver:
            raise RequestError(f"{kind}: this page watches; "
                               + ("nobody drives: ask to drive first" if self.driver is None
                                  else f"page {self.driver} drives (take over to drive)"))
        self._driver_request(client, request)

    def _driver_request(self, client: str, request: Request) -> None:
        kind = request.type
        if kind == "release":
            with self._lock:
                self.driver = None
            self._stop_jog("the driver left the seat")
            self._stop_base("the driver left the seat")
            self.publish("role", driver=None)
            self.log(f"page {client} stopped driving")
        elif kind == "stop":
            self.stop(f"stop from page {client}", who=client)
        elif kind == "rearm":
            self.rearm(client)
        elif kind == "jog_stop":
            self._stop_jog("released")
        elif kind == "name_point":
            assert isinstance(request, NamePoint)
            path = self.mobile.name_point(request)
            self.log(f"point {request.name!r} at x {request.x_m:+.2f} m, y {request.y_m:+.2f} "
                     f"m, {request.yaw_deg:+.0f} deg saved in {path}")
            self.publish("robot", robot=self.describe())
        elif kind == "record":
            assert isinstance(request, Record)
            if self.recorder.handle(request):
                self.publish("robot", robot=self.describe())
        elif kind == "save_pose":
            assert isinstance(request, Named)
            self._save_pose(request.name)
        else:
            self._check_can_move(kind)
            if isinstance(request, Jog):
                self._start_jog(request)
            elif isinstance(request, BaseDrive):
                self._start_base(client, request)
            elif isinstance(request, Torque):
                self._torque(request)
            else:
                self._start_job(request)

    def _take_seat(self, client: str, take_over: bool) -> None:
        with self._lock:
            if self.driver == client:
                return
            if self.driver is not None and not take_over:
                raise RequestError(f"page {self.driver} drives: take over explicitly "
                                   "(take_over: true) to drive from this page")
            before, self.driver, self._heard = self.driver, client, time.monotonic()
        if before is not None:
            self._stop_jog(f"page {client} took over")
            self._stop_base(f"page {client} took over")
        self.publish("role", driver=client)
        self.log(f"page {client} drives" + (f" (took over from {before})" if before else ""))

    def _check_can_move(self, kind: str) -> None:
        halted = self.arm.bus.halted
        if halted is not None:
            raise RequestError(f"{kind}: the robot is stopped ({halted}): re-arm it first")
        if self._job is not None:
            raise RequestError(f"{kind}: {self._job.name} is running: stop it first")

    # ------------------------------------------------------------------ stopping

    def estop(self, why: str) -> None:
        """Halt the bus (latched), cancel the job and the jog."""
        self.arm.bus.halt(why)
        with self._lock:
            self._jog = None
            job = self._job
        if job is not None:
            job.cancel.set()
        self._stop_base("e-stop")
        self.log(f"E-STOP: {why}; every servo holds where it stopped; re-arm to move again",
                 "error")

    def stop(self, why: str, *, who: str | None) -> None:
        """Cancel the job and the jog; every servo holds (MOVE_STOP), the wheels stop.
        Not latched."""
        self._stop_base(why)
        with self._jog_io:
            with self._lock:
                self._jog = None
                job = self._job
            if job is None:
                self.arm.bus.emergency_stop()
        if job is None:
            self.log(f"stopped: {why}; every servo holds where it stopped")
            return
        with self._lock:  # before the halt: a job it ends at once must find it (_end_job)
            latched = self.arm.bus.halted is not None
            if not latched:  # not an e-stop: the robot may move again once the job ended
                self._rearm_after = why
        self.arm.bus.halt(why)  # cuts the job short, from its own thread's next write
        job.cancel.set()
        job.thread.join(timeout=JOB_STOP_WAIT_S)
        with self._lock:  # the job may have ended on its own just before the halt
            if not latched and self._job is None and self.arm.bus.halted == why:
                self.arm.bus.rearm()
        self.log(f"stopped {job.name}: {why}; every servo holds where it stopped"
                 + ("" if not job.thread.is_alive() else
                    " (the job is still ending; nothing moves until it has)"))

    def rearm(self, client: str) -> None:
        if self.arm.bus.halted is None:
            raise RequestError("rearm: the robot is not stopped")
        self.arm.bus.rearm()
        self.log(f"re-armed by page {client}: the robot may move again")

    # ------------------------------------------------------------------ the base

    def _start_base(self, client: str, request: BaseDrive) -> None:
        if self.teleop is None:
            raise RequestError("base_drive: this robot has no base (open the dashboard on "
                               "a controller board with a chassis)")
        twist = self.teleop.check(request)
        with self._lock:  # a page that lost the seat meanwhile (a take-over) does not drive
            if self.driver != client:
                raise RequestError(f"base_drive: page {self.driver} drives now")
            self.teleop.start(twist)

    def _stop_base(self, why: str) -> None:
        if self.teleop is not None:
            self.teleop.stop(why)

    # ------------------------------------------------------------------ jog

    def _start_jog(self, request: Jog) -> None:
        with self._lock:
            if self._jog is not None and self._jog.same_as(request.joint, request.axis,
                                                           request.direction):
                self._jog.speed = request.speed
                return
            self._jog = JogPlan(self.robot.config, self.arm.kin, joint=request.joint,
                                axis=request.axis, direction=request.direction,
                                speed=request.speed)
            self._jog_target = None

    def _stop_jog(self, why: str) -> None:
        with self._jog_io:
            with self._lock:
                jog, self._jog = self._jog, None
            if jog is None:
                return
            self.arm.bus.stop(self.arm.config.joint_ids)
        what = jog.joint or f"tool {jog.axis}"
        self.log(f"jog {what} stopped ({why}); the joints hold")

    def _watch(self) -> None:
        """The deadman: a jog stops when the driver has not been heard for JOG_HOLD_S, the
        base's drive after BASE_HOLD_S (and is repeated to the base meanwhile)."""
        while not self._closed.wait(WATCH_PERIOD_S):
            with self._lock:
                silent_s = time.monotonic() - self._heard
                lost = self._jog is not None and silent_s > JOG_HOLD_S
            if self.teleop is not None:
                self.teleop.tick()
            if lost:
                self._stop_jog(f"no heartbeat from the driver for {JOG_HOLD_S * 1000:.0f} ms")

    def _jog_tick(self, joints: tuple[float, ...]) -> None:
        with self._lock:
            jog, heard = self._jog, self._heard
        if jog is None or time.monotonic() - heard > JOG_HOLD_S:
            return  # the deadman stops it (``_watch``)
        target = self._jog_target or joints
        step = jog.step(target, joints, self.period_s)
        if step.joints_deg is None:
            self._stop_jog(step.blocked or "blocked")
            return
        try:
            with self._jog_io:
                if self._jog is not jog:
                    return  # released (or stopped) while this step was planned
                self.arm.command_joints(step.joints_deg, self.period_s * 2)
        except (BusArmError, ValueError) as exc:
            self._stop_jog(str(exc))
            return
        self._jog_target = step.joints_deg

    # ------------------------------------------------------------------ small commands

    def _torque(self, request: Torque) -> None:
        if request.servo not in self.robot.config.servo_ids:
            raise RequestError(f"torque: servo {request.servo} is not one of this arm's "
                               f"({', '.join(map(str, self.robot.config.servo_ids))})")
        self.arm.bus.set_torque(request.servo, request.on)
        self.log(f"servo {request.servo} torque {'on: it holds' if request.on else 'off: limp'}")

    def _save_pose(self, name: str) -> None:
        joints = self.arm.read_joints_deg()
        save_pose(self.folder, self.robot.config, name, joints)
        self.log(f"saved pose {name!r}: " + ", ".join(f"{a:.1f}" for a in joints) + " deg")
        self.publish("robot", robot=self.describe())

    # ------------------------------------------------------------------ jobs

    def _start_job(self, request: Request) -> None:
        run, name = self._job_for(request)
        self._stop_base(f"{request.type} starts")
        with self._lock:
            if self._job is not None:
                raise RequestError(f"{request.type}: {self._job.name} is running")
            job = _Job(name, threading.Thread(target=lambda: self._run_job(job, run),
                                              name=f"busarm-job-{request.type}", daemon=True))
            self._job = job
        self.log(f"{name}: started")
        job.thread.start()

    def _job_for(self, request: Request) -> tuple[Callable[[_Job], str], str]:
        """What the job does (checked here, before it starts) and its name."""
        if isinstance(request, Named) and request.type == "move_pose":
            pose = find_pose(self.folder, self.robot.config, request.name)
            self.robot.config.check_joints(pose.joints_deg)
            return lambda job: jobs.move_pose(self.arm, pose), f"move to {pose.name}"
        if isinstance(request, Gripper):
            return lambda job: jobs.gripper(self.arm, request.action), (
                f"gripper {request.action}")
        if isinstance(request, Named) and request.type == "play":
            saved = self.folder / "actions" / f"{request.name}.d6a"
            group, what = read_group_or_sample(saved if saved.exists() else request.name)
            self.arm.action_targets(group)  # every frame checked before the first is sent
            return (lambda job: jobs.play(self.arm, group, job.cancel, self._progress(job)),
                    f"play {what}")
        if isinstance(request, PickSort):
            # Bins for the rule first (a refusal moves nothing, stops nothing).
            SortRule(request.by).places(self.robot.bins, request.colors)
            folder = jobs.report_folder(self.reports)
            self.robot.require_camera_calibration()

            def pick(job: _Job) -> str:
                try:
                    return jobs.pick_sort(self.robot, request, folder, self._progress(job))
                finally:
                    if (folder / "report.json").exists():
                        self.publish("report", name=folder.name)
            return pick, "pick-sort"
        if isinstance(request, NavTransport | LineFollow | Localise):
            mobile, name = self.mobile.job_for(request)
            return lambda job: mobile(job.cancel, self._progress(job)), name
        raise RequestError(f"{request.type}: not a job")

    def _progress(self, job: _Job) -> Callable[[str], None]:
        def say(text: str) -> None:
            job.progress = text
            self.publish("job", name=job.name, state="running", text=text)
        return say

    def _run_job(self, job: _Job, run: Callable[[_Job], str]) -> None:
        try:
            outcome = run(job)
        except HaltedError as exc:
            self._end_job(job, "stopped", f"{job.name}: stopped ({self.arm.bus.halted or 'stop'})"
                          + "".join(f"; {note}" for note in getattr(exc, "notes", [])))
        except BusArmError as exc:
            self.arm.bus.emergency_stop()
            self._end_job(job, "failed", f"{job.name}: {exc}; every servo holds"
                          + "".join(f"; {note}" for note in getattr(exc, "notes", [])))
        except Exception as exc:  # a bug must not leave the arm moving nor kill the server
            log.exception("job %s", job.name)
            self.arm.bus.emergency_stop()
            self._end_job(job, "failed", f"{job.name}: {type(exc).__name__}: {exc}; every "
                                         "servo holds")
        else:
            self._end_job(job, "done", outcome)
        finally:
            # A twin renders in the thread that asks (pick-sort's camera): free this
            # thread's GL contexts here, or they are freed at exit from another thread,
            # which EGL refuses (EGL_BAD_ACCESS, a traceback on Ctrl+C).
            if self.robot.sim is not None:
                self.robot.sim.release_renderers()

    def _end_job(self, job: _Job, state: str, text: str) -> None:
        with self._lock:
            self._job = None
            if self._rearm_after is not None and self.arm.bus.halted == self._rearm_after:
                self.arm.bus.rearm()  # the stop that cut it short was not an e-stop
            self._rearm_after = None
        self.publish("job", name=job.name, state=state, text=text)
        if job.name in MOBILE_JOBS:  # a map made, points set up: the page's lists change
            self.publish("robot", robot=self.describe())
        self.log(text, "info" if state == "done" else "error" if state == "failed" else "warning")

    # ------------------------------------------------------------------ control thread

    def _run(self) -> None:
        next_at = time.monotonic()
        while not self._closed.is_set():
            self._tick()
            next_at += self.period_s
            delay = next_at - time.monotonic()
            if delay < 0:  # late (a slow bus): start again from now, do not race
                next_at, delay = time.monotonic(), 0.0
            self._closed.wait(delay)

    def _tick(self) -> None:
        state: dict[str, Any]
        try:
            reading = self.reader.read()
        except BusArmError as exc:
            self._stop_jog(f"the robot did not answer: {exc}")
            state = {"error": f"the robot did not answer: {exc}"}
        else:
            self._jog_tick(reading.joints_deg)
            state = self.reader.as_dict(reading)
        with self._lock:
            job, jog = self._job, self._jog
            state.update({
                "t": round(time.time(), 3), "driver": self.driver,
                "halted": self.arm.bus.halted,
                "job": None if job is None else {"name": job.name, "text": job.progress},
                "jog": None if jog is None else {"joint": jog.joint, "axis": jog.axis,
                                                 "direction": jog.direction},
                "recording": (None if self.recorder.frames is None
                              else len(self.recorder.frames)),
                "map": self.mobile.view.sequence if self.mobile.available else None,
                "has_map": self.mobile.has_map,
            })
        if self.teleop is not None:
            state["base"] = self.teleop.state()
            state["lidar_error"] = None if self.scans is None else self.scans.error
        self.last_state = state
        self.publish("state", **state)
