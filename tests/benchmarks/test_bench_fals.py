"""benchmarks/bench_fals.py --quick: the harness runs, every method falsifies the planted bugs it should, and a
second invocation resumes from the results file (nothing run again)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_fals.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_fals", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_quick_run_falsifies_the_planted_bugs_and_resumes(tmp_path, capsys):
    bench = _bench()
    results = tmp_path / "results.jsonl"
    table = bench.main(["--quick", "--workers", "1", "--results", str(results), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert out["budget"] == 40 and out["seeds"] == 2
    assert set(table) == {"ACC-gross", "planted:line-corner", "planted:ramp-late"}
    for label, row in table.items():
        for method in ("guided", "whitebox"):
            assert row[method]["runs"] == 2 and row[method]["falsified"] == 2, (label, method, row[method])
            assert row[method]["errors"] == 0
    # Monte-Carlo cannot find ramp-late's needle (share 2.5e-4) in 40 draws; guided's vertices do
    assert table["planted:ramp-late"]["monte-carlo"]["falsified"] == 0
    lines = results.read_text().splitlines()
    assert len(lines) == sum(row[m]["runs"] for row in table.values() for m in out["methods"])
    again = bench.main(["--quick", "--workers", "1", "--results", str(results)])
    assert "0 to run" in capsys.readouterr().out
    assert again == table and results.read_text().splitlines() == lines


def _cell(falsified: int, mean: float | None) -> dict:
    return {"runs": 10, "falsified": falsified, "mean": mean, "median": mean}


def test_the_whitebox_goal_is_three_times_zlschecks_mean_and_every_run_falsified():
    bench = _bench()
    zl = bench.PUBLISHED["zlscheck 2020"]
    table = {"AT1": {"whitebox": _cell(10, 3 * 3.4), "published": {"zlscheck 2020": zl["AT1"]}},         # at the bound
             "AT2": {"whitebox": _cell(10, 3 * 15.5 + 0.1), "published": {"zlscheck 2020": zl["AT2"]}},  # just above
             "AT51": {"whitebox": _cell(9, 4.0), "published": {"zlscheck 2020": zl["AT51"]}},          # a run missed
             "AT52": {"whitebox": _cell(10, 10.5), "published": {"zlscheck 2020": zl["AT52"]}},        # <=3.5 -> 10.5
             "CC2": {"whitebox": _cell(10, 99.0), "published": {}}}                                   # no zlscheck figure
    assert bench.whitebox_goal(table) == ["AT2 mean 46.6 vs 46.5", "AT51 9/10 (mean 4.0 vs 10.5)"]
