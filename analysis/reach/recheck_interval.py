"""Outward-rounded float interval arithmetic for the independent re-check (:mod:`analysis.reach.recheck_own`).

No code of the producer (``zonotope``, ``flowpipe``, ``series``, ``sets``, ``engine``) is used.  Every float
array here is read as the exact real numbers it denotes; each operation returns a float result together with a
bound of its rounding error, so the sets hold the exact ones.  The arguments (IEEE 754 binary64, round to
nearest, ``u = 2⁻⁵³``):

* one rounded operation ``fl(a ∘ b) = (a ∘ b)(1 + ε) + η`` with ``|ε| <= u`` and ``|η| <= 2⁻¹⁰⁷⁵`` (underflow);
  ``np.nextafter`` one ulp outward therefore encloses the exact result of that single operation;
* a computed dot product of length ``k``, in any summation order, with or without FMA, is within
  ``γ_k Σ|a_i b_i|`` (``γ_k = k u/(1 − k u)``) plus ``k`` underflow terms of the exact one (Higham, *Accuracy
  and Stability of Numerical Algorithms*, 2nd ed., §3.1 and §3.5).  numpy's ``@`` calls BLAS ``dgemm``/``dgemv``,
  which compute each entry as such a dot product (blocked, reordered, possibly FMA: all covered).  The argument
  fails for a BLAS that uses Strassen-like fast multiplication or lower internal precision (none of the
  reference, OpenBLAS or MKL ``dgemm`` kernels does for float64), and under a flush-to-zero/denormals-are-zero
  mode (then an underflow error can reach ``2⁻¹⁰²²``: covered too, since :data:`TINY` is ``2⁻¹⁰⁰⁰`` per term);
* for non-negative ``a, b``: the exact ``a @ b`` is at most ``fl(a @ b)(1 + 2(k + 2)u) + (k + 2)·TINY``, rounded
  up once more (:func:`nn_up`).

Intervals are midpoint-radius pairs ``(m, r)``: the exact set is ``{x : |x − m| <= r}`` entrywise.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np

__all__ = ["U", "TINY", "up", "down", "nn_up", "add_up", "imatmul", "point_product", "float_interval",
           "expm_taylor", "ExpEnclosure", "exp_enclosure", "sum_up",
           "EXPLICIT_POWERS", "WEIGHTS"]

U = 2.0 ** -53
TINY = 2.0 ** -1000


def up(x: Any) -> np.ndarray:
    """One ulp towards ``+∞`` (encloses the exact result of the single operation that gave ``x``)."""
    return np.nextafter(x, np.inf)


def down(x: Any) -> np.ndarray:
    """One ulp towards ``−∞``."""
    return np.nextafter(x, -np.inf)


def nn_up(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """An upper bound of the exact ``a @ b`` for non-negative ``a`` and ``b``."""
    k = a.shape[-1]
    return up(up(a @ b) * (1.0 + 2.0 * (k + 2) * U) + (k + 2) * TINY)


def sum_up(x: np.ndarray, axis: int | None = None) -> np.ndarray:
    """An upper bound of the exact sum of non-negative ``x`` (along ``axis``)."""
    k = x.size if axis is None else x.shape[axis]
    return up(up(np.sum(x, axis=axis)) * (1.0 + 2.0 * (k + 2) * U) + (k + 2) * TINY)


def add_up(*terms: Any) -> np.ndarray:
    """An upper bound of the exact sum of non-negative arrays (each addition rounded up)."""
    total = np.asarray(terms[0], dtype=float)
    for t in terms[1:]:
        total = up(total + t)
    return total


def point_product(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(fl(a @ b), r)`` with ``|a @ b − fl(a @ b)| <= r`` entrywise (exact ``a``, ``b``)."""
    k = a.shape[-1]
    return a @ b, up(nn_up(np.abs(a), np.abs(b)) * ((k + 2) * U) + (k + 2) * TINY)


