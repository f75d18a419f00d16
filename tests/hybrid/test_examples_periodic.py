"""The limit-cycle reference models (thermostat cycle, relay feedback, buck converter) against their closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybrid.continuous import simulate_continuous
from hybrid.errors import ModelDefinitionError
from hybrid.examples import (
    ReferenceModel,
    buck_converter,
    buck_converter_steady_state,
    relay_feedback,
    relay_feedback_cycle,
    thermostat_cycle,
    thermostat_switch_times,
)
from hybrid.model import Conjunction
from hybrid.symbolic import is_symbolic

TIGHT = {"rtol": 1e-12, "atol": 1e-12, "event_tol": 1e-300}  # event_tol: as narrow as the executor goes (4 ulp)


def test_the_thermostat_cycle_is_the_interval_of_its_switch_times():
    cycle = thermostat_cycle()
    times = thermostat_switch_times(T0=19.0, count=5)  # from the section: on at t = 0, then off, on, off, on
    assert times[0] == 0.0 and times[2] == pytest.approx(cycle.period, abs=1e-13)
    assert times[4] - times[2] == pytest.approx(cycle.period, abs=1e-12)
    assert cycle.time_on == pytest.approx(math.log(11 / 9) / 0.1, abs=1e-13) and cycle.multiplier == 1.0
    other = thermostat_cycle(ambient=0.0, heater=40.0, rate=0.5, low=18.0, high=22.0)
    assert other.time_off == pytest.approx(math.log(22 / 18) / 0.5) and other.time_on == pytest.approx(math.log(22 / 18) / 0.5)
    with pytest.raises(ModelDefinitionError, match="expected ambient < low < high < heater"):
        thermostat_cycle(low=22.0)


def test_the_relay_cycle_returns_to_itself_and_is_symmetric():
    model, cycle = relay_feedback(), relay_feedback_cycle()
    x_star = np.array(cycle.switch_state)
    assert x_star[0] == pytest.approx(-0.1, abs=1e-15)  # on the section y = -eps
    run = simulate_continuous(model.system, tuple(x_star), duration=cycle.period * (1 + 1e-9), initial_mode="plus", **TIGHT)
    (first, second), end = run.events[:2], run.final_state
    assert (first.transition, second.transition) == ("to_minus", "to_plus")
    assert first.time == pytest.approx(cycle.half_period, abs=1e-10) and second.time == pytest.approx(cycle.period, abs=1e-10)
    assert np.abs(np.array(first.state_before) + x_star).max() < 1e-10  # x(h) = -x*
    assert np.abs(np.array(second.state_before) - x_star).max() < 1e-10
    peak = np.abs(run.states[:, 0]).max()
    assert peak <= cycle.amplitude + 1e-12 and peak == pytest.approx(cycle.amplitude, abs=1e-4)
    assert cycle.first_harmonic < cycle.amplitude  # the fundamental of a flattened wave is below its peak
    # the closed-form monodromy carries the flow direction: trivial multiplier 1, the others inside the unit circle
    assert abs(cycle.multipliers[0] - 1.0) < 1e-12 and max(abs(m) for m in cycle.multipliers[1:]) < 0.03


def test_from_rest_the_relay_settles_on_the_cycle():
    model, cycle = relay_feedback(), relay_feedback_cycle()
    run = simulate_continuous(model.system, model.x0, duration=model.duration)
    last = [e for e in run.events if e.transition == "to_plus"][-1]
    assert np.abs(np.array(last.state_before) - cycle.switch_state).max() < 1e-6  # multipliers 0.026: fast


def test_the_describing_function_is_close_to_the_exact_cycle():
    cycle = relay_feedback_cycle()
    assert cycle.df_period == pytest.approx(2 * math.pi / cycle.df_frequency)
    g = 1.0 / (1j * cycle.df_frequency + 1.0) ** 3  # the harmonic balance it solved: G(iω) = -(π/4d)(√(a² − ε²) + iε)
    assert g == pytest.approx(-(math.pi / 4) * complex(math.sqrt(cycle.df_amplitude ** 2 - 0.01), 0.1), abs=1e-12)
    assert 0.0 < cycle.harmonic_ratio < 0.05  # the plant filters the relay's harmonics (the DF's hypothesis)
    assert abs(cycle.df_period - cycle.period) < 2 * cycle.harmonic_ratio * cycle.period


def test_the_buck_converter_steady_state_is_a_fixed_point_of_one_period():
    model, exact = buck_converter(), buck_converter_steady_state()
    i0, v0, _ = exact.fixed_point
    run = simulate_continuous(model.system, (i0, v0, 0.0), duration=exact.period * (1 + 1e-9), initial_mode="on", **TIGHT)
    off, on = run.events[:2]
    assert (off.transition, on.transition) == ("switch_off", "switch_on") and on.time == pytest.approx(exact.period, rel=1e-12)
    assert np.abs(np.array(on.state_before) - exact.fixed_point).max() < 1e-9
    assert off.state_before[0] == pytest.approx(exact.peak_current, abs=1e-9)
    assert on.state_after == (pytest.approx(i0, abs=1e-9), pytest.approx(v0, abs=1e-9), 0.0)
    # over the period: mean output D·V_in, mean current D·V_in/R (trapezoid on dense samples)
    t = np.linspace(0.0, exact.period, 20001)
    states, _ = run.sample(t)
    assert np.trapezoid(states[:, 1], t) / exact.period == pytest.approx(exact.mean_voltage, abs=1e-6)
    assert np.trapezoid(states[:, 0], t) / exact.period == pytest.approx(exact.mean_current, abs=1e-6)
    assert states[:, 1].max() - states[:, 1].min() == pytest.approx(exact.voltage_ripple, rel=1e-6)
    # the first-order ripple formula holds within the bound Δv_C·D·T/L, which is not vacuous
    assert abs(exact.ripple - exact.ripple_first_order) <= exact.ripple_bound < 0.01 * exact.ripple
    assert exact.valley_current > 0.0 and abs(exact.multipliers[0]) == pytest.approx(math.exp(-0.02), rel=1e-12)


@pytest.mark.parametrize("build", [relay_feedback, buck_converter], ids=["relay", "buck"])
def test_the_models_are_clean_symbolic_and_affine(build):
    model = build()
    assert isinstance(model, ReferenceModel) and model.planted == () and model.box.contains(model.x0)
    system, a = model.system, model.system.automaton
    parts = list(system.flows.values()) + list(system.jumps.values())
    parts += [t.guard for t in a.transitions] + [term for m in a.modes for term in m.invariant.terms]
    assert all(is_symbolic(p) for p in parts) and all(isinstance(m.invariant, Conjunction) for m in a.modes)
    for mode in a.modes:
        assert mode.description and mode.invariant_text
    for t in a.transitions:
        assert t.guard_text and t.reads and bool(t.reset_text) == (t.name in system.jumps)
    rng = np.random.default_rng(3)
    x, y = model.box.sample(rng, 2)
    for f in system.flows.values():  # affine: f(αx + (1 − α)y) = α f(x) + (1 − α) f(y)
        mid = np.array(f(0.0, tuple(0.3 * x + 0.7 * y), {}))
        assert np.allclose(mid, 0.3 * np.array(f(0.0, tuple(x), {})) + 0.7 * np.array(f(0.0, tuple(y), {})), rtol=1e-9)


def test_bad_parameters_are_refused():
    with pytest.raises(ModelDefinitionError, match=r"hysteresis = 2\.0 >= gain \* relay"):
        relay_feedback(hysteresis=2.0)
    with pytest.raises(ModelDefinitionError, match=r"relay = -1\.0; expected a finite relay amplitude"):
        relay_feedback_cycle(relay=-1.0)
    with pytest.raises(ModelDefinitionError, match=r"duty = 1\.0; expected a duty ratio in \(0, 1\)"):
        buck_converter(duty=1.0)
    with pytest.raises(ModelDefinitionError, match=r"inductance = 0\.0; expected a finite inductance"):
        buck_converter_steady_state(inductance=0.0)
