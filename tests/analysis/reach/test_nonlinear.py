"""Nonlinear (smooth) reachability: flowpipes against fine simulations, planted sets, refusals, the re-check.

Yardsticks independent of the reachability code: trajectories from scipy's ``solve_ivp`` (DOP853,
``rtol = 1e-10``, ``atol = 1e-12``) or the executor (:func:`hybrid.continuous.simulate_continuous`, same
tolerances, events located to 1e-12 s), so the simulated points are within ~1e-8 of the true
trajectories over these horizons; they are accepted within ``TOL = 1e-6`` (state and time), far below
the planted sets' margins.  Membership is decided by a facet test written here (2-D zonotopes).
The true maxima of the planted sets come from the same fine simulations (a dense grid of the initial
box's boundary, which the flow maps to the boundary of the reached set).
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from analysis.reach import AffineError, reach, recheck_flowpipe, safety_fragment, unsafe_set
from analysis.reach.float_series import float_bloating, float_exp_enclosure
from analysis.reach.series import bloating_matrices
from analysis.reach.split import covers, split_box
from analysis.reach.verdict import METHOD_NONLINEAR, ReachProof, reach_proof
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode, Transition
from hybrid.continuous import simulate_continuous
from hybrid.symbolic import atan2, coordinates, cos, exp, flow_map, ite, jump_map, select, sin
from hybrid.system import HybridSystem

TOL = 1e-6
NAMES = ("x", "y")
X = coordinates(*NAMES)


def _one_mode(flow, names=NAMES, invariant=None, name="s") -> HybridSystem:
    automaton = HybridAutomaton(name=name, modes=(Mode(name="m", invariant=invariant),), transitions=(),
                                variables=names)
    return HybridSystem(automaton=automaton, state_names=names, flows={"m": flow})


def vdp(mu: float = 1.0) -> HybridSystem:
    return _one_mode(flow_map(X.y, mu * (1.0 - X.x ** 2) * X.y - X.x), name="vdp")


def lotka_volterra() -> HybridSystem:
    """ARCH-COMP's LOVO parameters: x' = 1.5 x − x y, y' = x y − 3 y."""
    return _one_mode(flow_map(1.5 * X.x - X.x * X.y, X.x * X.y - 3.0 * X.y), name="lovo")


def _vdp_rhs(mu):
    return lambda t, z: [z[1], mu * (1 - z[0] ** 2) * z[1] - z[0]]


def _lv_rhs(t, z):
    return [1.5 * z[0] - z[0] * z[1], z[0] * z[1] - 3.0 * z[1]]


def _inside(segment, points: np.ndarray) -> np.ndarray:
    ok = np.all((points >= segment.lo - TOL) & (points <= segment.hi + TOL), axis=1)
    z = segment.zonotope
    d = points - z.center
    g = z.generators
    normals = np.vstack([np.vstack([-g[1], g[0]]).T, g.T])
    norms = np.hypot(normals[:, 0], normals[:, 1])
    normals = normals[norms > 0] / norms[norms > 0, None]
    reach_ = np.abs(normals @ g).sum(axis=1) + TOL * np.abs(normals).sum(axis=1)
    return ok & np.all(np.abs(d @ normals.T) <= reach_, axis=1)


def _check_inside(result, times: np.ndarray, modes: np.ndarray, points: np.ndarray) -> None:
    covered = np.zeros(times.size, dtype=bool)
    order = np.argsort(times, kind="stable")
    t_sorted = times[order]
    for s in result.segments:
        a = np.searchsorted(t_sorted, s.t_lo - TOL, side="left")
        b = np.searchsorted(t_sorted, s.t_hi + TOL, side="right")
        rows = order[a:b]
        rows = rows[(modes[rows] == s.mode) & ~covered[rows]]
        if rows.size:
            covered[rows] = _inside(s, points[rows])
    missing = np.nonzero(~covered)[0]
    assert missing.size == 0, (f"{missing.size} of {times.size} simulated points outside the flowpipe, e.g. "
                               f"t = {times[missing[0]]!r}, x = {points[missing[0]]!r}")


def _samples(fine_runs, rhs, lo, hi, horizon, count, seed, every=0.01):
    times, points = fine_runs(rhs, lo, hi, horizon, count, seed, every)
    return times, np.array(["m"] * times.size), points


