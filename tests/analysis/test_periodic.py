"""Periodic orbits: closed forms (thermostat, relay feedback, buck converter), finite differences, saltation, bad input."""

from __future__ import annotations

import importlib.util
import json
import math
import pickle
from pathlib import Path

import numpy as np
import pytest

import analysis.periodic as periodic
from analysis.periodic import (
    PeriodicOrbitError,
    ShootingError,
    finite_difference_monodromy,
    periodic_orbit,
    poincare_map,
    saltation_matrix,
)
from hybrid import HybridAutomaton, HybridSystem, MemoryVariable, Mode, Transition
from hybrid.errors import DivergenceError, ZenoError
from hybrid.examples import (
    bouncing_ball,
    buck_converter,
    buck_converter_steady_state,
    relay_feedback,
    relay_feedback_cycle,
    thermostat,
    thermostat_cycle,
)

ROOT = Path(__file__).resolve().parents[2]


def user_thermostat(band: float = 2.0) -> HybridSystem:
    """``thermostat_system`` of examples/thermostat.py: plain lambdas, as a user writes them."""
    spec = importlib.util.spec_from_file_location("thermostat_example_for_periodic", ROOT / "examples" / "thermostat.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.thermostat_system(band, 0.1)


def clocked(rate: float) -> HybridSystem:
    """A clock p (reset at 1) and r' = rate (r - 1): the orbit r = 1, period 1, multipliers 1 and e^rate."""
    automaton = HybridAutomaton(
        name="clocked", variables=("p", "r"), initial_mode="run",
        modes=(Mode(name="run", invariant=lambda v, m: 1.0 - v[0]),),
        transitions=(Transition(name="tick", source="run", target="run", guard=lambda v, m: v[0] - 1.0),))
    return HybridSystem(automaton=automaton, state_names=("p", "r"), flows={"run": lambda t, x, m: (1.0, rate * (x[1] - 1.0))},
                        jumps={"tick": lambda x, m: (0.0, x[1])})


@pytest.fixture(scope="module")
def relay():
    model = relay_feedback()
    orbit = periodic_orbit(model.system, section="to_plus", initial_state=model.x0, initial_mode="plus")
    return model.system, orbit, relay_feedback_cycle()


@pytest.fixture(scope="module")
def buck():
    model = buck_converter()
    return model.system, periodic_orbit(model.system, section="switch_on", initial_state=(0.0, 0.0, 1.0)), \
        buck_converter_steady_state()


# ---------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("build", [lambda: thermostat().system, user_thermostat], ids=["symbolic", "lambdas"])
def test_thermostat_period_and_multiplier_match_the_closed_form(build):
    system = build()
    cycle = thermostat_cycle()
    orbit = periodic_orbit(system, section="heat_on", initial_state=(18.0,))  # projected onto T = 19
    assert abs(orbit.period - cycle.period) < 1e-9  # measured 8e-12
    assert cycle.period == pytest.approx(2 * math.log(11 / 9) / 0.1, abs=1e-13)
    assert orbit.fixed_point == pytest.approx(cycle.fixed_point, abs=1e-12) and orbit.jumps == ("heat_off", "heat_on")
    assert orbit.jump_times[-1] == orbit.period and orbit.jump_times[0] == pytest.approx(cycle.time_on, abs=1e-9)
    # one state: the only multiplier is the trivial one, exactly 1 (the saltations undo the flows' contraction)
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-9 and orbit.nontrivial_multipliers == ()
    assert orbit.poincare_jacobian.shape == (0, 0) and orbit.verdict == "orbitally stable"
    assert orbit.derivatives == "casadi" and orbit.derivative_notes == ()
    assert abs(finite_difference_monodromy(system, orbit)[0, 0] - 1.0) < 1e-6


def test_functions_that_do_not_trace_fall_back_on_finite_differences_and_say_so():
    base = thermostat().system  # float() of a CasADi symbol is NaN: the traced flow of 'off' is caught
    opaque = HybridSystem(automaton=base.automaton, state_names=("T",),
                          flows={"off": lambda t, x, m: (-0.1 * (float(x[0]) - 10.0),),
                                 "on": lambda t, x, m: (-0.1 * (x[0] - 30.0),)})
    orbit = periodic_orbit(opaque, section="heat_on", initial_state=(19.0,))
    assert orbit.derivatives == "finite differences" and abs(orbit.period - thermostat_cycle().period) < 1e-9
    assert len(orbit.derivative_notes) == 1 and "flow of mode 'off'" in orbit.derivative_notes[0]
    assert "the traced values [nan] differ from the function's" in orbit.derivative_notes[0]
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-8  # a linear flow: central differences are exact but for rounding


def test_relay_orbit_is_the_exact_symmetric_cycle(relay):
    system, orbit, cycle = relay
    assert abs(orbit.period - cycle.period) < 1e-9  # measured 1.6e-11
    assert np.abs(np.array(orbit.fixed_point) - cycle.switch_state).max() < 1e-9  # measured 1.1e-11
    assert orbit.jumps == ("to_minus", "to_plus") and orbit.jump_times[0] == pytest.approx(cycle.half_period, abs=1e-9)
    assert orbit.verdict == "orbitally stable" and orbit.derivatives == "casadi"
    # the monodromy against e^{Ah} S_2 e^{Ah} S_1 built from the closed form (both modes share A)
    assert np.abs(orbit.monodromy - np.array(cycle.monodromy)).max() < 1e-8  # measured 6e-11
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-9
    assert np.abs(np.array(orbit.nontrivial_multipliers) - np.array(cycle.multipliers[1:])).max() < 1e-9
    # the nontrivial multipliers are the eigenvalues of M without the trivial one
    rest = sorted((z for z in orbit.multipliers if z != orbit.trivial_multiplier), key=abs, reverse=True)
    assert np.abs(np.array(rest) - np.array(orbit.nontrivial_multipliers)).max() < 1e-9
    lo, hi = orbit.extent("x1")  # the samples (steps and 33 points per flow) pass within 1e-5 of the peak
    assert hi == pytest.approx(cycle.amplitude, abs=2e-5) and lo == pytest.approx(-cycle.amplitude, abs=2e-5)


def test_relay_multipliers_match_the_finite_difference_monodromy(relay):
    system, orbit, _ = relay
    fd = np.sort_complex(np.linalg.eigvals(finite_difference_monodromy(system, orbit)))
    assert np.abs(fd - np.sort_complex(np.array(orbit.multipliers))).max() < 1e-6  # measured 1.7e-10


def test_describing_function_is_within_its_harmonic_tolerance(relay):
    """The DF balances the first harmonic only; its errors are of the order of the neglected harmonics.

    ρ = Σ_{k odd ≥ 3} |G(ikω)|/(k|G(iω)|) = 2.66 % here; the tolerance is 2ρ.  Measured: period 1.01 %
    short, first-harmonic amplitude 1.92 % low (over eps in [0.02, 0.2] at most 1.2 % and 2.6 %).
    """
    _, orbit, cycle = relay
    tolerance = 2.0 * cycle.harmonic_ratio
    period_gap = abs(cycle.df_period - orbit.period) / orbit.period
    amplitude_gap = abs(cycle.df_amplitude - cycle.first_harmonic) / cycle.first_harmonic
    assert 0.005 < period_gap < tolerance and 0.005 < amplitude_gap < tolerance
    # without the hysteresis' phase lag the DF would predict omega = sqrt(3): 24 % off, far outside the tolerance
    assert abs(2 * math.pi / math.sqrt(3) - orbit.period) / orbit.period > 4 * tolerance


def test_buck_converter_orbit_is_the_exact_periodic_steady_state(buck):
    system, orbit, exact = buck
    assert abs(orbit.period - exact.period) < 1e-9 * exact.period and orbit.jumps == ("switch_off", "switch_on")
    assert np.abs(np.array(orbit.fixed_point) - exact.fixed_point).max() < 1e-9  # measured 3e-12 A, V
    lo, hi = orbit.extent("i_L")
    assert abs((hi - lo) - exact.ripple) < 1e-9 and abs(lo - exact.valley_current) < 1e-9
    # the first-order formula is off by at most Δv_C·D·T/L (the capacitor voltage is not constant): 2.7e-4 <= 6.9e-4 A
    assert abs((hi - lo) - exact.ripple_first_order) <= exact.ripple_bound
    assert abs(exact.ripple - exact.ripple_first_order) > 1e-5  # the bound is not met trivially
    v_lo, v_hi = orbit.extent("v_C")
    assert (v_hi - v_lo) == pytest.approx(exact.voltage_ripple, rel=1e-4)
    assert np.abs(np.array(orbit.nontrivial_multipliers) - np.array(exact.multipliers)).max() < 1e-9
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-9 and orbit.verdict == "orbitally stable"
    fd = np.sort_complex(np.linalg.eigvals(finite_difference_monodromy(system, orbit)))
    assert np.abs(fd - np.sort_complex(np.array(orbit.multipliers))).max() < 1e-6  # measured 1.7e-10


@pytest.mark.parametrize(("rate", "verdict"), [(-0.5, "orbitally stable"), (0.5, "unstable"), (0.0, "undecided")])
def test_the_verdict_follows_the_nontrivial_multiplier(rate, verdict):
    orbit = periodic_orbit(clocked(rate), section="tick", initial_state=(1.0, 1.2))  # rate 0: every r is periodic
    assert orbit.period == pytest.approx(1.0, abs=1e-12)
    assert orbit.fixed_point == pytest.approx((1.0, 1.0 if rate else 1.2), abs=1e-9)
    assert orbit.nontrivial_multipliers[0] == pytest.approx(math.exp(rate), abs=1e-9)
    assert abs(orbit.trivial_multiplier - 1.0) < 1e-9 and orbit.verdict == verdict


def test_memory_latched_by_the_resets_is_used_along_the_revolution():
    """The heater's temperature is a memory value set by the jumps: the on phase must use the reset's value."""
    automaton = HybridAutomaton(
        name="latched", variables=("T",), initial_mode="off", memory=(MemoryVariable(name="P", initial=0.0),),
        modes=(Mode(name="off", invariant=lambda v, m: v[0] - 19.0), Mode(name="on", invariant=lambda v, m: 21.0 - v[0])),
        transitions=(
            Transition(name="heat_on", source="off", target="on", guard=lambda v, m: 19.0 - v[0],
                       reset=lambda v, m: {"P": 30.0}, writes=("P",)),
            Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - 21.0,
                       reset=lambda v, m: {"P": -1.0}, writes=("P",))))
    system = HybridSystem(automaton=automaton, state_names=("T",),
                          flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),), "on": lambda t, x, m: (-0.1 * (x[0] - m["P"]),)})
    orbit = periodic_orbit(system, section="heat_on", initial_state=(19.0,))
    assert abs(orbit.period - thermostat_cycle().period) < 1e-9
    assert orbit.memory == (("P", -1.0),) and orbit.iterations == 2  # the first revolution found the cycle's memory


