"""The continuous-time executor against closed forms, and its failure modes."""

import json
import math

import numpy as np
import pytest

from hybrid import (
    DivergenceError,
    ExecutionError,
    HybridAutomaton,
    HybridSystem,
    Mode,
    NumericalFailure,
    Transition,
    ZenoError,
    all_of,
    simulate_continuous,
)
from hybrid.continuous import METHODS, locate_crossing
from hybrid.examples import (
    bouncing_ball,
    bouncing_ball_apex_heights,
    bouncing_ball_impact_times,
    bouncing_ball_zeno_time,
    reference_models,
    thermostat,
    thermostat_switch_times,
    water_tanks,
    water_tanks_switch_times,
    water_tanks_zeno_time,
)

G, E = 9.81, 0.8


def clock(transitions, modes=("wait", "done"), flow=lambda t, x, m: (1.0,)):
    automaton = HybridAutomaton(
        name="clock", modes=tuple(Mode(name=n) for n in modes), transitions=tuple(transitions), variables=("x",)
    )
    return HybridSystem(automaton=automaton, state_names=("x",), flows={n: flow for n in modes})


# ---------------------------------------------------------------------------- bouncing ball
@pytest.fixture(scope="module")
def ball_run():
    ball = bouncing_ball(gravity=G, restitution=E, h0=1.0, v0=0.0)
    return simulate_continuous(ball.system, ball.x0, duration=10.0)


def test_bouncing_ball_impacts_match_the_closed_form(ball_run):
    """RK45 integrates the quadratic flight exactly; what is left is the 1e-12 s event bracket per bounce."""
    times = ball_run.event_times
    assert len(times) >= 40
    exact = np.array(bouncing_ball_impact_times(gravity=G, restitution=E, h0=1.0, v0=0.0, count=len(times)))
    assert np.max(np.abs(times - exact) / exact) < 1e-9
    v1 = math.sqrt(2.0 * G)
    speeds = np.array([e.state_after[1] for e in ball_run.events])
    # each bracket (<= 1e-12 s) shifts the impact speed by <= g * 1e-12 m/s and the error carries
    # over (scaled by e < 1) to later bounces: absolute, not relative, agreement near the Zeno point
    np.testing.assert_allclose(speeds, v1 * E ** np.arange(1, len(times) + 1), rtol=1e-9, atol=G * 1e-12 * len(times))


def test_bouncing_ball_apex_heights_from_the_dense_output(ball_run):
    apexes = bouncing_ball_apex_heights(gravity=G, restitution=E, h0=1.0, v0=0.0, count=6)
    for k, event in enumerate(ball_run.events[:6]):
        t_apex = event.time + event.state_after[1] / G
        states, modes = ball_run.sample([t_apex])
        assert modes == ("fly",)
        assert states[0, 0] == pytest.approx(apexes[k], rel=1e-9)


def test_bouncing_ball_zeno_time_is_estimated_and_the_run_stops(ball_run):
    assert ball_run.termination == "zeno"
    zeno = ball_run.zeno
    assert zeno.kind == "accumulation" and zeno.transitions == ("bounce",) and zeno.modes == ("fly",)
    exact = bouncing_ball_zeno_time(gravity=G, restitution=E, h0=1.0, v0=0.0)
    assert exact == pytest.approx(math.sqrt(2 / G) + 2 * E * math.sqrt(2 * G) / (G * (1 - E)), rel=1e-15)
    assert abs(zeno.zeno_time - exact) / exact < 1e-6
    assert zeno.ratio == pytest.approx(E, rel=1e-6)
    assert ball_run.final_time < exact


def test_zeno_raise_and_continue_policies():
    ball = bouncing_ball()
    with pytest.raises(ZenoError, match="jumps accumulate"):
        simulate_continuous(ball.system, ball.x0, duration=10.0, zeno="raise")
    run = simulate_continuous(ball.system, ball.x0, duration=10.0, zeno="continue", max_jumps=80)
    assert run.zeno is not None and run.termination in ("jump_limit", "solver_failure")


def test_crossing_guard_sitting_on_zero_after_its_reset_does_not_fire_again():
    """Guard -h with direction +1: after the reset h = 0 exactly, the next crossing is the next impact."""
    ball = HybridAutomaton(
        name="ball", modes=(Mode(name="fly"),),
        transitions=(Transition(name="bounce", source="fly", target="fly", guard=lambda v, m: -v[0], direction=+1),),
        variables=("h", "v"),
    )
    system = HybridSystem(automaton=ball, state_names=("h", "v"), flows={"fly": lambda t, x, m: (x[1], -G)},
                          jumps={"bounce": lambda x, m: (0.0, -E * x[1])})
    run = simulate_continuous(system, (1.0, 0.0), duration=3.0)
    exact = bouncing_ball_impact_times(gravity=G, restitution=E, h0=1.0, v0=0.0, count=len(run.events))
    assert all(not e.instantaneous for e in run.events)
    np.testing.assert_allclose(run.event_times, exact, rtol=1e-9)


