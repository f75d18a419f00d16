"""Affine modes solved in closed form (``simulate_continuous(closed_form=True)``, :mod:`hybrid.closed_form`).

Every expectation is computed here by an independent route: the analytic solutions written out
(``T(t) = T∞ + (T0 − T∞) e^{−kt}``, the ball's parabola), :func:`scipy.linalg.expm` of the augmented matrix,
or the numerical executor (``closed_form=False``, RK45) at tight tolerances.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.closed_form import AffinePropagator, affine_flow
from hybrid.continuous import simulate_continuous
from hybrid.errors import ExecutionError
from hybrid.examples import bouncing_ball, thermostat
from hybrid.symbolic import coordinates, flow_map, memory, sin

AMBIENT, HEATER, RATE, LOW, HIGH = 10.0, 30.0, 0.1, 19.0, 21.0


def thermostat_times(count: int, T0: float = 20.0, k: float = RATE) -> np.ndarray:
    """Switch times of the thermostat from ``T0`` (off), from ``T(t) = T∞ + (T0 − T∞) e^{−kt}`` solved for t."""
    times, t, T, on = [], 0.0, T0, False
    for _ in range(count):
        target, rest = (HIGH, HEATER) if on else (LOW, AMBIENT)
        t += math.log((T - rest) / (target - rest)) / k
        times.append(t)
        T, on = target, not on
    return np.array(times)


def test_thermostat_switch_times_match_the_analytic_formula():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=model.duration, closed_form=True)
    exact = thermostat_times(len(run.events))
    assert len(run.events) >= 6 and run.termination == "end_time"
    # each located event lies at most event_tol = 1e-12 s after the root; the state carries the offset on
    assert np.max(np.abs(run.event_times - exact)) < 1e-10
    assert [e.transition for e in run.events[:2]] == ["heat_on", "heat_off"]
    assert all(abs(e.state_before[0] - (LOW if e.transition == "heat_on" else HIGH)) < 1e-11 for e in run.events)
    # one closed-form step per flow, no right-hand side evaluated
    assert run.stats.steps == len(run.segments) and run.stats.rhs_evaluations == 0


def test_thermostat_dense_output_is_the_exponential():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=model.duration, closed_form=True)
    for seg in run.segments[:4]:
        T0, rest = seg.states[0, 0], (AMBIENT if seg.mode == "off" else HEATER)
        t = np.linspace(seg.t_start, seg.t_end, 7)
        exact = rest + (T0 - rest) * np.exp(-RATE * (t - seg.t_start))
        np.testing.assert_allclose(seg(t)[0], exact, rtol=1e-14, atol=1e-13)
        assert seg(float(t[3]))[0] == pytest.approx(exact[3], rel=1e-14)


def test_closed_form_and_numerical_integration_agree_to_the_executor_tolerance():
    model = thermostat()
    exact = simulate_continuous(model.system, model.x0, duration=model.duration, closed_form=True)
    rk = simulate_continuous(model.system, model.x0, duration=model.duration, closed_form=False)
    assert [e.transition for e in exact.events] == [e.transition for e in rk.events]
    # rtol = 1e-10 per step of RK45, accumulated over the flows: far above the closed form's 1e-12 s brackets
    assert np.max(np.abs(exact.event_times - rk.event_times)) < 1e-7
    assert np.max(np.abs(rk.event_times - thermostat_times(len(rk.events)))) > np.max(
        np.abs(exact.event_times - thermostat_times(len(exact.events))))


def test_bouncing_ball_on_the_polynomial_route():
    g, e = 9.81, 0.8
    ball = bouncing_ball(gravity=g, restitution=e, h0=1.0, v0=0.0)
    run = simulate_continuous(ball.system, ball.x0, duration=ball.duration, closed_form=True)
    v1 = math.sqrt(2.0 * g)
    exact = [math.sqrt(2.0 / g)]
    for k in range(1, len(run.events)):
        exact.append(exact[-1] + 2.0 * v1 * e ** k / g)  # flight k: up and down at speed v1 e^k
    assert len(run.events) == 8
    np.testing.assert_allclose(run.event_times, exact, rtol=1e-10)
    seg = run.segments[1]  # h(t) = v t - g t^2 / 2 after the first impact
    t = np.linspace(seg.t_start, seg.t_end, 5)
    h = seg.states[0, 1] * (t - seg.t_start) - 0.5 * g * (t - seg.t_start) ** 2
    np.testing.assert_allclose(seg(t)[0], h + seg.states[0, 0], atol=1e-12)


def _oscillator(guard_level: float, a: np.ndarray, b: np.ndarray, stops=None):
    x = coordinates("p", "q")
    automaton = HybridAutomaton(
        name="osc", modes=(Mode(name="run"), Mode(name="done")), variables=("p", "q"),
        transitions=(Transition(name="hit", source="run", target="done", guard=x.p >= guard_level),),
        initial_mode="run")
    flow = flow_map(a[0, 0] * x.p + a[0, 1] * x.q + b[0], a[1, 0] * x.p + a[1, 1] * x.q + b[1])
    return HybridSystem(automaton=automaton, state_names=("p", "q"), flows={"run": flow, "done": flow_map(0.0, 0.0)})


@pytest.mark.parametrize("a, b, route", [
    (np.array([[-0.1, 2.0], [-2.0, -0.1]]), np.array([0.0, 0.3]), ("eigen", False)),  # complex eigenvalues
    (np.array([[-1.0, 1.0], [0.0, 0.0]]), np.array([0.5, 0.0]), ("eigen", True)),  # an input: augmented matrix
    (np.array([[-1.0, 0.0], [0.0, 0.0]]), np.array([0.5, 1.0]), ("expm",)),  # a clock: defective, scipy's expm
])
def test_two_state_modes_against_the_matrix_exponential_and_rk45(a, b, route):
    system = _oscillator(0.25, a, b)
    found = affine_flow(system.flows["run"], 2, {}).route
    assert (found[0], *found[5:]) == route
    x0 = (0.0, 0.0)
    run = simulate_continuous(system, x0, duration=20.0, closed_form=True)
    rk = simulate_continuous(system, x0, duration=20.0, rtol=1e-12, atol=1e-14)
    assert [e.transition for e in run.events] == [e.transition for e in rk.events] == ["hit"]
    assert run.events[0].time == pytest.approx(rk.events[0].time, abs=1e-9)
    seg = run.segments[0]
    augmented = np.zeros((3, 3))
    augmented[:2, :2], augmented[:2, 2] = a, b
    for t in np.linspace(0.0, seg.t_end, 9):
        exact = (expm(augmented * t) @ np.array([*x0, 1.0]))[:2]
        np.testing.assert_allclose(seg(t), exact, rtol=1e-11, atol=1e-13)
    assert run.events[0].state_before[0] == pytest.approx(0.25, abs=1e-10)


def test_only_exactly_affine_symbolic_flows_are_read():
    x = coordinates("p", "q")
    m = memory("k")
    assert affine_flow(flow_map(x.q, -9.81), 2, {}).matrix.tolist() == [[0.0, 1.0], [0.0, 0.0]]
    form = affine_flow(flow_map(m.k * (x.p - 2.0) / 4.0, 3.0 - x.q), 2, {"k": 2.0})
    assert form.matrix.tolist() == [[0.5, 0.0], [0.0, -1.0]] and form.offset.tolist() == [-1.0, 3.0]
    for flow in (flow_map(x.p * x.q, 0.0), flow_map(sin(x.p), 0.0), flow_map(abs(x.p), 0.0),
                 flow_map(m.k * x.p, 0.0)):  # memory not given: not a constant
        assert affine_flow(flow, 2, {}) is None
    assert affine_flow(lambda t, x, m: (x[1], -9.81), 2, {}) is None
    assert affine_flow(flow_map(x.q), 2, {}) is None  # wrong dimension


def test_a_non_affine_mode_keeps_the_numerical_solver():
    x = coordinates("x")
    automaton = HybridAutomaton(name="grow", modes=(Mode(name="a"), Mode(name="b")), variables=("x",),
                                transitions=(Transition(name="go", source="a", target="b", guard=x.x >= 2.0),),
                                initial_mode="a")
    system = HybridSystem(automaton=automaton, state_names=("x",),
                          flows={"a": flow_map(x.x * x.x), "b": flow_map(0.0 * x.x)})
    on = simulate_continuous(system, (1.0,), duration=0.6, closed_form=True)
    off = simulate_continuous(system, (1.0,), duration=0.6, closed_form=False)
    assert on.event_times.tolist() == off.event_times.tolist()  # same solver, same steps in mode a
    assert on.events[0].time == pytest.approx(0.5, abs=1e-8)  # x = 1 / (1 - t) reaches 2 at t = 0.5
    assert on.segments[0].times.size > 2


def test_closed_form_keeps_the_executors_limits_and_bad_input_is_named():
    model = thermostat()
    run = simulate_continuous(model.system, model.x0, duration=100.0, max_steps=5, closed_form=True)
    assert run.termination == "solver_failure" and "max_steps" in run.detail
    with pytest.raises(ExecutionError, match="closed_form = 'yes'; expected True or False"):
        simulate_continuous(model.system, model.x0, duration=1.0, closed_form="yes")


def test_a_propagator_evaluates_one_time_and_many_alike():
    form = affine_flow(flow_map(-0.5 * coordinates("x").x + 1.0), 1, {})
    prop = AffinePropagator(form, 2.0, (4.0,))
    t = np.array([2.0, 2.5, 4.0])
    exact = 2.0 + 2.0 * np.exp(-0.5 * (t - 2.0))
    np.testing.assert_allclose(prop(t)[0], exact, rtol=1e-15)
    assert prop.point(2.5)[0] == pytest.approx(exact[1], rel=1e-15) and prop(2.0).tolist() == [4.0]


def _chain(n: int):
    """x_i' = x_{i+1} - x_i, x_{n-1}' = 0.5: a Jordan block at -1 and a clock (defective, not nilpotent)."""
    names = [f"x{i}" for i in range(n)]
    x = coordinates(*names)
    return flow_map(*[getattr(x, names[i + 1]) - getattr(x, names[i]) for i in range(n - 1)], 0.5 + 0.0 * x.x0)


def test_a_large_system_without_a_cheap_route_keeps_the_numerical_solver():
    assert affine_flow(_chain(8), 8, {}) is None
    small = affine_flow(_chain(4), 4, {})  # small: scipy's expm at each time
    assert small is not None and small.route[0] == "expm"
    t = np.array([0.0, 0.7, 2.0])
    x0 = (1.0, -1.0, 0.5, 0.0)
    ode = solve_ivp(lambda _, x: [x[1] - x[0], x[2] - x[1], x[3] - x[2], 0.5], (0.0, 2.0), x0, method="DOP853",
                    t_eval=t, rtol=1e-13, atol=1e-15)  # an independent route: a high-order integrator
    np.testing.assert_allclose(AffinePropagator(small, 0.0, x0)(t), ode.y, rtol=1e-10, atol=1e-12)


def test_an_unwatched_flow_is_one_step_of_the_exact_solution():
    x = coordinates("p", "q")
    automaton = HybridAutomaton(name="free", modes=(Mode(name="run"),), transitions=(), variables=("p", "q"))
    system = HybridSystem(automaton=automaton, state_names=("p", "q"), flows={"run": flow_map(x.q, -x.p)})
    run = simulate_continuous(system, (1.0, 0.0), duration=50.0, closed_form=True)
    assert run.stats.steps == 1 and run.segments[0].times.tolist() == [0.0, 50.0]
    np.testing.assert_allclose(run.final_state, (math.cos(50.0), -math.sin(50.0)), atol=1e-13)
