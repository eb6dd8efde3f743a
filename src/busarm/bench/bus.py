"""``busarm bench``: how fast the bus runs, beside what the wire allows.

Three measurements, each reported with the wire limit computed from the same baud
rate and servo turnaround: single-servo position reads, a full-arm state loop
(position, temperature and voltage of every servo) and an ID scan of 0..253. On
real hardware this is also the diagnostic to run first: a rate far below the wire
limit points at adapter latency or a noisy bus.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import statistics
import subprocess
import sys
import termios
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial

from busarm.bench.common import latency_percentiles_ms, machine_info
from busarm.bus.board import SERVO_LINE_BAUDRATE
from busarm.bus.board_bus import BoardServoBus
from busarm.bus.driver import DEFAULT_TIMEOUT_MARGIN_S, ServoBus
from busarm.bus.lx_port import LxServoPort
from busarm.bus.ports import PortSpec
from busarm.errors import BusArmError, ConfigError, TransportError
from busarm.progress import Progress, quiet
from busarm.protocol import MAX_SERVO_ID, SPECS, Command, encode_request
from busarm.protocol.board import ServoSub

__all__ = [
    "CPU_BATCH",
    "WARM_UP_READS",
    "BusBenchReport",
    "BusBenchResult",
    "ScanTimes",
    "SimServerProcess",
    "bench_os_floor",
    "bench_position_reads",
    "bench_scan",
    "bench_state_loop",
    "board_absent_id_s",
    "run_bench",
    "sim_pty_server",
]


WARM_UP_READS = 200


@dataclass
class ScanTimes:
    """What the ID scans found, and the best and median time of one scan."""

    found: list[int]
    best_s: float
    median_s: float
    board_absent_id_s: float | None = None
    """Through a controller board: how long the board takes to answer for an absent ID
    (its own wait for the servo, then "no answer"), measured; None on the LX line."""
    board_floor_s: float | None = None
    """Through a controller board: ``board_absent_id_s`` for each ID 0..253, about the
    least a scan through it can take (the board asks one servo at a time; the few
    present servos answer sooner)."""


@dataclass
class BusBenchResult:
    """One measurement: rate against the wire limit, latency percentiles, client CPU."""

    name: str
    unit: str
    count: int
    rate: float
    wire_limit: float
    latency_ms: dict[str, float] = field(default_factory=dict)
    """p50, p90, p99 and max (``latency_percentiles_ms``)."""
    cpu_us_median: float | None = None
    errors: int = 0
    scan: ScanTimes | None = None
    """The ID scan's times; None for the other measurements."""

    @property
    def ratio(self) -> float:
        return self.rate / self.wire_limit if self.wire_limit else 0.0

    def to_dict(self) -> dict[str, object]:
        d = asdict(self)
        del d["scan"]
        d["extra"] = asdict(self.scan) if self.scan is not None else {}
        d["ratio"] = round(self.ratio, 4)
        d["rate"], d["wire_limit"] = round(self.rate, 1), round(self.wire_limit, 1)
        return d


@dataclass
class BusBenchReport:
    port: str
    baudrate: int
    """The servo line's rate."""
    turnaround_ms: float
    echo: bool
    machine: dict[str, str]
    results: list[BusBenchResult]
    board_baudrate: int | None = None
    """Through a controller board: its link's rate (the servo line is behind it)."""
    board_link_reads_s: float | None = None
    """Through a controller board: the position reads/s its link alone would allow."""

    def to_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["results"] = [r.to_dict() for r in self.results]
        return d


def _reply_bytes(command: Command) -> int:
    length = SPECS[command].reply_length
    assert length is not None
    return length + 3


CPU_BATCH = 50
"""Client CPU is read once per this many transactions (the clock is itself a syscall)."""


