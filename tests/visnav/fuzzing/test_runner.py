"""visnav.fuzzing.runner: the supervisor's measurement stage around the generic sequence runner."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings

from analysis.sequences import SequenceRunner
from hybrid import settle
from visnav.fuzzing.runner import MAX_JUMPS_PER_SAMPLE, SupervisorRunner, run_supervisor
from visnav.fuzzing.space import MeasurementSpace, signal_runs
from visnav.fuzzing.variants import make_variant

PROFILE = "ci" if os.environ.get("CI") else "dev"
SPACE = MeasurementSpace()
ENV, SETTINGS = SPACE.envelopes, SPACE.settings
RESOLVED = make_variant("resolved", ENV, SETTINGS, SPACE.n_obstacles)
EXPLICIT = settings(max_examples=40 if PROFILE == "dev" else 150, derandomize=True, database=None, deadline=None,
                    suppress_health_check=list(HealthCheck))


def row(d0, d1=1.6, side=1.0, d_occ=160.0, d_bord=320.0, pan=0.0, alpha=0.0, visible=1.0):
    return (d0, d1, side, d_occ, d_bord, pan, alpha, visible)


@given(signal_runs(SPACE, bounded=False, respect=False, max_length=150))
@EXPLICIT
def test_the_runner_agrees_with_hybrid_settle(rows):
    """The fuzzer's stepper has the semantics of the executor (same modes, memory, jumps)."""
    steps = run_supervisor(RESOLVED, SPACE, rows)
    automaton = RESOLVED.model.automaton
    runner_signals = [s.signals for s in steps]
    mode, memory, previous = automaton.initial_mode, automaton.initial_memory(), None
    for s, v in zip(steps, runner_signals):
        mode, memory, events = settle(automaton, mode, memory, v, previous)
        assert (mode, memory) == (s.mode, dict(s.memory))
        assert [e.transition for e in events] == [j.transition for j in s.jumps]
        previous = v


def test_variant_loop_needs_matching_signals():
    with pytest.raises(ValueError, match="reads 1 obstacle distance"):
        run_supervisor(make_variant("resolved", ENV, SETTINGS, 1), SPACE, [row(1.0)])


def test_the_supervisor_runner_is_the_generic_runner_behind_the_measurement_stage():
    """Same modes, memory and jumps as analysis.sequences.SequenceRunner fed the measurement stage's signals."""
    rows = [row(0.8 - 0.05 * k, d_occ=100.0 - 8 * k, pan=0.04 * k) for k in range(14)]
    runner = SupervisorRunner(RESOLVED, SPACE)
    generic = SequenceRunner(RESOLVED.model.automaton)
    for r in rows:
        s, g = runner.step(r), generic.step(runner.signals(r))
        assert (s.mode, dict(s.memory), s.jumps, s.zeno) == (g.mode, dict(g.memory), g.jumps, g.zeno is not None)
        assert (s.mu_coll, s.mu_occ) == RESOLVED.model.risk(s.mode, s.signals, s.memory)
    assert any(s.jumps for s in run_supervisor(RESOLVED, SPACE, rows))
    assert (runner.mode, runner.index, runner.previous) == (generic.mode, generic.index, generic.previous)


def test_the_jump_limit_is_the_kernels():
    from hybrid.instant import MAX_JUMPS_PER_INSTANT

    assert MAX_JUMPS_PER_SAMPLE == MAX_JUMPS_PER_INSTANT == 8
