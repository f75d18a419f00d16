"""The first segment's interpolation bound ``F = Σ_{k>=2} c_k (|A|δ)^k/k!`` (issue 27's tighter bloating).

Yardsticks independent of ``analysis.reach.series``: scipy's ``expm`` for the true interpolation error
``e^{At} x0 − ((1 − t/δ) x0 + (t/δ) e^{Aδ} x0)`` on a fine time grid (``expm`` is accurate to ~1e-15 relative here,
far below the slack between the error and ``F |x0|`` that the asserts rely on), and a dense grid of ``τ − τ^k`` for
the coefficients (the grid's maximum is below the true one, so ``c_k >=`` it is necessary, not sufficient; the
closed form ``k^{−1/(k−1)} (1 − 1/k)`` is checked too).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.reach.float_series import float_bloating
from analysis.reach.series import bloating_matrices, interpolation_coefficient


@pytest.mark.parametrize("k", range(2, 30))
def test_coefficients_bound_the_maximum_of_tau_minus_tau_power_k(k):
    tau = np.linspace(0.0, 1.0, 200_001)
    exact = k ** (-1.0 / (k - 1)) * (1.0 - 1.0 / k)
    assert interpolation_coefficient(k) >= float(np.max(tau - tau ** k))
    assert interpolation_coefficient(k) >= exact * (1 - 4e-16)  # the float closed form is within a few ulps
    assert interpolation_coefficient(k) <= 1.0
    if k == 2:
        assert interpolation_coefficient(2) == 0.25


@pytest.mark.parametrize("seed", range(6))
def test_corrected_bound_holds_the_interpolation_error_and_is_a_quarter_of_the_old(seed):
    rng = np.random.default_rng(seed)
    n = 3
    a = rng.normal(size=(n, n)) * rng.uniform(0.5, 5.0)
    delta = float(rng.uniform(0.01, 0.3)) / float(np.abs(a).sum(axis=1).max())
    exact = [[Fraction(float(v)) for v in row] for row in a]
    f, s = bloating_matrices(exact, Fraction(delta), corrected=True)
    d, s_old = bloating_matrices(exact, Fraction(delta))
    assert np.array_equal(s, s_old)  # S is not changed by the correction
    assert np.all(f <= d) and np.all(f >= 0.0)
    # ‖A‖δ small: the k = 2 term dominates, so F ≈ D/4 (within the k >= 3 terms' share, ~‖A‖δ)
    norm = float(np.abs(a).sum(axis=1).max()) * delta
    ratio = f[d > 1e-300] / d[d > 1e-300]
    assert np.all(ratio <= 0.25 + 0.4 * norm + 1e-12) and np.all(ratio >= 0.25 - 1e-12)
    # the float series gives the same bound (within its own, larger roundings)
    f_float, _ = float_bloating(a, delta, corrected=True)
    assert np.all(f_float >= f * (1 - 1e-9)) and np.all(f_float <= f * (1 + 1e-9) + 1e-250)
    phi = expm(a * delta)
    for x0 in rng.normal(size=(20, n)):
        bound = f @ np.abs(x0)
        for t in np.linspace(0.0, delta, 101):
            error = expm(a * t) @ x0 - ((1 - t / delta) * x0 + (t / delta) * (phi @ x0))
            assert np.all(np.abs(error) <= bound + 1e-14 * np.abs(x0).sum()), (t, error, bound)
