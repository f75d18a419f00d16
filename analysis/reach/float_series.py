"""The discretised affine step of a linearisation in floating point, rigorously (midpoint-radius intervals).

:mod:`analysis.reach.series` encloses ``e^{Aδ}`` in exact rationals, which costs about a millisecond
per matrix: right for an affine mode (once per mode), too slow for the conservative linearisation
of :mod:`analysis.reach.nonlinear`, which needs a new matrix at every step.  Here the same three
quantities are enclosed with float midpoint-radius interval matrices (Rump, *Fast and parallel
interval arithmetic*, BIT 39, 1999):

* ``Φ ∋ e^{Mδ}`` (``M`` the augmented matrix ``[[A, c/s], [0, 0]]``): the truncated Taylor series
  ``Σ_{k<=K} P_k``, ``P_k = P_{k−1} (Mδ) / k``, each product enclosed as
  ``[Pc Mc ± (|Pc| Mr + Pr (|Mc| + Mr) + γ_n |Pc||Mc|)]`` and each sum with its rounding, plus the
  tail ``‖Mδ‖∞^{K+1}/(K+1)! / (1 − ‖Mδ‖∞/(K+2))`` on every entry;
* ``D >= e^{|M|δ} − I − |M|δ`` (or the tighter ``F = Σ_{k>=2} c_k (|M|δ)^k/k!``, ``c_2 = 1/4``, which the
  flowpipe uses) and ``S >= Σ_{k>=1} |M|^k δ^{k+1}/(k+1)!``: series of non-negative
  matrices computed in floats and bounded above with :func:`analysis.reach.zonotope.upper`, plus
  their tails.

:func:`float_series` (what :func:`float_dynamics` uses) computes the three in one loop, with ``Φ``'s radius an
a-priori bound of the float Taylor sum's rounding (its docstring) instead of a midpoint-radius product per term.

Every radius and bound is a non-negative expression bounded above by
:func:`~analysis.reach.zonotope.upper` (the rounding argument of ``docs/reachability.md``);
``γ_n`` is Higham's bound of a float dot product of length ``n``.  The tests compare ``Φ`` with
scipy's ``expm`` and ``D``, ``S`` with the exact rational ones of :mod:`analysis.reach.series`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .flowpipe import ModeDynamics
from .series import MatrixEnclosure, interpolation_coefficient
from .zonotope import UNIT_ROUNDOFF, Zonotope, box_generators, gamma, upper

__all__ = ["float_exp_enclosure", "float_bloating", "float_dynamics", "float_series"]

_TAIL = 2.0 ** -70
_TINY = 2.0 ** -1000
"""Absolute slack per rounding for underflow (far above the subnormal spacing)."""


def _terms(norm: float) -> int:
    """A truncation order ``K`` with ``norm < K + 2`` and the tail below ``_TAIL``."""
    k, term = 1, norm * norm / 2.0
    while k < 60 and (norm >= k + 2 or term / (1.0 - norm / (k + 2)) > _TAIL):
        k += 1
        term *= norm / (k + 1)
    return k


def _tail(norm: float, order: int, shift: int = 0) -> float:
    """An upper bound of ``Σ_{k>order} norm^k/(k+shift)!`` (``norm < order + 2``)."""
    first = float(upper(norm ** (order + 1) / math.factorial(order + 1 + shift), order + 3))
    return float(upper(first / (1.0 - norm / (order + 2 + shift)), 3)) + _TINY


def _product(pc: np.ndarray, pr: np.ndarray, mc: np.ndarray, weight: np.ndarray, wide_m: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``[pc ± pr] [mc ± mr]`` with ``weight = mr + γ_n |mc|`` and ``wide_m = |mc| + mr`` (fixed over a series).

    The radius ``|pc| mr + pr (|mc| + mr) + γ_n |pc||mc|`` is computed as ``|pc| weight + pr wide_m`` (the same
    exact value; along any term at most ``n + 4`` roundings, within ``upper``'s ``4n + 6``)."""
    n = mc.shape[0]
    radius = np.abs(pc) @ weight + pr @ wide_m
    return pc @ mc, upper(radius, 4 * n + 6) + _TINY


