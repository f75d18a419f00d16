"""Rigorous enclosures of ``e^{Aδ}`` and of the Taylor tails used by the flowpipe, in exact rationals.

For a rational matrix ``M = Aδ`` (every float is one), the truncated series
``T_K = Σ_{k=0}^{K} M^k / k!`` is computed *exactly* (integers over one common
denominator), and the tail is bounded entrywise by the norm bound
``|Σ_{k>K} M^k/k!|_{ij} <= ‖M‖∞^{K+1} / (K+1)! · 1 / (1 − ‖M‖∞/(K+2))``
(every entry of ``M^k`` is at most ``‖M^k‖∞ <= ‖M‖∞^k``; the geometric
factor bounds the ratio of consecutive terms, valid when ``‖M‖∞ < K + 2``).
The float center ``Φc`` is ``T_K`` rounded to nearest and the radius
``Φr`` is ``|T_K − Φc|`` rounded up plus the tail rounded up, so the exact
``e^{Aδ}`` lies in ``[Φc − Φr, Φc + Φr]`` with no rounding left unaccounted.

The same construction on ``|A|`` (entrywise absolute values) gives the two
non-negative matrices of the first-segment bloating
(:mod:`analysis.reach.flowpipe`):

* ``D = e^{|A|δ} − I − |A|δ``: the interpolation error
  ``|x(t) − ((1 − t/δ) x0 + (t/δ) e^{Aδ} x0)| <= D |x0|`` for ``t ∈ [0, δ]``; with ``corrected=True``
  the tighter ``F = Σ_{k>=2} c_k (|A|δ)^k / k!`` (:func:`interpolation_coefficient`; ``c_2 = 1/4``), which
  bounds the same error (Althoff's correction matrix, CORA);
* ``S = Σ_{k>=1} |A|^k δ^{k+1} / (k+1)!``: the input correction
  ``|∫_0^t (e^{A(t−s)} − I) B u(s) ds| <= S |B u|max``.
"""

from __future__ import annotations

import math
from fractions import Fraction
from collections.abc import Sequence

import numpy as np

from .zonotope import round_up, upper

__all__ = ["MatrixEnclosure", "exp_enclosure", "bloating_matrices", "MAX_NORM_STEP"]

MAX_NORM_STEP = 4.0
"""Largest ``‖A‖∞ δ`` accepted (a larger step makes the bloating useless and the series long)."""

_TAIL = 2.0 ** -80
"""The truncation order is chosen so that the tail bound is below this (times ``max(1, ‖M‖∞)``)."""


class MatrixEnclosure:
    """An interval matrix ``[center − radius, center + radius]``, both float arrays of shape ``(n, n)``."""

    __slots__ = ("center", "radius")

    def __init__(self, center: np.ndarray, radius: np.ndarray) -> None:
        self.center = center
        self.radius = radius


def _order(norm: float) -> int:
    k = 2
    term = norm ** 3 / 6.0
    while k < 200 and (norm >= k + 2 or term / (1.0 - norm / (k + 2)) > _TAIL * max(1.0, norm)):
        k += 1
        term *= norm / (k + 1)
    return k


def _common(matrix: Sequence[Sequence[Fraction]]) -> tuple[np.ndarray, int]:
    """``matrix = N / d`` with ``N`` an integer (object) array and ``d > 0`` an integer."""
    d = 1
    for row in matrix:
        for q in row:
            d = d * q.denominator // math.gcd(d, q.denominator)
    n = np.array([[int(q * d) for q in row] for row in matrix], dtype=object)
    return n, d


