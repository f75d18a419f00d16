"""A check report is CLEAN only when every check ran and decided: one test per path that used to pass wrongly.

The models are in ``check_fixtures.py``; each test fails on the code before ``hybrid.completeness``
(where ``clean`` meant only "no error and no warning").
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from hybrid import check
from hybrid.completeness import CHECK_STATUSES, SMT_CANNOT_DECIDE, finding_counts
from hybrid.errors import ExecutionError

_spec = importlib.util.spec_from_file_location("check_fixtures", Path(__file__).with_name("check_fixtures.py"))
F = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(F)

SAMPLES = 200


def statuses(report):
    return {s.check: s.status for s in report.statuses}


def test_smt_on_plain_callables_is_not_clean_and_says_why():
    """zero band, plain lambdas, --method smt: was CLEAN with samples = 0 and function_calls = 0."""
    report = check(F.plain_zero_band(), F.BOX, samples=SAMPLES, method="smt")
    assert not report.clean and not report.complete and report.no_findings
    st = statuses(report)
    assert st["deadlock"] == st["reset_outside_invariant"] == "skipped"
    assert st["reset_retriggers"] == st["zeno"] == "undecided"
    assert any(SMT_CANNOT_DECIDE in r for r in report.incomplete)
    for mode in report.searched.modes:  # nothing sampled, and the notes do not say "decided by the SMT solver"
        assert mode.samples == 0 and not any(n.startswith("decided by the SMT solver") for n in mode.notes)
        assert mode.function_calls > 0  # the corners and centre probe
    assert report.searched.checks["deadlock"].startswith("skipped: ")
    assert all(report.claim(c) != "sampled" for c in ("nondeterminism", "deadlock", "reset_outside_invariant"))
    # the same model with auto finds the two re-triggers
    auto = check(F.plain_zero_band(), F.BOX, samples=SAMPLES, method="auto")
    assert not auto.clean and len(auto.of_kind("reset_retriggers")) == 2


@pytest.mark.parametrize("how", sorted(F.BAD_GUARDS))
@pytest.mark.parametrize("method", ["auto", "smt"])
def test_a_guard_that_raises_or_returns_nan_or_none_is_the_same_error_under_smt_and_auto(how, method):
    """smt never called the plain guard: CLEAN; now the same ExecutionError naming the guard as auto."""
    with pytest.raises(ExecutionError, match="guard of transition 'heat_on'") as info:
        check(F.bad_guard(how), F.BOX, samples=SAMPLES, method=method)
    assert {"raises": "raised RuntimeError", "nan": "returned NaN", "none": "returned None"}[how] in str(info.value)


@pytest.mark.parametrize("method", ["auto", "sampled", "smt"])
def test_no_box_skips_every_state_check_and_is_not_clean(method):
    report = check(F.thermostat(19.0, 21.0, symbolic=True), None, method=method)
    assert report.no_findings and not report.clean and not report.complete
    assert statuses(report) == {"unreachable": "decided", "sink_mode": "decided",
                                **dict.fromkeys(("nondeterminism", "deadlock", "reset_outside_invariant",
                                                 "reset_retriggers", "zeno"), "skipped")}
    assert len(report.incomplete) == 5 and all("no box given" in r for r in report.incomplete)
    assert report.completeness()["complete"] is False


def test_time_reading_flow_under_smt_skips_the_deadlock_and_labels_nothing_sampled():
    """Flows that read t: deadlock was SAMPLED with samples = 0 beside 'decided by the SMT solver (not sampled)'."""
    report = check(F.thermostat(19.0, 21.0, symbolic=True, time_flow=True), F.BOX, samples=SAMPLES, method="smt")
    st = statuses(report)
    assert st["deadlock"] == "skipped" and "sampled" not in st.values()
    assert st["zeno"] == "undecided" and not report.clean
    # the re-trigger question does not read the flow: decided (no instantaneous lap, proven)
    assert st["reset_retriggers"] == "decided" and st["reset_outside_invariant"] == "decided"
    zero = check(F.time_flow_zero_band(), F.BOX, samples=SAMPLES, method="smt")
    assert len(zero.of_kind("reset_retriggers")) == 1 and statuses(zero)["deadlock"] == "skipped"
    auto = check(F.time_flow_zero_band(), F.BOX, samples=SAMPLES, method="auto")
    assert auto.of_kind("reset_retriggers") and not auto.clean


def test_sampled_zeno_is_undecided_but_a_decided_model_is_clean():
    sampled = check(F.thermostat(19.0, 21.0, symbolic=False), F.BOX, samples=SAMPLES)
    assert sampled.no_findings and not sampled.clean
    assert [r.split()[:2] for r in sampled.incomplete] == [["zeno", "undecided:"]]
    decided = check(F.thermostat(19.0, 21.0, symbolic=True), F.BOX, samples=SAMPLES)
    assert decided.clean and decided.complete and decided.incomplete == ()
    assert set(statuses(decided).values()) == {"decided"}


def test_a_mode_without_box_is_not_complete():
    report = check(F.thermostat(19.0, 21.0, symbolic=True), {"off": F.BOX}, samples=SAMPLES)
    assert not report.clean
    assert any("not searched" in r for r in report.incomplete), report.incomplete


FIXTURES = {
    "plain_zero_band": F.plain_zero_band, "time_flow_zero_band": F.time_flow_zero_band,
    "time_flow": lambda: F.thermostat(19.0, 21.0, symbolic=True, time_flow=True),
    "plain_overlap": F.plain_overlap, "symbolic": lambda: F.thermostat(19.0, 21.0, symbolic=True),
    "plain": lambda: F.thermostat(19.0, 21.0, symbolic=False),
}


@pytest.mark.parametrize("name", sorted(FIXTURES))
@pytest.mark.parametrize("method", ["auto", "sampled", "smt"])
def test_statuses_agree_with_clean_and_the_claims(name, method):
    report = check(FIXTURES[name](), F.BOX, samples=SAMPLES, method=method)
    st = report.statuses
    assert all(s.status in CHECK_STATUSES for s in st)
    assert report.clean == (report.no_findings and all(s.complete for s in st))
    for s in st:  # a check is never SAMPLED unless a mode was sampled
        if s.status == "sampled":
            assert any(m.samples > 0 for m in report.searched.modes), (s.check, report.searched.modes)
    counts = finding_counts(report.findings)  # the summary counts are the findings' (an independent tally)
    kinds = [f.kind for f in report.findings]
    assert counts["instantaneous"] == kinds.count("reset_retriggers")
    assert counts["overlap"] == kinds.count("nondeterminism") + kinds.count("priority_overlap")


def _unknown(constraints, timeout_s):
    from hybrid.smt import Answer

    return Answer("unknown", reason="timeout")


def test_a_solver_that_answers_unknown_leaves_the_checks_undecided_not_clean(monkeypatch):
    """Every solver call 'unknown' (as a timeout): the old report was CLEAN with UNDECIDED claims."""
    import importlib

    # the solver is called by the questions of hybrid.decide (hybrid.decide_questions, issue 26: module length)
    questions_module = importlib.import_module("hybrid.decide_questions")

    monkeypatch.setattr(questions_module, "check_sat", _unknown)
    report = check(F.thermostat(19.0, 21.0, symbolic=True), F.BOX, samples=SAMPLES, method="smt")
    assert report.no_findings and not report.clean and not report.complete
    st = statuses(report)
    assert st["deadlock"] == st["reset_outside_invariant"] == st["zeno"] == "undecided"
    assert any("without an answer (the solver's unknown or its timeout of 5 s)" in r for r in report.incomplete)