# ---------------------------------------------------------------------------- thermostat
@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_thermostat_switch_times_match_the_closed_form(method):
    """Exponential flows: the event error follows the integration error, so tight tolerances reach 1e-12."""
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=200.0, method=method, rtol=1e-13, atol=1e-13)
    exact = np.array(thermostat_switch_times(count=len(run.events)))
    assert len(exact) >= 90
    assert np.max(np.abs(run.event_times - exact) / exact) < 1e-9
    assert [e.transition for e in run.events[:2]] == ["heat_on", "heat_off"]
    assert run.termination == "end_time" and run.final_time == 200.0 and run.zeno is None


@pytest.mark.parametrize("method", ["Radau", "BDF", "LSODA", "RK23"])
def test_thermostat_on_every_solver(method):
    """Stiff (implicit) solvers too; their accuracy is that of rtol = 1e-10 over ~100 periods."""
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=200.0, method=method)
    exact = np.array(thermostat_switch_times(count=len(run.events)))
    assert np.max(np.abs(run.event_times - exact) / exact) < 1e-8


def test_methods_table_lists_the_stiff_solvers():
    assert {"Radau", "BDF", "LSODA"} <= set(METHODS)


# ---------------------------------------------------------------------------- water tanks
def test_water_tanks_switch_times_zeno_time_and_chatter():
    model = water_tanks()
    run = simulate_continuous(model.system, model.x0, duration=100.0, chatter_window=0.5)
    exact = np.array(water_tanks_switch_times(count=len(run.events)))
    np.testing.assert_allclose(run.event_times, exact, rtol=1e-9)
    assert run.termination == "zeno"
    assert abs(run.zeno.zeno_time - water_tanks_zeno_time()) / water_tanks_zeno_time() < 1e-6
    assert set(run.zeno.modes) == {"fill1", "fill2"}
    assert len(run.chatter) == 1
    episode = run.chatter[0]
    assert set(episode.transitions) == {"to_fill1", "to_fill2"} and episode.switches >= 6
    assert episode.shortest_dwell < 0.5 and episode.end <= water_tanks_zeno_time()


def test_stop_on_chatter_ends_the_run():
    model = water_tanks()
    run = simulate_continuous(model.system, model.x0, duration=100.0, chatter_window=0.5, stop_on_chatter=True,
                              zeno="continue")
    assert run.termination == "chatter" and "fill1" in run.detail


# ---------------------------------------------------------------------------- planted defects
def test_deadlock_ends_with_invariant_violated_at_the_boundary():
    model = reference_models()["deadlock"]
    run = simulate_continuous(model.system, model.x0, duration=model.duration)
    assert run.termination == "invariant_violated"
    assert run.final_time == pytest.approx(1.0, abs=1e-12)
    assert "deadlock" in run.detail and "'run'" in run.detail


def test_instantaneous_zeno_is_reported_not_hung():
    model = reference_models()["retrigger"]
    run = simulate_continuous(model.system, model.x0, duration=model.duration, max_jumps_per_instant=10)
    assert run.termination == "zeno" and run.zeno.kind == "instantaneous"
    assert len(run.events) == 10 and all(e.time == pytest.approx(1.0, abs=1e-12) for e in run.events)
    assert run.zeno.transitions == ("fire",)


def test_reset_outside_every_invariant_is_an_error_naming_transition_state_time():
    model = reference_models()["bad_reset"]
    with pytest.raises(ExecutionError, match=r"after transition 'reverse'.*x = \(2\).*t = 1.*mode 'down'"):
        simulate_continuous(model.system, model.x0, duration=model.duration)


def test_equal_priorities_enabled_together_is_non_determinism():
    system = clock(
        [Transition(name="left", source="wait", target="done", guard=lambda v, m: v[0] - 1.0),
         Transition(name="right", source="wait", target="done", guard=lambda v, m: v[0] - 1.0)]
    )
    with pytest.raises(ExecutionError, match=r"non-determinism at t = 1 s in mode 'wait'.*\['left', 'right'\]"):
        simulate_continuous(system, (0.0,), duration=2.0)


