"""busarm beside other Python LX-servo libraries, on the same simulator.

Run as ``make bench-peers`` (installs the ``[peers]`` extra: pylx16a, lewansoul-lx16a).

1. Rate. N position reads of servo 1 per library: reads/s, latency p50/p99 and client
   CPU per read (median of ``time.thread_time`` around each call), beside the wire limit
   1 / ((6 + 8) bytes x 10 bits / 115200 + 0.5 ms). The reads are split over a few
   rounds with the libraries' order rotating (the machine's load drifts); every library
   gets a fresh simulator process (``busarm sim serve`` on a pseudo-terminal, wire timing
   on, 115200 baud, 0.5 ms turnaround) in every round, so no state leaks.
2. Glitches. For each library, a fresh in-process simulator (servo 1 at 100 pulses,
   servo 2 at 700) and three tests: a stray 0x00 byte before the next reply, a stray
   0x55 byte (half a frame header), and a reply 0.2 s late (longer than every library's
   timeout). After the glitch the library reads servos 2 and 1 again: each read is
   right, wrong (another value, e.g. the other servo's) or an error; a call that does not
   return within a watchdog limit is a hang. Verdict per library: "recovers" (every later
   read right), "desynchronised" (a later read returned a wrong value), "misreads" (only
   the glitched read returned a wrong value), "errors" (later reads fail) or "hang".
3. A summary: busarm's rate against the best peer's, and who passes each glitch test.

Peers are only imported and called. Each call runs on a watchdog thread with its output
captured, so a peer that prints, raises or hangs is recorded and the bench goes on. Exit
status: 0 whatever the peers do; 1 if busarm fails a glitch test or is slower than the
best peer by more than the run-to-run noise (``--tolerance``, 2%: on this simulator every
library runs within a few percent of the wire limit); 2 if the bench itself breaks.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import logging
import statistics
import sys
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from busarm.bench import latency_percentiles_ms, machine_info, sim_pty_server
from busarm.bus.driver import ServoBus
from busarm.sim.bus import ARM_SERVO_IDS, GRIPPER_ID, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.servo import ServoParams, SimServo
from busarm.units import CENTER_PULSES

BAUD = 115200
TURNAROUND_MS = 0.5
REQUEST_BYTES = 6
POS_REPLY_BYTES = 8
WIRE_S = (REQUEST_BYTES + POS_REPLY_BYTES) * 10 / BAUD + TURNAROUND_MS / 1000
WIRE_LIMIT = 1.0 / WIRE_S
"""Position reads per second the wire allows: request, turnaround, reply."""

PEER_TIMEOUT_S = 0.05
"""Read timeout given to the peers (busarm derives its own from the baud rate)."""
CALL_LIMIT_S = 2.0
"""Watchdog: a single call taking longer than this is a hang."""
OPEN_LIMIT_S = 10.0
LATE_S = 0.2
"""How late the delayed reply is: longer than any library's timeout."""
GLITCH_POSITIONS = {1: 100, 2: 700}
AFTER_GLITCH = (2, 1, 1, 2, 1)
"""Servos read after each glitch: alternating shows a reply shifted by one transaction,
the repeat shows a stale reply of the same servo."""
RATE_TOLERANCE = 0.02
"""Run-to-run noise of the rate (all three libraries run close to the wire limit, and
repeated runs move by about 1%): busarm counts as slower than a peer only beyond it."""
ABORT_AFTER_ERRORS = 25
WARMUP_READS = 20
"""Unmeasured reads at the start of each round."""
ROUNDS = 4
"""The rate loop stops after this many consecutive failed reads (a peer that cannot talk)."""


# ---------------------------------------------------------------------- guarded calls


@dataclass
class Outcome:
    """What one guarded call did: "ok" with a value, "error" with a message, or "hang"."""

    kind: str
    value: Any = None
    error: str = ""
    seconds: float = 0.0
    output: str = ""


