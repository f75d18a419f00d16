"""The supervisor on the continuous-time executor, and the sampled loop converging to it."""

import dataclasses
import json
import math

import numpy as np
import pytest

from hybrid import simulate_continuous
from visnav.closed_loop import ClosedLoop
from visnav.studies.convergence import ConvergenceStudy, observed_order, sampled_convergence, simulate_continuous_time
from visnav.scenario import load_scenario
from visnav.simulation import simulate


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def continuous(paper):
    return simulate_continuous_time(paper)


@pytest.fixture(scope="module")
def study(paper, continuous):
    return sampled_convergence(paper, reference=continuous)


def test_continuous_run_reaches_the_goal_with_the_sampled_runs_transitions(paper, continuous):
    trajectory = continuous.trajectory
    assert trajectory.termination == "stop:success"
    sampled = simulate(paper)
    assert [e.transition for e in trajectory.events] == [e.transition for e in sampled.trace.events]
    # the sampled run can only notice success at a sample: within one period after the exact time
    assert 0.0 <= sampled.trace.times[-1] - trajectory.final_time + paper.sampling_period_s <= paper.sampling_period_s


def test_continuous_events_are_located_where_the_guard_switches_on(continuous):
    """At each located event the fired guard holds; 1e-9 s earlier it did not (event_tol is 1e-12 s)."""
    trajectory = continuous.trajectory
    system = continuous.loop.continuous_system()
    transitions = {t.name: t for t in system.automaton.transitions}
    checked = 0
    for event in trajectory.events:
        if event.instantaneous:
            continue
        tr = transitions[event.transition]
        memory = dict(next(s for s in trajectory.segments if s.t_end == event.time and s.mode == event.source).memory)
        v_at = system.signals(event.time, event.state_before)
        assert tr.guard(v_at, memory) >= 0.0
        segment = next(s for s in trajectory.segments if s.t_end == event.time and s.mode == event.source)
        before = tuple(segment(event.time - 1e-9))
        assert tr.guard(system.signals(event.time - 1e-9, before), memory) < 0.0
        checked += 1
    assert checked >= 7


def test_sampled_trajectory_converges_to_continuous_time_at_first_order(study):
    assert all(study.same_transitions)
    # Zero-order hold: the held input differs from the continuous one by O(T), so before any
    # switching the deviation is first order and halves with T to within a few per cent.
    assert study.smooth_phase_order == pytest.approx(1.0, abs=0.05)
    for coarse, fine in zip(study.smooth_phase_error_m, study.smooth_phase_error_m[1:]):
        assert fine / coarse == pytest.approx(0.5, abs=0.03)
    # Whole run: every event is also quantised to the sample grid (an O(T) shift whose size
    # depends on where the exact time falls between samples), so single halvings are
    # irregular; the least-squares slope over the five periods is still first order.
    assert 0.85 <= study.order <= 1.25
    assert 0.8 <= study.event_shift_order <= 1.5
    assert study.position_error_m[-1] < study.position_error_m[0] / 8.0
    assert study.position_error_m[-1] < 5e-3


def test_convergence_study_rejects_bad_periods(paper, continuous):
    with pytest.raises(ValueError, match="decreasing"):
        sampled_convergence(paper, (0.01, 0.02), reference=continuous)
    with pytest.raises(ValueError, match="does not divide"):
        sampled_convergence(paper, (0.05, 0.03), reference=continuous)


def test_observed_order_of_exact_power_laws():
    assert observed_order([0.1, 0.05, 0.025], [3e-2, 7.5e-3, 1.875e-3]) == pytest.approx(2.0, abs=1e-12)
    with pytest.raises(ValueError, match="positive"):
        observed_order([0.1, 0.05], [1.0, 0.0])


def test_continuous_loop_on_a_stiff_method_agrees(paper, continuous):
    """Radau (implicit) and DOP853 give the same events to well within the tolerances' reach."""
    loop = ClosedLoop(scenario=paper)
    radau = simulate_continuous(
        loop.continuous_system(), paper.start.as_tuple(), duration=12.0, method="Radau",
        rtol=1e-9, atol=1e-11, max_step=0.5,
    )
    reference = [e for e in continuous.trajectory.events if e.time < 12.0]
    assert [e.transition for e in radau.events] == [e.transition for e in reference]
    assert max(abs(a.time - b.time) for a, b in zip(radau.events, reference)) < 1e-5
    assert math.isclose(radau.final_time, 12.0)


def test_convergence_study_as_dict_lists_every_field(study):
    data = study.as_dict()
    assert list(data) == [f.name for f in dataclasses.fields(ConvergenceStudy)]
    assert data["periods"] == list(study.periods) and data["order"] == study.order
    assert data["continuous_events"] == [[t, name] for t, name in study.continuous_events]
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_convergence_study_as_dict_writes_nonfinite_as_null(study):
    odd = dataclasses.replace(study, event_shift_s=(math.nan,) + study.event_shift_s[1:], event_shift_order=math.nan,
                              position_error_m=(np.float64(0.5),) + study.position_error_m[1:])
    data = odd.as_dict()
    assert data["event_shift_s"][0] is None and data["event_shift_order"] is None
    assert data["position_error_m"][0] == 0.5 and type(data["position_error_m"][0]) is float
