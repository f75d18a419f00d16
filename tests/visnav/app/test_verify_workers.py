"""``visnav verify --workers N``: the same seed gives byte-identical JSON whatever the worker count."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _verify(tmp_path: Path, *extra: str) -> subprocess.CompletedProcess:
    out = tmp_path / ("w" + "_".join(extra).replace("-", ""))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", "examples/thermostat.py:problem",
                           "--method", "monte-carlo", "--budget", "6", "--seed", "3", "--json", "--out", str(out),
                           *extra], capture_output=True, cwd=ROOT, env=env, timeout=600)


def test_the_thermostat_verdicts_do_not_depend_on_the_worker_count(tmp_path):
    alone, pooled = _verify(tmp_path), _verify(tmp_path, "--workers", "2")
    assert alone.returncode == pooled.returncode == 0, (alone.stderr, pooled.stderr)
    assert b'"method": "monte-carlo"' in alone.stdout and b'"points": 6' in alone.stdout
    assert alone.stdout == pooled.stdout
