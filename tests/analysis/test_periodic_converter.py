"""A PWM buck converter's steady state: the periodic orbit against the exact stroboscopic fixed point and the ripple."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.periodic import finite_difference_monodromy, periodic_orbit
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition

V_IN, L, C, R = 12.0, 100e-6, 100e-6, 5.0  # V, H, F, Ω
PERIOD, DUTY = 50e-6, 0.4  # switching period [s] (20 kHz), duty ratio
SCALE = 1e4  # time in units of 100 µs keeps the solver's absolute tolerances meaningful


def buck() -> HybridSystem:
    """States (i_L [A], v_C [V], clock [100 µs]); the switch opens at D·T and closes (clock reset) at T."""
    t_on, t_end = DUTY * PERIOD * SCALE, PERIOD * SCALE
    automaton = HybridAutomaton(
        name="buck", variables=("i_L", "v_C", "clock"), initial_mode="on",
        modes=(Mode(name="on", invariant=lambda v, m: t_on - v[2]), Mode(name="off", invariant=lambda v, m: t_end - v[2])),
        transitions=(Transition(name="open", source="on", target="off", guard=lambda v, m: v[2] - t_on),
                     Transition(name="close", source="off", target="on", guard=lambda v, m: v[2] - t_end)))
    k = 1.0 / SCALE
    return HybridSystem(
        automaton=automaton, state_names=("i_L", "v_C", "clock"),
        flows={"on": lambda t, x, m: (k * (V_IN - x[1]) / L, k * (x[0] - x[1] / R) / C, 1.0),
               "off": lambda t, x, m: (k * (-x[1]) / L, k * (x[0] - x[1] / R) / C, 1.0)},
        jumps={"close": lambda x, m: (x[0], x[1], 0.0)})


def exact_steady_state() -> np.ndarray:
    """Fixed point of the stroboscopic map x ↦ Φ_off (Φ_on x + b_on) + b_off (affine flows, matrix exponentials)."""
    a = np.array([[0.0, -1.0 / L], [1.0 / C, -1.0 / (R * C)]])

    def affine_step(b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = a, b
        e = expm(aug * t)
        return e[:2, :2], e[:2, 2]

    phi_on, c_on = affine_step(np.array([V_IN / L, 0.0]), DUTY * PERIOD)
    phi_off, c_off = affine_step(np.zeros(2), (1.0 - DUTY) * PERIOD)
    m, c = phi_off @ phi_on, phi_off @ c_on + c_off
    return np.linalg.solve(np.eye(2) - m, c)


@pytest.fixture(scope="module")
def converter_orbit():
    system = buck()
    return system, periodic_orbit(system, section="close", initial_state=(0.0, 0.0, PERIOD * SCALE),
                                  max_iterations=10)


def test_the_orbit_is_the_exact_steady_state(converter_orbit):
    _, orbit = converter_orbit
    i0, v0 = exact_steady_state()
    assert abs(orbit.period - PERIOD * SCALE) < 1e-9  # the clock is exact: one switching period
    assert abs(orbit.fixed_point[0] - i0) < 1e-6 * abs(i0) and abs(orbit.fixed_point[1] - v0) < 1e-6 * abs(v0)
    assert orbit.verdict == "orbitally stable" and orbit.jumps == ("open", "close")


def test_the_ripple_matches_the_first_order_formula(converter_orbit):
    """Δi_L = (V_in − V_out)·D·T/L to first order (V_out ≈ D·V_in, the capacitor voltage nearly constant)."""
    _, orbit = converter_orbit
    states = np.asarray(orbit.states)
    ripple = float(states[:, 0].max() - states[:, 0].min())
    v_out = float(states[:, 1].mean())
    approx = (V_IN - v_out) * DUTY * PERIOD / L
    assert abs(v_out - DUTY * V_IN) / (DUTY * V_IN) < 0.02  # ideal conversion ratio, within the ripple's effect
    # first order in T/sqrt(LC) = 0.005 and T/(RC) = 0.1: the curvature of i_L over a phase is a few per cent
    assert abs(ripple - approx) / approx < 0.02  # measured 0.46 %


def test_multipliers_against_finite_differences(converter_orbit):
    system, orbit = converter_orbit
    fd = np.sort_complex(np.linalg.eigvals(finite_difference_monodromy(system, orbit, step=1e-5)))
    assert np.abs(fd - np.sort_complex(np.array(orbit.multipliers))).max() < 1e-6
