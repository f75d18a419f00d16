"""Exact rational definiteness and Hurwitz tests against numpy on random matrices."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, strategies as st

from analysis.exact import characteristic_polynomial, is_hurwitz, is_positive_definite, rational_matrix
from hybrid.errors import ParameterError


def test_known_matrices():
    assert is_positive_definite(rational_matrix([[2.0, -1.0], [-1.0, 2.0]]))
    assert not is_positive_definite(rational_matrix([[1.0, 0.0], [0.0, 0.0]]))  # semidefinite is not definite
    assert not is_positive_definite(rational_matrix([[1.0, 2.0], [2.0, 1.0]]))
    assert not is_positive_definite(rational_matrix([[1.0, 0.5], [0.4, 1.0]]))  # not symmetric
    tiny = 2.0 ** -60  # a float rounding would lose it: exact arithmetic keeps the sign
    assert is_positive_definite([[Fraction(1), Fraction(1)], [Fraction(1), Fraction(1) + Fraction(tiny)]])
    assert not is_positive_definite([[Fraction(1), Fraction(1)], [Fraction(1), Fraction(1) - Fraction(tiny)]])
    assert characteristic_polynomial(rational_matrix([[0.0, 1.0], [-2.0, -3.0]])) == [1, 3, 2]
    assert is_hurwitz(rational_matrix([[0.0, 1.0], [-2.0, -3.0]]))
    assert not is_hurwitz(rational_matrix([[0.0, 1.0], [-1.0, 0.0]]))  # on the imaginary axis: not Hurwitz


@given(st.integers(1, 7), st.integers(0, 2**32 - 1), st.floats(-1.0, 1.0))
def test_agrees_with_numpy_away_from_the_boundary(n, seed, shift):
    rng = np.random.default_rng(seed)
    b = rng.standard_normal((n, n))
    sym = b @ b.T + shift * n * np.eye(n)
    low = np.linalg.eigvalsh(sym).min()
    if abs(low) > 1e-8:
        assert is_positive_definite(rational_matrix(sym)) == (low > 0)
    a = rng.standard_normal((n, n)) + shift * 2.0 * np.eye(n)
    abscissa = np.linalg.eigvals(a).real.max()
    if abs(abscissa) > 1e-8:
        assert is_hurwitz(rational_matrix(a)) == (abscissa < 0)


def test_bad_input_names_the_parameter():
    with pytest.raises(ParameterError, match="^matrix = .*expected finite entries"):
        rational_matrix([[1.0, float("nan")]])
    with pytest.raises(ParameterError, match=r"^matrix = \(3,\): expected a two-dimensional array"):
        rational_matrix([1.0, 2.0, 3.0])
