"""The paper scenario end to end: the acceptance figures of issue 2 as regression tests."""

import dataclasses
import math

import numpy as np
import pytest

from hybrid import DivergenceError
from visnav.scenario import load_scenario
from visnav.simulation import simulate
from visnav.supervisor import split_mode


@pytest.fixture(scope="module")
def paper():
    return simulate(load_scenario("paper"))


def test_task_succeeds_without_collision(paper):
    m = paper.metrics
    assert m.success and m.termination == "success"
    assert not m.collided
    assert m.min_clearance_m > 0.2
    assert m.final_feature_error_px <= paper.scenario.success_tolerance_px


def test_occlusion_is_real_and_long(paper):
    m = paper.metrics
    assert m.occlusion_duration_s >= 15.0
    assert m.all_hidden_duration_s > 2.0  # all four features hidden for a while
    trace = paper.trace
    all_hidden = trace.record("n_hidden") >= 4
    # while everything is hidden the pan is driven by the reconstructed target only (mu_occ = 1)
    assert np.all(trace.record("mu_occ")[all_hidden] == 1.0)
    assert np.all(trace.record("mu_coll")[all_hidden] == 1.0)
    assert np.all(trace.record("reconstructing")[all_hidden] == 1.0)


def test_reconstruction_ten_times_better_than_the_paper(paper):
    m = paper.metrics
    assert m.max_reconstruction_error_px <= 0.017
    assert m.max_depth_error_mm <= 0.12


def test_controls_within_limits_and_no_chatter(paper):
    m = paper.metrics
    assert m.within_actuator_limits
    assert m.chatter_count == 0
    # smooth: no input jumps by more than what 50 ms of the largest observed slew allows
    limits = paper.scenario.limits
    assert m.max_input_step[0] <= 0.05 * limits.v_max_mps
    assert m.max_input_step[1] <= 0.1 * limits.omega_max_radps
    assert m.max_input_step[2] <= 0.1 * limits.pan_rate_max_radps


def test_risk_parameters_continuous_at_every_transition(paper):
    trace, model = paper.trace, paper.loop.supervisor
    env = paper.scenario.envelopes
    mu_c, mu_o = trace.record("mu_coll"), trace.record("mu_occ")
    assert np.all((0 <= mu_c) & (mu_c <= 1) & (0 <= mu_o) & (mu_o <= 1))
    # no jump at any transition: both sides of each jump give the same mu on the same signals
    memory = model.automaton.initial_memory()
    for e in trace.events:
        v = trace.signals[e.sample]
        before = model.risk(e.source, v, memory)
        memory = dict(e.memory)
        assert model.risk(e.target, v, memory) == pytest.approx(before, abs=1e-12), e.transition
    # continuity in time: each step of mu is bounded by the steepest release band times the
    # change of the measured distance (bands are at least d+ - d0 and D+ - D0 wide)
    d_obstacles = trace.signals[:, 6:]
    step_d = np.abs(np.diff(d_obstacles, axis=0)).max(axis=1)
    d_occ = trace.signal("d_occ_px")
    finite = np.isfinite(d_occ[1:]) & np.isfinite(d_occ[:-1])
    step_docc = np.where(finite, np.abs(np.diff(np.where(np.isfinite(d_occ), d_occ, 0.0))), np.inf)
    assert np.all(np.abs(np.diff(mu_c)) <= step_d / (env.d_plus_m - env.d_zero_m) + 1e-12)
    assert np.all(np.abs(np.diff(mu_o)) <= step_docc / (env.D_plus_px - env.D_zero_px) + 1e-12)


def test_mode_sequence_follows_the_paper(paper):
    collision = [split_mode(name)[0] for name in paper.metrics.modes_visited]
    assert collision[0] == "FAR" and "ARMED" in collision and "LEAVE" in collision
    assert "PASSED" in collision  # LEAVE held back while the target was hidden
    assert paper.trace.final_mode == "FAR|CLEAR"


def test_divergence_reports_time_mode_and_cause():
    scenario = load_scenario("paper")
    bad = dataclasses.replace(scenario, estimator=dataclasses.replace(scenario.estimator, newton_maxiter=1))
    with pytest.raises(DivergenceError, match=r"diverged at t = [0-9.]+ s in mode '[A-Z]+\|[A-Z]+': .*Newton") as info:
        simulate(bad)
    assert info.value.time > 0 and "|" in info.value.mode
    assert math.isfinite(info.value.time)