class _LogCapture(logging.Handler):
    """Collects what libraries log (lewansoul-lx16a logs warnings on odd replies)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        with contextlib.suppress(Exception):
            self.lines.append(f"{record.name}: {record.getMessage()}")


LOG_CAPTURE = _LogCapture()


def guarded(fn: Callable[[], Any], limit_s: float) -> Outcome:
    """Run ``fn`` on a daemon thread; give up on it after ``limit_s`` (a hang).

    stdout and stderr are captured while the main thread waits (and restored even if
    the call never returns), so a chatty peer cannot garble the tables.
    """
    box: dict[str, Any] = {}

    def run() -> None:
        t0 = time.perf_counter()
        try:
            box["value"] = fn()
        except BaseException as exc:  # peers raise anything, SystemExit included
            box["error"] = f"{type(exc).__name__}: {exc}".strip()
        box["seconds"] = time.perf_counter() - t0

    out = io.StringIO()
    thread = threading.Thread(target=run, name="peer-call", daemon=True)
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        thread.start()
        thread.join(limit_s)
    if thread.is_alive():
        return Outcome("hang", seconds=time.perf_counter() - t0, output=out.getvalue())
    seconds = box.get("seconds", 0.0)
    if "error" in box:
        return Outcome("error", error=box["error"], seconds=seconds, output=out.getvalue())
    return Outcome("ok", box.get("value"), seconds=seconds, output=out.getvalue())


# ---------------------------------------------------------------------- the libraries


class Client:
    """One library's position read, in pulses, for one port."""

    name = ""
    package = ""

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        raise NotImplementedError

    def read_pulses(self, servo_id: int) -> int:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def describe(self) -> str:
        return ""


class BusarmClient(Client):
    name = "busarm"
    package = "busarm"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        # busarm's defaults: echo detected at open, baud-derived timeouts, 2 retries.
        self.bus = ServoBus.open(path, baudrate=BAUD, turnaround_s=TURNAROUND_MS / 1000)
        self.read_pulses = self.bus.read_position_pulses  # type: ignore[method-assign]

    def close(self) -> None:
        self.bus.close()

    def describe(self) -> str:
        plan_timeout = self.bus.timeout_s(REQUEST_BYTES, POS_REPLY_BYTES)
        return (f"ServoBus.read_position_pulses; timeout {plan_timeout * 1e3:.1f} ms per attempt, "
                f"{self.bus.retries} retries, echo {'on' if self.bus.echo else 'off'}")


class PylxClient(Client):
    """pylx16a: a class-wide serial port, LX16A(id) objects reading angles in degrees."""

    name = "pylx16a"
    package = "pylx16a==1.1.1"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        from pylx16a.lx16a import LX16A

        self.cls = LX16A
        LX16A.initialize(path, timeout_s)
        # The constructor reads a dozen registers and enables torque.
        self.servos = {sid: LX16A(sid) for sid in ids}

    def read_pulses(self, servo_id: int) -> int:
        return round(self.servos[servo_id].get_physical_angle() * 25 / 6)

    def close(self) -> None:
        port = self.cls._controller
        self.cls._controller = None
        if port is not None:
            port.close()

    def describe(self) -> str:
        return (f"LX16A(id).get_physical_angle(); timeout {self.cls.get_timeout() * 1e3:.0f} ms "
                "(LX16A.initialize)")


class LewansoulClient(Client):
    """lewansoul-lx16a: ServoController(serial.Serial(...)).get_position(id)."""

    name = "lewansoul-lx16a"
    package = "lewansoul-lx16a==0.1"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        import lewansoul_lx16a
        import serial

        self.timeout_s = timeout_s
        self.port = serial.Serial(path, BAUD, timeout=timeout_s)
        self.ctrl = lewansoul_lx16a.ServoController(self.port, timeout=timeout_s)

    def read_pulses(self, servo_id: int) -> int:
        return int(self.ctrl.get_position(servo_id))

    def close(self) -> None:
        self.port.close()

    def describe(self) -> str:
        return (f"ServoController.get_position(id); timeout {self.timeout_s * 1e3:.0f} ms "
                "(ServoController(timeout=...))")


