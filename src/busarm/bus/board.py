"""The vendor's controller board on one serial link: typed calls, every read timed out.

``BoardLink`` writes the board's frames and reads its stream, in which the board mixes
its own reports (IMU, battery, keys) with the answers to our reads. A servo read is
matched by function, servo ID and sub-command; everything else in between is kept (the
latest IMU sample and battery voltage, the key presses) or counted, never taken for the
answer. Each read has a deadline derived from both legs of the trip (the host link at
1,000,000 baud, the servo line behind the board) and a bounded number of attempts: a
silent board, a garbled or misaddressed reply, or a flood of reports ends in a typed
error, never a hang (the vendor's SDK waits for ever in one version) or a wrong value.

The board offers no raw pass-through to the servo line: what the LX protocol can do and
the board's sub-commands cannot (motor mode, the servos' LEDs, the queued move of
MOVE_TIME_WAIT_WRITE) raises UnsupportedError.
"""

from __future__ import annotations

import math
import struct
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from busarm.bus.transport import Transport
from busarm.errors import (
    BusTimeoutError,
    ChecksumError,
    ConfigError,
    HaltedError,
    ProtocolError,
)
from busarm.protocol import SERVO_TURNAROUND_S, SPECS
from busarm.protocol.board import (
    FRAME_OVERHEAD,
    LX_COMMANDS,
    MOTOR_COUNT,
    READ_FORMATS,
    Battery,
    BoardFrameParser,
    BoardReport,
    BoardRequest,
    BuzzerBeep,
    ImuSample,
    KeyEvent,
    LedBlink,
    MotorEncoders,
    MotorSpeeds,
    PwmServoMove,
    PwmServoRead,
    PwmServoReply,
    PwmSub,
    ServoRead,
    ServoReply,
    ServoSub,
    decode_report,
)
from busarm.units import check_int_range, check_range, range_text

__all__ = [
    "BOARD_SERVO_WAIT_S",
    "DEFAULT_MARGIN_S",
    "DEFAULT_RETRIES",
    "PWM_MAX_US",
    "PWM_MIN_US",
    "REPORT_MAX_DATA",
    "SERVO_LINE_BAUDRATE",
    "WHEEL_LIMIT_REV_S",
    "BoardLink",
    "BoardReadings",
]


SERVO_LINE_BAUDRATE = 115200
"""The servo line behind the board (the LX servos' rate)."""
BOARD_SERVO_WAIT_S = 0.012
"""Allowance for the board's own wait on a servo before it answers -1 (not published by
the vendor: generous)."""
DEFAULT_MARGIN_S = 0.004
DEFAULT_RETRIES = 2
WHEEL_LIMIT_REV_S = 1.5
"""The firmware's wheel speed limit (about 1.5 rev/s): faster commands are refused."""
REPORT_MAX_DATA = 64
"""The longest frame the board sends (an SBUS report has 36 data bytes)."""
PWM_MIN_US = 500
PWM_MAX_US = 2500
"""The hobby servo pulse range the PWM headers are driven in (us): the vendor's SDK
examples stay within it; the firmware itself passes any uint16 on."""
_READ_CHUNK = 4096
_POLL_MAX_BYTES = 16 * _READ_CHUNK


@dataclass
class BoardReadings:
    """The latest of what the board reports on its own, with when it came (link clock)."""

    imu: ImuSample | None = None
    imu_at_s: float = -math.inf
    battery_v: float | None = None
    battery_at_s: float = -math.inf
    encoders: MotorEncoders | None = None
    """The latest encoder counts (busarm's extension: the stock firmware sends none)."""
    encoders_at_s: float = -math.inf
    keys: deque[KeyEvent] = field(default_factory=lambda: deque(maxlen=64))
    reports: int = 0
    stray_replies: int = 0
    """Servo replies that answered nothing asked (late, or for another servo)."""


