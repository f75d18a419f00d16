"""The nonlinear re-check's slope form (``recheck_smooth.SmoothStepper.slope_taylor``, issue 27 item 4).

Yardsticks, independent of the code judged: the closed form of ``x' = −x³``, ``x(t) = x0 / sqrt(1 + 2 x0² t)``
(monotone in ``x0``: the true reach set at ``t`` is ``[x(t; lo), x(t; hi)]``), and the second-order Taylor map
``g_s(x) = x + s f(x) + s²/2 (Df·f)(x)`` written out by hand for the cube and for Van der Pol and evaluated in
exact rationals (:class:`fractions.Fraction`) at seeded random points.
"""

from __future__ import annotations

import functools
import json
import math
from fractions import Fraction

import numpy as np
import pytest

from analysis.reach import reach, recheck_flowpipe, safety_fragment
from analysis.reach.model import affine_model
from analysis.reach.recheck_smooth import SmoothStepper, grid_pieces, slope_remainder
from analysis.reach.verdict import reach_proof
from analysis.stl.syntax import parse_tree
from hybrid import HybridAutomaton, Mode
from hybrid.symbolic import coordinates, flow_map
from hybrid.system import HybridSystem


def _one_mode(name, flow, names) -> HybridSystem:
    automaton = HybridAutomaton(name=name, modes=(Mode(name="m"),), transitions=(), variables=names)
    return HybridSystem(automaton=automaton, state_names=names, flows={"m": flow})


def _cube() -> HybridSystem:
    x = coordinates("x")
    return _one_mode("cube", flow_map(-x.x ** 3), ("x",))


def _vdp() -> HybridSystem:
    x = coordinates("x", "y")
    return _one_mode("vdp", flow_map(x.y, 1.0 * (1.0 - x.x ** 2) * x.y - x.x), ("x", "y"))


def _closed(x0: float, t: float) -> float:
    return x0 / math.sqrt(1.0 + 2.0 * x0 * x0 * t)


def _fragment(box):
    text = f"always[0, 2] (x < {box[1] + 0.05} and x > {box[0] - 0.05})"
    return safety_fragment(parse_tree(text), ("x",))


# -------------------------------------------------------------------------------------- the cube, re-checked
@pytest.mark.parametrize("box", [(-0.5, 1.0), (-1.0, 1.0), (0.0, 1.0)])
def test_the_cube_proof_is_rechecked(box):
    """Issue 27: the run proved the 0.05-outside bounds but the re-check failed on its first segment."""
    proof, decision = reach_proof(_cube(), _fragment(box), {"x": box}, time_step=0.01)
    assert decision.holds and proof.holds
    assert proof.rechecked, proof.evidence
    check = recheck_flowpipe(reach(_cube(), {"x": box}, horizon=2.0, time_step=0.01).to_json(), _cube(),
                             {"x": box}, _fragment(box))
    assert check.passed, check.failure
    # sound: never above the true slack (the reach set over [0, 2] is the initial box: slack 0.05 exactly, up to
    # the decimal text of the bounds); precise: the re-check's own sets lose less than 10⁻³ of it
    assert 0.049 < check.margin <= 0.05 + 1e-12


@functools.lru_cache(maxsize=1)
def _cube_json() -> str:
    return reach(_cube(), {"x": (-0.5, 1.0)}, horizon=2.0, time_step=0.01).to_json()


@pytest.mark.parametrize("index, side", [(1, "lo"), (1, "hi"), (2, "lo"), (51, "hi"), (101, "lo"), (181, "hi")])
def test_a_segment_shrunk_below_the_true_reach_set_is_rejected(index, side):
    """A claim shrunk 10⁻³ inside the true reach set at one segment (the closed form's extreme at the segment's
    start left out) fails the re-check at that segment, while the unchanged JSON passes
    (:func:`test_the_cube_proof_is_rechecked`, and :func:`test_saved_boxes_near_the_true_reach_set_are_confirmed`
    with the true set plus 0.05)."""
    box = (-0.5, 1.0)
    bad = json.loads(_cube_json())
    seg = bad["segments"][index]
    t0 = max(seg["t"][0], 0.0)
    if side == "lo":
        seg["box"][0][0] = _closed(box[0], t0) + 1e-3
    else:
        seg["box"][1][0] = _closed(box[1], t0) - 1e-3
    assert seg["box"][0][0] < seg["box"][1][0]
    check = recheck_flowpipe(bad, _cube(), {"x": box}, _fragment(box))
    assert not check.passed
    assert f"segment {index - 1}:" in check.failure and "not inside the saved box" in check.failure, check.failure