def test_simultaneous_transitions_resolved_by_priority_and_reported():
    system = clock(
        [Transition(name="second", source="wait", target="done", guard=lambda v, m: v[0] - 1.0, priority=2),
         Transition(name="first", source="wait", target="done", guard=lambda v, m: v[0] - 1.0, priority=1)]
    )
    run = simulate_continuous(system, (0.0,), duration=2.0)
    assert [(e.transition, e.outranked) for e in run.events] == [("first", ("second",))]
    assert run.events[0].time == pytest.approx(1.0, abs=2e-12)


# ---------------------------------------------------------------------------- event location details
def window(lo, hi):
    return clock([Transition(name="hit", source="wait", target="done", guard=lambda v, m: (v[0] - lo) * (hi - v[0]))])


def test_guard_entered_and_left_inside_one_step():
    """x' = 1 is integrated exactly, so RK45 steps grow tenfold: one step spans [1.11, 11.11] s."""
    missed = simulate_continuous(window(5.5, 6.5), (0.0,), duration=20.0, sign_checks=0)
    assert missed.events == ()  # the end-of-step test alone (what solve_ivp does) misses it
    found = simulate_continuous(window(5.5, 6.5), (0.0,), duration=20.0)  # default sign checks
    assert [e.time for e in found.events] == [pytest.approx(5.5, abs=2e-12)]
    bounded = simulate_continuous(window(4.9, 4.95), (0.0,), duration=20.0, sign_checks=0, max_step=0.05)
    assert [e.time for e in bounded.events] == [pytest.approx(4.9, abs=2e-12)]


def test_event_time_is_the_right_end_of_a_bracket_narrower_than_event_tol():
    run = simulate_continuous(window(math.pi, 10.0), (0.0,), duration=20.0, max_step=1.0)
    t = run.events[0].time
    assert 0.0 <= t - math.pi <= 1e-12
    assert run.events[0].state_before[0] >= math.pi  # the guard holds where the jump is taken


def test_locate_crossing_handles_infinite_values_and_flat_roots():
    for phi, root in ((lambda t: -math.inf if t < 0.3 else 1.0, 0.3), (lambda t: (t - 0.5) ** 3, 0.5),
                      (lambda t: math.exp(t) - 10.0, math.log(10.0))):
        lo, hi, _, _, iterations = locate_crossing(phi, 0.0, 3.0, phi(0.0), phi(3.0))
        assert hi - lo <= 1e-12 and lo <= root + 1e-15 and hi >= root - 1e-15 and phi(hi) >= 0.0
        assert iterations <= 200


def test_stop_function_ends_the_run_at_the_located_time():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=100.0, stops={"half": lambda t, x, mode, m: t - 12.5})
    assert run.termination == "stop:half" and run.final_time == pytest.approx(12.5, abs=1e-12)


def test_trajectory_on_the_hybrid_time_domain():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=30.0)
    assert [s.jump for s in run.segments] == list(range(len(run.events) + 1))
    for segment, event in zip(run.segments, run.events):
        assert segment.t_end == event.time and segment.mode == event.source
        assert tuple(segment.states[-1]) == event.state_before
    assert len(run.times) == len(run.states) == len(run.jumps) == len(run.modes)
    assert not run.states.flags.writeable
    assert json.dumps(run.as_dict(), sort_keys=True) == json.dumps(
        simulate_continuous(model.system, model.x0, duration=30.0).as_dict(), sort_keys=True)


def test_termination_causes_jump_limit_and_solver_failure():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=100.0, max_jumps=3)
    assert run.termination == "jump_limit" and len(run.events) == 3
    blow_up = clock([], modes=("wait",), flow=lambda t, x, m: (x[0] * x[0],))
    run = simulate_continuous(blow_up, (1.0,), duration=2.0)  # x = 1/(1 - t) blows up at t = 1
    assert run.termination == "solver_failure" and run.final_time < 1.0 + 1e-6
    run = simulate_continuous(model.system, model.x0, duration=100.0, max_steps=5)
    assert run.termination == "solver_failure" and "max_steps" in run.detail


# ---------------------------------------------------------------------------- bad input
def test_guard_returning_nan_or_garbage_names_transition_mode_state_time():
    nan = clock([Transition(name="hit", source="wait", target="done", guard=lambda v, m: math.nan)])
    with pytest.raises(ExecutionError, match=r"guard of transition 'hit' is NaN in mode 'wait' at t = 0 s, x = \(0\)"):
        simulate_continuous(nan, (0.0,), duration=1.0)
    garbage = clock([Transition(name="hit", source="wait", target="done", guard=lambda v, m: (1.0, 2.0))])
    with pytest.raises(ExecutionError, match=r"guard of transition 'hit' returned \(1.0, 2.0\)"):
        simulate_continuous(garbage, (0.0,), duration=1.0)


