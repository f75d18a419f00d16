"""visnav.studies.path_following_sos on the paper scenario: region, bypass bounds, admissible gains."""

from __future__ import annotations

import json
import math

import casadi as ca
import numpy as np
import pytest

from analysis.polynomial import normal_form
from visnav import model
from visnav.scenario import load_scenario
from visnav.studies.loop_analysis import entry_angles_from_simulation
from visnav.studies.path_following import path_following_model
from visnav.studies.path_following_sos import (
    path_following_sos,
    polynomial_loop,
    sos_admissible_gains,
)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def analysis(scenario):
    """The expensive run, once: region and re-checked bypass bounds at the scenario's k (no gain scan)."""
    angles = [a for _, _, a in entry_angles_from_simulation(scenario)]
    return path_following_sos(scenario, entry_angles=angles, scan=False)


@pytest.fixture(scope="module")
def simulated_bypass(scenario):
    """Largest |delta| and |omega| of the simulated run while the supervisor follows the obstacle (sampled)."""
    from visnav.geometry import proximity
    from visnav.simulation import simulate
    from visnav.supervisor import split_mode

    trace = simulate(scenario).trace
    start = next(e for e in trace.events if split_mode(e.target)[0] == "AVOID")
    end = next(e for e in trace.events if split_mode(e.target)[0] == "LEAVE")
    memory = dict(start.memory)
    obstacle = scenario.obstacles[int(memory["obstacle"])]
    times = np.asarray(trace.times)
    mask = (times >= start.time) & (times <= end.time)
    deltas = [proximity(x, y, th, obstacle, int(memory["side"])).d_coll - scenario.envelopes.d_zero_m
              for x, y, th, _ in np.asarray(trace.states)[mask]]
    return float(np.max(np.abs(deltas))), float(np.max(np.abs(np.asarray(trace.inputs)[mask, 1])))


def test_the_loop_is_composed_from_the_model_and_matches_the_hand_analysis(scenario):
    env, gains = scenario.envelopes, scenario.gains
    loop = polynomial_loop(k=gains.k_path, v=gains.v_coll_mps, d_zero=env.d_zero_m, radii=(1.4, 0.35))
    delta, alpha = ca.SX.sym("delta"), ca.SX.sym("alpha")
    k, v = gains.k_path, gains.v_coll_mps
    closed = normal_form(-v * (k * delta + alpha + 2 * k * ca.sin(alpha)), [delta, alpha])
    assert (loop.rates["alpha"] - closed).reduce_pythagorean().is_zero
    pf = path_following_model(k=k, v=v, d_zero=env.d_zero_m, radius=1.4)
    hand_rate = normal_form(pf.lyapunov_rate, [pf.delta, pf.alpha, pf.kappa])
    assert (loop.hand_rate - hand_rate).reduce_pythagorean().is_zero
    with pytest.raises(ValueError, match="k = -1"):
        polynomial_loop(k=-1.0, v=v, d_zero=env.d_zero_m, radii=(1.4,))


def test_region_is_proven_and_larger_than_the_hand_one(analysis):
    region = analysis.region
    assert region.status == "proven" and region.recheck_problems == ()
    assert region.certificate.certified and region.certificate.entry_time_bound is not None
    assert region.area_ratio > 1.0
    assert region.hand_level == pytest.approx(min(2.0, 4.0 * 0.5**2 / 2))


def _rate_with_floats(v_poly, scenario, delta, alpha, h=1e-6):
    """dV/dt from the model's float functions and central differences of V (independent of the normal form)."""
    gains, env = scenario.gains, scenario.envelopes
    kappa = 1.0 / (1.4 + env.d_zero_m + delta)
    omega = model.path_following_omega(delta, alpha, kappa, 1, gains.v_coll_mps, gains.k_path)
    ddelta, dalpha = model.path_error_rates(gains.v_coll_mps, omega, alpha, kappa, 1)

    def value(d, a):
        return v_poly.evaluate_at({"delta": d, "alpha": a})

    grad_d = (value(delta + h, alpha) - value(delta - h, alpha)) / (2 * h)
    grad_a = (value(delta, alpha + h) - value(delta, alpha - h)) / (2 * h)
    return grad_d * ddelta + grad_a * dalpha


def test_every_certified_v_decreases_at_random_points(analysis, scenario):
    rng = np.random.default_rng(7)
    cases = [(analysis.region.lyapunov, 1.0, 0.01, analysis.region.certificate.region)]
    for bypass in analysis.bypass:
        cases += [(s.lyapunov, s.level, 0.5 * s.level, s.certificate.region) for s in bypass.sets if s.certified]
    assert len(cases) >= 3
    for v_poly, rho_out, rho_in, region in cases:
        (dlo, dhi), (alo, ahi) = region
        checked = 0
        for d, a in zip(rng.uniform(dlo, dhi, 4000), rng.uniform(alo, ahi, 4000)):
            level = v_poly.evaluate_at({"delta": float(d), "alpha": float(a)})
            if rho_in <= level <= rho_out:
                assert _rate_with_floats(v_poly, scenario, float(d), float(a)) <= 1e-9
                checked += 1
        assert checked > 20


