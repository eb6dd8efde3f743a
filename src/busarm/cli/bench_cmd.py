"""``busarm bench``: bus throughput and latency beside the wire limit."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import click
from rich.table import Table

from busarm.bench.bus import BusBenchReport, run_bench, sim_pty_server
from busarm.bench.common import machine_line
from busarm.cli.bench_report import judged, said, seeded_world_options, verdict
from busarm.cli.common import (
    IdListType,
    RangeType,
    Settings,
    no_servos,
    pass_settings,
)
from busarm.sim.spec import SimSpec
from busarm.twin.arena_families import FAMILIES as ROOM_FAMILIES
from busarm.units import listing

if TYPE_CHECKING:
    from busarm.bench.dashboard import DashboardBenchReport
    from busarm.bench.dashboard_mobile import MobilePageReport
    from busarm.bench.ik import IkBenchReport
    from busarm.bench.line import LineBenchReport
    from busarm.bench.locate import LocateBenchReport
    from busarm.bench.mobile import MobileBenchReport
    from busarm.bench.pick import PickBenchReport
    from busarm.bench.transport import TransportBenchReport
    from busarm.bench.vision import VisionBenchReport

__all__ = [
    "TARGET_BOARD_SCAN_S",
    "TARGET_CPU_US",
    "TARGET_RATIO",
    "TARGET_SCAN_S",
    "bench",
    "bench_dashboard",
    "bench_ik",
    "bench_line",
    "bench_locate",
    "bench_mobile",
    "bench_pick",
    "bench_ros",
    "bench_transport",
    "bench_vision",
]


TARGET_RATIO = 0.90
TARGET_SCAN_S = 0.5
"""An ID scan 0..253 on the LX line (each ID waited for as long as its reply can take)."""
TARGET_BOARD_SCAN_S = 1.5
"""... and through the controller board (which waits for every absent ID itself)."""
TARGET_CPU_US = 35.0


@click.group(invoke_without_command=True)
@click.option("--ids", "servo_ids", type=IdListType(), default="1,2,3,4,5,10", show_default=True,
              help="Servos on the bus; the first is used for the position-read run.")
@click.option("--reads", type=click.IntRange(10, 1_000_000), default=3000, show_default=True,
              help="Position reads to time.")
@click.option("--loops", type=click.IntRange(1, 100_000), default=200, show_default=True,
              help="Full state loops (position, temperature, voltage of every servo).")
@click.option("--scans", type=click.IntRange(1, 100), default=3, show_default=True,
              help="Full ID scans 0..253.")
@click.option("--turnaround-ms", type=RangeType("turnaround", 0.0, 100.0, "ms"), default=0.5,
              show_default=True,
              help="Servo reply delay in ms, used for the wire limit (and by the simulator).")
@click.option("--sim-echo", is_flag=True,
              help="With --port sim: the simulated adapter echoes what is sent (one-wire style).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def bench(
    settings: Settings, servo_ids: list[int], reads: int, loops: int, scans: int,
    turnaround_ms: float, sim_echo: bool, as_json: bool,
) -> None:
    """Measure position reads, a full-arm state loop and an ID scan against the wire limit.

    With the default port `sim`, the simulated arm runs in its own process on a
    pseudo-terminal with 115200-baud wire timing, so the numbers include the real
    serial path. On hardware (`--port /dev/ttyUSB0`) this is the first diagnostic to
    run: a rate far below the wire limit points at adapter latency or a noisy bus.
    `busarm bench ik` measures the arm's inverse kinematics instead. A benchmark that
    judges its report against targets (ik, locate, vision, dashboard, pick) exits with
    code 1 when it prints FAIL, after the whole report (--json too).
    """
    if click.get_current_context().invoked_subcommand is not None:
        return
    kwargs = dict(servo_ids=servo_ids, reads=reads, loops=loops, scans=scans,
                  turnaround_ms=turnaround_ms, echo=settings.echo,
                  timeout_margin_s=settings.timeout_margin_ms / 1000.0,
                  progress=lambda text: settings.err.print(f"bench {text}", highlight=False))
    world = settings.world(settings.port)
    if isinstance(world, SimSpec):  # the simulator in its own process, on a pty
        ids = ",".join(map(str, servo_ids))
        board = world.through_board
        with sim_pty_server(turnaround_ms, ids, echo=sim_echo, board=board) as path:
            report = run_bench(settings.world(path), **kwargs)  # type: ignore[arg-type]
        report.port = f"{settings.port} (own process, pty {path.removeprefix('board://')})"
    else:
        report = run_bench(world, **kwargs)  # type: ignore[arg-type]
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=2))
    else:
        _print(settings, report)


def _print(settings: Settings, report: BusBenchReport) -> None:
    m = report.machine
    line = (f"servo line {report.baudrate} baud behind a controller board "
            f"({report.board_baudrate:,} baud)" if report.board_baudrate else
            f"{report.baudrate} baud")
    settings.out.print(
        f"[bold]busarm bench[/] on {report.port}: {line}, turnaround "
        f"{report.turnaround_ms} ms, echo {'on' if report.echo else 'off'}\n"
        f"{machine_line(m)}"
    )
    table = Table()
    for col in ("measurement", "rate", "wire limit", "of limit", "p50 ms", "p99 ms",
                "client CPU", "errors"):
        table.add_column(col, justify="left" if col == "measurement" else "right")
    for r in report.results:
        ok = r.ratio >= TARGET_RATIO
        table.add_row(
            r.name,
            f"{r.rate:,.1f} {r.unit}",
            f"{r.wire_limit:,.1f}",
            f"[{'green' if ok else 'yellow'}]{r.ratio:.1%}[/]",
            f"{r.latency_ms['p50']:.3f}",
            f"{r.latency_ms['p99']:.3f}",
            "" if r.cpu_us_median is None else f"{r.cpu_us_median:.1f} us",
            str(r.errors),
        )
    settings.out.print(table)
    if report.board_link_reads_s is not None:
        settings.out.print(
            f"wire limit: both legs, the board's {report.board_baudrate:,}-baud link and the "
            f"{report.baudrate}-baud servo line behind it; the link alone would allow "
            f"{report.board_link_reads_s:,.0f} position reads/s. A scan through the board "
            "waits, for every absent ID, as long as the board waits for its reply.")
    scan = report.results[-1].scan  # bench_scan is always last
    assert scan is not None
    target_s = TARGET_BOARD_SCAN_S if report.board_baudrate else TARGET_SCAN_S
    settings.out.print(
        f"scan: best {scan.best_s} s, median {scan.median_s} s "
        f"(target <= {target_s} s), found {len(scan.found)} servo(s)"
        + (f": {listing(scan.found)}" if scan.found else "")
    )
    if scan.board_floor_s is not None and scan.board_absent_id_s is not None:
        settings.out.print(
            f"the board answers an absent ID in {scan.board_absent_id_s * 1e3:.1f} ms "
            f"(measured), so a scan through it takes at least {scan.board_floor_s} s")


@bench.command("ik")
@click.option("--n", "n", type=click.IntRange(10, 1_000_000), default=10_000, show_default=True,
              help="How many random targets for accuracy and single-call timing.")
@click.option("--batch-n", type=click.IntRange(10, 100_000_000), default=1_000_000,
              show_default=True, help="Rows for the ik_batch throughput run.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the random joint vectors and targets.")
@click.option("--peers", is_flag=True,
              help="Also time Robotics Toolbox and ikpy on the same targets (make bench-ik).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_ik(
    settings: Settings, n: int, batch_n: int, seed: int, peers: bool, as_json: bool,
) -> None:
    """Accuracy and speed of the arm's closed-form IK (no bus), optionally beside peers."""
    from busarm.bench.ik import run_ik_bench  # numpy only when asked for

    report = run_ik_bench(n=n, batch_n=batch_n, seed=seed, peers=peers)
    judged(settings, as_json, report.to_dict(), lambda shown: _print_ik(shown, report))


