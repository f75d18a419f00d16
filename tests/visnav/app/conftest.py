"""Helpers of the CLI tests: ``cli`` (the command line in-process) and, for the report tests (``test_report.py``,
``test_report_committed.py``), running the console script."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import pytest

from visnav.app.cli_types import VERDICT_EXIT_CODES as EXIT_CODES

from visnav.app.verification_report import REPORT_EXIT_CODES

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
    """The report exits with its verdict's code: 0 proven / not falsified, 1 falsified or a structural error,
    3 diverged (:data:`visnav.app.verification_report.REPORT_EXIT_CODES`)."""
    assert (out / "report.json").is_file(), done.stderr
    data = json.loads((out / "report.json").read_text())
    verdict = data["verdict"]
    assert done.returncode == REPORT_EXIT_CODES[verdict] == data["exit_code"], (verdict, done.stderr)
    assert REPORT_EXIT_CODES[verdict] == EXIT_CODES.get(verdict, 1)  # the verification's own code, or a finding


def _counterexamples(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((folder / "counterexamples").glob("*.json"))}



@pytest.fixture
def cli(capsys) -> Callable[..., tuple[int, str, str]]:
    """``cli(*argv) -> (exit code, stdout, stderr)``: the command line run in-process by ``visnav.app.cli.main``.

    ``main`` must return its exit code: a ``SystemExit`` (or anything else) escaping it is not caught here.
    """
    from visnav.app.cli import main

    def run(*argv: object) -> tuple[int, str, str]:
        code = main([str(a) for a in argv])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run


@pytest.fixture(scope="session")
def report_tools() -> SimpleNamespace:
    """``run`` (the console script), ``exit_is_the_verdicts``, ``counterexamples``, ``committed`` (the folder)."""
    return SimpleNamespace(run=_run_report, exit_is_the_verdicts=_assert_exit_is_the_verdicts,
                           counterexamples=_counterexamples, committed=COMMITTED)


SYMBOLIC_THERMOSTAT = '''
"""A user's thermostat written with hybrid.symbolic guards, invariants and flows, checked over a box."""
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter
from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.symbolic import coordinates, flow_map

v = coordinates("T")
automaton = HybridAutomaton(
    name="symbolic-thermostat",
    modes=(Mode(name="off", invariant=v.T - 19.0), Mode(name="on", invariant=21.0 - v.T)),
    transitions=(Transition(name="heat_on", source="off", target="on", guard=19.0 - v.T),
                 Transition(name="heat_off", source="on", target="off", guard=v.T - 21.0)),
    variables=("T",), initial_mode="off")
system = HybridSystem(automaton=automaton, state_names=("T",),
                      flows={"off": flow_map(-0.1 * (v.T - 10.0)), "on": flow_map(-0.1 * (v.T - 30.0))})
problem = hybrid_problem(
    name="symbolic-thermostat", system=system,
    initial={"T": Parameter(name="T0", low=19.5, high=20.5, nominal=20.0)},
    horizon=20.0, sample_period=0.5, check_box=Box(bounds={"T": (15.0, 25.0)}),
    requirements=(Requirement(name="comfort", formula="always[0, 20] (abs(T - 20) <= 1.5)",
                              description="the room stays within 1.5 of 20"),))
'''
"""A problem file with a symbolic model: its structural checks are decided by the SMT solver (PROVEN)."""


@pytest.fixture()
def symbolic_problem(tmp_path: Path) -> str:
    """``FILE.py:problem`` of :data:`SYMBOLIC_THERMOSTAT` written in the test's folder."""
    path = tmp_path / "symbolic_thermostat.py"
    path.write_text(SYMBOLIC_THERMOSTAT)
    return f"{path}:problem"