# ---------------------------------------------------------------------- saltation
def test_the_saltation_matrix_is_the_first_order_jump_of_a_neighbour():
    rng = np.random.default_rng(1)
    r = np.diag([1.0, -0.5, 2.0]) + 0.1 * rng.standard_normal((3, 3))
    grad = np.array([1.0, 0.3, -0.2])
    f_minus, f_plus = np.array([0.7, -0.1, 0.4]), np.array([-0.3, 0.5, 0.2])
    s = saltation_matrix(r, f_minus, f_plus, grad)
    assert np.allclose(s @ f_minus, f_plus, atol=1e-14)  # the flow direction is carried across
    for _ in range(3):  # a neighbour δ reaches the guard τ later: δ⁺ = R(δ + f⁻τ) − f⁺τ
        delta = 1e-7 * rng.standard_normal(3)
        tau = -(grad @ delta) / (grad @ f_minus)
        after = r @ (delta + f_minus * tau) - f_plus * tau
        assert np.abs(after - s @ delta).max() < 1e-9 * np.abs(delta).max()
    with pytest.raises(ArithmeticError, match="tangent to the guard"):
        saltation_matrix(r, np.array([0.0, 1.0, 0.0]), f_plus, np.array([1.0, 0.0, 0.0]))


def test_the_poincare_jacobian_is_the_derivative_of_the_poincare_map(relay):
    """Central differences of Π along the section's tangent plane against V^T (I − f∇g^T/∇g^T f) M V."""
    system, orbit, _ = relay
    x, basis, h = np.array(orbit.fixed_point), orbit.section_basis, 1e-6
    back = poincare_map(system, section="to_plus", state=x)
    assert back.time == pytest.approx(orbit.period, abs=1e-9) and back.jumps == ("to_plus", "to_minus", "to_plus")
    columns = []
    for j in range(basis.shape[1]):
        plus = poincare_map(system, section="to_plus", state=x + h * basis[:, j]).state
        minus = poincare_map(system, section="to_plus", state=x - h * basis[:, j]).state
        columns.append(basis.T @ (np.array(plus) - np.array(minus)) / (2 * h))
    assert np.abs(np.column_stack(columns) - orbit.poincare_jacobian).max() < 1e-6  # measured ~1e-9


