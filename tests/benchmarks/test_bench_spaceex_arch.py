"""``benchmarks/bench_spaceex_arch.py --quick``: the ARCH-COMP instances decided in seconds get the published verdict.

The published verdicts are those of the ARCH-COMP AFF reports (docs/spaceex.md, "Published verdicts"), written in
the script beside each instance; visnav's verdict must agree with them (``proven`` where the report says safe,
``falsified`` where it says unsafe), and a proven margin is a lower bound of the true slack computed independently
in tests/analysis/test_spaceex_verdicts.py (the closed forms), so here it must only be positive.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "bench_spaceex_arch.py"


def test_quick_instances_get_the_published_verdicts():
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--json"], capture_output=True, text=True,
                          env=env, timeout=900, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    data = json.loads(done.stdout)
    rows = {r["instance"]: r for r in data["rows"]}
    assert set(rows) == {"BLDC01-BDU02", "BLDF01-BDU02", "PLAD01-BND42", "PLAA01-BND42", "GRBX01-MES01"}
    for name, row in rows.items():
        wanted = "proven" if row["published"] == "safe" else "falsified"
        assert row["verdict"] == wanted == row["expected"], row
        if wanted == "proven":
            assert row["flowpipe"] == "holds, re-checked" and row["margin"] > 0.0, row