def _series(matrix: Sequence[Sequence[Fraction]], order: int, first: int, shift: int) -> tuple[np.ndarray, int]:
    """``Σ_{k=first}^{order} M^k / (k + shift)!`` exactly, as an integer array over a positive integer."""
    num, d = _common(matrix)
    size = num.shape[0]
    power = np.array([[int(i == j) for j in range(size)] for i in range(size)], dtype=object)
    top = math.factorial(order + shift)
    total = np.array([[0] * size for _ in range(size)], dtype=object)
    for k in range(order + 1):
        if k >= first:
            # M^k/(k+shift)! = power / d^k / (k+shift)!  ->  over d^order * top: power * d^(order-k) * top/(k+shift)!
            total = total + power * (d ** (order - k) * (top // math.factorial(k + shift)))
        if k < order:
            power = power.dot(num)
    return total, d ** order * top


def _to_float(total: np.ndarray, den: int) -> tuple[np.ndarray, np.ndarray]:
    """Nearest floats of ``total / den`` and an upper bound of the rounding error, entrywise."""
    size = total.shape[0]
    center = np.empty((size, size))
    error = np.empty((size, size))
    for i in range(size):
        for j in range(size):
            exact = Fraction(int(total[i, j]), den)
            center[i, j] = float(exact)
            error[i, j] = float(round_up(float(abs(exact - Fraction(center[i, j])))))
    return center, error


def _tail(norm: Fraction, order: int, shift: int = 0) -> float:
    """An upper bound of ``Σ_{k>order} norm^k / (k + shift)!`` (requires ``norm < order + 2``)."""
    first = norm ** (order + 1) / math.factorial(order + 1 + shift)
    bound = first / (1 - norm / (order + 2 + shift))
    return float(round_up(float(bound)))


def _norm(matrix: Sequence[Sequence[Fraction]]) -> Fraction:
    return max((sum((abs(q) for q in row), Fraction(0)) for row in matrix), default=Fraction(0))


def exp_enclosure(a: Sequence[Sequence[Fraction]], step: Fraction) -> MatrixEnclosure:
    """An interval matrix containing ``e^{A·step}`` exactly.

    Parameters
    ----------
    a : sequence of sequences of Fraction, shape (n, n)
    step : Fraction
        ``δ > 0`` [s], with ``‖A‖∞ δ <= MAX_NORM_STEP`` (checked by the caller).
    """
    m = [[q * step for q in row] for row in a]
    norm = _norm(m)
    order = _order(float(norm))
    total, den = _series(m, order, 0, 0)
    center, error = _to_float(total, den)
    radius = upper(error + _tail(norm, order), 2)
    return MatrixEnclosure(center, radius)


def _float_up_matrix(matrix: Sequence[Sequence[Fraction]]) -> np.ndarray:
    """Floats ``>=`` the (non-negative) exact entries."""
    out = np.array([[float(q) for q in row] for row in matrix], dtype=float).reshape(len(matrix), -1)
    for i, row in enumerate(matrix):
        for j, q in enumerate(row):
            if Fraction(out[i, j]) < q:
                out[i, j] = float(round_up(out[i, j]))
    return out


def interpolation_coefficient(k: int) -> float:
    """A float ``c_k >= max_{τ ∈ [0, 1]} (τ − τ^k) = k^{−1/(k−1)} (1 − 1/k)`` (``k >= 2``), and ``c_k <= 1``.

    The interpolation error of the first segment is ``Σ_{k>=2} (t^k − t δ^{k−1}) A^k x0 / k!`` and
    ``|t^k − t δ^{k−1}| = δ^k (τ − τ^k)`` with ``τ = t/δ`` (the maximum at ``τ = k^{−1/(k−1)}``).  ``c_2 = 1/4``
    exactly; ``c_3 = 2/(3√3) < 0.385`` (``27 · 0.385² > 4``); for ``k >= 4`` the bound ``1 − 1/k`` (rounded up).
    """
    if k == 2:
        return 0.25
    if k == 3:
        return 0.385
    return float(round_up((k - 1) / k))


def bloating_matrices(a: Sequence[Sequence[Fraction]], step: Fraction, *, corrected: bool = False
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Upper bounds of ``D = e^{|A|δ} − I − |A|δ`` and ``S = Σ_{k>=1} |A|^k δ^{k+1}/(k+1)!`` (both ``>= 0``).

    Every term is non-negative, so the series are summed in floating point and bounded from above: each term
    ``(|A|δ)^k / k!`` is the previous one times ``|A|δ`` (rounded up entrywise) over ``k``, inflated by
    :func:`~analysis.reach.zonotope.upper` for its ``n + 2`` roundings, which keeps it above the exact term;
    the tails beyond the truncation order are the rigorous bounds of :func:`_tail`.  ``corrected``: the first
    matrix is ``F = Σ_{k>=2} c_k (|A|δ)^k / k!`` instead (:func:`interpolation_coefficient`, each term times
    ``c_k`` rounded up; the tail keeps ``c_k <= 1``), about a quarter of ``D`` for small ``‖A‖δ``.
    """
    m = [[abs(q) * step for q in row] for row in a]
    norm = _norm(m)
    order = _order(float(norm))
    size = len(m)
    mf = _float_up_matrix(m)
    term = np.eye(size)
    d_sum = np.zeros((size, size))
    s_sum = np.zeros((size, size))
    for k in range(1, order + 1):
        term = upper((term @ mf) / k, size + 2)
        if k >= 2:
            d_sum = d_sum + (upper(term * interpolation_coefficient(k), 1) if corrected else term)
        s_sum = s_sum + term / (k + 1)
    d_upper = upper(d_sum + _tail(norm, order), order + 2)
    # S = δ Σ_{k>=1} (|A|δ)^k / (k+1)!
    s_upper = upper((upper(s_sum, 2 * order + 2) + _tail(norm, order, 1)) * float(step), 3)
    return np.maximum(d_upper, 0.0), np.maximum(s_upper, 0.0)