def test_without_the_correction_term_the_checks_fail(relay, monkeypatch):
    """A saltation matrix reduced to R (here I) gives Φ = e^{AT}: multipliers e^{-T}, no 1; the checks catch it."""
    system, orbit, _ = relay
    monkeypatch.setattr(periodic, "saltation_matrix", lambda r, f_minus, f_plus, grad: np.asarray(r, dtype=float))
    broken = periodic_orbit(system, section="to_plus", initial_state=orbit.fixed_point)  # converged at once
    assert broken.iterations == 1
    fd = np.sort_complex(np.linalg.eigvals(finite_difference_monodromy(system, broken)))
    assert np.abs(fd - np.sort_complex(np.array(broken.multipliers))).max() > 0.5
    assert abs(broken.trivial_multiplier - 1.0) > 0.5


# ---------------------------------------------------------------------- results
def test_results_are_json_ready_and_errors_pickle(relay):
    _, orbit, _ = relay
    data = json.loads(json.dumps(orbit.as_dict()))
    assert data["period"] == orbit.period and data["verdict"] == "orbitally stable" and "times" not in data
    assert len(data["monodromy"]) == 3 and data["multipliers"][0][1] == 0.0 and data["finding"] == orbit.finding
    assert orbit.times[0] == 0.0 and orbit.times[-1] == orbit.period and orbit.states.shape == (orbit.times.size, 3)
    assert set(orbit.modes) == {"plus", "minus"} and not orbit.states.flags.writeable
    error = pickle.loads(pickle.dumps(ShootingError("no", 3, 0.5)))
    assert (error.iterations, error.residual, str(error)) == (3, 0.5, "no")


