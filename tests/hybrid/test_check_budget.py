"""The sampled structural search is bounded in wall-clock time (issue 25): a slow guard cannot hold
`check-model` for minutes, and what was not searched makes the report incomplete, never clean."""

from __future__ import annotations

import time

import pytest

from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition, check
from hybrid.errors import ExecutionError


def _slow_system(delay: float) -> HybridSystem:
    def guard(v, m):
        time.sleep(delay)
        return v[0] - 1.0

    a = HybridAutomaton(name="slow", variables=("x", "y"), modes=(Mode(name="a"), Mode(name="b")),
                        transitions=(Transition(name="go", source="a", target="b", guard=guard, guard_text="x >= 1"),
                                     Transition(name="back", source="b", target="a", guard=lambda v, m: -1.0 - v[0],
                                                guard_text="x <= -1")))
    return HybridSystem(automaton=a, state_names=("x", "y"),
                        flows={"a": lambda t, x, m: (1.0, 0.0), "b": lambda t, x, m: (-1.0, 0.0)})


BOX = Box(bounds={"x": (-2.0, 2.0), "y": (-2.0, 2.0)})


def test_a_slow_guard_is_cut_by_the_budget_and_the_report_says_what_was_not_searched():
    start = time.monotonic()
    report = check(_slow_system(0.01), BOX, budget_s=0.5)
    assert time.monotonic() - start < 10.0  # ~2000 samples x 10 ms = 20 s without the budget
    assert not report.complete and not report.clean
    assert any("time budget of 0.5 s ran out" in line for line in report.incomplete)


def test_a_fast_model_within_its_budget_is_searched_whole():
    report = check(_slow_system(0.0), BOX, budget_s=60.0, samples=200)
    assert not any("time budget" in line for line in report.incomplete)


@pytest.mark.parametrize("budget", [0.0, -1.0, float("nan"), True, "10"])
def test_a_bad_budget_is_refused_naming_it(budget):
    with pytest.raises(ExecutionError, match="budget_s"):
        check(_slow_system(0.0), BOX, budget_s=budget)