def _ik_table(report: IkBenchReport) -> Table:
    """busarm's single-call and batch rates, and the peers', against the targets."""
    from busarm.bench.ik import TARGET_BATCH_PER_S, TARGET_SINGLE_US

    table = Table()
    for col in ("solver", "n", "median us", "p90 us", "rate", "target / ratio"):
        table.add_column(col, justify="left" if col == "solver" else "right")
    for t in report.single:
        target = ""
        if t.name.startswith("ik_best"):
            target = f"<= {TARGET_SINGLE_US:g} us {verdict(t.median_us <= TARGET_SINGLE_US)}"
        table.add_row(f"busarm {t.name}", str(t.n), f"{t.median_us:.2f}", f"{t.p90_us:.2f}",
                      f"{1e6 / t.median_us:,.0f}/s", target)
    b = report.batch
    batch_ok = verdict(b.solves_per_s >= TARGET_BATCH_PER_S)
    table.add_row(f"busarm ik_batch{'' if b.all_ok else ' (NOT all ok)'}", f"{b.n:,}",
                  "", "", f"{b.solves_per_s:,.0f}/s", f">= {TARGET_BATCH_PER_S:,.0f}/s {batch_ok}")
    for p in report.peers:
        table.add_row(p.name,
                      str(p.n), f"{p.median_us:.2f}", f"{p.p90_us:.2f}",
                      f"{1e6 / p.median_us:,.0f}/s", f"{p.ratio:g}x busarm")
    return table