# ---------------------------------------------------------------------- bad input and failures
def test_bad_input_names_the_parameter():
    system = thermostat().system
    with pytest.raises(PeriodicOrbitError, match=r"^section = 'heat': expected one of the transitions"):
        periodic_orbit(system, section="heat", initial_state=(19.0,))
    with pytest.raises(PeriodicOrbitError, match=r"^initial_state = \(1\.0, 2\.0\): expected 1 finite values \(T\)"):
        periodic_orbit(system, section="heat_on", initial_state=(1.0, 2.0))
    with pytest.raises(PeriodicOrbitError, match=r"^initial_state = \(nan,\)"):
        periodic_orbit(system, section="heat_on", initial_state=(math.nan,))
    with pytest.raises(PeriodicOrbitError, match=r"^initial_mode = 'nope': expected one of the modes"):
        periodic_orbit(system, section="heat_on", initial_state=(19.0,), initial_mode="nope")
    with pytest.raises(PeriodicOrbitError, match=r"^tol = 0: expected a positive finite number"):
        periodic_orbit(system, section="heat_on", initial_state=(19.0,), tol=0)
    with pytest.raises(PeriodicOrbitError, match=r"^memory = \{'P': 1\.0\}: expected values of the memory"):
        periodic_orbit(system, section="heat_on", initial_state=(19.0,), memory={"P": 1.0})


