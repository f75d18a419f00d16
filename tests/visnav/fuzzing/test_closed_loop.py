"""visnav.fuzzing.closed_loop: a variant in the paper's closed loop, and the classified outcome."""

from __future__ import annotations

from visnav.fuzzing.closed_loop import OUTCOMES, classify_outcome, simulate_variant
from visnav.scenario import load_scenario


def test_closed_loop_outcomes_of_the_paper_scenario():
    paper = load_scenario("paper")
    resolved = simulate_variant(paper, "resolved")
    assert resolved.outcome == "success" and resolved.switch_jump <= 1e-9
    assert classify_outcome(paper, resolved.trace, resolved.metrics) == "success"
    as_written = simulate_variant(paper, "paper")
    assert as_written.outcome in OUTCOMES and as_written.outcome != "success"  # LEAVE is never reset
    assert as_written.trace.final_mode.startswith("LEAVE|")
