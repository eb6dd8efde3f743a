"""What ``busarm.bench.peers`` reports, and how it prints it: the rate of every library,
what each did around each glitch, and the summary (``PeersReport.to_dict()`` is the
``--json`` file)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

from busarm.bench.peer_clients import AFTER_GLITCH, GLITCH_POSITIONS, WIRE_LIMIT

__all__ = [
    "GlitchResult",
    "GlitchStep",
    "PeersReport",
    "PeersSummary",
    "RateResult",
    "RateStats",
    "glitch_table",
    "print_glitches",
    "print_rates",
    "print_summary",
    "rate_table",
]


@dataclass
class RateStats:
    """One library's rate run, over all its rounds."""

    rounds: int
    count: int
    errors: int
    wrong_values: int
    wrong_examples: dict[int, int]
    """The most common wrong values read, and how often."""
    rate: float
    round_rates: list[float]
    latency_ms: dict[str, float]
    cpu_us_median: float
    first_errors: list[str]


@dataclass
class RateResult:
    """One library in the rate run: its status, and its numbers if it ran."""

    library: str
    package: str
    status: str = "ok"
    api: str = ""
    log_count: int = 0
    stats: RateStats | None = None

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {"library": self.library, "package": self.package,
                                "status": self.status, "api": self.api,
                                "log_count": self.log_count}
        if self.stats is not None:
            d.update(asdict(self.stats))
        return d


@dataclass
class GlitchStep:
    """One read around a glitch: "right", "wrong" (with the value), "error" or "hang"."""

    servo: int
    expect: int
    result: str
    ms: float
    value: object = None
    note: str = ""
    """Whose position a wrong value is, if another servo's."""
    error: str = ""

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {"servo": self.servo, "expect": self.expect,
                                "result": self.result}
        if self.result in ("right", "wrong"):
            d["value"] = self.value
            if self.note:
                d["note"] = self.note
        else:
            d["error"] = self.error
        d["ms"] = self.ms
        return d


@dataclass
class GlitchResult:
    """One library, one glitch test: the reads before, the glitched one, the ones after."""

    library: str
    test: str
    verdict: str = ""
    before: list[GlitchStep] | None = None
    glitched: GlitchStep | None = None
    later: list[GlitchStep] | None = None
    detail: str | None = None
    """Why the library could not be opened."""
    log_count: int | None = None
    log_lines: list[str] | None = None

    def to_dict(self) -> dict[str, object]:
        d: dict[str, object] = {"library": self.library, "test": self.test}
        if self.before is not None:
            d["before"] = [s.to_dict() for s in self.before]
        if self.glitched is not None:
            d["glitched"] = self.glitched.to_dict()
        if self.later is not None:
            d["later"] = [s.to_dict() for s in self.later]
        d["verdict"] = self.verdict
        for key in ("detail", "log_count", "log_lines"):
            if getattr(self, key) is not None:
                d[key] = getattr(self, key)
        return d


@dataclass
class PeersSummary:
    busarm_reads_per_s: float | None
    best_peer: str | None
    best_peer_reads_per_s: float | None
    ratio: float | None
    """busarm's rate over the best peer's."""
    rate_tolerance: float
    passes: dict[str, list[str]]
    """Per glitch test, the libraries that recover."""
    rate_not_clean: list[str]
    problems: list[str]
    """What busarm fails; empty if it passes everything."""


@dataclass
class PeersReport:
    machine: dict[str, str]
    baudrate: int
    turnaround_ms: float
    peer_timeout_ms: float
    reads: int
    rounds: int
    wire_limit_reads_per_s: float
    rate: list[RateResult]
    glitch_tests: dict[str, str]
    glitches: list[GlitchResult]
    summary: PeersSummary
    elapsed_s: float

    def to_dict(self) -> dict[str, object]:
        return {
            "machine": self.machine, "baudrate": self.baudrate,
            "turnaround_ms": self.turnaround_ms, "peer_timeout_ms": self.peer_timeout_ms,
            "reads": self.reads, "rounds": self.rounds,
            "wire_limit_reads_per_s": self.wire_limit_reads_per_s,
            "rate": [r.to_dict() for r in self.rate], "glitch_tests": self.glitch_tests,
            "glitches": [g.to_dict() for g in self.glitches],
            "summary": asdict(self.summary), "elapsed_s": self.elapsed_s,
        }



# ---------------------------------------------------------------------- printing


def _short(step: GlitchStep) -> str:
    r = step.result
    if r == "right":
        return f"{step.value} ok"
    if r == "wrong":
        return f"{step.value} WRONG"
    if r == "error":
        name = step.error.split(":", 1)[0]
        return "E:" + name.removeprefix("Servo").removesuffix("Error")
    return r


