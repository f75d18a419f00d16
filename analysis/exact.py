"""Exact rational linear algebra for re-checking certificates outside the solver that produced them.

A float is a rational number: :func:`rational_matrix` converts a float matrix to
:class:`fractions.Fraction` entries *exactly* (no rounding), so a test on the converted matrix is a
statement about the float data itself.  :func:`is_positive_definite` decides ``M ≻ 0`` for a
symmetric rational matrix by symmetric Gaussian elimination without pivoting (an ``LDLᵀ``
factorisation): ``M ≻ 0`` if and only if every pivot is positive (Sylvester's criterion on the
leading principal minors, which are the products of the pivots).  No square root, no round-off.
:func:`is_hurwitz` decides whether every eigenvalue of a rational matrix has a negative real part
from its exact characteristic polynomial (Faddeev–LeVerrier) by the Routh–Hurwitz criterion: the
monic polynomial is Hurwitz iff all its coefficients and all its Hurwitz determinants are positive.

Examples
--------
>>> is_positive_definite(rational_matrix([[2.0, -1.0], [-1.0, 2.0]]))
True
>>> is_positive_definite(rational_matrix([[1.0, 2.0], [2.0, 1.0]]))
False
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np

from hybrid.errors import ParameterError

__all__ = ["RationalMatrix", "rational_matrix", "is_positive_definite", "ldl_pivots", "mat_mul", "mat_add",
           "transpose", "scaled", "characteristic_polynomial", "determinant", "is_hurwitz"]

RationalMatrix = list[list[Fraction]]
"""A dense matrix of exact rationals, row by row."""


def rational_matrix(matrix: Any) -> RationalMatrix:
    """The exact rational value of a finite float matrix, shape ``(r, c)``.

    Raises
    ------
    ParameterError
        A non-finite entry or not two-dimensional.
    """
    array = np.asarray(matrix, dtype=float)
    if array.ndim != 2:
        raise ParameterError("matrix", array.shape, "a two-dimensional array", "pass a matrix")
    if not np.all(np.isfinite(array)):
        raise ParameterError("matrix", array.tolist(), "finite entries", "remove NaN and infinite values")
    return [[Fraction(float(v)) for v in row] for row in array]


def ldl_pivots(matrix: RationalMatrix) -> list[Fraction]:
    """Pivots of symmetric elimination without pivoting, stopping at the first that is not positive.

    For a symmetric ``M`` the ``k``-th pivot is ``det(M_k)/det(M_{k-1})`` (leading principal minors).
    """
    a = [row[:] for row in matrix]
    n = len(a)
    pivots: list[Fraction] = []
    for k in range(n):
        pivot = a[k][k]
        pivots.append(pivot)
        if pivot <= 0:
            return pivots
        for i in range(k + 1, n):
            factor = a[i][k] / pivot
            if factor:
                row_i, row_k = a[i], a[k]
                for j in range(k + 1, n):
                    row_i[j] -= factor * row_k[j]
    return pivots


def is_positive_definite(matrix: RationalMatrix) -> bool:
    """Exactly whether the symmetric rational ``matrix`` is positive definite (``False`` if not symmetric)."""
    n = len(matrix)
    if any(len(row) != n for row in matrix):
        return False
    if any(matrix[i][j] != matrix[j][i] for i in range(n) for j in range(i)):
        return False
    pivots = ldl_pivots(matrix)
    return len(pivots) == n and all(p > 0 for p in pivots)


def transpose(a: RationalMatrix) -> RationalMatrix:
    """``aᵀ``."""
    return [list(col) for col in zip(*a)]


def mat_mul(a: RationalMatrix, b: RationalMatrix) -> RationalMatrix:
    """``a b`` exactly."""
    bt = transpose(b)
    return [[sum((x * y for x, y in zip(row, col)), Fraction(0)) for col in bt] for row in a]


def mat_add(*terms: RationalMatrix) -> RationalMatrix:
    """The exact sum of matrices of one shape."""
    out = [row[:] for row in terms[0]]
    for t in terms[1:]:
        for i, row in enumerate(t):
            for j, v in enumerate(row):
                out[i][j] += v
    return out


def scaled(a: RationalMatrix, c: Fraction | int) -> RationalMatrix:
    """``c a`` exactly."""
    return [[c * v for v in row] for row in a]


def determinant(matrix: RationalMatrix) -> Fraction:
    """The exact determinant (Gaussian elimination with row exchanges on exact rationals)."""
    a = [row[:] for row in matrix]
    n = len(a)
    det = Fraction(1)
    for k in range(n):
        pivot_row = next((i for i in range(k, n) if a[i][k] != 0), None)
        if pivot_row is None:
            return Fraction(0)
        if pivot_row != k:
            a[k], a[pivot_row] = a[pivot_row], a[k]
            det = -det
        pivot = a[k][k]
        det *= pivot
        for i in range(k + 1, n):
            factor = a[i][k] / pivot
            if factor:
                for j in range(k, n):
                    a[i][j] -= factor * a[k][j]
    return det


def characteristic_polynomial(matrix: RationalMatrix) -> list[Fraction]:
    """Coefficients ``[1, c_1, …, c_n]`` of ``det(sI − A) = sⁿ + c_1 sⁿ⁻¹ + … + c_n`` (Faddeev–LeVerrier)."""
    n = len(matrix)
    coefficients = [Fraction(1)]
    m = [[Fraction(0)] * n for _ in range(n)]
    for k in range(1, n + 1):
        for i in range(n):
            m[i][i] += coefficients[-1]
        am = mat_mul(matrix, m)
        coefficients.append(-sum((am[i][i] for i in range(n)), Fraction(0)) / k)
        m = am
    return coefficients


def is_hurwitz(matrix: RationalMatrix) -> bool:
    """Exactly whether every eigenvalue of ``matrix`` has a negative real part (Routh–Hurwitz)."""
    c = characteristic_polynomial(matrix)
    n = len(c) - 1
    if any(x <= 0 for x in c):
        return False

    def coefficient(index: int) -> Fraction:
        return c[index] if 0 <= index <= n else Fraction(0)

    for k in range(1, n + 1):
        hurwitz_k = [[coefficient(2 * (j + 1) - (i + 1)) for j in range(k)] for i in range(k)]
        if determinant(hurwitz_k) <= 0:
            return False
    return True
