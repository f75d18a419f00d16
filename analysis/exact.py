"""Exact rational linear algebra: re-checking a certificate outside the solver that produced it.

Every float is a rational number (a dyadic one, ``m·2^e``), so a float matrix converts to exact
rationals *without rounding*: a test on the converted matrix is a statement about the float data
itself, decided with no round-off.  :class:`RationalMatrix` stores a matrix as Python integers over
one common positive denominator, so products and sums are integer arithmetic (fast, exact, no
``gcd`` per entry).

Definiteness, without square roots
----------------------------------
A symmetric ``M`` has the factorisation ``M = L D Lᵀ`` (``L`` unit lower triangular) by symmetric
Gaussian elimination without pivoting whenever its leading principal minors ``Δ_1 … Δ_n`` are
non-zero, with pivots ``d_k = Δ_k / Δ_{k−1}``; Sylvester's criterion: ``M ≻ 0`` iff every
``Δ_k > 0`` iff every ``d_k > 0``.  :func:`pivot_test` computes the ``Δ_k`` by Bareiss' fraction-free
elimination (each intermediate entry is itself a minor, so every division is exact in the integers)
and stops at the first ``Δ_k ≤ 0``.

Semidefiniteness needs more care (a zero pivot does not decide): :func:`inertia` counts the
positive, negative and zero eigenvalues exactly by symmetric elimination with ``1×1`` pivots on a
non-zero diagonal entry and ``2×2`` pivots ``[[0, b], [b, 0]]`` (inertia ``(1, 1, 0)``) when the whole
diagonal of what is left is zero; Sylvester's law of inertia says the Schur complements keep the
count.  ``M ⪰ 0`` iff no eigenvalue is negative.

Hurwitz test
------------
:func:`is_hurwitz` decides whether every eigenvalue of a rational matrix has a negative real part:
the exact characteristic polynomial (Faddeev–LeVerrier) is Hurwitz iff its leading coefficient and
all its Hurwitz determinants are positive (the Routh–Hurwitz criterion), decided in rationals.

Examples
--------
>>> is_positive_definite([[2.0, -1.0], [-1.0, 2.0]])
True
>>> is_positive_definite([[1.0, 2.0], [2.0, 1.0]])
False
>>> inertia([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -3.0]])
(1, 1, 1)
>>> is_hurwitz([[0.0, 1.0], [-2.0, -3.0]])
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from numbers import Rational
from typing import Any

import numpy as np

from hybrid.errors import ParameterError

__all__ = [
    "ExactError",
    "RationalMatrix",
    "PivotTest",
    "rational",
    "as_rational",
    "pivot_test",
    "is_positive_definite",
    "is_negative_definite",
    "is_positive_semidefinite",
    "inertia",
    "characteristic_polynomial",
    "determinant",
    "is_hurwitz",
    "nullspace",
]


class ExactError(ParameterError):
    """Input that exact arithmetic cannot represent (NaN, infinity) or the wrong shape."""


def rational(value: Any, *, where: str = "value") -> Fraction:
    """The exact rational value of a finite number (a float converts without rounding).

    Raises
    ------
    ExactError
        ``nan``, ``inf``, a boolean or a non-number.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, Rational, np.integer, np.floating)):
        raise ExactError(where, value, "a finite real number", "give an int, a float or a Fraction")
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(float(value)):
            raise ExactError(where, float(value), "a finite number", "remove NaN and infinite values")
        return Fraction(float(value))
    return Fraction(int(value)) if isinstance(value, (int, np.integer)) else Fraction(value)