def float_exp_enclosure(matrix: np.ndarray, step: float) -> MatrixEnclosure:
    """An interval matrix containing ``e^{matrix·step}`` exactly (``matrix``: floats, shape (m, m)).

    Requires ``‖matrix‖∞ step`` below 50 (the caller keeps it below 4).
    """
    a = np.asarray(matrix, dtype=float)
    m = a.shape[0]
    mc = a * float(step)
    mr = upper(UNIT_ROUNDOFF * np.abs(mc), 1) + _TINY
    norm = float(upper(np.max((np.abs(mc) + mr).sum(axis=1)) if m else 0.0, m + 1))
    order = _terms(norm)
    pc, pr = np.eye(m), np.zeros((m, m))
    tc, tr = np.eye(m), np.zeros((m, m))
    abs_mc = np.abs(mc)
    wide_m, weight = abs_mc + mr, mr + gamma(m) * abs_mc
    for k in range(1, order + 1):
        pc, pr = _product(pc, pr, mc, weight, wide_m)
        qc = pc / k
        pr = upper(pr / k + UNIT_ROUNDOFF * np.abs(qc), 2) + _TINY
        pc = qc
        sc = tc + pc
        tr = upper(tr + pr + UNIT_ROUNDOFF * np.abs(sc), 3) + _TINY
        tc = sc
    return MatrixEnclosure(tc, upper(tr + _tail(norm, order), 2))


@functools.lru_cache(maxsize=64)
def _weight(k: int) -> float:
    """A float ``>= c_k / k!`` (:func:`analysis.reach.series.interpolation_coefficient`; one rounding, bounded up)."""
    return float(upper(interpolation_coefficient(k) / math.factorial(k), 1))


@functools.lru_cache(maxsize=64)
def _weights(k: int) -> np.ndarray:
    """Floats ``>= (1/k!, c_k/k!, 1/(k+1)!)``, shape (3, 1, 1) (the factorial's conversion and the division
    rounded, bounded up)."""
    out = [float(upper(1.0 / math.factorial(k), 2)), _weight(k), float(upper(1.0 / math.factorial(k + 1), 2))]
    return np.array(out).reshape(3, 1, 1)


