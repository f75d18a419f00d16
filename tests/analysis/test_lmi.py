"""LMI certificates: planted answers found and re-checked; absence proven; dwell times; bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from analysis.exact import is_hurwitz, rational_matrix
from analysis.lmi import (
    LmiError,
    common_quadratic_lyapunov_lmi,
    dwell_time_lyapunov,
    recheck_common_lyapunov,
    recheck_no_common_lyapunov,
)
from analysis.random_families import planted_common_lyapunov, planted_no_common_lyapunov

SIZES = [(2, 2), (3, 10), (4, 3), (6, 6), (8, 4), (10, 10), (5, 2), (7, 8), (9, 5), (10, 3)]


@pytest.mark.parametrize("n, m", SIZES)
def test_a_planted_common_lyapunov_function_is_found_and_rechecked(n, m):
    family, _ = planted_common_lyapunov(np.random.default_rng(100 * n + m), n, m)
    result = common_quadratic_lyapunov_lmi(family)
    assert result.status == "exists" and result.proven and result.recheck.passed
    p = result.P
    assert np.linalg.eigvalsh(p).min() > 0 and abs(np.trace(p) - 1.0) < 1e-12
    for a in family:  # independent of the exact re-check: float eigenvalues with a margin
        assert np.linalg.eigvalsh(a.T @ p + p @ a).max() < -1e-9
    assert result.margin > 0
    rng = np.random.default_rng(n)
    for _ in range(5):  # every convex combination is Hurwitz when a common P exists
        w = rng.dirichlet(np.ones(m))
        assert np.linalg.eigvals(sum(wi * a for wi, a in zip(w, family))).real.max() < 0


@pytest.mark.parametrize("n, m", SIZES)
def test_a_planted_absence_is_proven(n, m):
    family, witness = planted_no_common_lyapunov(np.random.default_rng(7 * n + m), n, m)
    assert all(np.linalg.eigvals(a).real.max() < 0 for a in family)  # each mode is stable ...
    assert np.linalg.eigvals(witness).real.max() > 0  # ... their average is not (the planted reason)
    result = common_quadratic_lyapunov_lmi(family)
    assert result.status == "none" and result.proven and result.P is None and result.recheck.passed
    if result.witness_weights is not None:  # the witness is itself re-checked here, exactly
        w = result.witness_weights
        assert min(w) >= 0 and sum(w) > 0
        combo = sum(wi * a for wi, a in zip(w, family))
        assert not is_hurwitz(rational_matrix(combo))
    else:
        assert recheck_no_common_lyapunov(family, result.dual).passed


def test_a_dual_certificate_with_a_margin_on_the_lightly_damped_pair():
    """Both modes and their average are Hurwitz, yet no common P exists: the strict dual decides it."""
    a1 = np.array([[-0.1, 1.0], [-10.0, -0.1]])
    a2 = np.array([[-0.1, 10.0], [-1.0, -0.1]])
    assert np.linalg.eigvals(0.5 * (a1 + a2)).real.max() < 0
    result = common_quadratic_lyapunov_lmi([a1, a2], ("slow", "fast"))
    assert result.status == "none" and result.dual is not None and result.margin > 0
    assert recheck_no_common_lyapunov([a1, a2], result.dual).passed
    assert not recheck_no_common_lyapunov([a1, a2], [-z for z in result.dual]).passed  # sign matters
    # a switching signal that destabilises: 0.5·period in each, started on the right axis
    d = dwell_time_lyapunov([a1, a2], ("slow", "fast"))
    assert d.proven and 0 < d.dwell_time_s < math.inf


def test_the_recheck_refuses_a_wrong_certificate():
    a = [np.array([[-1.0, 0.0], [0.0, -2.0]])]
    assert recheck_common_lyapunov(a, np.eye(2)).passed
    assert not recheck_common_lyapunov(a, np.diag([1.0, -1e-12])).passed  # indefinite by a hair
    assert not recheck_common_lyapunov([np.array([[0.0, 1.0], [-1.0, 0.0]])], np.eye(2)).passed  # only ⪯ 0


def test_dwell_time_stabilises_where_fast_switching_diverges():
    """Two stable modes whose fast alternation is unstable; switching every T >= the certified dwell is stable."""
    a1 = np.array([[-0.1, 1.0], [-10.0, -0.1]])
    a2 = np.array([[-0.1, 10.0], [-1.0, -0.1]])
    d = dwell_time_lyapunov([a1, a2])
    half = math.pi / 2 / math.sqrt(10.0)  # a quarter turn of each mode: the classic destabilising schedule
    fast = expm(a2 * half) @ expm(a1 * half)
    assert max(abs(np.linalg.eigvals(fast))) > 1.0
    slow = expm(a2 * d.dwell_time_s) @ expm(a1 * d.dwell_time_s)
    assert max(abs(np.linalg.eigvals(slow))) < 1.0
    for i, (a, p) in enumerate(zip((a1, a2), d.P)):  # the LMIs hold at the certified dwell time
        assert np.linalg.eigvalsh(a.T @ p + p @ a).max() < 0
        e = expm(a * d.dwell_time_s)
        assert np.linalg.eigvalsh(e.T @ d.P[1 - i] @ e - p).max() < 0


def test_bad_input_is_refused_with_the_parameter_named():
    with pytest.raises(LmiError, match=r"^family = \[\]: expected at least one square matrix"):
        common_quadratic_lyapunov_lmi([])
    with pytest.raises(LmiError, match=r"^family\[1\] = \(2, 3\): expected a square matrix"):
        common_quadratic_lyapunov_lmi([np.eye(2), np.ones((2, 3))])
    with pytest.raises(LmiError, match=r"^family = \[\(2, 2\), \(3, 3\)\]: expected matrices of one size"):
        common_quadratic_lyapunov_lmi([np.eye(2), np.eye(3)])
    with pytest.raises(LmiError, match=r"^family\[0\] = .*expected finite entries"):
        common_quadratic_lyapunov_lmi([np.array([[np.nan, 0.0], [0.0, -1.0]])])
    with pytest.raises(LmiError, match=r"^names = \('a',\): expected 2 names"):
        common_quadratic_lyapunov_lmi([-np.eye(2), -np.eye(2)], ("a",))
    with pytest.raises(LmiError, match=r"^rel_tol = 2.0"):
        dwell_time_lyapunov([-np.eye(2)], rel_tol=2.0)
