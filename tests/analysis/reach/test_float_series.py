"""``analysis.reach.float_series.float_series``: ``Φ`` with its a-priori rounding bound, and ``F``, ``S``, against the
exact rational enclosures of :mod:`analysis.reach.series` (an independent route: every sum and product in rationals,
only the final conversion and the tail rounded)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from analysis.reach.float_series import float_series
from analysis.reach.series import bloating_matrices, exp_enclosure


def _cases():
    rng = np.random.default_rng(27)
    for _ in range(25):
        m = int(rng.integers(1, 5))
        a = rng.normal(size=(m, m)) * rng.uniform(0.1, 30.0)
        if rng.uniform() < 0.3:
            a[rng.uniform(size=(m, m)) < 0.5] = 0.0  # sparse, with exact zeros
        norm = max(1e-9, float(np.abs(a).sum(axis=1).max()))
        step = float(rng.choice([1e-4, 5e-3, 0.1, 1.0, 3.5])) / norm
        yield a, step
    # the augmented matrices of a Van der Pol step: [[A, c/s], [0, 0]]
    yield np.array([[0.0, 1.0, 0.0], [-4.3, -1.2, 0.55], [0.0, 0.0, 0.0]]), 0.005


@pytest.mark.parametrize("a, step", list(_cases()))
def test_phi_holds_the_exact_exponential_and_the_bloating_bounds_the_rational_one(a, step):
    phi, f, s = float_series(a, step)
    exact = [[Fraction(float(v)) for v in row] for row in a]
    rational = exp_enclosure(exact, Fraction(step))
    # the rational enclosure [rc ± rr] (which holds e^{Aδ}) lies inside [phi.center ± phi.radius], in rationals
    for i in range(a.shape[0]):
        for j in range(a.shape[0]):
            gap = abs(Fraction(float(rational.center[i, j])) - Fraction(float(phi.center[i, j])))
            assert gap + Fraction(float(rational.radius[i, j])) <= Fraction(float(phi.radius[i, j])), (i, j)
    # and it is tight: the radius is rounding-sized
    scale = np.abs(rational.center).max() + 1.0
    assert float(phi.radius.max()) <= 1e-12 * scale
    # F, S against the rational route's upper bounds (each within a few roundings of the exact series, hence the
    # relative 1e-12 below; above by at most the float route's roundings and its tail, below 2⁻⁷⁰ ≈ 8.5e-22 an entry)
    f_rational, s_rational = bloating_matrices(exact, Fraction(step), corrected=True)
    assert np.all(f >= f_rational * (1 - 1e-12)) and np.all(s >= s_rational * (1 - 1e-12))
    assert np.all(f <= f_rational * (1 + 1e-9) + 1e-20) and np.all(s <= s_rational * (1 + 1e-9) + 1e-20)
