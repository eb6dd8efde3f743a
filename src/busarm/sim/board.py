"""A simulated controller board: the vendor's STM32 board behind the same bytes.

``SimBoard`` speaks the board's frames to the host (1,000,000 baud) and the LX protocol
to the simulated servos behind it (a ``SimBus``, or a twin's), as the firmware does: a
multi-servo move becomes one MOVE_TIME_WRITE per servo, a read becomes the LX read and
its reply's value, or status -1 when the servo does not answer in time. It also hosts
four wheel motors with encoders (a first-order speed loop, as the firmware's PID at 100
Hz behaves from outside), an IMU and a battery, and streams IMU and battery reports on
its own as the real board does. It is a "line" like ``SimBus``: ``SimTransport`` serves
it in-process and ``PtyServer`` on a pseudo-terminal.

Rates and timings the vendor does not publish are this model's choices, named below.
"""

from __future__ import annotations

import math
import random
import struct
import threading
from collections import deque
from dataclasses import dataclass, field

from busarm.clock import Clock
from busarm.errors import ConfigError, ProtocolError
from busarm.protocol import Command, FrameParser, encode_request
from busarm.protocol.board import (
    BOARD_BAUDRATE,
    LX_COMMANDS,
    READ_FORMATS,
    WRITE_FORMATS,
    Battery,
    BatteryWarning,
    BoardFrameParser,
    BoardRequest,
    BuzzerBeep,
    ImuSample,
    KeyEvent,
    KeyEventKind,
    LedBlink,
    MotorDuties,
    MotorEncoders,
    MotorSpeeds,
    OledText,
    PwmServoMove,
    PwmServoRead,
    PwmServoReply,
    PwmServoSetOffset,
    PwmSub,
    RgbSet,
    ServoMove,
    ServoRead,
    ServoReply,
    ServoStop,
    ServoSub,
    ServoWrite,
    decode_request,
)
from busarm.protocol.commands import SPECS
from busarm.protocol.frames import Frame
from busarm.sim.bus import DUE_EPS_S, SimBus, WireTiming

__all__ = [
    "BATTERY_HZ",
    "ENCODER_TICKS_PER_REV",
    "HALF_SPREAD_M",
    "IMU_HZ",
    "OUT_CAP_BYTES",
    "PWM_START_US",
    "SERVO_REPLY_WAIT_S",
    "TX_QUEUE_S",
    "WHEEL_DIAMETER_M",
    "WHEEL_MAX_REV_S",
    "WHEEL_TIME_CONSTANT_S",
    "BoardFaults",
    "BoardLog",
    "SimBoard",
    "SimPwmServo",
    "SimWheel",
]


SERVO_REPLY_WAIT_S = 0.010
"""How long the simulated firmware waits for a servo's LX reply before answering -1."""
IMU_HZ = 100.0
BATTERY_HZ = 2.0
WHEEL_MAX_REV_S = 1.5
"""The firmware's speed limit (field notes: about 1.5 rev/s); faster commands are clamped."""
WHEEL_TIME_CONSTANT_S = 0.08
ENCODER_TICKS_PER_REV = 3960
WHEEL_DIAMETER_M = 0.0965
HALF_SPREAD_M = (0.218 + 0.195) / 2
"""The JetAuto chassis (busarm.base's jetauto.toml), for the gyro of a board with no twin:
it turns as the wheels would turn that base (motors 1, 2 on the left, mounted mirrored)."""
OUT_CAP_BYTES = 4096
"""Reports the host has not read beyond this are dropped, oldest first (a full tty buffer)."""
TX_QUEUE_S = 0.002
"""The firmware's transmit queue, in line time: a streamed report that would wait longer
for the line is skipped, so reports asked for faster than the line carries cost reports,
not a backlog that delays every reply behind it."""
PWM_START_US = 1500
"""A PWM servo's pulse before its first move (this model's choice: the vendor does not say)."""
_MAX_CATCH_UP_S = 0.2  # streams restart from now after a longer gap, not with a burst


@dataclass
class BoardFaults:
    """Faults to inject at the board: a silent board, damaged or misaddressed replies."""

    silent: bool = False
    corrupt_rate: float = 0.0
    wrong_id_rate: float = 0.0
    seed: int = 0