class BoardLink:
    """One controller board on ``transport`` (framing ``board``). Thread-safe."""

    def __init__(self, transport: Transport, *, timeout_margin_s: float = DEFAULT_MARGIN_S,
                 retries: int = DEFAULT_RETRIES,
                 wheel_limit_rev_s: float = WHEEL_LIMIT_REV_S) -> None:
        if transport.framing != "board":
            raise ConfigError(f"{transport.name} is not a controller board's port "
                              "(give board:///dev/ttyACM0, or board://sim)")
        self.transport = transport
        self.clock = transport.clock
        self.timeout_margin_s = check_range("timeout_margin_s", timeout_margin_s, 0.0, 1.0, "s")
        self.retries = retries
        self.wheel_limit_rev_s = wheel_limit_rev_s
        self.readings = BoardReadings()
        self.wheel_targets_rev_s: dict[int, float] = {}
        """What each wheel motor was last told on this link (rev/s), by motor number."""
        self.wheels_halted: str | None = None
        """Why the wheels are latched stopped (the bus's ``halt``), or None: while set, a
        speed other than 0 raises HaltedError (a stop still goes out)."""
        self._parser = BoardFrameParser(max_data_len=REPORT_MAX_DATA)
        self._lock = threading.RLock()
        self._depth = 0  # how deep the link is in use (its lock is re-entrant)
        self._listeners: list[Callable[[BoardReport, float], None]] = []
        self._last_report_s = -math.inf
        self._host_byte_s = 10.0 / transport.baudrate
        self.servo_byte_s = 10.0 / SERVO_LINE_BAUDRATE
        self._attempt_s = {sub: self._attempt_deadline_s(sub) for sub in READ_FORMATS}

    # ------------------------------------------------------------------ writing

    def write(self, request: BoardRequest) -> None:
        """Send one request (encoded first: a bad value raises before anything is sent)."""
        data = request.encode()
        with self._held():
            self.transport.write(data)

    def set_motor_speeds(self, speeds_rev_s: dict[int, float]) -> None:
        """Wheel motors 1..4 at these speeds (rev/s); every speed is checked first."""
        for motor, rev_s in speeds_rev_s.items():
            if isinstance(motor, bool) or motor not in range(1, MOTOR_COUNT + 1):
                raise ConfigError(f"motor = {motor!r}; allowed: 1..{MOTOR_COUNT}")
            limit = self.wheel_limit_rev_s
            if isinstance(rev_s, float) and not math.isfinite(rev_s):  # said with the range
                raise ConfigError(f"motor {motor} speed = {rev_s} rev/s is out of range "
                                  f"{range_text(-limit, limit, 'rev/s')}")
            check_range(f"motor {motor} speed", rev_s, -limit, limit, "rev/s")
        if speeds_rev_s:
            request = MotorSpeeds(tuple(sorted(speeds_rev_s.items())))
            with self._held():  # checked and sent under the lock: a halt is before or after
                if self.wheels_halted is not None and any(speeds_rev_s.values()):
                    raise HaltedError(f"wheel speeds refused: the robot is halted "
                                      f"({self.wheels_halted}); re-arm it first")
                self.write(request)
                self.wheel_targets_rev_s.update(speeds_rev_s)

    def stop_motors(self) -> None:
        """Every wheel motor to 0 rev/s."""
        self.write(MotorSpeeds(tuple((m, 0.0) for m in range(1, MOTOR_COUNT + 1))))
        self.wheel_targets_rev_s = dict.fromkeys(range(1, MOTOR_COUNT + 1), 0.0)

    @property
    def wheels_turning(self) -> bool:
        """Whether this link last told a wheel motor to turn (and not to stop since)."""
        return any(rev_s != 0.0 for rev_s in self.wheel_targets_rev_s.values())

    def beep(self, freq_hz: int = 2400, on_s: float = 0.1, off_s: float = 0.0,
             repeat: int = 1) -> None:
        """Sound the buzzer ``repeat`` times."""
        check_range("freq_hz", freq_hz, 0, 20000, "Hz")
        self.write(BuzzerBeep(int(freq_hz), _ms("on_s", on_s), _ms("off_s", off_s),
                              _count(repeat)))

    def blink(self, led_id: int = 1, on_s: float = 0.1, off_s: float = 0.1,
              repeat: int = 1) -> None:
        """Blink the board's LED ``repeat`` times (0: until told otherwise)."""
        check_range("led_id", led_id, 1, 255)
        self.write(LedBlink(int(led_id), _ms("on_s", on_s), _ms("off_s", off_s),
                            _count(repeat)))

    def pwm_move(self, pulses_us: dict[int, int], duration_s: float = 0.0) -> None:
        """PWM servos on ports 1..4 to these pulse widths (us) in ``duration_s``; every
        value is checked first (a bad one raises, naming it and its range; nothing sent)."""
        if not pulses_us:
            raise ConfigError("PWM move of no port: give at least one of ports 1..4")
        targets = tuple((check_int_range("PWM port", port, 1, 4),
                         check_int_range(f"PWM port {port} pulse_us", pulse_us, PWM_MIN_US,
                                         PWM_MAX_US, "us"))
                        for port, pulse_us in sorted(pulses_us.items()))
        self.write(PwmServoMove(_ms("duration_s", duration_s), targets))

    def pwm_read_us(self, port: int, *, retries: int | None = None) -> int:
        """The pulse (us) the board drives PWM port ``port`` with now (mid-move: on the
        way); BusTimeoutError if no answer came in ``retries + 1`` attempts."""
        check_int_range("PWM port", port, 1, 4)
        data = PwmServoRead(PwmSub.READ_POSITION, port).encode()
        attempt_s = (self._host_byte_s * (2 * FRAME_OVERHEAD + 6) + BOARD_SERVO_WAIT_S
                     + self.transport.latency_s + self.timeout_margin_s)
        attempts = (self.retries if retries is None else retries) + 1
        with self._held():
            for _ in range(attempts):
                self.poll()
                self.transport.write(data)
                deadline = self.clock.now() + attempt_s
                while (remaining := deadline - self.clock.now()) > 0:
                    for report in self._take(self.transport.read(_READ_CHUNK, remaining)):
                        if (isinstance(report, PwmServoReply) and report.port == port
                                and report.sub is PwmSub.READ_POSITION):
                            return report.value
        raise BusTimeoutError(f"PWM servo port {port} through the controller board: no "
                              f"answer in {attempts} attempt(s)", timeout_s=attempt_s)

    # ------------------------------------------------------------------ reading

    def read_budget_s(self, sub: ServoSub) -> float:
        """The longest one servo read can take before it returns or raises."""
        return (self.retries + 1) * self.attempt_s(sub)

    def attempt_s(self, sub: ServoSub) -> float:
        """One attempt's deadline: both legs on the wire, the servo's and the board's
        turnaround, the adapter's latency and the margin."""
        return self._attempt_s[sub]

    def _attempt_deadline_s(self, sub: ServoSub) -> float:
        request_and_reply = (FRAME_OVERHEAD + 2) + (FRAME_OVERHEAD + 3 + _value_size(sub))
        host = request_and_reply * self._host_byte_s
        spec = SPECS[LX_COMMANDS[sub]]
        servo = (6 + (spec.reply_length or 0) + 3) * self.servo_byte_s
        return (host + servo + SERVO_TURNAROUND_S + BOARD_SERVO_WAIT_S
                + self.transport.latency_s + self.timeout_margin_s)

    def servo_read(self, sub: ServoSub, servo_id: int, *, retries: int | None = None
                   ) -> ServoReply:
        """One servo's value; BusTimeoutError or ProtocolError (typed) when no good answer
        came in ``retries + 1`` attempts."""
        request = ServoRead(sub, servo_id)
        data = request.encode()
        attempts = (self.retries if retries is None else retries) + 1
        problems: list[str] = []
        garbled = False
        with self._held():
            for _ in range(attempts):
                self.poll()  # what came before is not the answer: keep its reports
                damaged_before = self._damaged()
                self.transport.write(data)
                reply, other = self._await_reply(sub, servo_id, self.attempt_s(sub))
                if reply is not None and reply.ok:
                    return reply
                damaged = self._damaged() > damaged_before
                garbled |= damaged
                problems.append("the board said the servo did not answer (status -1)"
                                if reply is not None else
                                f"a reply for servo {other} came instead" if other is not None
                                else "damaged frames came back" if damaged
                                else "nothing came back")
        return self._fail(sub, servo_id, problems, garbled)

    def _await_reply(self, sub: ServoSub, servo_id: int, timeout_s: float
                     ) -> tuple[ServoReply | None, int | None]:
        deadline = self.clock.now() + timeout_s
        other: int | None = None
        while True:
            remaining = deadline - self.clock.now()
            chunk = self.transport.read(_READ_CHUNK, remaining) if remaining > 0 else b""
            if not chunk:
                return None, other
            for report in self._take(chunk):
                if isinstance(report, ServoReply):
                    if report.sub is sub and report.servo_id == servo_id:
                        return report, None
                    self.readings.stray_replies += 1
                    if report.sub is sub:
                        other = report.servo_id

    def _damaged(self) -> int:
        # A damaged frame fails its CRC, or (its header or length hit) is skipped as noise.
        return self._parser.crc_failures + self._parser.skipped_bytes

    def _fail(self, sub: ServoSub, servo_id: int, problems: list[str], garbled: bool
              ) -> ServoReply:
        name = sub.name.lower().replace("_", " ")
        said = "; ".join(sorted(set(problems), key=problems.index))
        tries = f" in {len(problems)} attempts" if len(problems) > 1 else ""
        text = f"servo {servo_id} {name} through the controller board: no answer{tries} ({said})"
        if garbled:
            raise ChecksumError(text + ": check the USB cable")
        if any("instead" in p for p in problems):
            raise ProtocolError(text)
        raise BusTimeoutError(text, servo_id=servo_id, command=int(LX_COMMANDS[sub]),
                              timeout_s=self.attempt_s(sub))

    @contextmanager
    def _held(self) -> Iterator[None]:
        with self._lock:
            self._depth += 1
            try:
                yield
            finally:
                self._depth -= 1

    def add_listener(self, listener: Callable[[BoardReport, float], None]) -> None:
        """Call ``listener(report, at_s)`` for every report the board sends, in order,
        whoever reads it (a servo read, a poll): odometry must see every encoder and IMU
        report, not only the latest. It runs with the link in use: it must only take note
        (no lock another thread may hold, no link call)."""
        self._listeners.append(listener)

    def poll_if_idle(self) -> list[BoardReport] | None:
        """``poll()`` unless the link is in use, by another thread or by this one further
        up its stack (a callback run while it waits on a simulated clock): None then."""
        if not self._lock.acquire(blocking=False):
            return None
        try:
            return None if self._depth else self.poll()
        finally:
            self._lock.release()

    def poll(self, timeout_s: float = 0.0) -> list[BoardReport]:
        """Read what the board has sent (waiting up to ``timeout_s`` for the first bytes);
        keep its reports; return them."""
        out: list[BoardReport] = []
        with self._held():
            chunks = [self.transport.read(_READ_CHUNK, timeout_s)]
            taken = len(chunks[0])
            # Bounded: a board reporting faster than this loop parses must not hold it.
            while chunks[-1] and taken < _POLL_MAX_BYTES:
                chunks.append(self.transport.read(_READ_CHUNK, 0.0))
                taken += len(chunks[-1])
            # Parsed as one: chunks read at one instant are dated back together (each
            # dated on its own, a full chunk's last frame would be dated after the next's).
            out += self._take(b"".join(chunks))
            # No read waits while polling: a servo reply here is a late or stray one.
            self.readings.stray_replies += sum(isinstance(r, ServoReply) for r in out)
        return out

    def check_talking(self, timeout_s: float = 1.0) -> None:
        """BusTimeoutError unless the board sends something within ``timeout_s`` (it
        reports its IMU and battery on its own: a silent port is not a working board)."""
        self._next_report(object, "report", timeout_s)

    def read_imu(self, timeout_s: float = 0.5) -> ImuSample:
        """The next IMU sample the board sends (BusTimeoutError if none in ``timeout_s``)."""
        imu = self._next_report(ImuSample, "IMU sample", timeout_s)
        assert isinstance(imu, ImuSample)
        return imu

    def read_battery_v(self, timeout_s: float = 2.0) -> float:
        """The battery voltage: the latest report if under a second old, else the next."""
        r = self.readings
        self.poll()
        if r.battery_v is not None and self.clock.now() - r.battery_at_s < 1.0:
            return r.battery_v
        battery = self._next_report(Battery, "battery report", timeout_s)
        assert isinstance(battery, Battery)
        return battery.voltage_v

    def key_events(self) -> list[KeyEvent]:
        """The board's button presses since the last call."""
        self.poll()
        with self._held():
            keys = list(self.readings.keys)
            self.readings.keys.clear()
        return keys

    def _next_report(self, kind: type, what: str, timeout_s: float) -> BoardReport:
        """The next report of ``kind`` the board sends (``object``: any)."""
        check_range("timeout_s", timeout_s, 0.0, 60.0, "s")
        with self._held():
            before = self.readings.reports
            deadline = self.clock.now() + timeout_s
            while True:
                for report in self.poll(max(deadline - self.clock.now(), 0.0)):
                    if isinstance(report, kind):
                        return report
                if self.clock.now() >= deadline:
                    others = self.readings.reports - before
                    came = f" (only {others} report(s) of other kinds)" if others else ""
                    raise BusTimeoutError(
                        f"{self.transport.name}: no {what} from the controller board in "
                        f"{timeout_s:g} s{came}: is it powered, and is this its port?",
                        timeout_s=timeout_s)

    def _take(self, chunk: bytes) -> list[BoardReport]:
        """Frames in ``chunk`` as reports, the readings kept up to date."""
        out: list[BoardReport] = []
        r = self.readings
        now = self.clock.now()
        frames = self._parser.feed(chunk)
        # Frames read together came one after another: each is dated back by the line time
        # of those behind it (a long read would otherwise stamp a burst all at once).
        byte_s = 10.0 / self.transport.baudrate if self.transport.baudrate else 0.0
        behind = [0] * len(frames)
        for k in range(len(frames) - 2, -1, -1):
            behind[k] = behind[k + 1] + len(frames[k + 1].data) + FRAME_OVERHEAD
        for frame, after in zip(frames, behind, strict=True):
            try:
                report = decode_report(frame)
            except ProtocolError:
                continue  # a frame no board sends: noise that happened to pass the CRC
            # Never before the last report: a read cut short by its size leaves the rest
            # of a burst to the next read, at the same instant, dated back less far.
            at = self._last_report_s = max(now - after * byte_s, self._last_report_s)
            for listener in self._listeners:
                listener(report, at)
            r.reports += 1
            if isinstance(report, ImuSample):
                r.imu, r.imu_at_s = report, at
            elif isinstance(report, Battery):
                r.battery_v, r.battery_at_s = report.voltage_v, at
            elif isinstance(report, MotorEncoders):
                r.encoders, r.encoders_at_s = report, at
            elif isinstance(report, KeyEvent):
                r.keys.append(report)
            out.append(report)
        return out

    def close(self) -> None:
        self.transport.close()


def _value_size(sub: ServoSub) -> int:
    return struct.calcsize(READ_FORMATS[sub])


def _ms(name: str, seconds: float) -> int:
    return round(check_range(name, seconds, 0.0, 65.535, "s") * 1000)


def _count(repeat: int) -> int:
    check_range("repeat", repeat, 0, 65535)
    return int(repeat)
