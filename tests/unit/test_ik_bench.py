"""``busarm bench ik`` at a small size: structure and correctness, no timing asserts."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from busarm.bench.ik import run_ik_bench
from busarm.cli.main import cli


def test_run_ik_bench_small() -> None:
    r = run_ik_bench(n=200, batch_n=1000, seed=3)
    a, o = r.accuracy, r.outside
    assert a.n == 200 and a.check_table is False
    assert a.failures == 0 and a.no_solution == 0 and a.wrong_pose == 0
    assert a.out_of_limits == 0 and a.best_failures == 0 and a.batch_failures == 0
    assert a.solutions >= a.n
    assert a.worst_pos_mm <= 1e-3 and a.worst_rot_deg <= 1e-3
    assert o.n == 200
    assert o.accepted_ik == 0 and o.accepted_batch == 0
    assert o.accepted_ik_no_limits == 0 and o.accepted_batch_no_limits == 0
    assert o.inside_accepted_no_limits == o.n
    assert [t.name for t in r.single] == ["ik_best", "ik (all solutions)"]
    assert all(t.n == 200 and t.median_us > 0 for t in r.single)
    assert r.batch.n == 1000 and r.batch.all_ok and r.batch.solves_per_s > 0
    assert r.peers == [] and r.peers_note is None
    d = r.to_dict()
    assert {"machine", "accuracy", "outside", "single", "batch", "peers"} <= set(d)
    json.dumps(d)


def test_cli_bench_ik_json(monkeypatch: pytest.MonkeyPatch) -> None:
    # Targets met whatever the machine: a missed one (FAIL) would make the exit code 1.
    monkeypatch.setattr("busarm.bench.ik.TARGET_BATCH_PER_S", 0.0)
    monkeypatch.setattr("busarm.bench.ik.TARGET_SINGLE_US", float("inf"))
    res = CliRunner().invoke(cli, ["bench", "ik", "--n", "50", "--batch-n", "100", "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert d["accuracy"]["failures"] == 0 and d["outside"]["accepted_ik"] == 0