def float_bloating(matrix: np.ndarray, step: float, *, corrected: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Upper bounds of ``D = e^{|M|δ} − I − |M|δ`` and ``S = Σ_{k>=1} |M|^k δ^{k+1}/(k+1)!`` (both ``>= 0``).

    ``corrected``: the first matrix is ``F = Σ_{k>=2} c_k (|M|δ)^k / k!`` instead, the tighter bound of the same
    interpolation error (:func:`analysis.reach.series.interpolation_coefficient`; the tail keeps ``c_k <= 1``).
    """
    p = np.abs(np.asarray(matrix, dtype=float))
    m = p.shape[0]
    q = upper(p * float(step), 1) + _TINY  # >= |M|δ entrywise
    norm = float(upper(np.max(q.sum(axis=1)) if m else 0.0, m + 1))
    order = _terms(norm)
    power = q.copy()  # >= (|M|δ)^k
    d = np.zeros((m, m))
    s = upper(q / 2.0, 1)
    for k in range(2, order + 1):
        power = upper(power @ q, 2 * m + 2) + _TINY
        if corrected:  # power·w_k (one rounding) plus the sum (one): within upper's 3
            d = upper(d + power * _weight(k), 3) + _TINY
        else:
            d = upper(d + power / math.factorial(k), 3) + _TINY
        s = upper(s + power / math.factorial(k + 1), 3) + _TINY
    d = upper(d + _tail(norm, order), 2)
    s = upper((s + _tail(norm, order, 1)) * float(step), 3)
    return d, s


def float_series(matrix: np.ndarray, step: float) -> tuple[MatrixEnclosure, np.ndarray, np.ndarray]:
    """``Φ ∋ e^{Mδ}``, ``F`` and ``S`` (as :func:`float_bloating` with ``corrected=True``) in one loop.

    ``Φ``'s centre is the float Taylor sum ``T̂`` (``P̂_k = fl(fl(P̂_{k−1} M̂)/k)``, ``M̂ = fl(Mδ)``, summed in
    order); its radius an a-priori bound instead of a midpoint-radius product per term:

    * rounding: ``|T̂ − Σ_{k<=K} M̂^k/k!| <= γ_{K(m+2)} Σ_{k<=K} |M̂|^k/k!`` entrywise (by induction
      ``|P̂_k − M̂^k/k!| <= γ_{k(m+1)} |M̂|^k/k!``: the product adds ``γ_m``, the division ``u``; the ``K``
      additions ``γ_K`` of the sum of ``|P̂_k|``; Higham's ``γ_a + γ_b + γ_a γ_b <= γ_{a+b}``), and
      ``Σ |M̂|^k/k! <= Σ q^k/k!`` with ``q >= |M̂|, |Mδ|`` the matrix of the ``F``, ``S`` series (summed alongside);
    * truncation: ``|Σ_{k>K} M̂^k/k!| <=`` the tail of ``‖q‖∞`` (as in :func:`float_exp_enclosure`);
    * the rounding of ``Mδ``: ``|e^{Mδ} − e^{M̂}| <= e^β ‖Mδ − M̂‖∞`` entrywise (``‖X^k − Y^k‖ <= k β^{k−1}
      ‖X − Y‖``, ``β >= ‖X‖, ‖Y‖``; ``β = ‖q‖∞``, ``e^β <= 2^{⌈1.443 β⌉ + 1}``, ``‖Mδ − M̂‖∞ <= u ‖q‖∞`` plus
      an underflow slack);
    * underflow: ``K(m + 2) + 2`` absolute slacks of ``2⁻¹⁰⁰⁰`` (a subnormal's error is ``2⁻¹⁰⁷⁵``), times ``e^β``.

    Requires ``‖M‖∞ δ`` below 50 (the caller keeps it below 4).
    """
    a = np.asarray(matrix, dtype=float)
    m = a.shape[0]
    mc = a * float(step)
    q = upper(np.abs(a) * float(step), 1) + _TINY  # >= |Mδ| and >= |M̂| entrywise
    norm = float(upper(np.max(q.sum(axis=1)) if m else 0.0, m + 1))
    order = _terms(norm)
    eye = np.eye(m)
    power = q.copy()  # >= q^k
    # the three non-negative series side by side: Σ q^k/k! (for Φ's radius), F = Σ_{k>=2} c_k q^k/k!, Σ q^k/(k+1)!
    sums = np.stack([upper(eye + q, 1), np.zeros((m, m)), upper(q / 2.0, 1)])
    tc = eye + mc
    pc = mc
    for k in range(2, order + 1):
        pc = (pc @ mc) / k
        tc = tc + pc
        power = upper(power @ q, 2 * m + 2) + _TINY
        sums = upper(sums + power * _weights(k), 3) + _TINY  # one product by a weight >= the coefficient, one sum
    e_abs, d, s = sums[0], sums[1], sums[2]
    grow = 2.0 ** (math.ceil(1.443 * norm) + 1)  # >= e^norm (log2 e < 1.443)
    gamma_k = order * (m + 2) * UNIT_ROUNDOFF / (1.0 - order * (m + 2) * UNIT_ROUNDOFF)
    shift = float(upper(UNIT_ROUNDOFF * norm, 1)) + m * _TINY  # >= ‖Mδ − M̂‖∞
    slack = (order * (m + 2) + 2) * _TINY
    radius = upper(gamma_k * e_abs + (_tail(norm, order) + grow * (shift + slack)), 8) + _TINY
    d = upper(d + _tail(norm, order), 2)
    s = upper((s + _tail(norm, order, 1)) * float(step), 3)
    return MatrixEnclosure(tc, radius), d, s


def float_dynamics(mode: str, a: np.ndarray, c: np.ndarray, scale: float, step: float,
                   input_radius: np.ndarray) -> ModeDynamics:
    """The :class:`~analysis.reach.flowpipe.ModeDynamics` of ``ẋ = A x + c + u``, ``|u| <= input_radius``.

    Parameters
    ----------
    a : ndarray, shape (n, n)
    c : ndarray, shape (n,)
        The constant; ``c / scale`` must be exact (``scale`` a power of two, no underflow).
    scale : float
        The constant coordinate of the augmented state.
    step : float
        ``δ`` [s].
    input_radius : ndarray, shape (n,)
        The input box ``[-r, r]`` (centred).
    """
    n = a.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = a
    aug[:n, n] = c / scale
    phi, deviation, s_matrix = float_series(aug, step)
    r = np.asarray(input_radius, dtype=float)
    scaled = r * float(step)
    rounding = upper(UNIT_ROUNDOFF * np.abs(scaled), 1)
    extra = upper(s_matrix[:n, :n] @ r, n + 1) + rounding
    top = np.hstack([box_generators(scaled), box_generators(extra)])
    gens = np.vstack([top, np.zeros((1, top.shape[1]))])
    return ModeDynamics(mode=mode, step=float(step), phi=phi, deviation=deviation,
                        input_step=Zonotope(center=np.zeros(n + 1), generators=gens))