def test_dense_clearance_equals_the_exact_flow_sampled_point_by_point():
    """The vectorised arc of dense_clearance against propagate_pose called per sub-step (same sub-steps)."""
    import math

    from visnav.geometry import propagate_pose
    from visnav.scenario import load_scenario
    from visnav.simulation import CLEARANCE_SUBSTEPS, dense_clearance, simulate

    scenario = load_scenario("paper")
    trace = simulate(scenario).trace
    best = math.inf
    for k in range(len(trace.times)):
        x, u = tuple(trace.states[k]), trace.inputs[k]
        for i in range(CLEARANCE_SUBSTEPS if k < len(trace.times) - 1 else 1):
            px, py, _, _ = propagate_pose(x, u[0], u[1], u[2], i * trace.period / CLEARANCE_SUBSTEPS)
            for o in scenario.obstacles:
                best = min(best, math.hypot(px - o.center_m[0], py - o.center_m[1]) - o.radius_m)
    # same formula, numpy vs math round-off: a few ulps of the coordinates (~1e-15 m)
    assert abs(dense_clearance(scenario, trace) - best) <= 1e-13


# ---------------------------------------------------------------------------------------------
# The outcome vocabulary and its classifier
# ---------------------------------------------------------------------------------------------


def _run(*, collided=False, termination="end_time", hidden=(0,) * 200, theta=(0.0, 0.1), transitions=()):
    """A fake (scenario, trace, metrics) with what classify_run reads: 4 target points, T = 0.05 s."""
    from types import SimpleNamespace

    scenario = SimpleNamespace(target=SimpleNamespace(points_m=((0, 0, 0),) * 4))
    records = {"n_hidden": np.array(hidden, dtype=float)}
    trace = SimpleNamespace(period=0.05, record=records.__getitem__, state=lambda name: np.array(theta),
                            events=[SimpleNamespace(transition=t) for t in transitions])
    metrics = SimpleNamespace(collided=collided, termination=termination, success=termination == "success")
    return scenario, trace, metrics


def test_outcome_vocabulary():
    from visnav.simulation import OUTCOMES, RUN_OUTCOMES, TIMEOUT_OUTCOMES

    assert OUTCOMES == ("success", "collision", "timeout", "stuck_in_loop", "target_lost", "diverged",
                        "invalid_scenario", "error")
    assert RUN_OUTCOMES == OUTCOMES[:5] and set(TIMEOUT_OUTCOMES) <= set(RUN_OUTCOMES)


def test_paper_run_is_classified_success(paper):
    from visnav.simulation import classify_run

    assert classify_run(paper.scenario, paper.trace, paper.metrics) == "success"


def test_classify_run_order_of_the_classes():
    from visnav.simulation import LOOP_TRANSITION_COUNT, TARGET_LOST_WINDOW_S, classify_run

    window = int(round(TARGET_LOST_WINDOW_S / 0.05))
    lost = (0,) * 50 + (4,) * window
    assert classify_run(*_run(collided=True, termination="success")) == "collision"  # collision wins
    assert classify_run(*_run(termination="collision")) == "collision"
    assert classify_run(*_run(termination="success", hidden=lost)) == "success"
    assert classify_run(*_run(hidden=lost, theta=(0.0, 7.0))) == "target_lost"
    assert classify_run(*_run(hidden=(0,) * 50 + (4,) * (window - 1))) == "timeout"  # hidden, not long enough
    assert classify_run(*_run(hidden=(0,) * 50 + (3,) * window)) == "timeout"  # one point still visible
    assert classify_run(*_run(theta=(0.0, 2.0 * math.pi))) == "stuck_in_loop"  # a full turn
    assert classify_run(*_run(transitions=("approach",) * LOOP_TRANSITION_COUNT)) == "stuck_in_loop"
    assert classify_run(*_run(transitions=("approach",) * (LOOP_TRANSITION_COUNT - 1) + ("leave",))) == "timeout"


def test_without_diagnosis():
    from visnav.simulation import OUTCOMES, without_diagnosis

    assert [without_diagnosis(name) for name in OUTCOMES] == [
        "success", "collision", "timeout", "timeout", "timeout", "diverged", "invalid_scenario", "error"]
    with pytest.raises(ValueError, match=r"outcome = 'exploded': expected one of success, collision"):
        without_diagnosis("exploded")