def _print_ik(settings: Settings, report: IkBenchReport) -> None:
    from busarm.bench.ik import POS_TOL_MM, ROT_TOL_DEG

    m, a, o = report.machine, report.accuracy, report.outside
    out = settings.out
    out.print(
        f"[bold]busarm bench ik[/]: {report.arm}\n{machine_line(m)}"
    )
    out.print(
        f"accuracy: {a.n} random joint vectors in the limits (seed {a.seed}), target = FK "
        f"pose; table check OFF (pure geometry: some put the tool under the table)\n"
        f"  ik: {a.solutions} solutions, failures {a.failures} (no solution {a.no_solution}, "
        f"pose > {POS_TOL_MM} mm / {ROT_TOL_DEG} deg {a.wrong_pose}, out of limits "
        f"{a.out_of_limits}) {verdict(a.failures == 0)}; worst {a.worst_pos_mm:.2e} mm, "
        f"{a.worst_rot_deg:.2e} deg\n"
        f"  ik_best failures {a.best_failures} {verdict(a.best_failures == 0)}; ik_batch "
        f"failures {a.batch_failures} {verdict(a.batch_failures == 0)}, worst "
        f"{a.batch_worst_pos_mm:.2e} mm, {a.batch_worst_rot_deg:.2e} deg"
    )
    refused = o.accepted_ik + o.accepted_batch + o.accepted_ik_no_limits \
        + o.accepted_batch_no_limits == 0
    out.print(
        f"just outside: {o.n} targets with the wrist {o.margin_mm} mm beyond full stretch: "
        f"accepted by ik {o.accepted_ik}, ik_batch {o.accepted_batch}; with no joint limits "
        f"and free roll {o.accepted_ik_no_limits} / {o.accepted_batch_no_limits} "
        f"{verdict(refused)}\n"
        f"  control, {o.margin_mm} mm inside, no limits: accepted {o.inside_accepted_no_limits}"
        f"/{o.n} {verdict(o.inside_accepted_no_limits == o.n)}"
    )
    out.print(_ik_table(report))
    out.print(f"timing: {report.timing_method}; timer overhead {report.timer_overhead_ns:g} ns")
    for p in report.peers:
        out.print(f"{p.name}: {p.version}; ok {p.success}/{p.n} (claims {p.claimed}), median "
                  f"error {p.median_pos_mm:.1e} mm, {p.median_rot_deg:.1e} deg")
    if report.peers:
        out.print(f"ratio = peer median / busarm ik_best median on the same targets; "
                  f"ok = within {POS_TOL_MM} mm and {ROT_TOL_DEG} deg and within the limits")
    if report.peers_note:
        out.print(f"[yellow]{report.peers_note}[/]")


@bench.command("locate")
@click.option("--placements", type=click.IntRange(1, 100_000), default=200, show_default=True,
              help="Block placements to locate (several per picture).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the calibration views and the placements.")
