"""Equilibria of modes against their invariants; derivatives through the user's own flows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.derivatives import mode_vector_field
from analysis.equilibria import mode_equilibria, mode_equilibrium
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.errors import ParameterError
from hybrid.examples import thermostat


def user_thermostat(band: float = 1.0, rate: float = 0.1) -> HybridSystem:
    """As a user writes it (examples/thermostat.py): plain lambdas."""
    low, high = 20.0 - band / 2, 20.0 + band / 2
    automaton = HybridAutomaton(
        name="room", variables=("T",), initial_mode="off",
        modes=(Mode(name="off", invariant=lambda v, m: v[0] - low, invariant_text=f"T >= {low:g}"),
               Mode(name="on", invariant=lambda v, m: high - v[0], invariant_text=f"T <= {high:g}")),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=lambda v, m: low - v[0]),
                     Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - high)))
    return HybridSystem(automaton=automaton, state_names=("T",),
                        flows={"off": lambda t, x, m: (-rate * (x[0] - 10.0),),
                               "on": lambda t, x, m: (-rate * (x[0] - 30.0),)})


def pendulum(friction: float = 0.5) -> HybridSystem:
    """A damped pendulum written with math.sin (does not trace: finite differences), one mode with a
    real equilibrium inside |theta| <= 1 and a mode whose flow never vanishes (a clock)."""
    automaton = HybridAutomaton(
        name="pendulum", variables=("theta", "omega", "clock"), initial_mode="swing",
        modes=(Mode(name="swing", invariant=lambda v, m: 1.0 - abs(v[0])), Mode(name="tick")),
        transitions=(Transition(name="go", source="swing", target="tick", guard=lambda v, m: v[2] - 5.0),))
    return HybridSystem(automaton=automaton, state_names=("theta", "omega", "clock"),
                        flows={"swing": lambda t, x, m: (x[1], -9.81 * math.sin(x[0]) - friction * x[1], 0.0),
                               "tick": lambda t, x, m: (x[1], -x[0], 1.0)})


@pytest.mark.parametrize("system", [thermostat().system, user_thermostat()], ids=["symbolic", "lambdas"])
def test_the_thermostat_modes_have_virtual_equilibria_outside_their_invariants(system):
    off, on = mode_equilibria(system, guess=(20.0,))
    assert (off.kind, on.kind) == ("virtual", "virtual")
    assert off.point == pytest.approx((10.0,), abs=1e-12) and on.point == pytest.approx((30.0,), abs=1e-12)
    assert off.derivatives == on.derivatives == "casadi"
    assert off.hurwitz and abs(off.jacobian[0, 0] + 0.1) < 1e-15
    assert off.invariant_value < 0 and "virtual equilibrium, outside the mode" in off.finding
    assert "exponentially stable" not in off.finding and "says nothing" in off.finding
    assert on.enabled_transitions == ("heat_off",)  # at 30 °C the heater would already have switched off


def test_an_equilibrium_inside_its_invariant_is_one_and_finite_differences_stand_in_for_tracing():
    system = pendulum(friction=0.5)
    field = mode_vector_field(system, "swing")
    assert field.method == "finite differences" and "differ from the function" in field.reason  # math.sin(SX) is NaN: the probe catches it
    x = np.array([0.3, -0.2, 1.0])
    exact = np.array([[0.0, 1.0, 0.0], [-9.81 * math.cos(0.3), -0.5, 0.0], [0.0, 0.0, 0.0]])
    assert np.abs(field.jacobian(x) - exact).max() < 1e-8  # central differences, step 1e-6: error ~1e-10
    eq = mode_equilibrium(system, "swing", guess=(0.4, 0.1, 1.0))
    assert eq.kind == "equilibrium" and eq.point[:2] == pytest.approx((0.0, 0.0), abs=1e-12)
    # the clock state does not move in this mode: one zero eigenvalue, so not Hurwitz
    assert not eq.hurwitz and sorted(round(m.real, 6) for m in eq.modes)[-1] == 0.0
    tick = mode_equilibrium(system, "tick", guess=(0.1, 0.1, 0.0))
    assert tick.kind == "none" and tick.point is None and "does not vanish" in tick.finding


def test_an_equilibrium_on_a_guard_is_a_switching_one():
    system = pendulum()
    eq = mode_equilibrium(system, "swing", guess=(0.1, 0.0, 7.0))  # clock 7 > 5: "go" is enabled there
    assert eq.kind == "switching" and eq.enabled_transitions == ("go",)


def test_bad_inputs_name_the_parameter():
    system = user_thermostat()
    with pytest.raises(ParameterError, match=r"^mode = 'heating': expected one of the modes \['off', 'on'\]"):
        mode_equilibrium(system, "heating")
    with pytest.raises(ParameterError, match=r"^guess = \(1\.0, 2\.0\): expected 1 finite values \(T\)"):
        mode_equilibrium(system, "off", guess=(1.0, 2.0))
    with pytest.raises(ParameterError, match=r"^guess = \(nan,\)"):
        mode_equilibrium(system, "off", guess=(math.nan,))
    with pytest.raises(ParameterError, match=r"^tol = -1"):
        mode_equilibrium(system, "off", tol=-1)
    with pytest.raises(ParameterError, match=r"^system = 3: expected a hybrid.HybridSystem"):
        mode_equilibria(3)
