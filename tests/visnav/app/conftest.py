"""Helpers of the report tests (``test_report.py``, ``test_report_committed.py``): running the console script."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from analysis.verdicts import EXIT_CODES

ROOT = Path(__file__).resolve().parents[3]
COMMITTED = ROOT / "reports" / "paper"


def _run_report(out: Path, *extra: str, hashseed: str = "7", blas_threads: str | None = None
                ) -> subprocess.CompletedProcess:
    # the console script, exactly as `make demo` runs it: hypothesis mixes constants of the imported
    # project modules into its draws, so `python -m visnav.app.cli` (which imports the CLI twice) could differ
    env = {**os.environ, "PYTHONHASHSEED": hashseed}
    if blas_threads is not None:  # the CLI must override it: threaded LAPACK changes the round-off
        env["OPENBLAS_NUM_THREADS"] = blas_threads
    script = Path(sys.executable).with_name("visnav")
    return subprocess.run([str(script), "report", "--scenario", "paper", "--out", str(out), *extra],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)


def _assert_exit_is_the_verdicts(done: subprocess.CompletedProcess, out: Path) -> None:
    """The report exits with its verification's code: 0 proven / not falsified, 1 falsified, 3 diverged."""
    assert (out / "report.json").is_file(), done.stderr
    verdict = json.loads((out / "report.json").read_text())["verdict"]
    assert done.returncode == EXIT_CODES[verdict], (verdict, done.stderr)


def _counterexamples(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((folder / "counterexamples").glob("*.json"))}



@pytest.fixture(scope="session")
def report_tools() -> SimpleNamespace:
    """``run`` (the console script), ``exit_is_the_verdicts``, ``counterexamples``, ``committed`` (the folder)."""
    return SimpleNamespace(run=_run_report, exit_is_the_verdicts=_assert_exit_is_the_verdicts,
                           counterexamples=_counterexamples, committed=COMMITTED)
