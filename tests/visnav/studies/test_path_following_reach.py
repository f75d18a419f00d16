"""The sampled path-following loop's flowpipe against an independent simulation of the held loop.

Yardstick: the loop the robot runs, integrated here period by period with scipy (DOP853, ``rtol 1e-10``):
``ω`` from :func:`visnav.model.path_following_omega` at each sample, held for ``T``, and the path-frame
rates :func:`visnav.model.path_error_rates` with the exact curvature ``1/(R + d0 + δ)`` — not the symbolic
automaton under test.  States are compared within ``1e-6`` (the integration is within ~1e-9).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from analysis.reach import reach
from visnav import model
from visnav.scenario import load_scenario
from visnav.studies.path_following_reach import (
    STATE_NAMES,
    BypassEntry,
    campaign_entries,
    modal_basis,
    prove_bypass,
    sampled_bypass_system,
)

TOL = 1e-6


def _held_loop(delta0, alpha0, radius, k, v, d0, period, horizon):
    """(times, states (δ, α)) of the sampled loop, every period and 10 points inside each."""
    side = 1.0
    times, states = [], []
    x = np.array([delta0, alpha0])
    t = 0.0
    while t < horizon - 1e-12:
        omega = model.path_following_omega(x[0], x[1], 1.0 / (radius + d0 + x[0]), side, v, k)

        def rates(_, z, omega=omega):
            return model.path_error_rates(v, omega, z[1], 1.0 / (radius + d0 + z[0]), side)

        span = np.linspace(t, t + period, 11)
        sol = solve_ivp(rates, (t, t + period), x, method="DOP853", t_eval=span, rtol=1e-10, atol=1e-12)
        times.append(sol.t)
        states.append(sol.y.T)
        x = sol.y[:, -1]
        t += period
    return np.concatenate(times), np.vstack(states)


@pytest.mark.parametrize("modal", [False, True])
def test_the_flowpipe_holds_the_sampled_loop(modal):
    scenario = load_scenario("paper")
    k, v, d0, period = (scenario.gains.k_path, scenario.gains.v_coll_mps, scenario.envelopes.d_zero_m,
                        scenario.sampling_period_s)
    d, a, radii = (-0.21, -0.2), (-0.6, -0.4), (1.38, 1.42)
    kappa = (1.0 / (radii[1] + d0 + d[1]) * (1 - 1e-15), 1.0 / (radii[0] + d0 + d[0]) * (1 + 1e-15))
    basis = modal_basis(k=k, v=v) if modal else ((1.0, 0.0), (0.0, 1.0))
    inverse = np.linalg.inv(np.array(basis))
    corners = np.array([inverse @ (p, q) for p in d for q in a])
    w1 = (corners[:, 0].min() - 1e-12, corners[:, 0].max() + 1e-12)
    w2 = (corners[:, 1].min() - 1e-12, corners[:, 1].max() + 1e-12)
    initial = {"delta": w1, "alpha": w2, "kappa": kappa, "delta_h": w1, "alpha_h": w2, "kappa_h": kappa,
               "clock": (0.0, 0.0)}
    horizon = 1.0
    result = reach(sampled_bypass_system(k=k, v=v, period=period, basis=basis if modal else None), initial,
                   horizon=horizon, time_step=period / 5, max_jumps=30)
    assert result.status == "complete"
    assert all(t.reason != "max_jumps" for t in result.terminations)
    rng = np.random.default_rng(4)
    starts = [(d0_, a0_, r) for d0_ in d for a0_ in a for r in radii]
    starts += [tuple(rng.uniform((d[0], a[0], radii[0]), (d[1], a[1], radii[1]))) for _ in range(12)]
    for delta0, alpha0, radius in starts:
        times, states = _held_loop(delta0, alpha0, radius, k, v, d0, period, horizon)
        for t, (delta, alpha) in zip(times, states @ inverse.T):  # in the automaton's coordinates
            hits = [s for s in result.segments if s.t_lo - TOL <= t <= s.t_hi + TOL
                    and s.lo[0] - TOL <= delta <= s.hi[0] + TOL and s.lo[1] - TOL <= alpha <= s.hi[1] + TOL]
            assert hits, f"t = {t}, δ = {delta}, α = {alpha} (start {delta0}, {alpha0}, R = {radius}) outside"


def test_a_short_bypass_is_proven_from_entries_and_reports_its_coverage():
    scenario = load_scenario("paper")
    entries = (BypassEntry(sample=0, obstacle="low", radius_m=1.40, delta_m=-0.204, alpha_rad=-0.55, duration_s=1.0),
               BypassEntry(sample=1, obstacle="low", radius_m=1.42, delta_m=-0.201, alpha_rad=-0.45, duration_s=1.0))
    out = prove_bypass(scenario, entries=entries, horizon_s=0.5)
    assert out.status == "proven", out.evidence
    assert out.coverage == {"claim": "measured", "entries": 2, "inside": 2, "samples": None, "seed": 0}
    # the proven bound is at least the largest |δ| the held loop reaches from the entries (independent)
    reached = max(float(np.max(np.abs(_held_loop(e.delta_m, e.alpha_rad, e.radius_m, out.k, out.v_mps, out.d_zero_m,
                                                 out.period_s, 0.5)[1][:, 0]))) for e in entries)
    assert reached <= out.delta_bound_m < out.d_zero_m
    assert out.as_dict()["status"] == "proven"
    assert set(STATE_NAMES) >= {"delta", "alpha"}


def test_campaign_entries_are_measured_states_at_the_switch():
    scenario = load_scenario("paper")
    entries = campaign_entries(scenario, samples=2, seed=0)
    assert entries
    d0, d_minus = scenario.envelopes.d_zero_m, scenario.envelopes.d_minus_m
    step = 1.25 * scenario.gains.v_coll_mps * scenario.sampling_period_s  # v_coll scaled up to 1.25 by the campaign
    for e in entries:
        # the switch happens at the first sample after crossing d−: δ within one step of d− − d0
        assert d_minus - d0 - step - 1e-9 <= e.delta_m <= d_minus - d0 + 1e-9
        assert math.isfinite(e.alpha_rad) and e.duration_s > 0


# --------------------------------------------------------------------------- the case study at its default settings

def _rk4_held_loop(starts: np.ndarray, k: float, v: float, d0: float, period: float, horizon: float,
                   sub: int = 50) -> np.ndarray:
    """max |δ| over ``[0, horizon]`` of the held loop from each start ``(δ, α, R)``: classical RK4 with ``sub``
    steps a period, vectorised over the starts, on :func:`visnav.model.path_error_rates` with ``ω`` from
    :func:`visnav.model.path_following_omega` held over each period (independent of the automaton).

    Step ``T / sub = 1 ms`` on rates of size ``v = 0.2`` m/s and curvature ~0.5: the local error is ~1e-15,
    far below the 1e-4 m the assertions leave.
    """
    delta, alpha, radius = (starts[:, i].astype(float) for i in range(3))
    h = period / sub
    peak = np.abs(delta)

    def rates(d, a, omega):
        return model.path_error_rates(v, omega, a, 1.0 / (radius + d0 + d), 1.0, ops=np)

    for _ in range(int(round(horizon / period))):
        omega = model.path_following_omega(delta, alpha, 1.0 / (radius + d0 + delta), 1.0, v, k, ops=np)
        for _ in range(sub):
            k1 = rates(delta, alpha, omega)
            k2 = rates(delta + h / 2 * k1[0], alpha + h / 2 * k1[1], omega)
            k3 = rates(delta + h / 2 * k2[0], alpha + h / 2 * k2[1], omega)
            k4 = rates(delta + h * k3[0], alpha + h * k3[1], omega)
            delta = delta + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            alpha = alpha + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            peak = np.maximum(peak, np.abs(delta))
    return peak


def test_rk4_yardstick_agrees_with_the_scipy_held_loop():
    scenario = load_scenario("paper")
    k, v, d0, period = (scenario.gains.k_path, scenario.gains.v_coll_mps, scenario.envelopes.d_zero_m,
                        scenario.sampling_period_s)
    start = (-0.205, -0.79, 1.36)
    fine = np.max(np.abs(_held_loop(*start, k, v, d0, period, 2.0)[1][:, 0]))
    assert _rk4_held_loop(np.array([start]), k, v, d0, period, 2.0)[0] == pytest.approx(fine, abs=1e-6)


@pytest.fixture(scope="module")
def paper_bypass():
    """The case study at its defaults (40 campaign draws, seed 0, the longest measured bypass): run once."""
    from visnav.studies.path_following_reach import bypass_reach

    scenario = load_scenario("paper")
    return scenario, bypass_reach(scenario), campaign_entries(scenario, samples=40, seed=0)


def test_the_paper_bypass_is_proven_re_checked_and_bounds_every_simulated_entry(paper_bypass):
    scenario, out, entries = paper_bypass
    assert out.status == "proven", out.evidence  # "proven" needs the flowpipe's decision and the re-check
    assert "re-checked from the saved flowpipe" in out.evidence
    assert out.coverage["inside"] == out.coverage["entries"] == len(entries) >= 30
    assert out.horizon_s >= max(e.duration_s for e in entries if math.isfinite(e.duration_s))
    assert out.delta_bound_m < out.d_zero_m
    # in step with the samples: one jump a period over the window (T/5 took 790 jumps for 632 periods)
    assert out.jumps == round(out.horizon_s / out.period_s)
    # independent yardstick: the held loop by RK4 from every measured entry and every corner of the box
    box = out.entry_box
    corners = [(d, a, r) for d in box["delta_m"] for a in box["alpha_rad"] for r in out.radius_m]
    starts = np.array([(e.delta_m, e.alpha_rad, e.radius_m) for e in entries] + corners)
    reached = _rk4_held_loop(starts, out.k, out.v_mps, out.d_zero_m, out.period_s, out.horizon_s)
    assert np.max(reached) <= out.delta_bound_m
    # and the bound is not vacuous: within 0.05 m of what the simulated corners reach (measured: 0.2704 m
    # reached, bound 0.3196 m, gap 0.049 m; at step T/5 the bound was 0.3117 m)
    assert out.delta_bound_m - np.max(reached) < 0.05
    # the entry box: short decimals holding the measured entries with the margins
    assert box["delta_m"][0] <= min(e.delta_m for e in entries) - 0.005
    assert box["alpha_rad"][1] >= max(e.alpha_rad for e in entries) + 0.05
    # short decimals, each bound's float on the outer side of its decimal (the printed box is inside the proven one)
    for lo, hi in box.values():
        assert Fraction(lo) <= Fraction(f"{lo:.4f}") and Fraction(hi) >= Fraction(f"{hi:.4f}")
        assert abs(lo - round(lo, 4)) <= 1e-16 and abs(hi - round(hi, 4)) <= 1e-16


def test_a_limit_below_what_the_simulated_loop_reaches_is_not_proven(paper_bypass):
    scenario, out, entries = paper_bypass
    box = out.entry_box
    corners = np.array([(d, a, r) for d in box["delta_m"] for a in box["alpha_rad"] for r in out.radius_m])
    horizon = 3.0  # the largest |δ| is reached within the first 3 s (|δ| then decays)
    reached = float(np.max(_rk4_held_loop(corners, out.k, out.v_mps, out.d_zero_m, out.period_s, horizon)))
    tight = prove_bypass(scenario, entries=entries, horizon_s=horizon, limit_m=reached - 1e-3)
    assert tight.status == "not proven" and math.isnan(tight.delta_bound_m)
    # the same window with a limit the flowpipe can prove: the bound sits between the simulation and d0
    loose = prove_bypass(scenario, entries=entries, horizon_s=horizon, limit_m=out.d_zero_m)
    assert loose.status == "proven" and reached <= loose.delta_bound_m < out.d_zero_m


def test_a_bad_limit_is_refused_by_name():
    scenario = load_scenario("paper")
    entry = BypassEntry(sample=0, obstacle="low", radius_m=1.4, delta_m=-0.2, alpha_rad=-0.5, duration_s=1.0)
    with pytest.raises(ValueError, match="limit_m"):
        prove_bypass(scenario, entries=(entry,), horizon_s=0.5, limit_m=-1.0)