def test_flow_that_raises_is_chained_with_mode_state_time():
    def broken(t, x, m):
        if x[0] > 0.5:
            raise ZeroDivisionError("boom")
        return (1.0,)

    with pytest.raises(ExecutionError, match=r"flow of mode 'wait' raised ZeroDivisionError: boom in mode 'wait'") as info:
        simulate_continuous(clock([], flow=broken), (0.0,), duration=1.0)
    assert isinstance(info.value.__cause__, ZeroDivisionError)


def test_flow_with_wrong_shape_or_nan_and_numerical_failure():
    with pytest.raises(ExecutionError, match=r"flow of mode 'wait' returned 2 values.*expected 1"):
        simulate_continuous(clock([], flow=lambda t, x, m: (1.0, 2.0)), (0.0,), duration=1.0)
    with pytest.raises(ExecutionError, match=r"flow of mode 'wait' gives NaN for 'x'"):
        simulate_continuous(clock([], flow=lambda t, x, m: (math.nan,)), (0.0,), duration=1.0)

    def fails(t, x, m):
        raise NumericalFailure("depth of point 2 is -0.01 m")

    with pytest.raises(DivergenceError, match=r"diverged at t = 0 s in mode 'wait': depth of point 2"):
        simulate_continuous(clock([], flow=fails), (0.0,), duration=1.0)


def test_reset_returning_the_wrong_memory_names_the_transition():
    from hybrid import MemoryVariable

    automaton = HybridAutomaton(
        name="count", modes=(Mode(name="wait"), Mode(name="done")),
        transitions=(Transition(name="hit", source="wait", target="done", guard=lambda v, m: v[0] - 0.5,
                                reset=lambda v, m: {"other": 1.0}, writes=("n",)),),
        variables=("x",), memory=(MemoryVariable(name="n"),),
    )
    system = HybridSystem(automaton=automaton, state_names=("x",), flows={"wait": lambda t, x, m: (1.0,),
                                                                          "done": lambda t, x, m: (1.0,)})
    with pytest.raises(ExecutionError, match=r"reset of transition 'hit'.*returned \['other'\].*\['n'\]"):
        simulate_continuous(system, (0.0,), duration=1.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"duration": 0.0}, r"duration = 0.0; expected a positive"),
        ({"duration": 1.0, "method": "Euler"}, r"method = 'Euler'; expected one of"),
        ({"duration": 1.0, "zeno": "ignore"}, r"zeno = 'ignore'"),
        ({"duration": 1.0, "sign_checks": -1}, r"sign_checks = -1; expected an int >= 0"),
        ({"duration": 1.0, "chatter_window": 0.0}, r"chatter_window = 0.0"),
        ({"duration": 1.0, "initial_memory": {"nope": 1.0}}, r"unknown variable\(s\) \['nope'\]"),
    ],
)
def test_bad_arguments(kwargs, message):
    with pytest.raises(ExecutionError, match=message):
        simulate_continuous(window(1.0, 2.0), (0.0,), **kwargs)


def test_bad_initial_state():
    with pytest.raises(ExecutionError, match=r"x0 = \(0.0, 1.0\); expected 1 finite values \(x\)"):
        simulate_continuous(window(1.0, 2.0), (0.0, 1.0), duration=1.0)
    deadlock = reference_models()["deadlock"]
    with pytest.raises(ExecutionError, match=r"initially, the state x = \(2\).*invariant of mode 'run'"):
        simulate_continuous(deadlock.system, (2.0,), duration=1.0)


def test_conjunction_guard_on_the_ball_fires_only_when_falling():
    guard = all_of(lambda v, m: -v[0], lambda v, m: -v[1])
    assert guard((0.0, -1.0), {}) >= 0.0 and guard((0.0, 1.0), {}) < 0.0


def test_jump_map_with_the_wrong_shape_names_the_transition_state_and_time():
    automaton = HybridAutomaton(
        name="jumpy", modes=(Mode(name="wait"), Mode(name="done")),
        transitions=(Transition(name="hit", source="wait", target="done", guard=lambda v, m: v[0] - 0.5),),
        variables=("x",),
    )
    system = HybridSystem(automaton=automaton, state_names=("x",),
                          flows={"wait": lambda t, x, m: (1.0,), "done": lambda t, x, m: (1.0,)},
                          jumps={"hit": lambda x, m: (x[0], 0.0)})
    with pytest.raises(ExecutionError, match=r"jump map of transition 'hit' returned 2 values at t = 0.5.*x = \(0.5"):
        simulate_continuous(system, (0.0,), duration=1.0)