@click.option("--keep", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Keep the calibration files the run makes in this folder.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_locate(settings: Settings, placements: int, seed: int, keep: Path | None,
                 as_json: bool) -> None:
    """Localisation accuracy on the twin, with calibrations made by our own flows.

    Calibrates the twin's camera (intrinsics from chessboard pictures, hand-eye from a tag
    board, lens distortion on), then places blocks over the table the arm reaches and
    compares where the camera puts them with where they are. Takes about a minute.
    """
    from busarm.bench.locate import run_locate_bench

    report = run_locate_bench(placements=placements, seed=seed, work_dir=keep,
                              progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: _print_locate(shown, report))


def _print_locate(settings: Settings, report: LocateBenchReport) -> None:
    from busarm.bench.locate import TARGET_MEDIAN_MM, TARGET_P95_MM
    from busarm.vision.calibration import distortion_text

    intr, he, a = report.calibration.intrinsics, report.calibration.hand_eye, report.accuracy
    ok_median = a.median_mm <= TARGET_MEDIAN_MM
    ok_p95 = a.p95_mm <= TARGET_P95_MM
    settings.out.print(
        f"[bold]busarm bench locate[/] (twin, lens distortion "
        f"{distortion_text(report.twin_lens_distortion)})\n"
        f"intrinsics: rms {intr.rms_px:.3f} px over {intr.views} views; hand-eye: rms "
        f"{he.rms_px:.3f} px over {he.views} views, {he.error_vs_truth_mm:.2f} mm / "
        f"{he.error_vs_truth_deg:.3f} deg from the truth\n"
        f"placements {a.placements}: located {a.located}, missed {a.missed}, wrong "
        f"colour {a.wrong_color}, in {a.pictures} pictures\n"
        f"location error: median {a.median_mm:.2f} mm "
        f"({verdict(ok_median)} <= {TARGET_MEDIAN_MM:g}), "
        f"p95 {a.p95_mm:.2f} mm ({verdict(ok_p95)} "
        f"<= {TARGET_P95_MM:g}), max {a.max_mm:.2f} mm")


@bench.command("vision")
@click.option("--pictures", type=click.IntRange(1, 1000), default=24, show_default=True,
              help="Twin pictures (640x480, 4-6 blocks) to cycle over.")
@click.option("--seconds", type=click.FloatRange(0.5, 600.0), default=3.0, show_default=True,
              help="Time per measured case in s.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the twin scenes pictured.")
@click.option("--family", type=click.Choice(["all", "random", "clutter"]), default="all",
              show_default=True,
              help="Scene families pictured for detect + localise: spaced-out blocks "
                   "(random), the pick bench's cluttered tables (clutter), or both.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_vision(settings: Settings, pictures: int, seconds: float, seed: int, family: str,
                 as_json: bool) -> None:
    """Colour detection beside the vendor-style pipeline, and full detect + localise, on
    one core at 640x480 (twin pictures): per scene family, with and without judging
    each blob's shape."""
    from busarm.bench.vision import run_vision_bench

    families = ("random", "clutter") if family == "all" else (family,)
    report = run_vision_bench(pictures=pictures, seed=seed, seconds_per_case=seconds,
                              families=families)
    judged(settings, as_json, report.to_dict(), lambda shown: _print_vision(shown, report))


def _print_vision(settings: Settings, report: VisionBenchReport) -> None:
    from busarm.bench.vision import TARGET_SPEEDUP

    d = report.detection
    ok_speed = d.speedup >= TARGET_SPEEDUP
    settings.out.print(
        f"[bold]busarm bench vision[/]: {report.pictures} twin pictures "
        f"{d.width_px}x{d.height_px} a family, one core; rates in frames per second of "
        f"CPU time\n"
        f"vendor-style pipeline {d.vendor_fps:.0f} frames/s, ours {d.ours_fps:.0f} "
        f"frames/s: {d.speedup:.2f}x ({verdict(ok_speed)} "
        f">= {TARGET_SPEEDUP:g}x); same blocks in {d.agreement.same_counts_frames}/{d.frames} "
        f"pictures ({report.families[0].family})")
    for rate in report.families:
        settings.out.print(
            f"detect + localise ({rate.family}): {rate.fps:.0f} frames/s "
            f"({verdict(rate.met)} >= {rate.target_fps:g}), {rate.blocks_located} blocks "
            f"located; shapes judged too: {rate.judged_fps:.1f} frames/s, "
            f"{rate.judged_blocks} blocks")


@bench.command("dashboard")
@click.option("--seconds", type=click.FloatRange(1.0, 600.0), default=10.0, show_default=True,
              help="How long two pages and two camera streams are measured, in s.")
@click.option("--tries", type=click.IntRange(1, 1000), default=50, show_default=True,
              help="E-stops (and lost heartbeats) measured.")
@click.option("--mobile", is_flag=True,
              help="The mobile robot's page (an arena twin): state and scan rates to two "
                   "pages; key release, lost heartbeat and e-stop to the wheels stopped.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_dashboard(settings: Settings, seconds: float, tries: int, mobile: bool,
                    as_json: bool) -> None:
    """The dashboard on the twin in real time: state rate to two pages while two camera
    streams run; e-stop (sent to MOVE_STOP at the servos) and lost-heartbeat stop times.
    With --mobile, the mobile robot's page and the base's stops."""
    if mobile:
        from busarm.bench.dashboard_mobile import run_mobile_page_bench

        mobile_report = run_mobile_page_bench(seconds=seconds, tries=tries,
                                              progress=settings.err.print)
        judged(settings, as_json, mobile_report.as_dict(),
                lambda shown: _print_mobile_page(shown, mobile_report))
        return
    from busarm.bench.dashboard import run_dashboard_bench

    report = run_dashboard_bench(seconds=seconds, tries=tries, progress=lambda text: None
                                 if " view " in text else settings.err.print(text))
    judged(settings, as_json, report.as_dict(), lambda shown: _print_dashboard(shown, report))


def _print_dashboard(settings: Settings, report: DashboardBenchReport) -> None:
    ok = verdict
    hz, fps = min(report.state_hz, default=0.0), min(report.camera_fps, default=0.0)
    settings.out.print(
        f"[bold]busarm bench dashboard[/] on the twin in real time ({report.machine['cpu']}, "
        f"{report.machine['cores']} cores)\n"
        f"two browsers: state {', '.join(f'{v:.1f}' for v in report.state_hz)} Hz "
        f"({ok(hz >= 20)} >= 20) while the wrist camera ({report.camera_size}) streamed to "
        f"them at {', '.join(f'{v:.1f}' for v in report.camera_fps)} fps ({ok(fps >= 15)} "
        f">= 15; the overview at {', '.join(f'{v:.1f}' for v in report.overview_fps)})\n"
        f"e-stop sent -> MOVE_STOP at the servos, {report.tries} tries: p50 "
        f"{report.estop_ms['p50']:.1f} ms, p99 {report.estop_ms['p99']:.1f} ms, max "
        f"{report.estop_ms['max']:.1f} ms ({ok(report.estop_ms['p99'] <= 100)} p99 <= 100)\n"
        f"heartbeat lost -> MOVE_STOP: p50 {report.deadman_ms['p50']:.0f} ms, max "
        f"{report.deadman_ms['max']:.0f} ms ({ok(report.deadman_ms['max'] <= 400)} <= 400)")


def _print_mobile_page(settings: Settings, report: MobilePageReport) -> None:
    ok = verdict
    hz, scan_hz = min(report.state_hz, default=0.0), min(report.scan_hz, default=0.0)
    release_p99 = report.key_release_ms["p99"]
    settings.out.print(
        f"[bold]busarm bench dashboard --mobile[/] on the arena twin in real time "
        f"({report.machine['cpu']}, {report.machine['cores']} cores)\n"
        f"two browsers: state {', '.join(f'{v:.1f}' for v in report.state_hz)} Hz "
        f"({ok(hz >= 20)} >= 20), Lidar scans {', '.join(f'{v:.1f}' for v in report.scan_hz)}"
        f" Hz ({ok(scan_hz >= 5)} >= 5), wrist camera "
        f"{', '.join(f'{v:.1f}' for v in report.camera_fps)} fps\n"
        f"key released -> wheels told 0, {report.tries} tries: p50 "
        f"{report.key_release_ms['p50']:.1f} ms, p99 {release_p99:.1f} ms, max "
        f"{report.key_release_ms['max']:.1f} ms ({ok(release_p99 <= 300)} p99 <= 300)\n"
        f"drives stop coming -> wheels told 0: p50 {report.deadman_ms['p50']:.0f} ms, max "
        f"{report.deadman_ms['max']:.0f} ms ({ok(report.deadman_ms['max'] <= 300)} <= 300)\n"
        f"e-stop sent -> wheels told 0: p50 {report.estop_ms['p50']:.1f} ms, p99 "
        f"{report.estop_ms['p99']:.1f} ms ({ok(report.estop_ms['p99'] <= 100)} p99 <= 100)")


@bench.command("pick")
@click.option("--scenes", type=click.IntRange(1, 10_000), default=50, show_default=True,
              help="Seeded twin scenes of 3-6 blocks to sort.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the first scene (scene i uses seed + i).")
@click.option("--workers", type=click.IntRange(1, 64), default=1, show_default=True,
              help="Scenes sorted side by side, each in its own process.")
@click.option("--family", type=click.Choice(["random", "clutter", "lookalike", "sized",
                                             "tagged"]),
              default="random", show_default=True,
              help="random: 3-6 blocks spaced out; clutter: 6-12 blocks in rows, clusters "
                   "and touching groups, things that are not blocks, lamp or window light; "
                   "lookalike: 3-6 cubes of 20-45 mm among cups, discs, bars and tall "
                   "boxes in block colours; sized: 4-6 cubes of 20-45 mm sorted by size "
                   "class; tagged: 3-5 tagged cubes sorted by tag id.")
@click.option("--realtime", is_flag=True,
              help="Run each twin on the wall clock (as `twin serve` does) instead of as "
                   "fast as the CPU allows: to compare the two.")
@click.option("--timeline", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also draw where the first 20 sorted blocks' cycles went (PNG).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_pick(settings: Settings, scenes: int, seed: int, workers: int, family: str,
               realtime: bool, timeline: Path | None, as_json: bool) -> None:
    """Pick-and-sort success rate, cycle time and localisation error over twin scenes.

    Calibrates the twin's camera with our flows first, then sorts each scene and checks
    the twin's truth: which blocks are in their bins, and whether a run ever reported a
    block sorted that is not. Twins run on a simulated clock, a few seconds per scene
    (with --realtime about 30 s); times in the report are twin seconds.
    """
    from busarm.bench.pick import run_pick_bench

    report = run_pick_bench(scenes=scenes, seed=seed, workers=workers, realtime=realtime,
                            family=family,
                            progress=said(settings))
    if timeline is not None:
        from busarm.bench.pick_timeline import draw_timeline

        draw_timeline(report.cycle_steps[:20], timeline,
                      f"busarm bench pick: {family} scenes from seed {seed}, median cycle "
                      f"{report.median_cycle_s} s of twin time")
    judged(settings, as_json, report.to_dict(), lambda shown: _print_pick(shown, report))


def _print_pick(settings: Settings, report: PickBenchReport) -> None:
    from busarm.bench.pick import TARGET_SORTED, TARGET_SPEEDUP, target_cycle_s

    ok_sorted = report.fitting_sorted_fraction >= TARGET_SORTED
    cycle = report.median_cycle_s
    target_s = target_cycle_s(report.family)
    ok_cycle = cycle is not None and cycle <= target_s
    settings.out.print(
        f"[bold]busarm bench pick[/]: {report.scenes} {report.family} scenes, "
        f"{report.blocks} blocks\n"
        f"in their bins: {report.in_their_bins} ({report.sorted_fraction:.1%})"
        + (f"; {report.beyond_bins} more than their bins hold (left with \"bin full\"): "
           f"{report.in_their_bins} of the {report.blocks - report.beyond_bins} that fit "
           f"({report.fitting_sorted_fraction:.1%})" if report.beyond_bins else "")
        + f" {verdict(ok_sorted)} >= {TARGET_SORTED:.0%}; "
        f"reported sorted but not: {report.reported_sorted_but_not}\n"
        f"cycle per block (twin time): median {cycle} s "
        f"({verdict(ok_cycle)} <= {target_s:g}; the vendor's "
        f"fixed grasp sequence alone takes about 5 s), "
        f"p95 {report.p95_cycle_s} s"
        + ("\nwhere a cycle goes (median s): " + ", ".join(
            f"{name} {t:.2f}" for name, t in report.median_phases_s)
           if report.median_phases_s else "")
        + ("" if report.clock != "wall" else
           f"; the twins fell behind the wall clock by {report.twin_slipped_s} s in all")
        + ("\nsurvey error median "
           f"{report.survey_error_median_mm} mm, p95 {report.survey_error_p95_mm} mm\n"
           if report.survey_error_median_mm is not None
           else "\nsurvey error: no block seen by the first survey\n")
        + (f"things that are not blocks: {report.distractors}, moved by the runs: "
           f"{report.distractors_moved}, in a bin: {report.not_blocks_binned}, reported "
           f"as blocks: {report.not_blocks_reported}\n" if report.distractors else "")
        + f"time: {report.sim_seconds} s of twin time in {report.seconds} s on this computer "
        f"({report.calibration_seconds} s of it calibrating), {report.workers} worker(s), "
        f"{report.clock} clock: {report.speedup:.1f}x real time"
        + ("" if report.clock == "wall" else
           f", the sorting alone {report.sorting_speedup:.1f}x"
           + ("" if report.workers > 1 else
              f" ({verdict(report.sorting_speedup >= TARGET_SPEEDUP)} >= "
              f"{TARGET_SPEEDUP:g}x on one worker)")))


@bench.command("mobile")
@click.option("--squares", type=click.IntRange(1, 100), default=5, show_default=True,
              help="2 m squares driven (each with its own slip noise seed).")
@click.option("--scans", type=click.IntRange(1, 1000), default=20, show_default=True,
              help="Lidar scans compared with the ray-cast truth (noise off, then on).")
@click.option("--seconds", type=RangeType("seconds", 1.0, 600.0, "s"), default=20.0,
              show_default=True, help="Simulated time of the real-time run, in s.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the arenas and of the first square's noise.")
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also draw the first square: the true path and the odometry's.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_mobile(settings: Settings, squares: int, scans: int, seconds: float, seed: int,
                 png: Path | None, as_json: bool) -> None:
    """The mobile twin (base, Lidar, arm and camera in an arena) against its ground truth.

    Odometry: 2 m squares by move_by with wheel slip on; the Lidar: every beam against the
    ray-cast truth; speed: driving, arm moving, camera at 10 fps and Lidar, in simulated
    seconds per wall second. About a minute.
    """
    from busarm.bench.mobile import run_mobile_bench

    report = run_mobile_bench(squares=squares, scans=scans, seconds=seconds, seed=seed,
                              picture=png,
                              progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: _print_mobile(shown, report))


