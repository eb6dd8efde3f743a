"""busarm beside other Python LX-servo libraries, on the same simulator.

Run as ``make bench-peers`` (installs the ``[peers]`` extra: pylx16a, lewansoul-lx16a),
or ``python -m busarm.bench.peers [--reads N] [--rounds N] [--json PATH]``.

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

Peers are only imported and called (``busarm.bench.peer_clients``). Exit status: 0
whatever the peers do; 1 if busarm fails a glitch test or is slower than the best peer
by more than the run-to-run noise (``--tolerance``, 2%: on this simulator every library
runs within a few percent of the wire limit); 2 if the bench itself breaks.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import statistics
import sys
import time
import traceback
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from busarm.bench.bus import sim_pty_server
from busarm.bench.common import Progress, latency_percentiles_ms, machine_info, quiet
from busarm.bench.peer_clients import (
    AFTER_GLITCH,
    BAUD,
    CALL_LIMIT_S,
    CLIENTS,
    GLITCH_POSITIONS,
    LOG_CAPTURE,
    TURNAROUND_MS,
    WIRE_LIMIT,
    Client,
    close_client,
    guarded,
    open_client,
)
from busarm.bench.peers_report import (
    GlitchResult,
    GlitchStep,
    PeersReport,
    PeersSummary,
    RateResult,
    RateStats,
    print_glitches,
    print_rates,
    print_summary,
)
from busarm.clock import WALL_CLOCK
from busarm.protocol.lx_units import CENTER_PULSES
from busarm.sim.bus import ARM_SERVO_IDS, GRIPPER_ID, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams

__all__ = [
    "ABORT_AFTER_ERRORS",
    "GLITCH_TESTS",
    "LATE_S",
    "PEER_TIMEOUT_S",
    "RATE_TOLERANCE",
    "ROUNDS",
    "WARMUP_READS",
    "RateSamples",
    "bench_rates",
    "glitch_sim",
    "glitch_test",
    "main",
    "rate_round",
    "run_peer_bench",
    "summarise",
]


PEER_TIMEOUT_S = 0.05
"""Read timeout given to the peers (busarm derives its own from the baud rate)."""
LATE_S = 0.2
"""How late the delayed reply is: longer than any library's timeout."""
RATE_TOLERANCE = 0.02
"""Run-to-run noise of the rate (all three libraries run close to the wire limit, and
repeated runs move by about 1%): busarm counts as slower than a peer only beyond it."""
ABORT_AFTER_ERRORS = 25
"""The rate loop stops after this many consecutive failed reads (a peer that cannot talk)."""
WARMUP_READS = 20
"""Unmeasured reads at the start of each round."""
ROUNDS = 4

GLITCH_TESTS: dict[str, str] = {
    "stray 0x00": "one 0x00 byte on the line before the reply to the next read of servo 1",
    "stray 0x55": "one 0x55 byte (half a header) before the reply to the next read of servo 1",
    "late reply": f"the reply to the next read of servo 1 arrives {LATE_S * 1e3:.0f} ms late; "
                  "later reads start once it has landed",
}


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


@dataclass
class _Tally:
    errors: int = 0
    consecutive: int = 0
    wrong: Counter[int] = field(default_factory=Counter)
    first_errors: list[str] = field(default_factory=list)


def _rate_loop(client: Client, servo_id: int, count: int, expect: int) -> RateSamples:
    """``count`` reads, each timed (wall and this thread's CPU). Runs on the worker thread."""
    latencies: list[float] = []
    cpu: list[float] = []
    tally = _Tally()
    aborted = ""
    read = client.read_pulses
    for _ in range(WARMUP_READS):
        with contextlib.suppress(Exception):
            read(servo_id)
    clock, cpu_clock = time.perf_counter, time.thread_time
    start = clock()
    for _ in range(count):
        t0, c0 = clock(), cpu_clock()
        error = ""
        try:
            value = read(servo_id)
        except Exception as exc:
            error = f"{type(exc).__name__}: {exc}"
            if len(tally.first_errors) < 3:
                tally.first_errors.append(error)
        c1, t1 = cpu_clock(), clock()
        cpu.append(c1 - c0)
        latencies.append(t1 - t0)
        if not error:
            tally.consecutive = 0
            if value != expect:
                tally.wrong[value] += 1
        else:
            tally.errors += 1
            tally.consecutive += 1
            if tally.consecutive >= ABORT_AFTER_ERRORS:
                aborted = f"stopped after {tally.consecutive} consecutive failed reads"
                break
    return RateSamples(latencies, cpu, clock() - start, tally.errors, tally.wrong,
                       tally.first_errors, aborted)