def _boundary_max(rhs, lo, hi, horizon, coordinate, per_side=60):
    """max of one coordinate over the reached set up to the horizon (fine simulations of the box's boundary)."""
    grid = np.linspace(0.0, 1.0, per_side)
    starts = [(lo[0] + (hi[0] - lo[0]) * a, lo[1] + (hi[1] - lo[1]) * b) for a in grid for b in grid
              if a in (0.0, 1.0) or b in (0.0, 1.0)]
    best = -math.inf
    for x0 in starts:
        sol = solve_ivp(rhs, (0.0, horizon), x0, method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
        ts = np.linspace(0.0, horizon, 4001)
        best = max(best, float(sol.sol(ts)[coordinate].max()))
    return best


# ---------------------------------------------------------------------------------------------- soundness
def test_van_der_pol_flowpipe_holds_fine_simulations(fine_runs):
    """μ = 1 from the VDP01 box (whole, not split) over 7 s: every sampled state lies in the flowpipe."""
    lo, hi = (1.25, 2.35), (1.55, 2.45)
    result = reach(vdp(), {"x": (lo[0], hi[0]), "y": (lo[1], hi[1])}, horizon=7.0, time_step=0.005)
    assert result.status == "complete", result.terminations
    _check_inside(result, *_samples(fine_runs, _vdp_rhs(1.0), lo, hi, 7.0, 60, seed=11))


def test_lotka_volterra_flowpipe_holds_fine_simulations(fine_runs):
    """LOVO's parameters and initial box x ∈ [1.3, 1.32], y ∈ [0.99, 1.01] over 3.64 s."""
    lo, hi = (1.3, 0.99), (1.32, 1.01)
    result = reach(lotka_volterra(), {"x": (lo[0], hi[0]), "y": (lo[1], hi[1])}, horizon=3.64, time_step=0.005)
    assert result.status == "complete", result.terminations
    _check_inside(result, *_samples(fine_runs, _lv_rhs, lo, hi, 3.64, 60, seed=12))


def test_a_hybrid_nonlinear_system_holds_executor_runs():
    """Two modes: a damped pendulum (sin) that jumps when θ reaches 0.3, its speed halved, to a linear mode."""
    th = coordinates("th", "w")
    names = ("th", "w")
    automaton = HybridAutomaton(name="pendulum", variables=names, modes=(
        Mode(name="m", invariant=th.th <= 0.3), Mode(name="lin")), transitions=(
        Transition(name="hit", source="m", target="lin", guard=th.th >= 0.3),), initial_mode="m")
    system = HybridSystem(automaton=automaton, state_names=names, flows={
        "m": flow_map(th.w, -9.81 * sin(th.th) - 0.2 * th.w), "lin": flow_map(th.w, -th.th)},
        jumps={"hit": jump_map(th.th, -0.5 * th.w)})
    result = reach(system, {"th": (-0.3, -0.25), "w": (1.5, 1.6)}, horizon=1.5, time_step=0.002, max_jumps=3)
    assert result.status == "complete", result.terminations
    assert any(j.transition == "hit" for j in result.jumps)
    rng = np.random.default_rng(5)
    starts = np.vstack([list(itertools.product((-0.3, -0.25), (1.5, 1.6))),
                        rng.uniform((-0.3, 1.5), (-0.25, 1.6), size=(40, 2))])
    times, modes, points = [], [], []
    for x0 in starts:
        tr = simulate_continuous(system, tuple(x0), duration=1.5, rtol=1e-10, atol=1e-12)
        times.append(np.asarray(tr.times))
        modes.append(np.asarray(tr.modes))
        points.append(np.asarray(tr.states))
    _check_inside(result, np.concatenate(times), np.concatenate(modes), np.vstack(points))


# ---------------------------------------------------------------------------------------------- verdicts
def test_vdp01_is_proven_and_rechecked_and_a_planted_set_it_enters_is_not():
    """ARCH-COMP VDP, μ = 1: y < 2.75 over 7 s proven (x split in 4, re-checked); the true maximum of y is
    about 2.679 (fine simulations of the box's boundary), so ``y < 2.6`` is violated and must never be proven."""
    box = {"x": (1.25, 1.55), "y": (2.35, 2.45)}
    safe = safety_fragment(parse_tree("always[0, 7] (y < 2.75)"), NAMES)
    proof, decision = reach_proof(vdp(), safe, box, time_step=0.005, splits={"x": 4})
    assert proof.holds and proof.rechecked, proof.evidence
    assert proof.method == METHOD_NONLINEAR
    true_max = _boundary_max(_vdp_rhs(1.0), (1.25, 2.35), (1.55, 2.45), 7.0, 1)
    assert 2.6 < true_max < 2.75  # the planted set below is entered, the safe one is not
    assert 0 < decision.margin <= 2.75 - true_max  # the margin is a lower bound of the true slack
    entered = safety_fragment(parse_tree("always[0, 7] (y < 2.6)"), NAMES)
    bad, _ = reach_proof(vdp(), entered, box, time_step=0.005, splits={"x": 4})
    assert not bad.holds


def test_planted_unsafe_sets_around_the_true_maximum():
    """Lotka–Volterra: the set x >= max + 0.02 is separated, x >= max − 0.02 (entered) is not."""
    lo, hi = (1.3, 0.99), (1.32, 1.01)
    top = _boundary_max(_lv_rhs, lo, hi, 3.64, 0)
    result = reach(lotka_volterra(), {"x": (lo[0], hi[0]), "y": (lo[1], hi[1])}, horizon=3.64, time_step=0.005,
                   unsafe=[unsafe_set("above", X.x >= top + 0.02, NAMES), unsafe_set("entered", X.x >= top - 0.02, NAMES)])
    distances = dict(result.distances)
    assert result.status == "complete"
    assert distances["above"] > 0
    assert distances["entered"] <= 0


# ---------------------------------------------------------------------------------------------- re-check
def test_a_tampered_nonlinear_flowpipe_fails_the_recheck():
    box = {"x": (1.25, 1.3), "y": (2.35, 2.4)}
    fragment = safety_fragment(parse_tree("always[0, 0.5] (y < 3)"), NAMES)
    result = reach(vdp(), box, horizon=0.5, time_step=0.005)
    good = recheck_flowpipe(result.to_json(), vdp(), box, fragment)
    assert good.passed, good.failure
    data = json.loads(result.to_json())
    seg = data["segments"][40]
    mid = [(a + b) / 2 for a, b in zip(*seg["box"])]
    seg["box"] = [[m - 0.7 * (m - a) for m, a in zip(mid, seg["box"][0])],
                  [m + 0.7 * (b - m) for m, b in zip(mid, seg["box"][1])]]
    bad = recheck_flowpipe(data, vdp(), box, fragment)
    assert not bad.passed and "segment 39" in bad.failure


# ---------------------------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("term, word", [
    (atan2(X.y, X.x), "atan2"), (exp(X.x), "exp"), (ite(X.x >= 0.0, X.x, -X.x), "piecewise"),
    (select(X.x, (X.y, X.x)), "piecewise"), (abs(X.x), "abs")])