@dataclass
class SimWheel:
    """One wheel motor: its commanded and actual speed (rev/s) and encoder count."""

    target_rev_s: float = 0.0
    rev_s: float = 0.0
    turns: float = 0.0

    @property
    def encoder_ticks(self) -> int:
        return math.floor(self.turns * ENCODER_TICKS_PER_REV)

    def advance(self, dt_s: float) -> None:
        if dt_s <= 0.0:
            return
        k = 1.0 - math.exp(-dt_s / WHEEL_TIME_CONSTANT_S)
        before = self.rev_s
        self.rev_s += (self.target_rev_s - self.rev_s) * k
        self.turns += 0.5 * (before + self.rev_s) * dt_s


@dataclass
class SimPwmServo:
    """One PWM servo header: its pulse moves linearly to the target over the duration, as
    the firmware's interpolation does; the offset is kept, as the firmware keeps it."""

    start_us: int = PWM_START_US
    target_us: int = PWM_START_US
    start_s: float = 0.0
    duration_s: float = 0.0
    offset: int = 0

    def pulse_us(self, now_s: float) -> int:
        if self.duration_s <= 0.0 or now_s >= self.start_s + self.duration_s:
            return self.target_us
        share = max(0.0, now_s - self.start_s) / self.duration_s
        return round(self.start_us + (self.target_us - self.start_us) * share)

    def move(self, pulse_us: int, duration_s: float, now_s: float) -> None:
        self.start_us, self.start_s = self.pulse_us(now_s), now_s
        self.target_us, self.duration_s = pulse_us, duration_s


@dataclass
class _PendingRead:
    request: ServoRead
    command: Command
    deadline: float


@dataclass
class BoardLog:
    """What the board was told to do with its LED and buzzer, and what it refused."""

    led: list[LedBlink] = field(default_factory=list)
    buzzer: list[BuzzerBeep] = field(default_factory=list)
    oled: dict[int, str] = field(default_factory=dict)
    """The OLED's lines by number, as last set."""
    rgb: dict[int, tuple[int, int, int]] = field(default_factory=dict)
    """The RGB pixels by number (from 1), as last set."""
    duties: list[MotorDuties] = field(default_factory=list)
    battery_warning_v: float | None = None
    rejected_frames: int = 0


