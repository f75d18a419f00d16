"""The adaptive step of nonlinear modes (``reach(..., adaptive_step=...)``, ``nonlinear.adaptive_segments``).

Yardsticks, none sharing the producer's set code: finely resolved DOP853 runs (scipy, ``rtol 1e-10``) from the
corners and seeded random points of the initial box, every sample inside a segment whose time interval holds the
sample's time; a planted requirement the true reach violates (its bound below a maximum attained by one fine run)
never proven.
"""

from __future__ import annotations

import json
import math
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from analysis.reach import ReachError, reach, safety_fragment
from analysis.reach.split import split_box
from analysis.reach.verdict import reach_proof
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem

NAMES = ("x", "y")
X = coordinates(*NAMES)
VDP_BOX = {"x": (1.25, 1.55), "y": (2.35, 2.45)}
TOL = 1e-7
"""Sample-to-set tolerance: DOP853 at ``rtol 1e-10, atol 1e-12`` over 7 s of a state of size ~3 errs far below it."""


def _vdp() -> HybridSystem:
    automaton = HybridAutomaton(name="vdp", modes=(Mode(name="m"),), transitions=(), variables=NAMES)
    return HybridSystem(automaton=automaton, state_names=NAMES, flows={"m": flow_map(X.y, (1.0 - X.x ** 2) * X.y - X.x)})


def _lovo() -> HybridSystem:
    automaton = HybridAutomaton(name="lovo", modes=(Mode(name="m"),), transitions=(), variables=NAMES)
    return HybridSystem(automaton=automaton, state_names=NAMES,
                        flows={"m": flow_map(1.5 * X.x - X.x * X.y, X.x * X.y - 3.0 * X.y)})


def _vdp_rhs(t, z):
    return [z[1], (1.0 - z[0] ** 2) * z[1] - z[0]]


def _lovo_rhs(t, z):
    return [1.5 * z[0] - z[0] * z[1], z[0] * z[1] - 3.0 * z[1]]


