"""``visnav check-model``: no path prints a pass (CLEAN, exit 0) over a check that did not complete.

One test per path that used to pass wrongly (each fails on the code before ``hybrid.completeness``),
and the summary lines against the findings on every fixture.  The problems are in
``check_model_problems.py`` (the models of ``tests/hybrid/check_fixtures.py``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from visnav.app.cli import main
from visnav.app.cli_types import EXIT_CODES, EXIT_INCOMPLETE

PROBLEMS = Path(__file__).with_name("check_model_problems.py")


def _run(capsys, name: str, *args: str) -> tuple[int, str]:
    code = main(["check-model", "--problem", f"{PROBLEMS}:{name}", "--samples", "200", *args])
    return code, capsys.readouterr().out


def _json(capsys, name: str, *args: str) -> tuple[int, dict]:
    code, out = _run(capsys, name, *args, "--json")
    return code, json.loads(out)


def test_exit_incomplete_is_5_and_documented():
    assert EXIT_INCOMPLETE == 5 and EXIT_CODES[5] == "a check or run did not decide"


def test_smt_on_plain_callables_is_incomplete_not_clean(capsys):
    """`--method smt` on the zero band's plain lambdas: was CLEAN, exit 0, samples = 0."""
    code, out = _run(capsys, "plain_zero_band", "--method", "smt")
    first = out.splitlines()[0]
    assert code == EXIT_INCOMPLETE and "CLEAN" not in first and "INCOMPLETE" in first
    assert "deadlock" in first and "plain callables cannot be decided by SMT, use --method auto or sampled" in first
    assert "neither decided nor sampled" in out and "decided by z3" not in out
    assert not any(ln.split()[1:2] == ["SAMPLED"] for ln in out.splitlines()[1:])
    code, data = _json(capsys, "plain_zero_band", "--method", "smt")
    assert code == EXIT_INCOMPLETE and data["clean"] is False and data["complete"] is False
    assert data["statuses"]["deadlock"]["status"] == "skipped" and len(data["incomplete"]) == 4
    # auto on the same model: the two re-triggers, exit 1
    code, data = _json(capsys, "plain_zero_band")
    assert code == 1 and [f["kind"] for f in data["findings"] if f["severity"] == "error"] == ["reset_retriggers"] * 2


@pytest.mark.parametrize("guard", ["guard_raises", "guard_nan", "guard_none"])
@pytest.mark.parametrize("method", ["auto", "smt"])
def test_a_bad_guard_is_the_same_error_under_smt_and_auto(guard, method, capsys):
    """Guards raising, NaN, None: exit 3 under auto, but CLEAN exit 0 under smt before."""
    code = main(["check-model", "--problem", f"{PROBLEMS}:{guard}", "--samples", "50", "--method", method])
    err = capsys.readouterr().err
    assert code == 3 and "guard of transition 'heat_on'" in err and "Traceback" not in err


def test_a_problem_without_check_box_is_incomplete(capsys):
    """No check_box: all five state checks SKIPPED, summary CLEAN, exit 0 before."""
    code, out = _run(capsys, "no_check_box")
    first = out.splitlines()[0]
    assert code == EXIT_INCOMPLETE and "CLEAN" not in first
    assert "nondeterminism, deadlock, reset_outside_invariant, reset_retriggers, zeno skipped: no box given" in first
    code, data = _json(capsys, "no_check_box")
    assert data["complete"] is False and data["clean"] is False and len(data["incomplete"]) == 5


def test_time_reading_flow_under_smt(capsys):
    """Flows reading t under smt: UNDECIDED checks with a CLEAN summary and SAMPLED labels with samples = 0 before."""
    code, out = _run(capsys, "time_flow", "--method", "smt")
    assert code == EXIT_INCOMPLETE and "deadlock skipped" in out.splitlines()[0]
    assert not any(ln.split()[1:2] == ["SAMPLED"] for ln in out.splitlines()[1:])
    code, data = _json(capsys, "time_flow", "--method", "smt")
    assert all(m["samples"] == 0 for m in data["searched"]["modes"])
    assert "sampled" not in {c["status"] for c in data["claims"].values()}
    # with a zero band the re-trigger is decided by the solver, and auto finds it too
    code, data = _json(capsys, "time_flow_zero_band", "--method", "smt")
    assert code == 1 and data["complete"] is False
    code, data = _json(capsys, "time_flow_zero_band")
    assert code == 1 and any(f["kind"] == "reset_retriggers" for f in data["findings"])