def _print_mobile(settings: Settings, report: MobileBenchReport) -> None:
    from busarm.bench.mobile import (
        SIDE_M,
        TARGET_HEADING_DEG,
        TARGET_LIDAR_HZ,
        TARGET_LIDAR_M,
        TARGET_POSITION_SHARE,
        TARGET_REALTIME,
    )

    out = settings.out
    out.print(f"[bold]busarm bench mobile[/] (twin, slip and sensor noise on)\n"
              f"{machine_line(report.machine)}")
    table = Table(title=f"odometry: {SIDE_M:g} m squares by move_by (encoders + IMU)")
    for col in ("seed", "driven", "position error", "share", "heading error",
                "worst corner"):
        table.add_column(col, justify="right")
    for run in report.squares:
        table.add_row(str(run.seed), f"{run.driven_m:g} m", f"{run.position_error_m * 100:.1f} cm",
                      f"{run.position_share:.2%} "
                      f"{verdict(run.position_share <= TARGET_POSITION_SHARE)}",
                      f"{run.heading_error_deg:.2f} deg "
                      f"{verdict(run.heading_error_deg <= TARGET_HEADING_DEG)}",
                      f"{run.worst_corner_share:.2%}")
    out.print(table)
    out.print(f"targets: position <= {TARGET_POSITION_SHARE:.0%} of the distance, heading <= "
              f"{TARGET_HEADING_DEG:g} deg at the end (worst corner: the error at a corner "
              "over the distance to it, the drift a closed square partly hands back)"
              + (f"; picture of seed {report.squares[0].seed}: {report.picture}"
                 if report.picture else ""))
    a, r = report.lidar, report.realtime
    out.print(f"Lidar (seeded arena {a.seed}, robot standing, {a.scans} scans, {a.beams} beams "
              f"with a surface in reach): noise off, largest error {a.max_error_m * 1000:.2f} mm "
              f"({verdict(a.max_error_m <= TARGET_LIDAR_M)} <= {TARGET_LIDAR_M * 1000:g} mm); "
              f"noise on, residual RMS {a.sigma_ratio:.2f} x the model's sigma, dropouts "
              f"{a.dropout_share:.1%}")
    out.print(f"real time: {r.sim_s:.1f} simulated s in {r.wall_s:.1f} s: {r.factor:.1f}x "
              f"({verdict(r.factor >= TARGET_REALTIME)} >= {TARGET_REALTIME:g}x) with the base "
              f"driving, the arm moving, the wrist camera streamed {r.camera_fps:.1f} frames "
              f"and the Lidar {r.lidar_hz:.1f} scans a simulated second "
              f"({verdict(r.lidar_hz >= TARGET_LIDAR_HZ)} >= {TARGET_LIDAR_HZ:g} Hz)")
    v = report.realtime_vision
    out.print(f"with the camera drawn as vision's pictures (antialiased) instead: "
              f"{v.factor:.1f}x ({v.camera_fps:.1f} frames, {v.lidar_hz:.1f} scans a "
              "simulated second)")