def rate_round(
    cls: type[Client], reads: int, timeout_s: float
) -> tuple[str, str, RateSamples | None]:
    """One library, one round, against a fresh simulator process: (status, api, samples)."""
    with sim_pty_server(TURNAROUND_MS) as path:
        client, opened = open_client(cls, path, timeout_s, [1])
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
            close_client(client)


def _rate_stats(got_all: Sequence[RateSamples]) -> RateStats:
    latencies = [x for g in got_all for x in g.latencies]
    cpu = [x for g in got_all for x in g.cpu]
    elapsed = sum(g.elapsed for g in got_all)
    wrong: Counter[int] = sum((g.wrong for g in got_all), Counter())
    return RateStats(
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


def bench_rates(reads: int, rounds: int, timeout_s: float,
                progress: Progress = quiet) -> list[RateResult]:
    """Every library, ``reads`` reads split over ``rounds`` rounds; the order of the
    libraries rotates each round, so drift in the machine's load hits them alike."""
    per_round = [reads // rounds + (1 if i < reads % rounds else 0) for i in range(rounds)]
    results = {c.name: RateResult(c.name, c.package) for c in CLIENTS}
    samples: dict[str, list[RateSamples]] = {c.name: [] for c in CLIENTS}
    for i, n in enumerate(per_round):
        if n == 0:
            continue
        order = CLIENTS[i % len(CLIENTS):] + CLIENTS[: i % len(CLIENTS)]
        progress(f"  rate round {i + 1}/{rounds}: {', '.join(c.name for c in order)}")
        for cls in order:
            r = results[cls.name]
            if r.status != "ok":
                continue  # a library that failed once is not run again
            before = len(LOG_CAPTURE.lines)
            status, api, got = rate_round(cls, n, timeout_s)
            r.log_count += len(LOG_CAPTURE.lines) - before
            r.api = api or r.api
            r.status = status
            if got is not None:
                samples[cls.name].append(got)
    for name, r in results.items():
        if samples[name]:
            r.stats = _rate_stats(samples[name])
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
    bus = SimBus(servos, timing=WireTiming(BAUD, TURNAROUND_MS / 1000, True), clock=WALL_CLOCK)
    server = PtyServer(bus)
    path = server.start()
    try:
        yield bus, path
    finally:
        server.stop()


def _step(client: Client, servo_id: int) -> GlitchStep:
    expect = GLITCH_POSITIONS[servo_id]
    o = guarded(lambda: client.read_pulses(servo_id), CALL_LIMIT_S)
    ms = round(o.seconds * 1e3, 2)
    if o.kind != "ok":
        return GlitchStep(servo_id, expect, o.kind, ms, error=o.error)
    other = [s for s, p in GLITCH_POSITIONS.items() if p == o.value and s != servo_id]
    return GlitchStep(servo_id, expect, "right" if o.value == expect else "wrong", ms,
                      value=o.value, note=f"servo {other[0]}'s position" if other else "")


def _verdict(glitched: GlitchStep, later: list[GlitchStep]) -> str:
    kinds = [s.result for s in [glitched, *later]]
    if "hang" in kinds:
        return "hang"
    if any(s.result == "wrong" for s in later):
        return "desynchronised"
    if glitched.result == "wrong":
        return "misreads"
    if any(s.result == "error" for s in later):
        return "errors"
    return "recovers"


def _glitch_and_after(bus: SimBus, client: Client, test: str, result: GlitchResult) -> None:
    """Glitch the next read of servo 1, then read ``AFTER_GLITCH``; fills ``result``."""
    if test.startswith("stray"):
        bus.inject_stray_bytes(bytes([int(test.split()[1], 16)]))
    else:
        bus.delay_next_reply(LATE_S)
    t0 = time.monotonic()
    glitched = _step(client, 1)
    if test == "late reply" and glitched.result != "hang":
        # Let the late reply land in the input buffer before the next request.
        time.sleep(max(0.0, t0 + LATE_S + 0.05 - time.monotonic()))
    later: list[GlitchStep] = []
    for sid in AFTER_GLITCH:
        if glitched.result == "hang" or (later and later[-1].result == "hang"):
            break
        later.append(_step(client, sid))
    result.glitched, result.later, result.verdict = glitched, later, _verdict(glitched, later)


def glitch_test(cls: type[Client], test: str, timeout_s: float) -> GlitchResult:
    """One library, one glitch, a fresh simulator."""
    result = GlitchResult(cls.name, test)
    logged = len(LOG_CAPTURE.lines)
    with glitch_sim() as (bus, path):
        client, opened = open_client(cls, path, timeout_s, sorted(GLITCH_POSITIONS))
        if client is None:
            result.verdict = "cannot open"
            result.detail = f"{opened.kind} {opened.error}".strip()
            return result
        try:
            result.before = [_step(client, 1), _step(client, 2)]
            if any(s.result != "right" for s in result.before):
                hung = any(s.result == "hang" for s in result.before)
                result.verdict = "hang" if hung else "cannot read"
                return result
            _glitch_and_after(bus, client, test, result)
        finally:
            close_client(client)
            result.log_count = len(LOG_CAPTURE.lines) - logged
            result.log_lines = LOG_CAPTURE.lines[logged:][-3:]
    return result


# ---------------------------------------------------------------------- 3. summary


def summarise(rates: Sequence[RateResult], glitches: Sequence[GlitchResult],
              tolerance: float) -> PeersSummary:
    """busarm's rate against the best clean peer's, who passes each glitch test, and
    what busarm fails."""
    ok_rates = {r.library: r.stats.rate for r in rates
                if r.stats is not None and r.status == "ok" and r.stats.errors == 0
                and r.stats.wrong_values == 0}
    ours = ok_rates.get("busarm")
    peer_rates = {k: v for k, v in ok_rates.items() if k != "busarm"}
    best_peer = max(peer_rates, key=peer_rates.__getitem__) if peer_rates else None
    passes = {
        test: [g.library for g in glitches if g.test == test and g.verdict == "recovers"]
        for test in GLITCH_TESTS
    }
    problems: list[str] = []
    if ours is None:
        problems.append("busarm's rate run failed")
    elif best_peer is not None and ours < peer_rates[best_peer] * (1 - tolerance):
        problems.append(f"busarm is slower than {best_peer} (beyond the "
                        f"{tolerance:.0%} noise band)")
    for test, libs in passes.items():
        if "busarm" not in libs:
            problems.append(f"busarm fails the {test} test")
    best_rate = peer_rates[best_peer] if best_peer is not None else None
    return PeersSummary(
        busarm_reads_per_s=ours, best_peer=best_peer, best_peer_reads_per_s=best_rate,
        ratio=ours / best_rate if ours is not None and best_rate is not None else None,
        rate_tolerance=tolerance, passes=passes,
        rate_not_clean=sorted({r.library for r in rates if r.library not in ok_rates}),
        problems=problems,
    )


def run_peer_bench(reads: int = 2000, rounds: int = ROUNDS, timeout_s: float = PEER_TIMEOUT_S,
                   tolerance: float = RATE_TOLERANCE, *,
                   progress: Progress = quiet) -> PeersReport:
    """The rate run, every glitch test for every library, and the summary."""
    started = time.perf_counter()
    root = logging.getLogger()
    root.addHandler(LOG_CAPTURE)
    # lewansoul-lx16a's logger has no handler: without this its warnings would go to stderr.
    root.setLevel(min(root.level or logging.WARNING, logging.WARNING))
    rates = bench_rates(reads, rounds, timeout_s, progress)
    glitches = [glitch_test(cls, test, timeout_s) for test in GLITCH_TESTS for cls in CLIENTS]
    summary = summarise(rates, glitches, tolerance)
    return PeersReport(
        machine=machine_info(), baudrate=BAUD, turnaround_ms=TURNAROUND_MS,
        peer_timeout_ms=timeout_s * 1e3, reads=reads, rounds=rounds,
        wire_limit_reads_per_s=round(WIRE_LIMIT, 2), rate=rates, glitch_tests=GLITCH_TESTS,
        glitches=glitches, summary=summary, elapsed_s=round(time.perf_counter() - started, 2),
    )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="busarm beside other Python LX-servo libraries, on the same simulator.")
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
    timeout_s = args.timeout_ms / 1e3
    try:
        print(f"busarm vs peers: {args.reads} position reads of servo 1 per library; "
              f"simulator at {BAUD} baud, {TURNAROUND_MS} ms turnaround")
        print(f"wire limit: 1 / ((6 + 8) bytes x 10 / {BAUD} + {TURNAROUND_MS} ms) = "
              f"{WIRE_LIMIT:.1f} reads/s; peer timeouts {timeout_s * 1e3:.0f} ms\n")
        report = run_peer_bench(args.reads, args.rounds, timeout_s, args.tolerance,
                                progress=lambda text: print(text, flush=True))
        print_rates(report)
        print_glitches(report)
        print_summary(report)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(report.to_dict(), indent=2, default=str) + "\n")
            print(f"   report: {args.json}")
    except Exception:
        traceback.print_exc()
        print("bench-peers: the bench itself failed", file=sys.stderr)
        return 2
    return 1 if report.summary.problems else 0


if __name__ == "__main__":
    sys.exit(main())