def rate_table(rates: Sequence[RateResult]) -> str:
    head = (f"{'library':<17}{'reads':>7}{'errors':>7}{'wrong':>7}{'reads/s':>9}{'% wire':>8}"
            f"{'p50 ms':>8}{'p99 ms':>8}{'CPU us/read':>13}  status")
    lines = [head, "-" * len(head)]
    for r in rates:
        s = r.stats
        if s is None:
            lines.append(f"{r.library:<17}{'-':>7}{'-':>7}{'-':>7}{'-':>9}{'-':>8}{'-':>8}"
                         f"{'-':>8}{'-':>13}  {r.status}")
            continue
        lat = s.latency_ms
        lines.append(
            f"{r.library:<17}{s.count:>7}{s.errors:>7}{s.wrong_values:>7}"
            f"{s.rate:>9.1f}{100 * s.rate / WIRE_LIMIT:>7.1f}%{lat['p50']:>8.3f}"
            f"{lat['p99']:>8.3f}{s.cpu_us_median:>13.1f}  {r.status}"
        )
    return "\n".join(lines)


def glitch_table(glitches: Sequence[GlitchResult]) -> str:
    head = (f"{'test':<12}{'library':<17}{'glitched read 1':<26}"
            f"{'then ' + ', '.join(map(str, AFTER_GLITCH)):<62}verdict")
    lines = [head, "-" * (len(head) + 8)]
    for g in glitches:
        if g.glitched is None:
            detail = g.detail or ", ".join(_short(s) for s in g.before or [])
            lines.append(f"{g.test:<12}{g.library:<17}{'-':<26}{detail[:60]:<62}{g.verdict}")
            continue
        glitched = _short(g.glitched)
        later = ", ".join(_short(s) for s in g.later or [])
        lines.append(f"{g.test:<12}{g.library:<17}{glitched[:25]:<26}{later[:61]:<62}"
                     f"{g.verdict}")
    return "\n".join(lines)


def print_rates(report: PeersReport) -> None:
    print(f"\n1. Rate ({report.rounds} rounds, each library against a fresh simulator process "
          "each round)\n")
    print(rate_table(report.rate))
    for r in report.rate:
        if r.api:
            print(f"   {r.library}: {r.api}")
        for e in r.stats.first_errors if r.stats else []:
            print(f"   {r.library} error: {e}")
        if r.stats and r.stats.round_rates:
            print(f"   {r.library} per round: "
                  f"{', '.join(f'{x:.0f}' for x in r.stats.round_rates)} reads/s")
        if r.log_count:
            print(f"   {r.library} logged {r.log_count} warnings")


def print_glitches(report: PeersReport) -> None:
    print("\n2. Glitches (in-process simulator; servo 1 at "
          f"{GLITCH_POSITIONS[1]} pulses, servo 2 at {GLITCH_POSITIONS[2]})\n")
    for test, text in report.glitch_tests.items():
        print(f"   {test}: {text}")
    print("   (each read: value and ok/WRONG, or E:<exception> for an error, or hang)\n")
    print(glitch_table(report.glitches))
    for g in report.glitches:
        if g.log_count and g.log_lines:
            print(f"   {g.test}, {g.library}: logged {g.log_count} warnings, "
                  f"e.g. {g.log_lines[-1]}")


def print_summary(report: PeersReport) -> None:
    s = report.summary
    tolerance = s.rate_tolerance
    print("\n3. Summary\n")
    if s.busarm_reads_per_s is not None and s.best_peer is not None and s.ratio is not None:
        tie = abs(s.ratio - 1) <= tolerance
        print(f"   rate: busarm {s.busarm_reads_per_s:.0f} reads/s = {s.ratio:.3f}x the best "
              f"peer ({s.best_peer}, {s.best_peer_reads_per_s:.0f} reads/s)"
              + (f", a tie within the {tolerance:.0%} noise band" if tie else "")
              + f"; wire limit {WIRE_LIMIT:.0f} reads/s")
        cpu = {r.library: r.stats.cpu_us_median for r in report.rate if r.stats is not None}
        if "busarm" in cpu and s.best_peer in cpu:
            print(f"   client CPU per read: busarm {cpu['busarm']:.1f} us, {s.best_peer} "
                  f"{cpu[s.best_peer]:.1f} us")
    else:
        ours = s.busarm_reads_per_s
        print(f"   rate: busarm {ours if ours is None else round(ours)} reads/s; "
              "no peer completed a clean rate run")
    if s.rate_not_clean:
        print(f"   rate run not clean: {', '.join(s.rate_not_clean)}")
    for test, libs in s.passes.items():
        print(f"   {test}: passed by {', '.join(libs) if libs else 'nobody'}")
    print(f"   {'FAIL: ' + '; '.join(s.problems) if s.problems else 'busarm: all checks pass'}")
    print(f"   took {report.elapsed_s:.1f} s")
