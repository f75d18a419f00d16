"""The quick run of ``benchmarks/bench_simulation.py``: both paths agree and the closed form is cheaper.

The timing assertion is loose on purpose (CPU time, shared machine): the thermostat's closed form is several
times cheaper per simulation than RK45 (the full run prints the ratio); the agreement assertions are the
executor's tolerances.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_simulation.py"


def test_quick_benchmark_agrees_and_the_closed_form_is_cheaper(capsys):
    spec = importlib.util.spec_from_file_location("bench_simulation", BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    results = bench.main(["--quick"])
    out = capsys.readouterr().out
    assert "thermostat" in out and "bouncing ball" in out and "ratio" in out
    for name in ("thermostat", "bouncing ball"):
        r = results[name]
        assert r["same_verdicts"] and r["same_jump_counts"], name
        assert r["jump_times"] < 1e-6 and r["signals"] < 1e-6 and r["robustness"] < 1e-6, (name, r)
        assert r["numerical_s"] > 0 and r["closed_form_s"] > 0
    assert results["thermostat"]["ratio"] > 2.0, results["thermostat"]
    at = results["AT"]  # issue 29 asks >= 20 simulations/s/core; the bound here is loose (a shared machine)
    assert set(at["seconds"]) == set(bench.AT_PROBLEMS) and all(s > 0 for s in at["seconds"].values())
    assert "AT throughput" in out and at["sims_per_s"] > 5.0, at
    cc = results["CC"]  # about 45 simulations/s/core on an idle core (22 before the float fast path); loose bound
    assert set(cc["seconds"]) == set(bench.CC_PROBLEMS) and all(s > 0 for s in cc["seconds"].values())
    assert "CC throughput" in out and cc["sims_per_s"] > 10.0, cc