CLIENTS: tuple[type[Client], ...] = (BusarmClient, PylxClient, LewansoulClient)


def _open_client(
    cls: type[Client], path: str, timeout_s: float, ids: Sequence[int]
) -> tuple[Client | None, Outcome]:
    client = cls()
    outcome = guarded(lambda: client.open(path, timeout_s, ids), OPEN_LIMIT_S)
    if outcome.kind != "ok":
        guarded(client.close, CALL_LIMIT_S)
        return None, outcome
    return client, outcome


def _close_client(client: Client | None) -> None:
    if client is not None:
        guarded(client.close, CALL_LIMIT_S)


# ---------------------------------------------------------------------- 1. rate


@dataclass
class RateSamples:
    """What the rate loop saw in one round."""

    latencies: list[float]
    cpu: list[float]
    elapsed: float
    errors: int
    wrong: Counter[int]
    first_errors: list[str]
    aborted: str


def _rate_loop(client: Client, servo_id: int, count: int, expect: int) -> RateSamples:
    """``count`` reads, each timed (wall and this thread's CPU). Runs on the worker thread."""
    latencies: list[float] = []
    cpu: list[float] = []
    errors = 0
    wrong: Counter[int] = Counter()
    first_errors: list[str] = []
    consecutive = 0
    aborted = ""
    read = client.read_pulses
    for _ in range(WARMUP_READS):
        with contextlib.suppress(Exception):
            read(servo_id)
    clock, cpu_clock = time.perf_counter, time.thread_time
    start = clock()
    for _ in range(count):
        t0, c0 = clock(), cpu_clock()
        try:
            value = read(servo_id)
            ok = True
        except Exception as exc:
            ok = False
            value = None
            if len(first_errors) < 3:
                first_errors.append(f"{type(exc).__name__}: {exc}")
        c1, t1 = cpu_clock(), clock()
        cpu.append(c1 - c0)
        latencies.append(t1 - t0)
        if ok:
            consecutive = 0
            if value != expect:
                wrong[value] += 1
        else:
            errors += 1
            consecutive += 1
            if consecutive >= ABORT_AFTER_ERRORS:
                aborted = f"stopped after {consecutive} consecutive failed reads"
                break
    return RateSamples(latencies, cpu, clock() - start, errors, wrong, first_errors, aborted)


def rate_round(
    cls: type[Client], reads: int, timeout_s: float
) -> tuple[str, str, RateSamples | None]:
    """One library, one round, against a fresh simulator process: (status, api, samples)."""
    with sim_pty_server(TURNAROUND_MS) as path:
        client, opened = _open_client(cls, path, timeout_s, [1])
        if client is None:
            return f"could not open: {opened.kind} {opened.error}".strip(), "", None
        try:
            api = client.describe()
            first = guarded(lambda: client.read_pulses(1), CALL_LIMIT_S)
            if first.kind != "ok":
                return f"first read failed: {first.kind} {first.error}".strip(), api, None
            limit = (reads + WARMUP_READS) * (timeout_s + 0.01) + 30.0
            run = guarded(lambda: _rate_loop(client, 1, reads, CENTER_PULSES), limit)
            if run.kind == "hang":
                return f"hang (no end after {limit:.0f} s)", api, None
            if run.kind == "error":
                return f"loop broke: {run.error}", api, None
            samples: RateSamples = run.value
            return samples.aborted or "ok", api, samples
        finally:
            _close_client(client)