@dataclass(frozen=True, slots=True)
class RationalMatrix:
    """A dense matrix of exact rationals: integer ``numerators`` over one positive ``denominator``.

    Build one with :meth:`from_entries` (floats, ints, Fractions: exact) or :func:`as_rational`.
    Operators ``@``, ``+``, ``-`` (binary and unary) and :attr:`T` are exact.

    Attributes
    ----------
    numerators : tuple of tuple of int, shape (r, c)
    denominator : int
        Positive; the value of entry ``(i, j)`` is ``numerators[i][j] / denominator``.
    """

    numerators: tuple[tuple[int, ...], ...]
    denominator: int

    @staticmethod
    def from_entries(entries: Any, *, where: str = "matrix") -> RationalMatrix:
        """The exact value of a two-dimensional array of finite numbers, shape ``(r, c)``.

        Raises
        ------
        ExactError
            Not two-dimensional, or a non-finite entry (``where`` names the parameter).
        """
        if isinstance(entries, RationalMatrix):
            return entries
        if isinstance(entries, np.ndarray) and entries.dtype.kind == "f":
            array = entries
        else:
            rows = [list(row) for row in entries] if not isinstance(entries, np.ndarray) else entries.tolist()
            if not rows or any(not isinstance(r, list) for r in rows) or len({len(r) for r in rows}) != 1:
                raise ExactError(where, np.shape(entries), "a two-dimensional array (rows of equal length)",
                                 "pass a matrix")
            values = [[rational(v, where=f"{where}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(rows)]
            return RationalMatrix._from_fractions(values)
        if array.ndim != 2:
            raise ExactError(where, array.shape, "a two-dimensional array", "pass a matrix")
        if not np.all(np.isfinite(array)):
            raise ExactError(where, array.shape, "finite entries", "remove NaN and infinite values")
        return RationalMatrix._from_fractions([[Fraction(float(v)) for v in row] for row in array.tolist()])

    @staticmethod
    def _from_fractions(values: Sequence[Sequence[Fraction]]) -> RationalMatrix:
        den = math.lcm(*(v.denominator for row in values for v in row)) if values and values[0] else 1
        return RationalMatrix._make([[v.numerator * (den // v.denominator) for v in row] for row in values], den)

    @staticmethod
    def _make(numerators: Sequence[Sequence[int]], denominator: int) -> RationalMatrix:
        common = math.gcd(denominator, *(v for row in numerators for v in row))
        if common > 1:
            numerators = [[v // common for v in row] for row in numerators]
            denominator //= common
        return RationalMatrix(tuple(tuple(row) for row in numerators), denominator)

    @staticmethod
    def identity(n: int) -> RationalMatrix:
        """The ``n × n`` identity."""
        return RationalMatrix(tuple(tuple(int(i == j) for j in range(n)) for i in range(n)), 1)

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, columns)``."""
        return (len(self.numerators), len(self.numerators[0]) if self.numerators else 0)

    @property
    def T(self) -> RationalMatrix:  # noqa: N802 - the usual name of a transpose
        """The transpose."""
        return RationalMatrix(tuple(zip(*self.numerators)), self.denominator)

    def __matmul__(self, other: RationalMatrix) -> RationalMatrix:
        if self.shape[1] != other.shape[0]:
            raise ExactError("matrix product", (self.shape, other.shape), "inner dimensions that agree",
                             "multiply an (r, k) matrix by a (k, c) one")
        columns = list(zip(*other.numerators))
        rows = [[sum(map(int.__mul__, row, col)) for col in columns] for row in self.numerators]
        return RationalMatrix._make(rows, self.denominator * other.denominator)

    def _combine(self, other: RationalMatrix, sign: int) -> RationalMatrix:
        if self.shape != other.shape:
            raise ExactError("matrix sum", (self.shape, other.shape), "matrices of one shape", "add equal shapes")
        den = math.lcm(self.denominator, other.denominator)
        fa, fb = den // self.denominator, sign * (den // other.denominator)
        rows = [[x * fa + y * fb for x, y in zip(ra, rb)] for ra, rb in zip(self.numerators, other.numerators)]
        return RationalMatrix._make(rows, den)

    def __add__(self, other: RationalMatrix) -> RationalMatrix:
        return self._combine(other, 1)

    def __sub__(self, other: RationalMatrix) -> RationalMatrix:
        return self._combine(other, -1)

    def __neg__(self) -> RationalMatrix:
        return RationalMatrix(tuple(tuple(-v for v in row) for row in self.numerators), self.denominator)

    def scaled(self, factor: Any) -> RationalMatrix:
        """``factor · self`` exactly (``factor`` a finite number, converted exactly)."""
        c = rational(factor, where="factor")
        rows = [[v * c.numerator for v in row] for row in self.numerators]
        return RationalMatrix._make(rows, self.denominator * c.denominator)

    def entries(self) -> tuple[tuple[Fraction, ...], ...]:
        """The entries as Fractions."""
        return tuple(tuple(Fraction(v, self.denominator) for v in row) for row in self.numerators)

    def to_array(self) -> np.ndarray:
        """The nearest floats (correctly rounded division), shape ``(r, c)``."""
        return np.array([[v / self.denominator for v in row] for row in self.numerators], dtype=float)

    def is_symmetric(self) -> bool:
        """Square and equal to its transpose, exactly."""
        rows = self.numerators
        n = len(rows)
        return all(len(r) == n for r in rows) and all(rows[i][j] == rows[j][i] for i in range(n) for j in range(i))

    def trace(self) -> Fraction:
        """The sum of the diagonal."""
        return Fraction(sum(self.numerators[i][i] for i in range(min(self.shape))), self.denominator)


def as_rational(matrix: Any, *, where: str = "matrix") -> RationalMatrix:
    """``matrix`` as a :class:`RationalMatrix` (itself when it already is one)."""
    return RationalMatrix.from_entries(matrix, where=where)


@dataclass(frozen=True, kw_only=True, slots=True)
class PivotTest:
    """The outcome of the exact ``LDLᵀ`` (Sylvester) test of one symmetric matrix.

    Attributes
    ----------
    positive_definite : bool
    size : int
        ``n``.
    failed_at : int or None
        Index ``k`` (0-based) of the first pivot ``d_k ≤ 0``; ``None`` when all are positive
        (also ``0`` for a non-symmetric matrix, which is never called definite).
    smallest_pivot : float
        The smallest pivot computed (rounded to a float for reports; the decision is exact).
    symmetric : bool
    """

    positive_definite: bool
    size: int
    failed_at: int | None
    smallest_pivot: float
    symmetric: bool = True


def pivot_test(matrix: Any) -> PivotTest:
    """Exactly whether a symmetric rational matrix is positive definite, with its pivots.

    Bareiss' fraction-free elimination on the integer numerators: after step ``k`` the diagonal
    entry is the leading principal minor ``Δ_{k+1}`` (of the numerator matrix, which differs from
    ``M`` by the positive factor ``denominator``); the ``LDLᵀ`` pivots are ``Δ_k / Δ_{k−1}``.

    Parameters
    ----------
    matrix : RationalMatrix or array_like, shape (n, n)

    Returns
    -------
    PivotTest
        A non-symmetric or non-square matrix is reported not positive definite (``symmetric=False``).
    """
    m = as_rational(matrix)
    n = m.shape[0]
    if not m.is_symmetric():
        return PivotTest(positive_definite=False, size=n, failed_at=0, smallest_pivot=math.nan, symmetric=False)
    a = [list(row) for row in m.numerators]
    previous, smallest = 1, math.inf
    for k in range(n):
        pivot = a[k][k]
        smallest = min(smallest, Fraction(pivot, previous * m.denominator))
        if pivot <= 0:
            return PivotTest(positive_definite=False, size=n, failed_at=k, smallest_pivot=float(smallest))
        row_k = a[k]
        for i in range(k + 1, n):
            row_i, aik = a[i], a[i][k]
            for j in range(i, n):  # upper triangle only; mirrored below
                row_i[j] = (row_i[j] * pivot - aik * row_k[j]) // previous
            for j in range(i + 1, n):
                a[j][i] = row_i[j]
        previous = pivot
    return PivotTest(positive_definite=True, size=n, failed_at=None,
                     smallest_pivot=float(smallest) if n else math.inf)


def is_positive_definite(matrix: Any) -> bool:
    """Exactly ``M ≻ 0`` (``False`` for a non-symmetric matrix)."""
    return pivot_test(matrix).positive_definite


def is_negative_definite(matrix: Any) -> bool:
    """Exactly ``M ≺ 0`` (``False`` for a non-symmetric matrix)."""
    return pivot_test(-as_rational(matrix)).positive_definite


def inertia(matrix: Any) -> tuple[int, int, int]:
    """The numbers of positive, negative and zero eigenvalues of a symmetric rational matrix, exactly.

    Symmetric elimination with ``1×1`` pivots (the non-zero diagonal entry of largest magnitude) and,
    when the remaining diagonal is zero but the block is not, a ``2×2`` pivot ``[[0, b], [b, 0]]``
    (one positive and one negative eigenvalue); Sylvester's law of inertia.

    Raises
    ------
    ExactError
        The matrix is not symmetric.
    """
    m = as_rational(matrix)
    if not m.is_symmetric():
        raise ExactError("matrix", m.shape, "a symmetric matrix", "symmetrise it, e.g. (M + Mᵀ)/2")
    s = [list(map(Fraction, row)) for row in m.numerators]  # the common denominator is positive: drop it
    positive = negative = 0
    while s:
        k = max(range(len(s)), key=lambda i: abs(s[i][i]))
        if s[k][k] != 0:
            pivot = s[k][k]
            positive, negative = positive + (pivot > 0), negative + (pivot < 0)
            col = [s[i][k] for i in range(len(s))]
            s = [[s[i][j] - col[i] * col[j] / pivot for j in range(len(s)) if j != k] for i in range(len(s)) if i != k]
            continue
        pair = next(((i, j) for i in range(len(s)) for j in range(i + 1, len(s)) if s[i][j] != 0), None)
        if pair is None:
            break  # what is left is the zero matrix
        p, q = pair
        b = s[p][q]
        positive, negative = positive + 1, negative + 1
        rest = [i for i in range(len(s)) if i not in pair]
        # Schur complement S − C B⁻¹ Cᵀ with B = [[0, b], [b, 0]], B⁻¹ = [[0, 1/b], [1/b, 0]]
        s = [[s[i][j] - (s[i][p] * s[q][j] + s[i][q] * s[p][j]) / b for j in rest] for i in rest]
    n = m.shape[0]
    return positive, negative, n - positive - negative


def is_positive_semidefinite(matrix: Any) -> bool:
    """Exactly ``M ⪰ 0`` (``False`` for a non-symmetric matrix); the fast ``LDLᵀ`` test first."""
    m = as_rational(matrix)
    if not m.is_symmetric():
        return False
    if pivot_test(m).positive_definite:
        return True
    return inertia(m)[1] == 0


def determinant(matrix: Any) -> Fraction:
    """The exact determinant of a square rational matrix (Bareiss with row exchanges)."""
    m = as_rational(matrix)
    n = m.shape[0]
    a = [list(row) for row in m.numerators]
    sign, previous = 1, 1
    for k in range(n):
        r = next((i for i in range(k, n) if a[i][k] != 0), None)
        if r is None:
            return Fraction(0)
        if r != k:
            a[k], a[r], sign = a[r], a[k], -sign
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                a[i][j] = (a[i][j] * a[k][k] - a[i][k] * a[k][j]) // previous
        previous = a[k][k]
    return Fraction(sign * (a[n - 1][n - 1] if n else 1), m.denominator ** n)


def characteristic_polynomial(matrix: Any) -> tuple[Fraction, ...]:
    """Coefficients ``(1, c_1, …, c_n)`` of ``det(sI − A) = sⁿ + c_1 sⁿ⁻¹ + … + c_n``, exactly.

    Faddeev–LeVerrier: ``M_k = A(M_{k−1} + c_{k−1}I)``, ``c_k = −tr(M_k)/k``.
    """
    a = as_rational(matrix)
    n = a.shape[0]
    coefficients = [Fraction(1)]
    m = RationalMatrix.identity(n).scaled(0)
    for k in range(1, n + 1):
        m = m + RationalMatrix.identity(n).scaled(coefficients[-1])
        m = a @ m
        coefficients.append(-m.trace() / k)
    return tuple(coefficients)


def is_hurwitz(matrix: Any) -> bool:
    """Exactly whether every eigenvalue of a square rational matrix has a negative real part.

    Routh–Hurwitz: the monic characteristic polynomial is Hurwitz iff every Hurwitz determinant
    ``Δ_1 … Δ_n`` is positive (which forces every coefficient positive).
    """
    c = characteristic_polynomial(matrix)
    n = len(c) - 1
    if any(x <= 0 for x in c):  # necessary; also a cheap early exit
        return False

    def coefficient(index: int) -> Fraction:
        return c[index] if 0 <= index <= n else Fraction(0)

    for k in range(1, n + 1):
        hurwitz_k = [[coefficient(2 * (j + 1) - (i + 1)) for j in range(k)] for i in range(k)]
        if determinant(hurwitz_k) <= 0:
            return False
    return True


def nullspace(rows: Sequence[Sequence[Any]], columns: int) -> tuple[tuple[Fraction, ...], ...]:
    """A basis of ``{x : R x = 0}`` in exact rationals (Gauss–Jordan with complete pivoting).

    Parameters
    ----------
    rows : sequence of sequence of numbers, shape (r, columns)
        The rows of ``R`` (may be empty: the basis is then the identity).
    columns : int

    Returns
    -------
    tuple of tuple of Fraction
        The basis vectors (each of length ``columns``), one per free column, in column order.
    """
    a = [[rational(v, where="rows") for v in row] for row in rows]
    if any(len(row) != columns for row in a):
        raise ExactError("rows", [len(r) for r in a], f"rows of {columns} entries", "give one entry per unknown")
    order: list[int] = []
    pivots: list[int] = []
    remaining = list(range(len(a)))
    while remaining:  # complete pivoting: the largest remaining entry, so the basis has entries of moderate size
        i, c = max(((i, c) for i in remaining for c in range(columns) if c not in pivots),
                   key=lambda ic: abs(a[ic[0]][ic[1]]), default=(None, None))
        if i is None or a[i][c] == 0:
            break
        inv = 1 / a[i][c]
        a[i] = [v * inv for v in a[i]]
        for k in range(len(a)):
            if k != i and a[k][c] != 0:
                f = a[k][c]
                a[k] = [x - f * y for x, y in zip(a[k], a[i])]
        pivots.append(c)
        remaining.remove(i)
        order.append(i)
    basis = []
    for free in (c for c in range(columns) if c not in pivots):
        v = [Fraction(0)] * columns
        v[free] = Fraction(1)
        for i, c in zip(order, pivots):
            v[c] = -a[i][free]
        basis.append(tuple(v))
    return tuple(basis)