def imatmul(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The product of two interval matrices ``(am ± ar)(bm ± br) ⊆ m ± r``."""
    (am, ar), (bm, br) = a, b
    m, r = point_product(am, bm)
    return m, add_up(r, nn_up(np.abs(am), br), nn_up(ar, up(np.abs(bm) + br)))


def float_interval(values: Any) -> tuple[np.ndarray, np.ndarray]:
    """Exact rationals (a list, or a list of rows, of Fraction) as ``(nearest floats, radius)``, radius rounded up."""
    flat = [v for row in values for v in row] if values and isinstance(values[0], (list, tuple)) else list(values)
    shape = (len(values), len(values[0])) if len(flat) != len(values) or (values and isinstance(
        values[0], (list, tuple))) else (len(values),)
    mid = np.array([float(v) for v in flat], dtype=float)
    rad = np.array([float(abs(Fraction(v) - Fraction(float(m)))) for v, m in zip(flat, mid)], dtype=float)
    return mid.reshape(shape), (up(rad) * (rad > 0)).reshape(shape)


def _div(a: tuple[np.ndarray, np.ndarray], k: int) -> tuple[np.ndarray, np.ndarray]:
    """``a/k`` for a whole number ``k >= 1`` (each midpoint division rounded: relative error ``<= u``)."""
    m = a[0] / k
    return m, add_up(up(a[1] / k), up(np.abs(m) * (2 * U)), TINY)


def _scale(a: tuple[np.ndarray, np.ndarray], s: float) -> tuple[np.ndarray, np.ndarray]:
    """``a·s`` for a float ``s > 0`` (rounding of the midpoint into the radius)."""
    m = a[0] * s
    return m, add_up(up(a[1] * s), up(np.abs(m) * (2 * U)), TINY)


def _iadd(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    m = a[0] + b[0]
    return m, add_up(a[1], b[1], up(np.abs(m) * (2 * U)), TINY)


def _norm_up(a: tuple[np.ndarray, np.ndarray]) -> float:
    """An upper bound of ``‖·‖∞`` over the interval matrix."""
    return float(np.max(sum_up(up(np.abs(a[0]) + a[1]), axis=1))) if a[0].size else 0.0


def _tail(q: float, order: int) -> float:
    """``q^{K+1}/(K+1)! / (1 − q/(K+2))`` rounded up (exact rationals), ``K = order``; requires ``q < K + 2``."""
    qq = Fraction(q)
    value = qq ** (order + 1) / math.factorial(order + 1) / (1 - qq / (order + 2))
    f = float(value)
    return float(up(f)) if Fraction(f) < value else f


def expm_taylor(a: tuple[np.ndarray, np.ndarray], tol: float = 2.0 ** -60
                ) -> tuple[tuple[np.ndarray, np.ndarray], list[tuple[np.ndarray, np.ndarray]], float]:
    """``(e^a enclosed, [a^k/k! for k = 0..K] enclosed, q)`` for an interval matrix with ``q = ‖a‖∞ <= 4``: the
    Taylor polynomial of order ``K`` plus the tail bound (entrywise) below ``tol`` relative to 1."""
    n = a[0].shape[0]
    q = _norm_up(a)
    if not q <= 4.0:
        raise ValueError(f"‖Aδ‖∞ = {q:.3g} > 4")
    eye = (np.eye(n), np.zeros((n, n)))
    terms = [eye]
    total = eye
    k = 0
    while True:
        k += 1
        term = _div(imatmul(terms[-1], a), k) if k > 1 else a
        terms.append(term)
        total = _iadd(total, term)
        if q < k + 2 and _tail(q, k) < tol:
            break
        if k > 80:
            raise ValueError("e^{Aδ}: the Taylor series did not converge")
    tail = _tail(q, k)
    return (total[0], up(total[1] + tail)), terms, q


EXPLICIT_POWERS = 8
"""The interpolation error uses the signed powers ``(A_aug δ)^k/k!`` up to this ``k``; beyond, ``|A_aug δ|^k/k!``."""
WEIGHTS = {2: 0.25, 3: 0.4, 4: 0.5}
"""``c_k >= max_{θ∈[0,1]} θ − θ^k = (k − 1) k^{−k/(k−1)}``: 1/4, 0.385 <= 0.4, 0.472 <= 0.5; 1 beyond (``θ − θ^k <= 1``)."""


class ExpEnclosure:
    """For ``ẋ = A x + c`` (exact rationals) and a float step ``δ``: the enclosures a step of the re-check needs.

    The constant is an extra coordinate ``x_{n+1} = s`` (``s`` a power of two ``>= max|c|``, so ``c/s`` is exact):
    ``A_aug = [[A, c/s], [0, 0]]``.  Attributes: ``phi`` (``e^{Aδ}``, interval ``n × n``), ``shift``
    (``∫₀^δ e^{Aτ} dτ c``, interval ``n``), ``scale`` (``s``), ``powers`` (``c_k (A_aug δ)^k/k!`` for
    ``k = 2..4``, intervals ``(n+1) × (n+1)``, with ``c_k >= max_{θ∈[0,1]} θ − θ^k``: 1/4, 2/5, 1/2) and ``rest``
    (a non-negative ``(n+1) × (n+1)`` matrix bounding ``Σ_{k>=5} |A_aug δ|^k/k!``).

    The interpolation error of one solution over the step: for ``t ∈ [0, δ]``,
    ``x(t) − ((1 − t/δ) x₀ + (t/δ) x(δ)) = Σ_{k>=2} (t^k − t δ^{k−1})/k! A_aug^k x₀`` (augmented), and
    ``|t^k − t δ^{k−1}| = δ^k |θ − θ^k|·… <= c_k δ^k`` with ``θ = t/δ``; so its modulus is at most
    ``Σ_{k=2}^{K'} |powers_k x₀| + rest |x₀|``.
    """

    def __init__(self, a: list[list[Fraction]], c: list[Fraction], step: float) -> None:
        n = len(a)
        big = max((abs(v) for v in c), default=Fraction(0))
        s = Fraction(1)
        while s < big:
            s *= 2
        while s / 2 >= big and big > 0:
            s /= 2
        self.scale = float(s)
        rows = [list(r) + [v / s] for r, v in zip(a, c)] + [[Fraction(0)] * (n + 1)]
        aug = _scale(float_interval(rows), step)
        total, terms, q = expm_taylor(aug)
        self.q = q
        self.phi = (total[0][:n, :n], total[1][:n, :n])
        self.shift = (total[0][:n, n] * self.scale, up(total[1][:n, n] * self.scale))
        last = min(EXPLICIT_POWERS, len(terms) - 1)  # the Taylor terms computed (signed), k = 2..last
        self.powers = [(terms[k][0] * w, up(up(terms[k][1] * w) + np.abs(terms[k][0] * w) * (2 * U)))
                       for k, w in ((k, WEIGHTS.get(k, 1.0)) for k in range(2, last + 1))]
        absaug = up(np.abs(aug[0]) + aug[1])
        term = np.eye(n + 1)
        rest = np.zeros((n + 1, n + 1))
        for k in range(1, last + 1):
            term = up(nn_up(term, absaug) / k * (1 + 4 * U))
        order = last
        while True:  # Σ_{k > last} |A_aug δ|^k/k! (weights <= 1), entrywise, plus the tail of the norms
            order += 1
            term = up(nn_up(term, absaug) / order * (1 + 4 * U))
            rest = up(rest + term)
            if q < order + 2 and _tail(q, order) < 2.0 ** -60:
                break
        self.rest = up(rest + _tail(q, order))


def exp_enclosure(a: list[list[Fraction]], c: list[Fraction], step: float) -> ExpEnclosure:
    """:class:`ExpEnclosure` (raises ``ValueError`` when ``‖A_aug δ‖∞ > 4``)."""
    return ExpEnclosure(a, c, step)