def bench_rates(reads: int, rounds: int, timeout_s: float) -> list[dict[str, Any]]:
    """Every library, ``reads`` reads split over ``rounds`` rounds; the order of the
    libraries rotates each round, so drift in the machine's load hits them alike."""
    per_round = [reads // rounds + (1 if i < reads % rounds else 0) for i in range(rounds)]
    results: dict[str, dict[str, Any]] = {
        c.name: {"library": c.name, "package": c.package, "status": "ok"} for c in CLIENTS
    }
    samples: dict[str, list[RateSamples]] = {c.name: [] for c in CLIENTS}
    logged = {c.name: 0 for c in CLIENTS}
    for i, n in enumerate(per_round):
        if n == 0:
            continue
        order = CLIENTS[i % len(CLIENTS):] + CLIENTS[: i % len(CLIENTS)]
        print(f"  rate round {i + 1}/{rounds}: {', '.join(c.name for c in order)}", flush=True)
        for cls in order:
            r = results[cls.name]
            if r["status"] != "ok":
                continue  # a library that failed once is not run again
            before = len(LOG_CAPTURE.lines)
            status, api, got = rate_round(cls, n, timeout_s)
            logged[cls.name] += len(LOG_CAPTURE.lines) - before
            r["api"] = api or r.get("api", "")
            r["status"] = status
            if got is not None:
                samples[cls.name].append(got)
    for name, r in results.items():
        got_all = samples[name]
        r["log_count"] = logged[name]
        if not got_all:
            continue
        latencies = [x for g in got_all for x in g.latencies]
        cpu = [x for g in got_all for x in g.cpu]
        elapsed = sum(g.elapsed for g in got_all)
        wrong: Counter[int] = sum((g.wrong for g in got_all), Counter())
        r.update(
            rounds=len(got_all),
            count=len(latencies),
            errors=sum(g.errors for g in got_all),
            wrong_values=sum(wrong.values()),
            wrong_examples=dict(wrong.most_common(3)),
            rate=len(latencies) / elapsed if elapsed > 0 else 0.0,
            round_rates=[round(len(g.latencies) / g.elapsed, 1) for g in got_all if g.elapsed],
            latency_ms=latency_percentiles_ms(latencies),
            cpu_us_median=round(statistics.median(cpu) * 1e6, 2),
            first_errors=[e for g in got_all for e in g.first_errors][:3],
        )
    return list(results.values())


# ---------------------------------------------------------------------- 2. glitches


@contextlib.contextmanager
def glitch_sim() -> Iterator[tuple[SimBus, str]]:
    """The arm's servos in this process (servo 1 at 100 pulses, 2 at 700), on a pty."""
    now = time.monotonic()
    servos = [
        SimServo(
            sid,
            params=ServoParams.gripper() if sid == GRIPPER_ID else ServoParams(),
            position_pulses=GLITCH_POSITIONS.get(sid, CENTER_PULSES),
            now=now,
        )
        for sid in ARM_SERVO_IDS
    ]
    bus = SimBus(servos, timing=WireTiming(BAUD, TURNAROUND_MS / 1000, True))
    server = PtyServer(bus)
    path = server.start()
    try:
        yield bus, path
    finally:
        server.stop()


def _step(client: Client, servo_id: int) -> dict[str, Any]:
    expect = GLITCH_POSITIONS[servo_id]
    o = guarded(lambda: client.read_pulses(servo_id), CALL_LIMIT_S)
    step: dict[str, Any] = {"servo": servo_id, "expect": expect}
    if o.kind == "ok":
        step["result"] = "right" if o.value == expect else "wrong"
        step["value"] = o.value
        other = [s for s, p in GLITCH_POSITIONS.items() if p == o.value and s != servo_id]
        if other:
            step["note"] = f"servo {other[0]}'s position"
    else:
        step["result"] = o.kind
        step["error"] = o.error
    step["ms"] = round(o.seconds * 1e3, 2)
    return step


def _verdict(glitched: dict[str, Any], later: list[dict[str, Any]]) -> str:
    kinds = [s["result"] for s in [glitched, *later]]
    if "hang" in kinds:
        return "hang"
    if any(s["result"] == "wrong" for s in later):
        return "desynchronised"
    if glitched["result"] == "wrong":
        return "misreads"
    if any(s["result"] == "error" for s in later):
        return "errors"
    return "recovers"


def _short(step: dict[str, Any]) -> str:
    r = step["result"]
    if r == "right":
        return f"{step['value']} ok"
    if r == "wrong":
        return f"{step['value']} WRONG"
    if r == "error":
        name = step["error"].split(":", 1)[0]
        return "E:" + name.removeprefix("Servo").removesuffix("Error")
    return r


GLITCH_TESTS: dict[str, str] = {
    "stray 0x00": "one 0x00 byte on the line before the reply to the next read of servo 1",
    "stray 0x55": "one 0x55 byte (half a header) before the reply to the next read of servo 1",
    "late reply": f"the reply to the next read of servo 1 arrives {LATE_S * 1e3:.0f} ms late; "
                  "later reads start once it has landed",
}


def glitch_test(cls: type[Client], test: str, timeout_s: float) -> dict[str, Any]:
    """One library, one glitch, a fresh simulator."""
    result: dict[str, Any] = {"library": cls.name, "test": test}
    logged = len(LOG_CAPTURE.lines)
    with glitch_sim() as (bus, path):
        client, opened = _open_client(cls, path, timeout_s, sorted(GLITCH_POSITIONS))
        if client is None:
            result.update(verdict="cannot open", detail=f"{opened.kind} {opened.error}".strip())
            return result
        try:
            before = [_step(client, 1), _step(client, 2)]
            result["before"] = before
            if any(s["result"] != "right" for s in before):
                hung = any(s["result"] == "hang" for s in before)
                result["verdict"] = "hang" if hung else "cannot read"
                return result
            if test.startswith("stray"):
                bus.inject_stray_bytes(bytes([int(test.split()[1], 16)]))
            else:
                bus.delay_next_reply(LATE_S)
            t0 = time.monotonic()
            glitched = _step(client, 1)
            if test == "late reply" and glitched["result"] != "hang":
                # Let the late reply land in the input buffer before the next request.
                time.sleep(max(0.0, t0 + LATE_S + 0.05 - time.monotonic()))
            later: list[dict[str, Any]] = []
            for sid in AFTER_GLITCH:
                if glitched["result"] == "hang" or (later and later[-1]["result"] == "hang"):
                    break
                later.append(_step(client, sid))
            result.update(glitched=glitched, later=later, verdict=_verdict(glitched, later))
        finally:
            _close_client(client)
            result["log_count"] = len(LOG_CAPTURE.lines) - logged
            result["log_lines"] = LOG_CAPTURE.lines[logged:][-3:]
    return result


# ---------------------------------------------------------------------- report


def _rate_table(rates: list[dict[str, Any]]) -> str:
    head = (f"{'library':<17}{'reads':>7}{'errors':>7}{'wrong':>7}{'reads/s':>9}{'% wire':>8}"
            f"{'p50 ms':>8}{'p99 ms':>8}{'CPU us/read':>13}  status")
    lines = [head, "-" * len(head)]
    for r in rates:
        if "rate" not in r:
            lines.append(f"{r['library']:<17}{'-':>7}{'-':>7}{'-':>7}{'-':>9}{'-':>8}{'-':>8}"
                         f"{'-':>8}{'-':>13}  {r['status']}")
            continue
        lat = r["latency_ms"]
        lines.append(
            f"{r['library']:<17}{r['count']:>7}{r['errors']:>7}{r['wrong_values']:>7}"
            f"{r['rate']:>9.1f}{100 * r['rate'] / WIRE_LIMIT:>7.1f}%{lat['p50']:>8.3f}"
            f"{lat['p99']:>8.3f}{r['cpu_us_median']:>13.1f}  {r['status']}"
        )
    return "\n".join(lines)


def _glitch_table(glitches: list[dict[str, Any]]) -> str:
    head = (f"{'test':<12}{'library':<17}{'glitched read 1':<26}"
            f"{'then ' + ', '.join(map(str, AFTER_GLITCH)):<62}verdict")
    lines = [head, "-" * (len(head) + 8)]
    for g in glitches:
        if "glitched" not in g:
            detail = g.get("detail") or ", ".join(_short(s) for s in g.get("before", []))
            lines.append(f"{g['test']:<12}{g['library']:<17}{'-':<26}{detail[:60]:<62}"
                         f"{g['verdict']}")
            continue
        glitched = _short(g["glitched"])
        later = ", ".join(_short(s) for s in g["later"])
        lines.append(f"{g['test']:<12}{g['library']:<17}{glitched[:25]:<26}{later[:61]:<62}"
                     f"{g['verdict']}")
    return "\n".join(lines)


def run(reads: int, rounds: int, timeout_s: float, tolerance: float) -> tuple[dict[str, Any], int]:
    started = time.perf_counter()
    root = logging.getLogger()
    root.addHandler(LOG_CAPTURE)
    # lewansoul-lx16a's logger has no handler: without this its warnings would go to stderr.
    root.setLevel(min(root.level or logging.WARNING, logging.WARNING))

    print(f"busarm vs peers: {reads} position reads of servo 1 per library; simulator at "
          f"{BAUD} baud, {TURNAROUND_MS} ms turnaround")
    print(f"wire limit: 1 / ((6 + 8) bytes x 10 / {BAUD} + {TURNAROUND_MS} ms) = "
          f"{WIRE_LIMIT:.1f} reads/s; peer timeouts {timeout_s * 1e3:.0f} ms\n")

    rates = bench_rates(reads, rounds, timeout_s)
    print(f"\n1. Rate ({rounds} rounds, each library against a fresh simulator process "
          "each round)\n")
    print(_rate_table(rates))
    for r in rates:
        if r.get("api"):
            print(f"   {r['library']}: {r['api']}")
        for e in r.get("first_errors", []):
            print(f"   {r['library']} error: {e}")
        if r.get("round_rates"):
            print(f"   {r['library']} per round: "
                  f"{', '.join(f'{x:.0f}' for x in r['round_rates'])} reads/s")
        if r.get("log_count"):
            print(f"   {r['library']} logged {r['log_count']} warnings")

    glitches: list[dict[str, Any]] = []
    for test in GLITCH_TESTS:
        for cls in CLIENTS:
            glitches.append(glitch_test(cls, test, timeout_s))
    print("\n2. Glitches (in-process simulator; servo 1 at "
          f"{GLITCH_POSITIONS[1]} pulses, servo 2 at {GLITCH_POSITIONS[2]})\n")
    for test, text in GLITCH_TESTS.items():
        print(f"   {test}: {text}")
    print("   (each read: value and ok/WRONG, or E:<exception> for an error, or hang)\n")
    print(_glitch_table(glitches))
    for g in glitches:
        if g.get("log_count"):
            print(f"   {g['test']}, {g['library']}: logged {g['log_count']} warnings, "
                  f"e.g. {g['log_lines'][-1]}")

    # ------------------------------------------------------------------ summary
    ok_rates = {r["library"]: r["rate"] for r in rates
                if "rate" in r and r["status"] == "ok" and r["errors"] == 0
                and r["wrong_values"] == 0}
    ours = ok_rates.get("busarm")
    peer_rates = {k: v for k, v in ok_rates.items() if k != "busarm"}
    best_peer = max(peer_rates, key=peer_rates.__getitem__) if peer_rates else None
    passes = {
        test: [g["library"] for g in glitches if g["test"] == test and g["verdict"] == "recovers"]
        for test in GLITCH_TESTS
    }
    failed_peers = sorted({r["library"] for r in rates if r["library"] not in ok_rates})
    problems: list[str] = []
    if ours is None:
        problems.append("busarm's rate run failed")
    elif best_peer is not None and ours < peer_rates[best_peer] * (1 - tolerance):
        problems.append(f"busarm is slower than {best_peer} (beyond the "
                        f"{tolerance:.0%} noise band)")
    for test, libs in passes.items():
        if "busarm" not in libs:
            problems.append(f"busarm fails the {test} test")
    elapsed = time.perf_counter() - started

    print("\n3. Summary\n")
    if ours is not None and best_peer is not None:
        ratio = ours / peer_rates[best_peer]
        tie = abs(ratio - 1) <= tolerance
        print(f"   rate: busarm {ours:.0f} reads/s = {ratio:.3f}x the best peer "
              f"({best_peer}, {peer_rates[best_peer]:.0f} reads/s)"
              + (f", a tie within the {tolerance:.0%} noise band" if tie else "")
              + f"; wire limit {WIRE_LIMIT:.0f} reads/s")
        cpu = {r["library"]: r["cpu_us_median"] for r in rates if "cpu_us_median" in r}
        if "busarm" in cpu and best_peer in cpu:
            print(f"   client CPU per read: busarm {cpu['busarm']:.1f} us, {best_peer} "
                  f"{cpu[best_peer]:.1f} us")
    else:
        ratio = None
        print(f"   rate: busarm {ours if ours is None else round(ours)} reads/s; "
              "no peer completed a clean rate run")
    if failed_peers:
        print(f"   rate run not clean: {', '.join(failed_peers)}")
    for test, libs in passes.items():
        print(f"   {test}: passed by {', '.join(libs) if libs else 'nobody'}")
    print(f"   {'FAIL: ' + '; '.join(problems) if problems else 'busarm: all checks pass'}")
    print(f"   took {elapsed:.1f} s")

    report = {
        "machine": machine_info(),
        "baudrate": BAUD,
        "turnaround_ms": TURNAROUND_MS,
        "peer_timeout_ms": timeout_s * 1e3,
        "reads": reads,
        "rounds": rounds,
        "wire_limit_reads_per_s": round(WIRE_LIMIT, 2),
        "rate": rates,
        "glitch_tests": GLITCH_TESTS,
        "glitches": glitches,
        "summary": {
            "busarm_reads_per_s": ours,
            "best_peer": best_peer,
            "best_peer_reads_per_s": peer_rates.get(best_peer) if best_peer else None,
            "ratio": ratio,
            "rate_tolerance": tolerance,
            "passes": passes,
            "rate_not_clean": failed_peers,
            "problems": problems,
        },
        "elapsed_s": round(elapsed, 2),
    }
    return report, (1 if problems else 0)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reads", type=int, default=2000,
                        help="position reads per library in the rate run (default 2000)")
    parser.add_argument("--rounds", type=int, default=ROUNDS,
                        help="split the reads over this many rounds, rotating the order of "
                             f"the libraries (default {ROUNDS})")
    parser.add_argument("--json", type=Path, metavar="PATH", help="also write the report here")
    parser.add_argument("--timeout-ms", type=float, default=PEER_TIMEOUT_S * 1e3,
                        help="read timeout given to the peers (default 50)")
    parser.add_argument("--tolerance", type=float, default=RATE_TOLERANCE,
                        help="rate noise band: busarm fails only if slower than the best "
                             "peer by more than this fraction (default 0.02)")
    args = parser.parse_args(argv)
    if args.reads < 1 or args.rounds < 1:
        parser.error("--reads and --rounds must be at least 1")
    try:
        report, status = run(args.reads, args.rounds, args.timeout_ms / 1e3, args.tolerance)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(report, indent=2, default=str) + "\n")
            print(f"   report: {args.json}")
    except Exception:
        traceback.print_exc()
        print("bench-peers: the bench itself failed", file=sys.stderr)
        return 2
    return status


if __name__ == "__main__":
    sys.exit(main())