def test_a_section_never_taken_again_says_from_where_and_within_what_time():
    base = thermostat().system  # a heater that cannot reach the upper threshold
    stuck = HybridSystem(automaton=base.automaton, state_names=("T",),
                         flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),), "on": lambda t, x, m: (-0.1 * (x[0] - 20.0),)})
    with pytest.raises(PeriodicOrbitError, match=r"^section = 'heat_on': expected a transition the flow takes again: "
                                                 r"from x = \(T=19\) in mode 'on' it was not taken within "
                                                 r"max_period = 50 s .*; fix: choose the guard"):
        periodic_orbit(stuck, section="heat_on", initial_state=(19.0,), max_period=50.0)


def test_a_shooting_that_does_not_converge_carries_its_iterations_and_residual(relay):
    system, _, _ = relay
    with pytest.raises(ShootingError, match=r"did not converge after 1 iterations \(residual .* = 1\.3") as info:
        periodic_orbit(system, section="to_plus", initial_state=(-0.1, 0.5, 0.5), max_iterations=1)
    assert info.value.iterations == 1 and info.value.residual == pytest.approx(1.335, abs=1e-3)


def test_too_many_jumps_diverging_and_zeno_revolutions_are_refused(relay):
    system, _, _ = relay
    with pytest.raises(PeriodicOrbitError, match=r"^max_jumps = 1: .*it took 2 jumps by t = 0\.39"):
        periodic_orbit(system, section="to_plus", initial_state=(-0.1, 0.5, 0.5), max_jumps=1)
    grow = HybridSystem(
        automaton=HybridAutomaton(name="grow", variables=("x",), modes=(Mode(name="a"),), transitions=(
            Transition(name="s", source="a", target="a", guard=lambda v, m: v[0] - 1.0, direction=1),)),
        state_names=("x",), flows={"a": lambda t, x, m: (x[0],)}, jumps={"s": lambda x, m: (2.0 * x[0],)})
    with pytest.raises(DivergenceError, match=r"diverged at t = 20\.03.* exceeds divergence_bound = 1e\+09 on the way "
                                              r"back to the section 's' from x = \(x=2\)") as info:
        periodic_orbit(grow, section="s", initial_state=(1.0,))
    assert info.value.mode == "a"
    # a ball that never climbs back to h = 10: its bounces accumulate first
    ball = HybridSystem(
        automaton=HybridAutomaton(name="ball", variables=("h", "v"), modes=(Mode(name="fly"),), transitions=(
            Transition(name="bounce", source="fly", target="fly", guard=lambda v, m: -v[0], direction=1),
            Transition(name="high", source="fly", target="fly", guard=lambda v, m: v[0] - 10.0, direction=1,
                       priority=1))),
        state_names=("h", "v"), flows={"fly": lambda t, x, m: (x[1], -9.81)},
        jumps={"bounce": lambda x, m: (0.0, -0.5 * x[1]), "high": lambda x, m: (x[0], 0.0)})
    with pytest.raises(ZenoError, match=r"the jumps accumulate \(Zeno: intervals shrink by 0\.5 per jump"):
        periodic_orbit(ball, section="high", initial_state=(10.0, 1.0), max_jumps=40)
    with pytest.raises(ZenoError, match=r"return time fell from 0\.815.* s to .*accumulate \(Zeno\)"):
        periodic_orbit(bouncing_ball().system, section="bounce", initial_state=(0.0, -5.0))  # Π(v) = e v: v* = 0
    with pytest.raises(ZenoError, match=r"takes no time \(an instantaneous cycle of jumps, Zeno\)"):
        periodic_orbit(user_thermostat(band=0.0), section="heat_on", initial_state=(20.0,))


def test_a_flow_that_reads_the_time_is_refused():
    base = thermostat().system
    driven = HybridSystem(automaton=base.automaton, state_names=("T",),
                          flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0 - math.sin(t)),),
                                 "on": lambda t, x, m: (-0.1 * (x[0] - 30.0),)})
    with pytest.raises(PeriodicOrbitError, match=r"^system = 'thermostat': expected an autonomous system.*; "
                                                 r"fix: make the time dependence a state"):
        periodic_orbit(driven, section="heat_on", initial_state=(19.0,))