def _cpu_per_call_s(call: Callable[[], object], count: int) -> list[float]:
    """Client CPU time per call (this thread, user + system), one sample per batch of
    CPU_BATCH calls with nothing else in the loop: the clock is itself a syscall."""
    samples: list[float] = []
    cpu_clock = time.thread_time
    for _ in range(max(count // CPU_BATCH, 1)):
        c0 = cpu_clock()
        for _ in range(CPU_BATCH):
            call()
        samples.append((cpu_clock() - c0) / CPU_BATCH)
    return samples


def _timed_reads(
    name: str, bus: LxServoPort, call: Callable[[], object], count: int
) -> BusBenchResult:
    """Rate and latency over ``count`` calls, then client CPU over as many again."""
    latencies: list[float] = []
    errors = 0
    clock = time.perf_counter
    start = clock()
    for _ in range(count):
        t0 = clock()
        try:
            call()
        except BusArmError:
            errors += 1
        latencies.append(clock() - t0)
    elapsed = clock() - start
    cpu = _cpu_per_call_s(call, count)
    wire = bus.wire_time_s(6, _reply_bytes(Command.POS_READ))
    return BusBenchResult(
        name, "reads/s", count, count / elapsed, 1.0 / wire, latency_percentiles_ms(latencies),
        round(statistics.median(cpu) * 1e6, 2), errors,
    )


def bench_position_reads(bus: LxServoPort, servo_id: int, count: int) -> BusBenchResult:
    """``count`` POS_READs of one servo, back to back (called through a C-level partial:
    a Python lambda here would add its own frame to the client CPU measured)."""
    return _timed_reads("position reads", bus, partial(bus.read_position_pulses, servo_id),
                        count)


def bench_os_floor(bus: LxServoPort, servo_id: int, count: int) -> BusBenchResult | None:
    """The same position read done with bare syscalls (flush, write, select, read) on
    the same file descriptor: what any client pays the OS. None if the port has no
    descriptor (URLs, the in-process simulator)."""
    fd = getattr(bus.transport, "fd", None)
    if fd is None or bus.transport.framing != "lx":
        return None
    request = encode_request(servo_id, Command.POS_READ)
    need = _reply_bytes(Command.POS_READ) + (len(request) if bus.echo else 0)

    def bare_read() -> None:
        termios.tcflush(fd, termios.TCIFLUSH)
        os.write(fd, request)
        got = 0
        while got < need and select.select((fd,), (), (), 0.1)[0]:
            got += len(os.read(fd, 256))

    return _timed_reads("position reads, bare syscalls (OS floor)", bus, bare_read, count)


def bench_state_loop(bus: LxServoPort, servo_ids: Sequence[int], loops: int) -> BusBenchResult:
    """``loops`` rounds of position + temperature + voltage of every servo."""
    latencies: list[float] = []
    errors = 0
    clock = time.perf_counter
    start = clock()
    for _ in range(loops):
        t0 = clock()
        try:
            bus.read_states(servo_ids)
        except BusArmError:
            errors += 1
        latencies.append(clock() - t0)
    elapsed = clock() - start
    # Per transaction: each loop is 3 reads per servo.
    cpu = [c / (3 * len(servo_ids)) for c in
           _cpu_per_call_s(partial(bus.read_states, servo_ids), max(loops // 4, CPU_BATCH))]
    per_servo = sum(
        bus.wire_time_s(6, _reply_bytes(c)) for c in (Command.POS_READ, Command.TEMP_READ,
                                                       Command.VIN_READ)
    )
    return BusBenchResult(
        f"{len(servo_ids)}-servo state loop", "loops/s", loops, loops / elapsed,
        1.0 / (per_servo * len(servo_ids)), latency_percentiles_ms(latencies),
        round(statistics.median(cpu) * 1e6, 2), errors,
    )


def bench_scan(bus: LxServoPort, repeats: int = 3) -> BusBenchResult:
    """Full ID scan 0..253, ``repeats`` times; the wire limit is every ID's request,
    turnaround and a reply's worth of waiting (a missing servo cannot be known sooner)."""
    durations: list[float] = []
    found: list[int] = []
    for _ in range(repeats):
        result = bus.scan()
        durations.append(result.duration_s)
        found = result.found
    wire = 254 * bus.wire_time_s(6, _reply_bytes(Command.ID_READ))
    best = min(durations)
    times = ScanTimes(found, round(best, 4), round(statistics.median(durations), 4))
    absent = next((i for i in range(MAX_SERVO_ID + 1) if i not in found), None)
    if isinstance(bus, BoardServoBus) and absent is not None:
        times.board_absent_id_s = round(board_absent_id_s(bus, absent), 5)
        times.board_floor_s = round(254 * times.board_absent_id_s, 3)
    return BusBenchResult(
        "ID scan 0..253", "scans/s", repeats, 1.0 / statistics.median(durations), 1.0 / wire,
        latency_percentiles_ms(durations), None, 0, times,
    )


def board_absent_id_s(bus: BoardServoBus, servo_id: int, asks: int = 9) -> float:
    """How long the controller board takes to answer an ID read of ``servo_id`` (absent):
    its own wait on the servo line, measured (the median of ``asks``); the vendor does
    not publish it, and a scan through the board pays it for every absent ID."""
    times: list[float] = []
    now = bus.clock.now
    for _ in range(asks):
        t0 = now()
        with contextlib.suppress(BusArmError):  # "no answer" (status -1) is what is timed
            bus.link.servo_read(ServoSub.READ_ID, servo_id, retries=0)
        times.append(now() - t0)
    return statistics.median(times)


class SimServerProcess:
    """``busarm sim serve ARGS`` in its own process (a fair, separate CPU for
    benchmarks; a real other program for tests). ``with`` yields its pty path; leaving
    stops it with SIGINT and keeps ``returncode`` and ``stderr``."""

    def __init__(self, *serve_args: str) -> None:
        self.args = [sys.executable, "-m", "busarm", "sim", "serve", *serve_args]
        self.returncode: int | None = None
        self.stderr = ""
        self._proc: subprocess.Popen[str] | None = None

    def __enter__(self) -> str:
        proc = subprocess.Popen(
            self.args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        self._proc = proc
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        if "/dev/" not in path:  # it prints its pty's path, or why it did not start
            self._stop()
            raise TransportError(f"simulator did not start: {self.stderr.strip() or path!r}")
        return path

    def __exit__(self, *exc: object) -> None:
        self._stop()

    def _stop(self) -> None:
        proc = self._proc
        if proc is None:
            return
        self._proc = None
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            _, self.stderr = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, self.stderr = proc.communicate()
        self.returncode = proc.returncode


def sim_pty_server(
    turnaround_ms: float, ids: str = "1,2,3,4,5,10", *, echo: bool = False,
    board: bool = False,
) -> SimServerProcess:
    """The simulated arm for ``busarm bench``, in its own process on a pseudo-terminal
    (behind a simulated controller board with ``board``: its port is ``board://...``)."""
    return SimServerProcess(
        "--ids", ids, "--turnaround-ms", str(turnaround_ms), *(["--echo"] if echo else []),
        *(["--board"] if board else []),
    )


def run_bench(
    port: PortSpec,
    *,
    servo_ids: Sequence[int] = (1, 2, 3, 4, 5, 10),
    reads: int = 3000,
    loops: int = 200,
    scans: int = 3,
    turnaround_ms: float = 0.5,
    echo: str = "auto",
    progress: Progress = quiet,
    timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S,
) -> BusBenchReport:
    """Run the three measurements on ``port`` (whose servos must include ``servo_ids``);
    ``progress`` hears of each stage as it starts."""
    if not servo_ids:
        raise ConfigError("bench needs at least one servo ID")
    with ServoBus.open(port, echo=echo, turnaround_s=turnaround_ms / 1000.0,
                       timeout_margin_s=timeout_margin_s) as bus:
        if bus.clock.is_simulated:
            raise ConfigError(f"{port.name} runs on a simulated clock: its wire takes no real time "
                              "to measure; bench the servo simulator (the default port, "
                              "sim) or `busarm twin serve`'s pty instead")
        for _ in range(WARM_UP_READS):  # fails fast if nobody is there
            bus.read_position_pulses(servo_ids[0])
        sid = servo_ids[0]
        with_floor = getattr(bus.transport, "fd", None) is not None and not isinstance(
            bus, BoardServoBus)
        stages = 4 if with_floor else 3  # 4: the OS floor
        progress(f"1/{stages}: {reads} position reads of servo {sid}")
        results = [bench_position_reads(bus, sid, reads)]
        progress(f"2/{stages}: {loops} state loops of {len(servo_ids)} servo(s)")
        results.append(bench_state_loop(bus, servo_ids, loops))
        progress(f"3/{stages}: {scans} ID scan(s) 0..253")
        results.append(bench_scan(bus, scans))
        if stages == 4:
            progress(f"4/{stages}: {reads} position reads by bare syscalls (the OS floor)")
        floor = bench_os_floor(bus, sid, reads)
        if floor is not None:
            results.insert(1, floor)
        if isinstance(bus, BoardServoBus):
            return BusBenchReport(
                port.name, SERVO_LINE_BAUDRATE, turnaround_ms, False, machine_info(), results,
                bus.transport.baudrate, 1.0 / bus.link_time_s(6, _reply_bytes(Command.POS_READ)))
        return BusBenchReport(
            port.name, bus.transport.baudrate, turnaround_ms, bus.echo, machine_info(), results
        )
