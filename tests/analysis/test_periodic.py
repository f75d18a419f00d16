"""Periodic orbits: closed forms (thermostat, relay feedback), finite-difference monodromy, saltation, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from analysis.periodic import (
    PeriodicOrbitError,
    ShootingError,
    finite_difference_monodromy,
    periodic_orbit,
    saltation_matrix,
)
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.continuous import simulate_continuous
from hybrid.examples import thermostat

A = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]])  # G(s) = 1/(s + 1)^3
B = np.array([0.0, 0.0, 1.0])
C = np.array([1.0, 0.0, 0.0])
RELAY, HYSTERESIS = 1.0, 0.05


def relay_feedback(d: float = RELAY, eps: float = HYSTERESIS) -> HybridSystem:
    """u = ±d switched by y = x1 through ∓eps (a relay with hysteresis), written as a user writes it."""
    automaton = HybridAutomaton(
        name="relay", variables=("x1", "x2", "x3"), initial_mode="plus",
        modes=(Mode(name="plus", invariant=lambda v, m: eps - v[0]), Mode(name="minus", invariant=lambda v, m: v[0] + eps)),
        transitions=(Transition(name="to_minus", source="plus", target="minus", guard=lambda v, m: v[0] - eps),
                     Transition(name="to_plus", source="minus", target="plus", guard=lambda v, m: -eps - v[0])))

    def flow(u: float):
        return lambda t, x, m: (-x[0] + x[1], -x[1] + x[2], -x[2] + u)

    return HybridSystem(automaton=automaton, state_names=("x1", "x2", "x3"), flows={"plus": flow(d), "minus": flow(-d)})


def relay_exact() -> tuple[float, np.ndarray]:
    """The symmetric orbit: x(h) = −x(0) after a half period h with u = d, and C x(0) = −eps (just switched to plus)."""
    a_inv = np.linalg.inv(A)

    def start(h: float) -> np.ndarray:
        e = expm(A * h)
        return -np.linalg.solve(np.eye(3) + e, a_inv @ (e - np.eye(3)) @ B * RELAY)

    h = brentq(lambda h: C @ start(h) + HYSTERESIS, 0.5, 10.0, xtol=1e-15)
    return 2.0 * h, start(h)


def relay_describing_function() -> tuple[float, float]:
    """Period and amplitude where G(iω) = −1/N(a), N(a) = 4d/(πa)·exp(−i·arcsin(eps/a)): Im G = −π eps/(4d)."""
    g = lambda w: 1.0 / (1j * w + 1.0) ** 3  # noqa: E731
    w = brentq(lambda w: g(w).imag + math.pi * HYSTERESIS / (4.0 * RELAY), 0.3, 1.7)
    return 2.0 * math.pi / w, math.hypot(g(w).real * 4.0 * RELAY / math.pi, HYSTERESIS)


def user_thermostat(rate: float = 0.1, low: float = 19.0, high: float = 21.0) -> HybridSystem:
    automaton = HybridAutomaton(
        name="room", variables=("T",), initial_mode="off",
        modes=(Mode(name="off", invariant=lambda v, m: v[0] - low), Mode(name="on", invariant=lambda v, m: high - v[0])),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=lambda v, m: low - v[0]),
                     Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - high)))
    return HybridSystem(automaton=automaton, state_names=("T",),
                        flows={"off": lambda t, x, m: (-rate * (x[0] - 10.0),),
                               "on": lambda t, x, m: (-rate * (x[0] - 30.0),)})


@pytest.fixture(scope="module")
def relay_orbit():
    system = relay_feedback()
    run = simulate_continuous(system, (0.0, 0.0, 0.0), duration=40.0)
    guess = [e for e in run.events if e.transition == "to_plus"][-1].state_before
    return system, periodic_orbit(system, section="to_plus", initial_state=guess)


@pytest.mark.parametrize("build", [lambda: thermostat().system, user_thermostat], ids=["symbolic", "lambdas"])
def test_thermostat_period_and_multiplier_match_the_closed_form(build):
    system = build()
    orbit = periodic_orbit(system, section="heat_on", initial_state=(18.0,))  # projected onto T = 19
    t_on = math.log((30.0 - 19.0) / (30.0 - 21.0)) / 0.1
    t_off = math.log((21.0 - 10.0) / (19.0 - 10.0)) / 0.1
    assert abs(orbit.period - (t_on + t_off)) < 1e-9
    assert orbit.fixed_point == pytest.approx((19.0,), abs=1e-12) and orbit.jumps == ("heat_off", "heat_on")
    # one state: the only multiplier is the trivial one, exactly 1 (the saltations undo the flow's contraction)
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-9 and orbit.nontrivial_multipliers == ()
    assert orbit.derivatives == "casadi" and orbit.verdict == "orbitally stable"


def test_relay_orbit_matches_the_exact_solution_and_the_finite_difference_monodromy(relay_orbit):
    system, orbit = relay_orbit
    period, start = relay_exact()
    assert abs(orbit.period - period) < 1e-9
    assert np.abs(np.array(orbit.fixed_point) - start).max() < 1e-8  # identity reset: before = after the jump
    assert orbit.jumps == ("to_minus", "to_plus") and orbit.verdict == "orbitally stable"
    fd = np.sort_complex(np.linalg.eigvals(finite_difference_monodromy(system, orbit)))
    assert np.abs(fd - np.sort_complex(np.array(orbit.multipliers))).max() < 1e-6
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-8
    # the describing function is a first-harmonic approximation: 1.1 % off in period here, amplitude within 5 %
    df_period, df_amplitude = relay_describing_function()
    assert abs(df_period - period) / period < 0.02
    amplitude = float(np.abs(np.asarray(orbit.states)[:, 0]).max())
    assert abs(df_amplitude - amplitude) / amplitude < 0.05


def test_the_saltation_matrix_is_the_derivative_of_the_jump_in_time(relay_orbit):
    """Against finite differences of the flow-then-jump map, and the flow direction maps to the new flow."""
    rng = np.random.default_rng(1)
    r = np.diag([1.0, -0.5, 2.0]) + 0.1 * rng.standard_normal((3, 3))
    grad = np.array([1.0, 0.3, -0.2])
    f_minus, f_plus = np.array([0.7, -0.1, 0.4]), np.array([-0.3, 0.5, 0.2])
    s = saltation_matrix(r, f_minus, f_plus, grad)
    assert np.allclose(s @ f_minus, f_plus, atol=1e-14)
    for _ in range(3):  # a neighbour δ reaches the guard τ later; compare x⁺(δ) with first order
        delta = 1e-7 * rng.standard_normal(3)
        tau = -(grad @ delta) / (grad @ f_minus)
        after = r @ (delta + f_minus * tau) - f_plus * tau
        assert np.abs(after - s @ delta).max() < 1e-20 + 1e-9 * np.abs(delta).max()
    with pytest.raises(ArithmeticError, match="tangent to the guard"):
        saltation_matrix(r, np.array([0.0, 1.0, 0.0]), f_plus, np.array([1.0, 0.0, 0.0]))
    _, orbit = relay_orbit  # without the saltations the monodromy would be Φ = e^{AT} (both modes share A):
    flow_only = expm(A * orbit.period)  # multipliers e^{-T}, no trivial 1: the finite-difference check would fail
    assert np.abs(np.linalg.eigvals(flow_only) - 1.0).min() > 0.9
    assert np.abs(orbit.monodromy - flow_only).max() > 0.1


def test_bad_input_and_failures_say_what_and_where():
    system = user_thermostat()
    with pytest.raises(PeriodicOrbitError, match=r"^section = 'heat': expected one of the transitions"):
        periodic_orbit(system, section="heat", initial_state=(19.0,))
    with pytest.raises(PeriodicOrbitError, match=r"^initial_state = \(1\.0, 2\.0\): expected 1 finite values \(T\)"):
        periodic_orbit(system, section="heat_on", initial_state=(1.0, 2.0))
    with pytest.raises(PeriodicOrbitError, match=r"^initial_state = \(nan,\)"):
        periodic_orbit(system, section="heat_on", initial_state=(math.nan,))
    # a thermostat whose heater cannot reach the upper threshold: the section is never met again
    stuck = HybridSystem(automaton=system.automaton, state_names=("T",),
                         flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),), "on": lambda t, x, m: (-0.1 * (x[0] - 20.0),)})
    with pytest.raises(PeriodicOrbitError, match=r"^section = 'heat_on': .*not taken within max_period = 50 s"):
        periodic_orbit(stuck, section="heat_on", initial_state=(19.0,), max_period=50.0)
    relay = relay_feedback()
    with pytest.raises(ShootingError, match=r"did not converge after 1 iterations \(residual .* = [0-9.e-]+"
                                            ) as info:
        periodic_orbit(relay, section="to_plus", initial_state=(-0.05, 0.5, 0.5), max_iterations=1)
    assert info.value.iterations == 1 and info.value.residual > 1e-6
