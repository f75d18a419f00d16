"""Exact rational linear algebra: definiteness, inertia, Hurwitz and null spaces against known answers and numpy."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, strategies as st

from analysis.exact import (
    ExactError,
    RationalMatrix,
    as_rational,
    characteristic_polynomial,
    determinant,
    inertia,
    is_hurwitz,
    is_negative_definite,
    is_positive_definite,
    is_positive_semidefinite,
    nullspace,
    pivot_test,
    rational,
)
from hybrid.errors import ParameterError

TINY = Fraction(1, 2**60)  # below float resolution at 1: a float computation would lose its sign


def hilbert(n: int) -> list[list[Fraction]]:
    return [[Fraction(1, i + j + 1) for j in range(n)] for i in range(n)]


def test_known_definite_semidefinite_and_indefinite_matrices():
    pd, psd, indefinite = [[2, -1], [-1, 2]], [[1, 1], [1, 1]], [[1, 2], [2, 1]]
    assert is_positive_definite(pd) and is_positive_semidefinite(pd) and inertia(pd) == (2, 0, 0)
    assert not is_positive_definite(psd) and is_positive_semidefinite(psd) and inertia(psd) == (1, 0, 1)
    assert not is_positive_definite(indefinite) and not is_positive_semidefinite(indefinite)
    assert inertia(indefinite) == (1, 1, 0)
    assert inertia([[0, 1], [1, 0]]) == (1, 1, 0)  # zero diagonal: the 2×2 pivot
    assert inertia([[0, 0], [0, 0]]) == (0, 0, 2) and is_positive_semidefinite([[0, 0], [0, 0]])
    assert is_negative_definite([[-1, 0], [0, -TINY]]) and not is_negative_definite([[-1, 0], [0, 0]])
    # one part in 2⁶⁰ decides: exact arithmetic keeps the sign that rounding would lose
    assert is_positive_definite([[1, 1], [1, 1 + TINY]])
    assert not is_positive_definite([[1, 1], [1, 1 - TINY]]) and inertia([[1, 1], [1, 1 - TINY]]) == (1, 1, 0)
    assert not is_positive_definite([[1.0, 0.5], [0.4, 1.0]])  # not symmetric: never called definite
    assert not pivot_test([[1.0, 0.5], [0.4, 1.0]]).symmetric
    with pytest.raises(ExactError, match="expected a symmetric matrix"):
        inertia([[1.0, 0.5], [0.4, 1.0]])


def test_pivots_are_those_of_ldlt():
    test = pivot_test([[4, 2], [2, 3]])  # L = [[1, 0], [1/2, 1]], D = diag(4, 2)
    assert test.positive_definite and test.failed_at is None and test.smallest_pivot == 2.0
    test = pivot_test([[1, 2], [2, 1]])  # D = diag(1, -3)
    assert not test.positive_definite and test.failed_at == 1 and test.smallest_pivot == -3.0
    test = pivot_test(as_rational([[0.5, 0.0], [0.0, 0.25]]).scaled(Fraction(1, 3)))  # a non-trivial denominator
    assert test.positive_definite and test.smallest_pivot == pytest.approx(1 / 12, rel=1e-15)


def test_hilbert_matrices_beyond_float_resolution():
    """λmin(H₁₂) ≈ 2.6e-17: numpy cannot tell H₁₂ from a singular matrix; the exact test can."""
    h = hilbert(12)
    assert is_positive_definite(h) and inertia(h) == (12, 0, 0)
    shifted = as_rational(h) - RationalMatrix.identity(12).scaled(Fraction(1, 10**15))
    assert not is_positive_definite(shifted) and inertia(shifted)[1] >= 1
    assert determinant(hilbert(4)) == Fraction(1, 6048000)


def test_rational_matrices_are_the_float_values_exactly():
    m = as_rational(np.array([[0.1, 2.0], [-3.5, 1e-300]]))
    assert m.entries()[0][0] == Fraction(0.1) != Fraction(1, 10)  # the float's own value, not its decimal
    assert m.entries()[1][1] == Fraction(1e-300)
    np.testing.assert_array_equal(m.to_array(), [[0.1, 2.0], [-3.5, 1e-300]])
    a = as_rational([[1, 2], [3, 4]])
    b = as_rational([[Fraction(1, 3), 0], [1, Fraction(-1, 7)]])
    assert (a @ b).entries() == ((Fraction(7, 3), Fraction(-2, 7)), (Fraction(5), Fraction(-4, 7)))
    assert (a + b - b).entries() == a.entries() and (-a).entries()[0] == (-1, -2)
    assert a.T.entries() == ((1, 3), (2, 4)) and a.trace() == 5 and not a.is_symmetric()
    assert a.scaled(0.5).entries() == ((Fraction(1, 2), 1), (Fraction(3, 2), 2))
    with pytest.raises(ExactError, match="inner dimensions"):
        a @ as_rational([[1, 2, 3]])


def symmetric_by_congruence():
    """``M = Sᵀ diag(d) S`` with ``S`` integer and invertible: by Sylvester's law of inertia the signs of ``d``
    are the inertia of ``M``, an exact oracle even for entries of ``d`` far below float resolution."""
    sizes = st.integers(1, 5)
    return sizes.flatmap(lambda n: st.tuples(
        st.lists(st.lists(st.integers(-3, 3), min_size=n, max_size=n), min_size=n, max_size=n),
        st.lists(st.sampled_from([-1, 0, 1]), min_size=n, max_size=n),
        st.lists(st.sampled_from([Fraction(1), Fraction(3, 7), TINY, Fraction(10**6)]), min_size=n, max_size=n)))


@given(symmetric_by_congruence())
def test_inertia_and_definiteness_agree_with_the_congruence_oracle(data):
    s_rows, signs, sizes = data
    s = as_rational(s_rows)
    assume(determinant(s) != 0)
    d = as_rational([[signs[i] * sizes[i] if i == j else 0 for j in range(len(signs))] for i in range(len(signs))])
    m = s.T @ d @ s
    expected = (signs.count(1), signs.count(-1), signs.count(0))
    assert inertia(m) == expected
    assert is_positive_definite(m) == (expected[0] == len(signs)) == pivot_test(m).positive_definite
    assert is_positive_semidefinite(m) == (expected[1] == 0)
    assert is_negative_definite(m) == (expected[1] == len(signs))


@given(st.integers(1, 7), st.integers(0, 2**32 - 1), st.floats(-1.0, 1.0))
def test_agrees_with_numpy_eigenvalues_away_from_zero(n, seed, shift):
    rng = np.random.default_rng(seed)
    b = rng.standard_normal((n, n))
    sym = b @ b.T + shift * n * np.eye(n)
    sym = 0.5 * (sym + sym.T)
    eig = np.linalg.eigvalsh(sym)
    if np.abs(eig).min() > 1e-8 * max(1.0, np.abs(eig).max()):
        assert is_positive_definite(sym) == (eig.min() > 0)
        assert inertia(sym) == (int((eig > 0).sum()), int((eig < 0).sum()), 0)
    a = rng.standard_normal((n, n)) + 2.0 * shift * np.eye(n)
    np.testing.assert_allclose([float(c) for c in characteristic_polynomial(a)], np.poly(a), rtol=1e-9, atol=1e-9)
    assert float(determinant(a)) == pytest.approx(np.linalg.det(a), rel=1e-9, abs=1e-12)
    abscissa = np.linalg.eigvals(a).real.max()
    if abs(abscissa) > 1e-8:
        assert is_hurwitz(a) == (abscissa < 0)


def test_hurwitz_on_the_boundary_is_decided_exactly():
    assert is_hurwitz([[0.0, 1.0], [-2.0, -3.0]])
    assert characteristic_polynomial([[0.0, 1.0], [-2.0, -3.0]]) == (1, 3, 2)
    assert not is_hurwitz([[0.0, 1.0], [-1.0, 0.0]])  # ±i: on the axis
    assert not is_hurwitz([[-1.0, 0.0], [0.0, 0.0]])
    eps = float(TINY)
    assert is_hurwitz([[-eps, 1.0], [-1.0, -eps]]) and not is_hurwitz([[eps, 1.0], [-1.0, -eps / 2]])
    companion = [[0, 1, 0], [0, 0, 1], [-1, -3, -3]]  # (s + 1)³
    assert is_hurwitz(companion) and not is_hurwitz([[0, 1, 0], [0, 0, 1], [1, -3, -3]])


def test_nullspace_is_exact():
    rows = [[1, 2, 3, 4], [2, 4, 6, 8], [0, 1, Fraction(1, 3), 0]]  # rank 2
    basis = nullspace(rows, 4)
    assert len(basis) == 2
    for v in basis:
        assert all(sum(Fraction(r) * x for r, x in zip(row, v)) == 0 for row in rows)
    assert np.linalg.matrix_rank(np.array([[float(x) for x in v] for v in basis])) == 2
    assert nullspace([], 3) == ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    assert nullspace([[1, 0], [0, 1]], 2) == ()
    tiny = nullspace([[float(TINY), 1.0, 1.0]], 3)  # complete pivoting: no entry of size 2⁶⁰ in the basis
    assert max(abs(x) for v in tiny for x in v) <= 1


def test_bad_input_names_the_parameter():
    with pytest.raises(ExactError, match=r"^matrix = \(1, 2\): expected finite entries"):
        as_rational(np.array([[1.0, float("nan")]]))
    with pytest.raises(ParameterError, match=r"^matrix = \(3,\): expected a two-dimensional array"):
        as_rational(np.array([1.0, 2.0, 3.0]))
    with pytest.raises(ExactError, match=r"^value = inf: expected a finite number"):
        rational(float("inf"))
    with pytest.raises(ExactError, match="expected a finite real number"):
        rational(True)
    with pytest.raises(ExactError, match=r"^matrix\[0\]\[1\] = 'x'"):
        as_rational([[1, "x"]])