def test_saved_boxes_near_the_true_reach_set_are_confirmed():
    """Precision: every saved box cut down to the closed form's extent (at the segment's start) plus 0.05 is still
    confirmed (the re-check's own tube stays within 0.05 of the true reach set over the 2 s)."""
    box = (-0.5, 1.0)
    data = json.loads(_cube_json())
    assert recheck_flowpipe(data, _cube(), {"x": box}, _fragment(box)).passed
    for seg in data["segments"]:
        t0 = max(seg["t"][0], 0.0)
        seg["box"] = [[max(seg["box"][0][0], _closed(box[0], t0) - 0.05)],
                      [min(seg["box"][1][0], _closed(box[1], t0) + 0.05)]]
    check = recheck_flowpipe(data, _cube(), {"x": box}, _fragment(box))
    assert check.passed, check.failure


# ------------------------------------------------------------------- the slope remainder in exact rationals
def _g_cube(x, s):
    (v,) = x
    f = -v ** 3
    q = 3 * v ** 5  # Df·f = (−3x²)(−x³)
    return [v + s * f + s * s / 2 * q]


def _g_vdp(x, s):
    v, w = x
    f1, f2 = w, (1 - v * v) * w - v
    q1 = f2  # row (0, 1) of Df times f
    q2 = (-2 * v * w - 1) * f1 + (1 - v * v) * f2
    return [v + s * f1 + s * s / 2 * q1, w + s * f2 + s * s / 2 * q2]


@pytest.mark.parametrize("system, g, lo, hi, s", [
    (_cube, _g_cube, [-0.5], [1.0], 0.01),
    (_cube, _g_cube, [-1.0], [1.0], 0.0025),
    (_vdp, _g_vdp, [1.25, 2.35], [1.55, 2.45], 0.005),
    (_vdp, _g_vdp, [-2.0, -3.0], [2.0, 3.0], 0.02),
])
def test_the_slope_remainder_holds_the_exact_remainder_at_random_points(system, g, lo, hi, s):
    """``g_s(x) − g_s(c) − M(x − c)`` in exact rationals at 300 seeded points of the box (and its corners) lies in
    :func:`slope_remainder`'s enclosure; and the enclosure is not vacuous: it exceeds the sampled range by at most
    half its width (plus 10⁻⁹; each of the 16 cells adds its slope spread ``(Dg_s(P) − M)(P − p)``, of the order of
    the range over a cell: a quarter of the box per coordinate in 2-D)."""
    stepper = SmoothStepper(affine_model(system(), nonlinear=True).modes["m"].smooth)
    lo, hi = np.array(lo), np.array(hi)
    center = 0.5 * lo + 0.5 * hi
    g_center = stepper.g_at(center, s)
    exact_gc = g([Fraction(v) for v in center], Fraction(s))
    assert all(Fraction(a) <= e <= Fraction(b) for a, b, e in zip(*g_center, exact_gc))
    d_lo, d_hi = stepper.slope_matrix(lo, hi, s)
    matrix = 0.5 * d_lo + 0.5 * d_hi
    r_lo, r_hi = slope_remainder(stepper, center, g_center, matrix, lo, hi, s, 16)
    rng = np.random.default_rng(27)
    points = [lo + (hi - lo) * rng.random(lo.size) for _ in range(300)]
    points += [np.array(c) for c in np.array(np.meshgrid(*zip(lo, hi))).reshape(lo.size, -1).T]
    seen_lo, seen_hi = [math.inf] * lo.size, [-math.inf] * lo.size
    for p in points:
        x = [Fraction(float(v)) for v in p]
        gx = g(x, Fraction(s))
        for i in range(lo.size):
            r = gx[i] - exact_gc[i] - sum((Fraction(float(matrix[i, j])) * (x[j] - Fraction(float(center[j])))
                                           for j in range(lo.size)), Fraction(0))
            assert Fraction(float(r_lo[i])) <= r <= Fraction(float(r_hi[i])), (p, i)
            seen_lo[i], seen_hi[i] = min(seen_lo[i], float(r)), max(seen_hi[i], float(r))
    for i in range(lo.size):
        width = seen_hi[i] - seen_lo[i]
        assert (seen_lo[i] - r_lo[i]) + (r_hi[i] - seen_hi[i]) <= 0.5 * width + 1e-9, (i, r_lo, r_hi, seen_lo, seen_hi)


def test_the_grid_covers_its_box():
    rng = np.random.default_rng(4)
    for n, pieces in [(1, 16), (2, 16), (3, 16), (6, 16), (2, 1)]:
        lo = rng.normal(size=n)
        hi = lo + rng.random(n) * np.array([10.0 ** -k for k in range(n)])
        cells = grid_pieces(lo, hi, pieces)
        assert 1 <= len(cells) <= pieces
        for _ in range(200):
            p = lo + (hi - lo) * rng.random(n)
            assert any(np.all(a <= p) and np.all(p <= b) for a, b in cells)
        for a, b in cells:
            assert np.all(lo <= a) and np.all(a <= b) and np.all(b <= hi)
