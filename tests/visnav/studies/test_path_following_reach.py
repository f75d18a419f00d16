"""The sampled path-following loop's flowpipe against an independent simulation of the held loop.

Yardstick: the loop the robot runs, integrated here period by period with scipy (DOP853, ``rtol 1e-10``):
``ω`` from :func:`visnav.model.path_following_omega` at each sample, held for ``T``, and the path-frame
rates :func:`visnav.model.path_error_rates` with the exact curvature ``1/(R + d0 + δ)`` — not the symbolic
automaton under test.  States are compared within ``1e-6`` (the integration is within ~1e-9).
"""

from __future__ import annotations

import math

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