def test_unsupported_terms_are_refused_by_name(term, word):
    system = _one_mode(flow_map(X.y, term))
    with pytest.raises(AffineError, match=word):
        reach(system, {"x": (0.0, 1.0), "y": (0.0, 1.0)}, horizon=1.0, time_step=0.01)
    # through verify's callable: a proof that does not hold and says why (inconclusive), not a traceback
    proof = ReachProof(system=system, fragment=safety_fragment(parse_tree("always[0, 1] (y < 5)"), NAMES),
                       initial=(("x", 0.0, 1.0), ("y", 0.0, 1.0)))()
    assert not proof.holds and "not decided by reachability" in proof.evidence and word in proof.evidence


def test_finite_escape_is_an_inconclusive_blow_up():
    """x' = x² from [1, 1.1] escapes by t = 1: the run says where it blew up, and proves nothing."""
    x = coordinates("x")
    system = _one_mode(flow_map(x.x ** 2), names=("x",))
    result = reach(system, {"x": (1.0, 1.1)}, horizon=2.0, time_step=0.01)
    assert result.status == "inconclusive"
    term = result.terminations[-1]
    assert term.reason == "blow_up" and "blew up at t = " in term.detail and "mode 'm'" in term.detail
    assert term.time <= 1.0
    proof, _ = reach_proof(system, safety_fragment(parse_tree("always[0, 2] (x < 1e9)"), ("x",)), {"x": (1.0, 1.1)},
                           time_step=0.01)
    assert not proof.holds


def test_a_smooth_flow_with_cos_is_read_and_enclosed():
    """x' = cos(x) from [0, 0.1]: x(t) = 2 atan(tanh(t/2 + atanh(tan(x0/2)))) stays inside the flowpipe."""
    x = coordinates("x")
    result = reach(_one_mode(flow_map(cos(x.x)), names=("x",)), {"x": (0.0, 0.1)}, horizon=2.0, time_step=0.01)
    assert result.status == "complete"
    for t in np.linspace(0.0, 2.0, 41):
        for x0 in (0.0, 0.05, 0.1):
            exact = 2 * math.atan(math.tanh(t / 2 + math.atanh(math.tan(x0 / 2))))
            assert result.contains("m", float(t), [exact], tol=TOL)


# ---------------------------------------------------------------------------------------------- pieces
def test_float_exponential_encloses_scipy_and_the_rational_bloating():
    rng = np.random.default_rng(3)
    for _ in range(30):
        a = rng.normal(size=(3, 3)) * rng.uniform(0.1, 30.0)
        step = float(rng.uniform(1e-3, 0.1)) / max(1.0, float(np.abs(a).sum(axis=1).max()))
        enc = float_exp_enclosure(a, step)
        reference = expm(a * step)
        assert np.all(np.abs(reference - enc.center) <= enc.radius + 1e-15 * np.abs(reference))
        assert float(enc.radius.max()) < 1e-12
        from fractions import Fraction

        d, s = float_bloating(a, step)
        d_exact, s_exact = bloating_matrices([[Fraction(float(v)) for v in row] for row in a], Fraction(step))
        assert np.all(d >= d_exact * (1 - 1e-12)) and np.all(s >= s_exact * (1 - 1e-12))
        assert np.all(d <= d_exact * (1 + 1e-9) + 1e-300) and np.all(s <= s_exact * (1 + 1e-9) + 1e-300)


def test_split_boxes_cover_exactly():
    box = {"x": (1.25, 1.55), "y": (2.35, 2.45)}
    pieces = split_box(box, {"x": 3, "y": 2})
    assert len(pieces) == 6 and covers(box, pieces)
    assert not covers(box, pieces[:-1])
    shifted = [dict(p) for p in pieces]
    shifted[0]["x"] = (shifted[0]["x"][0], math.nextafter(shifted[0]["x"][1], 0.0))
    assert not covers(box, shifted)
