"""``benchmarks/bench_reach.py --quick``: the small instances get their expected verdicts, soundly.

The expected verdicts are the closed forms' (``benchmarks/reach_instances.py``: the thermostat switches at
exactly 19 and 21, the ball never rises above its initial energy height, the switched pair keeps ``|x|``, the
tanks keep their total volume), computed there independently of the engine.  The soundness part runs seeded
executor simulations (scipy's RK45 with located events) and checks every step point against the flowpipe, and
checks that the planted sets reaching 0.01 inside the true reach set are never proven.  The peers (Hylaa) are not
needed here (``--no-peers``).
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "bench_reach.py"
TRUE_SLACK = {"bouncing ball": 0.02, "thermostat": 0.05, "two tanks": 0.05, "switched pair": 0.1}
"""Closed forms: the corner (1, ±0.1) reaches the apex h0 + v0²/(2g) (requirement: apex + 0.02); T reaches 19 and
21 (band ±0.05 beyond); the volume 2.2 and the empty level 0 are reached (2.25, -0.05); y = 2.5 at t = 0 (2.6)."""


@pytest.fixture(scope="module")
def quick():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    start = time.perf_counter()
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--json", "--repeats", "1", "--soundness", "25",
                           "--no-peers"], capture_output=True, text=True, env=env, timeout=300, cwd=ROOT)
    took = time.perf_counter() - start
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout), took


def test_quick_rows_get_the_expected_verdicts(quick):
    doc, _ = quick
    rows = {r["name"]: r for r in doc["rows"] if r.get("kind") != "nonlinear"}
    assert set(rows) == {"bouncing ball", "thermostat", "switched pair", "two tanks"}
    for name, row in rows.items():
        assert row["ours"]["verdict"] == row["expected"] == "safe", (name, row["ours"].get("reason"))
        assert row["ours"]["status"] == "complete"
        assert 0.0 < row["ours"]["margin"] <= TRUE_SLACK[name], name  # sound: never above the true slack


def test_quick_soundness(quick):
    doc, _ = quick
    for row in doc["rows"]:
        if row.get("kind") == "nonlinear":
            continue
        planted = row["planted"]
        assert planted["inside_proven"] == [], row["name"]  # reachable sets are never proven unreachable
        assert planted["inside"] >= 1
        sims = row["simulations"]
        assert sims["outside"] == 0, (row["name"], sims["example"])
        assert sims["runs"] >= 4 and sims["points"] > 100


def test_thermostat_margin_against_the_closed_form(quick):
    """The band [18.95, 21.05] has the true slack 0.05 (T reaches 19 and 21 exactly): a sound margin is below it."""
    doc, _ = quick
    row = next(r for r in doc["rows"] if r["name"] == "thermostat")
    assert 0.045 < row["ours"]["margin"] <= 0.05