@bench.command("transport")
@seeded_world_options("arenas", 30, "Seeded twin arenas (arena i uses seed + i).")
@click.option("--family", type=click.Choice(list(ROOM_FAMILIES)), default="standard",
              show_default=True, help="The rooms: the line arenas (standard), two rooms "
              "through a door, two joined by a corridor, the block in a corner, a big sparse "
              "room, a symmetric room, a carry over 8 m.")
def bench_transport(settings: Settings, arenas: int, seed: int, workers: int,
                    as_json: bool, family: str) -> None:
    """Navigation transport over seeded twin rooms, against the twin's truth: each room
    mapped by exploring, the robot carried elsewhere, then fetching the floor block from
    the pick point to the place point from an unknown start. About a minute a room."""
    from busarm.bench.transport import run_transport_bench

    report = run_transport_bench(arenas=arenas, seed=seed, workers=workers, family=family,
                                 progress=said(settings))
    judged(settings, as_json, report.to_dict(),
            lambda shown: _print_seeded(shown, "transport", report))


@bench.command("line")
@seeded_world_options("layouts", 20, "Seeded line layouts (layout i uses seed + i): 0-3 "
                       "blocks, 0-2 obstacles.")
@click.option("--family", "family", default="black", show_default=True,
              type=click.Choice(["black", "blue", "red", "green", "yellow", "white"]),
              help="The tape's colour (white: on a dark floor); the layouts are the same, "
                   "black is them as they always were. The robot is not told it.")