class SimBoard:
    """The controller board in front of ``servos``. Thread-safe."""

    framing = "board"

    def __init__(self, servos: SimBus, *, imu_hz: float = IMU_HZ,
                 battery_hz: float = BATTERY_HZ, battery_v: float = 12.3,
                 faults: BoardFaults | None = None, seed: int = 0,
                 encoders: bool = True) -> None:
        self.servos = servos
        self.clock: Clock = servos.clock
        self.timing = WireTiming(BOARD_BAUDRATE, turnaround_s=0.0)
        self.faults = faults or BoardFaults()
        self.wheels = [SimWheel() for _ in range(4)]
        self.pwm_servos = [SimPwmServo() for _ in range(4)]
        """The PWM servo headers, port 1 first."""
        self.battery_v = battery_v
        self.imu_gyro_rad_s = (0.0, 0.0, 0.0)
        """What the IMU's gyro measures now (before noise); a mobile twin sets it."""
        self.imu_follows_wheels = True
        """Whether the gyro's z also reads the yaw rate the wheels give a JetAuto base (a
        board on a base with no twin); a mobile twin turns this off and sets the gyro."""
        self.imu_accel_mps2 = (0.0, 0.0, 9.80665)
        self.imu_heading_rad: float | None = None
        """The heading the gyro integrates to (rad, unwrapped; a mobile twin sets it every
        step): each IMU sample adds its mean rate since the last sample to the gyro's z."""
        self._heading_seen = (0.0, -math.inf)
        self.encoder_noise_ticks = 0.0
        """Standard deviation of a count's jitter in each report (a mobile twin sets it);
        it does not accumulate: the counter itself stays true to the wheel."""
        self.log = BoardLog()
        self._rng = random.Random(seed)
        self._fault_rng = random.Random(self.faults.seed)
        self._lock = threading.RLock()
        self._parser = BoardFrameParser()
        self._lx = FrameParser()
        self._jobs: deque[BoardRequest] = deque()
        self._read: _PendingRead | None = None
        self._out: list[tuple[float, bytes, bool]] = []  # (due, bytes, is a stream report)
        self._line_in_free = 0.0
        self._line_out_free = 0.0
        now = self.clock.now()
        self._periods = {"imu": 1.0 / imu_hz if imu_hz > 0 else 0.0,
                         "battery": 1.0 / battery_hz if battery_hz > 0 else 0.0}
        # busarm's MotorEncoders report, at the IMU's rate (the stock firmware has none).
        self._periods["encoders"] = self._periods["imu"] if encoders else 0.0
        self._next = {name: now + period for name, period in self._periods.items()}
        self._wheels_at = now

    # ------------------------------------------------------------------ the host's side

    def receive(self, data: bytes) -> None:
        """Bytes the host sent."""
        with self._lock:
            now = self.clock.now()
            done = max(now, self._line_in_free) + len(data) * self.timing.byte_s
            self._line_in_free = done
            if self.faults.silent:
                return
            parser = self._parser
            refused = parser.crc_failures + parser.unknown_funcs  # damaged, or no board's
            for frame in parser.feed(data):
                try:
                    self._jobs.append(decode_request(frame))
                except ProtocolError:
                    self.log.rejected_frames += 1
            self.log.rejected_frames += parser.crc_failures + parser.unknown_funcs - refused
            self._run_jobs(now)

    def pop_output(self, max_bytes: int | None = None) -> bytes:
        """The bytes due on the host's side by now."""
        with self._lock:
            now = self.clock.now() + DUE_EPS_S
            self._pump(now)
            out = bytearray()
            while self._out and self._out[0][0] <= now:
                due, data, stream = self._out.pop(0)
                if max_bytes is not None and len(out) + len(data) > max_bytes:
                    keep = max_bytes - len(out)
                    out += data[:keep]
                    self._out.insert(0, (due, data[keep:], stream))
                    break
                out += data
            return bytes(out)

    def next_output_at(self) -> float | None:
        """When something is next due: a reply, a report, or a servo's answer to relay."""
        with self._lock:
            self._pump(self.clock.now() + DUE_EPS_S)
            due = [t for t in self._next.values() if not self.faults.silent and t > 0]
            if self._out:
                due.append(self._out[0][0])
            if self._read is not None:
                lx = self.servos.next_output_at()
                due.append(self._read.deadline if lx is None else min(lx, self._read.deadline))
            return min(due) if due else None

    def power_off(self) -> None:
        self.servos.power_off()

    # ------------------------------------------------------------------ test hooks

    def press_key(self, key_id: int = 1, event: KeyEventKind = KeyEventKind.CLICK) -> None:
        """The board's button ``key_id`` did ``event`` (reported at once)."""
        with self._lock:
            self._send(self.clock.now(), KeyEvent(key_id, event).encode(), stream=True)

    def inject(self, data: bytes) -> None:
        """Put ``data`` on the host's line now (garbage, a stray frame)."""
        with self._lock:
            self._send(self.clock.now(), data, stream=False)

    # ------------------------------------------------------------------ firmware

    def _run_jobs(self, now: float) -> None:
        while self._read is None and self._jobs:
            job = self._jobs.popleft()
            try:
                self._run(job, now)
            except ConfigError:  # a value no LX frame can carry: the firmware sends nothing
                self.log.rejected_frames += 1

    def _run(self, job: BoardRequest, now: float) -> None:
        if isinstance(job, ServoRead):
            command = LX_COMMANDS[job.sub]
            lx = encode_request(job.servo_id, command)
            self.servos.pop_output()  # nothing old is taken for this answer
            self._lx = FrameParser()
            self.servos.receive(lx)
            spec = SPECS[command]
            wire = (len(lx) + (spec.reply_length or 0) + 3) * self.servos.timing.byte_s
            self._read = _PendingRead(job, command, now + wire + SERVO_REPLY_WAIT_S)
        elif isinstance(job, ServoMove):
            # The firmware clamps a position above 1000 to 1000 and moves every servo.
            frames = [encode_request(sid, Command.MOVE_TIME_WRITE, min(pulses, 1000),
                                     min(job.duration_ms, 30000))
                      for sid, pulses in job.targets]  # all checked before any is sent
            for frame in frames:
                self.servos.receive(frame)
        elif isinstance(job, ServoStop):
            for sid in job.servo_ids:
                self.servos.receive(encode_request(sid, Command.MOVE_STOP))
        elif isinstance(job, ServoWrite):
            self._servo_write(job)
        elif isinstance(job, MotorSpeeds):
            self._advance_wheels(now)
            for motor, rev_s in job.speeds:
                if math.isfinite(rev_s):
                    clamped = max(-WHEEL_MAX_REV_S, min(WHEEL_MAX_REV_S, rev_s))
                    self.wheels[motor - 1].target_rev_s = clamped
        elif isinstance(job, PwmServoMove | PwmServoRead | PwmServoSetOffset):
            self._pwm(job, now)
        else:
            self._log(job)

    def _log(self, job: BoardRequest) -> None:
        """What the board shows or sounds: kept for tests to see."""
        if isinstance(job, LedBlink):
            self.log.led.append(job)
        elif isinstance(job, BuzzerBeep):
            self.log.buzzer.append(job)
        elif isinstance(job, OledText):
            self.log.oled[job.line] = job.text
        elif isinstance(job, RgbSet):
            self.log.rgb.update({p: (r, g, b) for p, r, g, b in job.pixels})
        elif isinstance(job, MotorDuties):
            self.log.duties.append(job)  # open-loop drive is not modelled: wheels keep on
        elif isinstance(job, BatteryWarning):
            self.log.battery_warning_v = job.threshold_v

    def _pwm(self, job: PwmServoMove | PwmServoRead | PwmServoSetOffset, now: float) -> None:
        """The firmware's PWM handler: it answers every read for ports 1..4 at once."""
        if isinstance(job, PwmServoMove):
            for port, pulse_us in job.targets:
                self.pwm_servos[port - 1].move(pulse_us, job.duration_ms / 1000.0, now)
        elif isinstance(job, PwmServoSetOffset):
            self.pwm_servos[job.port - 1].offset = job.offset
        else:
            servo = self.pwm_servos[job.port - 1]
            value = servo.pulse_us(now) if job.sub is PwmSub.READ_POSITION else servo.offset
            self._send(now, PwmServoReply(job.port, job.sub, value).encode(), stream=False)

    def _servo_write(self, job: ServoWrite) -> None:
        """The LX write the firmware sends: its own clamping, no other check (what the
        servo then does with a value its manual does not allow is the servo's business)."""
        args = _firmware_args(job)
        fmt = "<" + "B" * len(args) if job.sub in _TORQUE else "<" + WRITE_FORMATS[job.sub][2:]
        frame = Frame(job.servo_id, int(LX_COMMANDS[job.sub]), struct.pack(fmt, *args))
        self.servos.receive(frame.to_bytes())

    def _pump(self, now: float) -> None:
        """Relay a servo's answer, time out a read, move the wheels, stream reports."""
        read = self._read
        if read is not None:
            reply = self._lx_answer(read)
            if reply is None and now >= read.deadline:
                reply = ServoReply(read.request.servo_id, read.request.sub, -1,
                                   (0,) * (len(READ_FORMATS[read.request.sub]) - 1))
            if reply is not None:
                self._read = None
                self._send(now, self._mangle(reply), stream=False)
                self._run_jobs(now)
        self._advance_wheels(now)
        if not self.faults.silent:
            self._stream(now)

    def _lx_answer(self, read: _PendingRead) -> ServoReply | None:
        for frame in self._lx.feed(self.servos.pop_output()):
            asked = read.request.servo_id
            if frame.command == int(read.command) and (frame.servo_id == asked or asked == 254):
                fmt = READ_FORMATS[read.request.sub]
                try:
                    values = struct.unpack(fmt, frame.params)
                except struct.error:
                    continue
                return ServoReply(asked, read.request.sub, 0, tuple(int(v) for v in values))
        return None

    def _mangle(self, reply: ServoReply) -> bytes:
        f, rng = self.faults, self._fault_rng
        if f.wrong_id_rate and rng.random() < f.wrong_id_rate:
            reply = ServoReply((reply.servo_id % 253) + 1, reply.sub, reply.status, reply.values)
        data = bytearray(reply.encode())
        if f.corrupt_rate and rng.random() < f.corrupt_rate:
            data[rng.randrange(2, len(data))] ^= rng.randrange(1, 256)
        return bytes(data)

    def motor_rev_s(self, now: float) -> tuple[float, float, float, float]:
        """Each motor's actual speed at ``now`` (rev/s, as mounted), the board brought up
        to then: its speed loops, encoders and report streams (a mobile twin moves the
        base by them every step, so reports carry the state of their own time). Servo
        traffic waits for the host's side, as before."""
        with self._lock:
            self._advance_wheels(now)
            if not self.faults.silent:
                self._stream(now)
            a, b, c, d = (w.rev_s for w in self.wheels)
            return a, b, c, d

    def _advance_wheels(self, now: float) -> None:
        dt = now - self._wheels_at
        if dt > 0:
            for wheel in self.wheels:
                wheel.advance(dt)
            self._wheels_at = now

    def _stream(self, now: float) -> None:
        for name, period in self._periods.items():
            if period <= 0:
                continue
            due = self._next[name]
            if now - due > _MAX_CATCH_UP_S:
                due = now - _MAX_CATCH_UP_S
            while due <= now:
                if self._line_out_free - due <= TX_QUEUE_S:
                    self._send(due, self._report(name, due), stream=True)
                due += period
            self._next[name] = due

    def _report(self, name: str, at_s: float) -> bytes:
        gauss = self._rng.gauss
        if name == "battery":
            return Battery(round(self.battery_v + gauss(0.0, 0.01), 3)).encode()
        if name == "encoders":
            noise = self.encoder_noise_ticks
            a, b, c, d = (_int32(w.encoder_ticks + (round(gauss(0.0, noise)) if noise else 0))
                          for w in self.wheels)
            return MotorEncoders((a, b, c, d)).encode()
        ax, ay, az = self.imu_accel_mps2
        gx, gy, gz = self.imu_gyro_rad_s
        if self.imu_heading_rad is not None:
            # The rate of turn since the last sample, as an IMU's filter averages it: no
            # turn between two samples goes unseen.
            heading, since = self._heading_seen
            if at_s > since:
                gz += (self.imu_heading_rad - heading) / (at_s - since)
            self._heading_seen = (self.imu_heading_rad, at_s)
        if self.imu_follows_wheels:
            gz += (sum(w.rev_s for w in self.wheels) * math.pi * WHEEL_DIAMETER_M
                   / (4.0 * HALF_SPREAD_M))
        return ImuSample((ax + gauss(0, 0.02), ay + gauss(0, 0.02), az + gauss(0, 0.02)),
                         (gx + gauss(0, 0.001), gy + gauss(0, 0.001),
                          gz + gauss(0, 0.001))).encode()

    def _send(self, now: float, data: bytes, *, stream: bool) -> None:
        start = max(now, self._line_out_free)
        due = start + len(data) * self.timing.byte_s
        self._line_out_free = due
        self._out.append((due, data, stream))
        if len(self._out) > 1 and self._out[-2][0] > due:
            self._out.sort(key=lambda item: item[0])
        backlog = sum(len(d) for _, d, _ in self._out)
        while backlog > OUT_CAP_BYTES:
            oldest = next((i for i, item in enumerate(self._out) if item[2]), None)
            if oldest is None:
                break
            backlog -= len(self._out.pop(oldest)[1])


_TORQUE = (ServoSub.TORQUE_OFF, ServoSub.TORQUE_ON)


def _firmware_args(job: ServoWrite) -> tuple[int, ...]:
    """The LX values the firmware writes for ``job``: it clamps and orders limits
    (``serial_servo_set_temp_limit``, ``_set_angle_limit``, ``_set_vin_limit``)."""
    sub, values = job.sub, job.values
    if sub is ServoSub.TORQUE_OFF:
        return (0,)
    if sub is ServoSub.TORQUE_ON:
        return (1,)
    if sub is ServoSub.SET_TEMP_LIMIT:
        return (min(values[0], 100),)
    if sub is ServoSub.SET_ANGLE_LIMITS:
        low, high = (min(v, 1000) for v in values)
        return min(low, high), max(low, high)
    if sub is ServoSub.SET_VOLTAGE_LIMITS:
        low, high = max(values[0], 4500), min(values[1], 14000)
        return min(low, high), max(low, high)
    return values


def _int32(ticks: int) -> int:
    """An encoder count as a 32-bit counter holds it (it wraps)."""
    return (ticks + 2**31) % 2**32 - 2**31
