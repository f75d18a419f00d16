"""Zonotope operations, matrix-exponential enclosures and box clipping against brute force.

The references: the vertices of a zonotope enumerated over all sign vectors ``c + G s`` (every extreme
point is one of them), scipy's ``expm`` and convex hulls, exact rationals for the rounding claims.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial import Delaunay

from analysis.reach import Zonotope, interval_hull, linear_map, minkowski_sum, reduce_order, support_bounds
from analysis.reach.affine import Halfspace
from analysis.reach.result import zonotope_contains
from analysis.reach.series import bloating_matrices, exp_enclosure
from analysis.reach.sets import clip_box, tighten_box, to_float
from analysis.reach.zonotope import with_error


def _vertices(z: Zonotope) -> np.ndarray:
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=z.order)))
    return z.center + signs @ z.generators.T


def _random(rng, n=2, m=5, scale=1.0) -> Zonotope:
    return Zonotope(center=rng.normal(size=n) * scale, generators=rng.normal(size=(n, m)) * scale)


def _exact_max(points: np.ndarray, a: np.ndarray) -> Fraction:
    return max(sum(Fraction(float(ai)) * Fraction(float(pi)) for ai, pi in zip(a, p)) for p in points)


@pytest.mark.parametrize("seed", range(5))
def test_interval_hull_encloses_the_vertices_tightly(seed):
    z = _random(np.random.default_rng(seed), n=3, m=6)
    lo, hi = interval_hull(z)
    v = _vertices(z)
    assert np.all(v >= lo) and np.all(v <= hi)
    assert np.allclose(lo, v.min(axis=0), atol=1e-12) and np.allclose(hi, v.max(axis=0), atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_support_bounds_are_rigorous_and_tight(seed):
    rng = np.random.default_rng(seed)
    z = _random(rng, n=3, m=6, scale=1e3)
    for a in rng.normal(size=(10, 3)):
        lo, hi = support_bounds(z, a)
        v = _vertices(z)
        # the exact max over the exact (rational) vertices, the float data taken as exact
        exact_v = [[Fraction(float(c)) + sum(s * Fraction(float(g)) for s, g in zip(signs, row))
                    for c, row in zip(z.center, z.generators)]
                   for signs in itertools.product((-1, 1), repeat=z.order)]
        top = max(sum(Fraction(float(ai)) * xi for ai, xi in zip(a, x)) for x in exact_v)
        bottom = min(sum(Fraction(float(ai)) * xi for ai, xi in zip(a, x)) for x in exact_v)
        assert Fraction(hi) >= top and Fraction(lo) <= bottom
        assert hi - float(np.max(v @ a)) < 1e-9 and float(np.min(v @ a)) - lo < 1e-9


@pytest.mark.parametrize("seed", range(5))
def test_linear_map_contains_the_mapped_vertices(seed):
    rng = np.random.default_rng(seed)
    z = _random(rng, n=2, m=4)
    m = rng.normal(size=(2, 2))
    radius = np.full((2, 2), 1e-3)
    image, err = linear_map(z, m, radius)
    full = with_error(image, err)
    for dm in itertools.product((-1e-3, 1e-3), repeat=4):  # corners of the interval matrix
        mm = m + np.array(dm).reshape(2, 2)
        for x in _vertices(z):
            assert zonotope_contains(full, mm @ x)
    # the interval radius dominates: err = 1e-3 · Σ_j max |x_j| (plus rounding terms of relative size 1e-15)
    spread = 1e-3 * (np.abs(z.center) + np.abs(z.generators).sum(axis=1)).sum()
    assert np.allclose(err, spread, rtol=1e-9)


def test_minkowski_sum_vertices():
    rng = np.random.default_rng(7)
    a, b = _random(rng, m=3), _random(rng, m=2)
    s, err = minkowski_sum(a, b)
    full = with_error(s, err)
    for x in _vertices(a):
        for y in _vertices(b):
            assert zonotope_contains(full, x + y)


@pytest.mark.parametrize("seed", range(5))
def test_reduction_over_approximates(seed):
    rng = np.random.default_rng(seed)
    z = _random(rng, n=2, m=12)
    r = reduce_order(z, 3)
    assert r.order <= 6
    for d in rng.normal(size=(50, 2)):
        assert np.max(_vertices(r) @ d) >= np.max(_vertices(z) @ d) - 1e-12


def test_zonotope_contains_matches_a_convex_hull():
    rng = np.random.default_rng(11)
    z = _random(rng, n=2, m=5)
    hull = Delaunay(_vertices(z))
    for p in rng.uniform(-8, 8, size=(400, 2)):
        if abs(hull.plane_distance(p)).min() < 1e-9:
            continue
        assert zonotope_contains(z, p) == (hull.find_simplex(p) >= 0)
    z3 = _random(rng, n=3, m=5)
    hull3 = Delaunay(_vertices(z3))
    for p in rng.uniform(-5, 5, size=(60, 3)):
        assert zonotope_contains(z3, p) == (hull3.find_simplex(p) >= 0)


@pytest.mark.parametrize(("matrix", "step"), [
    ([[0.0, -1.0], [1.0, 0.0]], 0.01), ([[-0.1, 3.0], [0.0, -0.1]], 0.1), ([[0.0, 1.0], [-9.0, -0.3]], 0.3)])
def test_exp_enclosure_contains_scipy_expm(matrix, step):
    a = [[Fraction(v) for v in row] for row in matrix]
    enc = exp_enclosure(a, Fraction(step))
    ref = expm(np.array(matrix) * step)
    assert np.all(np.abs(enc.center - ref) <= enc.radius + 4e-16 * np.abs(ref) + 1e-300)
    assert np.all(enc.radius < 1e-15)


def test_bloating_matrices_against_closed_forms():
    """|A| nilpotent (double integrator): e^{|A|δ} − I − |A|δ = [[0, δ²/2·g]] exactly, S = δ²/2, δ³/6 terms."""
    delta = 0.125
    a = [[Fraction(0), Fraction(1)], [Fraction(0), Fraction(0)]]
    d, s = bloating_matrices(a, Fraction(delta))
    assert np.allclose(d, 0.0, atol=1e-20)  # |A|^2 = 0
    assert s[0, 1] >= delta ** 2 / 2 and s[0, 1] - delta ** 2 / 2 < 1e-15
    scalar = [[Fraction(-2)]]  # |A| = 2: D = e^{2δ} − 1 − 2δ
    d, _ = bloating_matrices(scalar, Fraction(delta))
    exact = np.expm1(2 * delta) - 2 * delta
    assert d[0, 0] >= exact - 1e-16 and d[0, 0] - exact < 1e-15


def test_clip_and_tighten_box_against_brute_force():
    rng = np.random.default_rng(5)
    z = _random(rng, n=2, m=4)
    h = to_float(Halfspace(normal=(Fraction(1), Fraction(1)), offset=Fraction(0.5)))
    lo, hi = interval_hull(z)
    box = clip_box(lo, hi, (h,))
    tight = tighten_box(z, lo, hi, (h,))
    samples = z.center + rng.uniform(-1, 1, size=(20000, 4)) @ z.generators.T
    feasible = samples[samples.sum(axis=1) <= 0.5]
    assert box is not None and tight is not None and feasible.size
    for b in (box, tight):
        assert np.all(feasible >= b[0]) and np.all(feasible <= b[1])
    assert np.all(tight[1] - tight[0] <= box[1] - box[0] + 1e-12)
    # the LP bound is the true extent of z ∩ {x + y <= 0.5} (sampled extent within a few percent)
    assert np.all(tight[1] - feasible.max(axis=0) < 0.05 * (hi - lo))
    away = to_float(Halfspace(normal=(Fraction(1), Fraction(0)), offset=Fraction(float(lo[0]) - 1.0)))
    assert clip_box(lo, hi, (away,)) is None and tighten_box(z, lo, hi, (away,)) is None