def test_a_decided_symbolic_problem_is_clean(capsys):
    for method in ("auto", "smt"):
        code, out = _run(capsys, "symbolic", "--method", method)
        assert code == 0 and out.splitlines()[0].endswith(": CLEAN")
    code, data = _json(capsys, "symbolic")
    assert data["complete"] is True and data["incomplete"] == [] and data["clean"] is True


def _number(pattern: str, line: str) -> int:
    found = re.search(pattern, line)
    assert found, (pattern, line)
    return int(found.group(1))


EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "thermostat.py"
FIXTURES = [f"{PROBLEMS}:{name}" for name in ("plain_zero_band", "time_flow_zero_band", "time_flow", "plain_overlap",
                                              "symbolic", "no_check_box", "partial_box")]
FIXTURES += [f"{EXAMPLE}:problem", f"{EXAMPLE}:zero_band"]


@pytest.mark.parametrize("spec", FIXTURES, ids=lambda spec: spec.rsplit("/", 1)[-1])
@pytest.mark.parametrize("method", ["auto", "sampled", "smt"])
def test_summary_lines_agree_with_the_findings(spec, method, capsys):
    """'0 instantaneous' beside reset_retriggers errors, '0 can be enabled together' beside a priority_overlap
    before: every count of the summary lines is the number of the findings it counts (counted here from the JSON)."""
    args = ["check-model", "--problem", spec, "--samples", "200", "--method", method]
    code = main([*args, "--json"])
    data = json.loads(capsys.readouterr().out)
    assert main(args) == code
    out = capsys.readouterr().out
    kinds = [f["kind"] for f in data["findings"]]
    lines = out.splitlines()
    first = lines[0]
    errors, warnings = (sum(f["severity"] == s for f in data["findings"]) for s in ("error", "warning"))
    if errors or warnings:
        assert f"{errors} error(s), {warnings} warning(s)" in first and code == 1
    else:
        assert ("CLEAN" in first) == (code == 0) == data["complete"]
    for line in lines:
        if line.startswith("  Zeno: ") and "cycle(s) of the mode graph not decided" not in line:
            assert _number(r"; (\d+) instantaneous", line) == kinds.count("reset_retriggers")
            zeno_points = re.search(r"; (\d+) with a Zeno point", line)
            assert (int(zeno_points.group(1)) if zeno_points else 0) == kinds.count("zeno_point")
        if line.startswith("  pairs: "):
            assert _number(r": (\d+) can be enabled together", line) == (kinds.count("nondeterminism")
                                                                         + kinds.count("priority_overlap"))
            assert _number(r"equal-priority overlaps: (\d+)", line) == kinds.count("nondeterminism")
        if line.startswith("  [info] "):
            kind, count = line[len("  [info] "):].split(": ")
            assert int(count) == kinds.count(kind)


def test_a_solver_timeout_is_incomplete(monkeypatch, capsys):
    """Every solver call 'unknown' (a timeout): UNDECIDED claims beside a CLEAN summary and exit 0 before."""
    import importlib

    # the solver is called by the questions of hybrid.decide (hybrid.decide_questions, issue 26: module length)
    questions_module = importlib.import_module("hybrid.decide_questions")
    from hybrid.smt import Answer

    monkeypatch.setattr(questions_module, "check_sat", lambda constraints, timeout_s: Answer("unknown", reason="timeout"))
    code, out = _run(capsys, "symbolic", "--timeout", "2")
    first = out.splitlines()[0]
    assert code == EXIT_INCOMPLETE and "CLEAN" not in first
    assert "deadlock, reset_outside_invariant undecided: 2 question(s) without an answer" in first
    assert "timeout of 2 s" in first


def test_a_mode_without_a_box_is_incomplete(capsys):
    """check_box for one mode of two: the other mode's checks did not run; was PROVEN and CLEAN before."""
    code, out = _run(capsys, "partial_box")
    first = out.splitlines()[0]
    assert code == EXIT_INCOMPLETE and "CLEAN" not in first and "not searched" in first