def bench_line(settings: Settings, layouts: int, seed: int, workers: int,
               as_json: bool, family: str) -> None:
    """Line following over seeded twin layouts, against the twin's truth: one lap each,
    blocks on the tape to clear, a box stepping onto it to stop for; the tape's colour
    measured on the first look, and every stop checked for something truly in the way.
    About a minute a layout."""
    from busarm.bench.line import run_line_bench

    report = run_line_bench(layouts=layouts, seed=seed, workers=workers, family=family,
                            progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: _print_seeded(shown, "line", report))


@bench.command("ros")
@click.option("--seconds", type=RangeType("seconds", 1.0, 600.0, "s"), default=10.0,
              show_default=True, metavar="S", help="How long to measure the streams, in s.")
@click.option("--drops", type=click.IntRange(1, 100), default=3, show_default=True,
              help="Links dropped mid-move, of each kind.")
@click.option("--blocks", type=click.IntRange(1, 8), default=5, show_default=True,
              help="Blocks on the seeded table the remote pick-sort sorts.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=3, show_default=True,
              help="Seed of the table.")
@click.option("--report", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="Folder for the MCAP file and the pick-sort reports "
                                 "[default: a temporary one]")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
@no_servos
def bench_ros(settings: Settings, seconds: float, drops: int, blocks: int, seed: int,
              out_dir: Path | None, as_json: bool) -> None:
    """The ROS 2 bridge between two busarm processes on loopback, against the twin's truth:
    /joint_states rate and latency, camera frames/s, a trajectory, links dropped
    mid-move, bad samples and a flood, pick-sort over zenoh:// recorded into MCAP. About
    four minutes."""
    from busarm.bench.ros import run_ros_bench

    report = run_ros_bench(seconds=seconds, drops=drops, blocks=blocks, seed=seed,
                           out_dir=out_dir, progress=said(settings))
    judged(settings, as_json, report.as_dict(), lambda shown: shown.out.print(
        "[bold]busarm bench ros[/]: " + report.text(verdict), highlight=False))


def _print_seeded(settings: Settings, name: str,
                  report: TransportBenchReport | LineBenchReport) -> None:
    """A benchmark over seeded twin worlds: its report's text, the targets judged."""
    settings.out.print(f"[bold]busarm bench {name}[/]: {report.text(verdict)}",
                       highlight=False)