def _bench_options() -> dict:
    """The VDP instance's options as the benchmark builds them (``benchmarks/reach_nln.py``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))
    try:
        import reach_nln
    finally:
        sys.path.pop(0)
    return reach_nln.build_vdp()[2]


def _inside(segment, points: np.ndarray) -> np.ndarray:
    """Points in the segment's box and in its zonotope (the zonotope's edge normals in 2-D, exact for a 2-D zonotope)."""
    ok = np.all((points >= segment.lo - TOL) & (points <= segment.hi + TOL), axis=1)
    g = segment.zonotope.generators
    normals = np.vstack([-g[1], g[0]]).T
    norms = np.hypot(normals[:, 0], normals[:, 1])
    normals = normals[norms > 0] / norms[norms > 0, None]
    spread = np.abs(normals @ g).sum(axis=1) + TOL * np.abs(normals).sum(axis=1)
    return ok & np.all(np.abs((points - segment.zonotope.center) @ normals.T) <= spread, axis=1)


def _corners(box) -> tuple[list[float], list[float]]:
    return [box[k][0] for k in NAMES], [box[k][1] for k in NAMES]


def _assert_covered(result, times: np.ndarray, points: np.ndarray) -> None:
    covered = np.zeros(times.size, dtype=bool)
    for s in result.segments:
        rows = np.nonzero((times >= s.t_lo) & (times <= s.t_hi) & ~covered)[0]
        if rows.size:
            covered[rows] = _inside(s, points[rows])
    missing = np.nonzero(~covered)[0]
    assert missing.size == 0, (f"{missing.size} of {times.size} samples outside every segment covering their time, "
                               f"e.g. t = {times[missing[0]]!r}, x = {points[missing[0]]!r}")


def _steps(result) -> list[float]:
    return [s.step for s in result.segments if not s.entry]


# ---------------------------------------------------------------------------------------------- soundness
def test_adaptive_vdp_piece_holds_fine_runs_on_a_non_uniform_grid(fine_runs):
    """The benchmark's options on the piece of the VDP box that decides the margin (the largest ``x``): the steps
    vary (powers of two times ``time_step``), the segments chain in time exactly, every sample is covered."""
    options = _bench_options()
    piece = split_box(VDP_BOX, options["splits"])[-1]
    result = reach(_vdp(), piece, horizon=7.0, time_step=options["time_step"], **options["engine"])
    assert result.status == "complete", result.terminations
    steps = _steps(result)
    assert len(set(steps)) >= 3  # a non-uniform grid
    for step in steps:
        ratio = step / options["time_step"]
        assert ratio == 2.0 ** round(math.log2(ratio))
    local = Fraction(0)  # the exact local time: [t_lo, t_hi] must hold [τ, τ + δ] (rounded outward)
    for seg, step in zip(result.segments[1:], steps):
        assert Fraction(seg.t_lo) <= local and Fraction(seg.t_hi) >= local + Fraction(step)
        local += Fraction(step)
    assert local > 7
    _assert_covered(result, *fine_runs(_vdp_rhs, *_corners(piece), 7.0, 40, 27, 0.005))


def test_adaptive_lovo_holds_fine_runs(fine_runs):
    """Lotka–Volterra (LOVO's parameters, a thin box) with the default ratio: every sample covered."""
    box = {"x": (1.3, 1.32), "y": (0.99, 1.01)}
    result = reach(_lovo(), box, horizon=3.64, time_step=0.005, adaptive_step=True)
    assert result.status == "complete", result.terminations
    assert len(set(_steps(result))) >= 2
    _assert_covered(result, *fine_runs(_lovo_rhs, *_corners(box), 3.64, 40, 28, 0.005))


# ---------------------------------------------------------------------------------------------- verdicts
def test_a_planted_requirement_the_true_reach_violates_is_never_proven():
    """``y < top − 0.005`` with ``top`` the maximum of ``y`` on one fine run from the box's corner
    ``(1.55, 2.45)``: a state of the true reach (up to the run's error, below 1e-7) lies 0.005 above the bound, so
    no sound flowpipe can prove it; with the benchmark's options it is not proven, and ``y < 2.75`` is (re-checked)."""
    sol = solve_ivp(_vdp_rhs, (0.0, 7.0), [1.55, 2.45], method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
    top = float(sol.sol(np.linspace(0.0, 7.0, 70_001))[1].max())
    assert 2.6 < top < 2.75
    options = _bench_options()
    planted = safety_fragment(parse_tree(f"always[0, 7] (y < {top - 0.005!r})"), NAMES)
    bad, decision = reach_proof(_vdp(), planted, VDP_BOX, time_step=options["time_step"],
                                splits=options["splits"], engine=options["engine"])
    assert not bad.holds and not decision.holds


def test_the_vdp_instance_is_proven_and_rechecked_below_the_true_slack():
    """ARCH VDP (``y < 2.75``) with the benchmark's options: proven, re-checked, the margin below the true slack."""
    options = _bench_options()
    safe = safety_fragment(parse_tree("always[0, 7] (y < 2.75)"), NAMES)
    proof, decision = reach_proof(_vdp(), safe, VDP_BOX, **options)
    assert proof.holds and proof.rechecked, proof.evidence
    sol = solve_ivp(_vdp_rhs, (0.0, 7.0), [1.55, 2.45], method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
    top = float(sol.sol(np.linspace(0.0, 7.0, 70_001))[1].max())
    assert 0 < decision.margin <= 2.75 - top


# ---------------------------------------------------------------------------------------------- options
@pytest.mark.parametrize("value", ["yes", 0, -1.0, 1e9, math.nan, None])
def test_a_bad_adaptive_step_is_refused_by_name(value):
    with pytest.raises(ReachError, match="adaptive_step"):
        reach(_vdp(), VDP_BOX, horizon=0.1, time_step=0.01, adaptive_step=value)


def test_fixed_steps_save_no_step_and_are_unchanged_by_default():
    """Without the option the JSON carries no per-segment step and equals ``adaptive_step=False``'s byte for byte."""
    plain = reach(_vdp(), VDP_BOX, horizon=0.2, time_step=0.01).to_json()
    off = reach(_vdp(), VDP_BOX, horizon=0.2, time_step=0.01, adaptive_step=False).to_json()
    assert plain == off
    assert all("step" not in seg for seg in json.loads(plain)["segments"])
