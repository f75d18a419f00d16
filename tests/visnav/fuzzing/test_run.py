"""visnav.fuzzing.run: every property fuzzed on the resolved automaton; determinism; argument checks.

Budgets: with the environment variable CI set (``.ci/run``) every property
runs its CI budget of examples (:func:`visnav.fuzzing.registry.budget`); locally a
fifth.  The runner's hypothesis settings are explicit and derandomised
(fixed ``max_examples``, ``database=None``), so both are deterministic
whatever profile ``tests/conftest.py`` loads.
"""

from __future__ import annotations

import os

import pytest

from visnav.fuzzing.counterexamples import counterexample_from_json, counterexample_to_json
from visnav.fuzzing.registry import PROPERTIES, budget
from visnav.fuzzing.run import fuzz, fuzz_property

PROFILE = "ci" if os.environ.get("CI") else "dev"


@pytest.mark.parametrize("name", list(PROPERTIES))
def test_property_holds_on_the_resolved_supervisor(name):
    result = fuzz_property(name, examples=budget(name, PROFILE))
    assert result.passed, (result.counterexample.message, result.counterexample.sample)
    # a state machine run may be instantiated once more than the examples (hypothesis' explicit phase)
    assert budget(name, PROFILE) <= result.examples <= budget(name, PROFILE) + 5 and result.steps > 0
    assert result.as_dict()["failures"] == 0


def test_same_seed_gives_the_same_shrunk_counterexample_byte_for_byte():
    texts = {counterexample_to_json(fuzz_property("no_chatter", variant="no_hysteresis", examples=30,
                                                  seed=1).counterexample) for _ in range(2)}
    (text,) = texts
    cx = counterexample_from_json(text, "cx.json")
    assert cx.seed == 1 and len(cx.measurements) <= 3  # shrunk to a handful of samples
    assert "instantaneous Zeno" in cx.message or "undone" in cx.message


def test_fuzz_rejects_unknown_names_and_budgets():
    with pytest.raises(KeyError, match="unknown property 'x'; known: mu_range"):
        fuzz(["x"])
    with pytest.raises(KeyError, match="unknown supervisor variant 'y'; known: resolved, paper"):
        fuzz_property("mu_range", variant="y")
    with pytest.raises(ValueError, match="examples = 0: expected an integer >= 1"):
        fuzz_property("mu_range", examples=0)
    with pytest.raises(ValueError, match="budget profile 'z'"):
        budget("mu_range", "z")