def test_bypass_bounds_contain_the_simulation_and_beat_the_hand_bounds(analysis, simulated_bypass):
    sim_delta, sim_omega = simulated_bypass
    (bypass,) = analysis.bypass
    assert bypass.status == "proven" and bypass.combined.recheck_problems == ()
    assert all(s.recheck_problems == () for s in bypass.sets if s.certified)
    bound = bypass.combined
    assert bound.delta_max_m >= sim_delta and bound.omega_max_radps >= sim_omega  # below would be a bug
    hand = bypass.hand_closed_form["segment_end"]  # the same entry segment
    assert bound.delta_max_m <= hand["delta_max_m"] and bound.omega_max_radps <= hand["omega_max_radps"]
    assert bypass.hand_closed_form["nominal"]["omega_max_radps"] > analysis.omega_limit_radps  # the old finding
    assert bound.min_distance_m >= analysis.clearance_m and bound.omega_max_radps <= analysis.omega_limit_radps


def test_result_is_json_ready_and_labelled(analysis):
    data = analysis.as_dict()
    text = json.dumps(data)
    assert "NaN" not in text and "Infinity" not in text
    statuses = {c["status"] for c in data["claims"]}
    assert statuses <= {"proven", "not proven", "sampled", "computed"}
    assert data["claims"][0]["status"] == "proven" and data["region"]["area_ratio"] > 1
    assert data["admissible"]["proven_gains"] == [analysis.k]


def test_gain_scan_refutes_proves_and_keeps_the_hand_finding(scenario):
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    delta_entry = (env.d_minus_m - env.d_zero_m - gains.v_coll_mps * scenario.sampling_period_s,
                   env.d_minus_m - env.d_zero_m)
    result = sos_admissible_gains(v=gains.v_coll_mps, d_zero=env.d_zero_m, radii=(1.4, 0.35),
                                  delta_entry=delta_entry, entry_angles=(-0.5125816990919788,), clearance=0.1,
                                  omega_max=limits.omega_max_radps, k_range=(0.1, 10.0), coarse=3, refine=0)
    verdicts = {round(e.k, 6): e.verdict for e in result.evaluations}
    assert verdicts == {0.1: "refuted by simulation", 1.0: "proven admissible", 10.0: "refuted at the entry"}
    assert result.interval == (1.0, 1.0) and result.hand["interval"] is None
    assert "hand-given V admits none" in result.finding
    with pytest.raises(ValueError, match="entry_angles is empty"):
        sos_admissible_gains(v=0.2, d_zero=0.5, radii=(1.4,), delta_entry=delta_entry, entry_angles=(),
                             clearance=0.1, omega_max=1.2)
    assert math.isfinite(result.evaluations[1].omega_max_radps)


def test_k_interval_certificates_prove_every_gain_between_two(scenario):
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    delta_entry = (env.d_minus_m - env.d_zero_m - gains.v_coll_mps * scenario.sampling_period_s,
                   env.d_minus_m - env.d_zero_m)
    result = sos_admissible_gains(v=gains.v_coll_mps, d_zero=env.d_zero_m, radii=(1.4, 0.35),
                                  delta_entry=delta_entry, entry_angles=(-0.5125816990919788,), clearance=0.1,
                                  omega_max=limits.omega_max_radps, k_range=(3.5, 4.0), coarse=2, refine=0,
                                  prove_intervals=True, max_ratio=1.2)
    assert result.proven_gains == (3.5, 4.0) and all(e.rechecked for e in result.evaluations)
    (piece,) = result.intervals_proven
    assert piece["proven"], piece["why"]
    assert result.interval_proven and result.continuous_interval == (3.5, 4.0)
    assert "every k in it" in result.finding


@pytest.mark.parametrize("kwargs, pattern", [
    ({"entry_angles": []}, r"^entry_angles = \[\]: expected a non-empty sequence of finite angles"),
    ({"entry_angles": None}, r"^entry_angles = None: expected a non-empty sequence"),
    ({"entry_angles": "ab"}, r"^entry_angles = 'ab': expected"),
    ({"entry_angles": [math.nan]}, r"^entry_angles = \(nan,\): expected .*finite angles"),
    ({"entry_angles": [3.1]}, r"^entry_angles = \(3\.1,\): expected .*\|alpha\| < 2\.98451"),
    ({"entry_angles": [True]}, r"^entry_angles = \(True,\): expected"),
    ({"entry_angles": [-0.5], "degree": "4"}, r"^degree = '4': expected an even integer >= 2"),
    ({"entry_angles": [-0.5], "degree": 3}, r"^degree = 3: expected an even integer >= 2"),
])
def test_bad_arguments_are_refused_before_any_work(scenario, kwargs, pattern):
    from hybrid.errors import ParameterError

    with pytest.raises(ParameterError, match=pattern):
        path_following_sos(scenario, scan=False, **kwargs)
