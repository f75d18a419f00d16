"""The independent re-check's own sets: float zonotopes read as exact reals, mapped with every rounding bounded.

A :class:`FZ` is ``{c + G ξ : |ξ|∞ <= 1} ⊕ [−e, e]`` (``c`` of shape ``(n,)``, ``G`` ``(n, p)``, ``e >= 0``).
Mapping by an interval matrix ``[Φm ± Φr]`` with an interval shift ``[vm ± vr]`` keeps the weights ``ξ``:
``c' = fl(Φm c + vm)``, ``G' = fl(Φm G)``, and the error box collects ``|Φm| e``, ``Φr |x|`` (``|x|`` bounded over
the set), the roundings of the products (:func:`analysis.reach.recheck_interval.point_product`) and ``vr``.
So each point ``x = c + Gξ + ε`` of the set is mapped to a point ``c' + G'ξ + ε'`` with the *same* ``ξ``.

The tube of a step (:func:`tube`): with ``Z₁ = Φ Z₀ + v`` (same weights), every solution from ``x₀ ∈ Z₀`` is, at
``t ∈ [0, δ]``, within the interpolation error (:class:`~analysis.reach.recheck_interval.ExpEnclosure`) of
``(1 − λ) x₀ + λ x(δ)``, ``λ = t/δ``; and ``(1 − λ)(c + Gξ + ε) + λ(c' + G'ξ + ε')`` lies in
``(c + c')/2 + (G + G')/2 ξ + (c − c')/2 μ + (G − G')/2 (μξ)`` ``⊕ [−max(e, e'), max(e, e')]`` with
``μ = 1 − 2λ ∈ [−1, 1]`` — a zonotope with ``2p + 1`` generators.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .recheck_interval import TINY, U, ExpEnclosure, add_up, down, nn_up, point_product, sum_up, up

__all__ = ["FZ", "tube", "exact_image"]


@dataclass(slots=True)
class FZ:
    """``{center + gens ξ} ⊕ [−err, err]`` (see the module)."""

    center: np.ndarray
    gens: np.ndarray
    err: np.ndarray

    @staticmethod
    def of_box(lo: np.ndarray, hi: np.ndarray) -> "FZ":
        """A box as a zonotope (the midpoint's and the half-widths' roundings in ``err``)."""
        c = (lo + hi) * 0.5
        r = (hi - lo) * 0.5
        slack = up(up(np.abs(c) * (2 * U)) + TINY)
        keep = r > 0
        gens = np.diag(r)[:, keep]
        return FZ(center=c, gens=gens, err=up(np.abs(r) * (2 * U)) + slack)

    def radius(self) -> np.ndarray:
        """An upper bound of the half-widths."""
        return add_up(sum_up(np.abs(self.gens), axis=1), self.err) if self.gens.shape[1] else self.err.copy()

    def magnitude(self) -> np.ndarray:
        """An upper bound of ``|x|`` over the set."""
        return add_up(np.abs(self.center), self.radius())

    def hull(self) -> tuple[np.ndarray, np.ndarray]:
        """``lo <= x <= hi`` over the set (outward)."""
        r = self.radius()
        return down(self.center - r), up(self.center + r)

    def mapped(self, phi: tuple[np.ndarray, np.ndarray], shift: tuple[np.ndarray, np.ndarray] | None,
               carry: bool = True) -> "FZ":
        """``[Φm ± Φr] Z + shift`` (see the module); ``shift`` ``None``: zero.  ``carry=False`` leaves the mapped error
        ``Φm ε`` out of the error box, which then holds only the step's fresh error ``f`` (``ε' = Φm ε + f``,
        bounded elsewhere: :mod:`analysis.reach.recheck_modal`)."""
        pm, pr = phi
        c, rc = point_product(pm, self.center)
        err = add_up(rc, nn_up(pr, self.magnitude()))
        if carry:
            err = add_up(err, nn_up(np.abs(pm), self.err))
        if shift is not None:
            c2 = c + shift[0]
            err = add_up(err, shift[1], up(np.abs(c2) * (2 * U)), TINY)
            c = c2
        if self.gens.shape[1]:
            g, rg = point_product(pm, self.gens)
            err = add_up(err, sum_up(rg, axis=1))
        else:
            g = self.gens.copy()
        return FZ(center=c, gens=g, err=err)

    def plus(self, other: "FZ") -> "FZ":
        """The Minkowski sum (generators side by side)."""
        c = self.center + other.center
        return FZ(center=c, gens=np.hstack([self.gens, other.gens]),
                  err=add_up(self.err, other.err, up(np.abs(c) * (2 * U)), TINY))

    def exact(self) -> tuple[list[Fraction], list[list[Fraction]]]:
        """``(center, generator columns)`` in exact rationals, the error box as diagonal generators."""
        n = self.center.size
        cols = [[Fraction(float(v)) for v in self.gens[:, j]] for j in range(self.gens.shape[1])]
        cols += [[Fraction(float(e)) if i == k else Fraction(0) for i in range(n)] for k, e in enumerate(self.err) if e]
        return [Fraction(float(v)) for v in self.center], cols


def tube(z0: FZ, z1: FZ, enc: ExpEnclosure) -> FZ:
    """A zonotope holding every solution from ``z0`` over ``[0, δ]`` given ``z1 = Φ z0 + v`` (same weights)."""
    c = (z0.center + z1.center) * 0.5
    gsum = (z0.gens + z1.gens) * 0.5
    gdiff = (z0.gens - z1.gens) * 0.5
    cd = ((z0.center - z1.center) * 0.5).reshape(-1, 1)
    absg = add_up(sum_up(np.abs(z0.gens), axis=1), sum_up(np.abs(z1.gens), axis=1)) if z0.gens.shape[1] else 0.0
    rounding = up(add_up(np.abs(z0.center), np.abs(z1.center), up(absg * 2.0)) * (2 * U) + 4 * TINY)
    err = add_up(np.maximum(z0.err, z1.err), rounding, interpolation(z0, enc))
    return FZ(center=c, gens=np.hstack([gsum, cd, gdiff]), err=err)


def interpolation(z: FZ, enc: ExpEnclosure) -> np.ndarray:
    """``Σ_k |powers_k x̂| + rest |x̂|`` bounded over ``x̂ = (x, s)``, ``x ∈ z`` (first ``n`` rows)."""
    n = z.center.size
    cols = np.zeros((n + 1, z.gens.shape[1] + 1))
    cols[:n, 0] = z.center
    cols[n, 0] = enc.scale
    cols[:n, 1:] = z.gens
    mag = np.append(z.magnitude(), enc.scale)
    err = np.append(z.err, 0.0)
    total = nn_up(enc.rest, mag)
    for pm, pr in enc.powers:
        y, ry = point_product(pm, cols)
        total = add_up(total, sum_up(up(np.abs(y) + ry), axis=1), nn_up(np.abs(pm), err), nn_up(pr, mag))
    return total[:n]


def exact_image(matrix: Any, offset: Any, lo: list[Fraction], hi: list[Fraction]) -> FZ:
    """The exact image ``R box + r`` (rationals) as an :class:`FZ` (floats, the roundings in the error box)."""
    n = len(matrix)
    mid = [(a + b) / 2 for a, b in zip(lo, hi)]
    rad = [(b - a) / 2 for a, b in zip(lo, hi)]
    center = [sum((row[k] * mid[k] for k in range(len(mid)) if row[k]), Fraction(0)) + offset[i]
              for i, row in enumerate(matrix)]
    cols = [[matrix[i][k] * rad[k] for i in range(n)] for k in range(len(rad)) if rad[k]]
    err = [Fraction(0)] * n
    cf = []
    for i, v in enumerate(center):
        f = Fraction(float(v))
        err[i] += abs(v - f)
        cf.append(float(f))
    gens = np.zeros((n, len(cols)))
    for j, col in enumerate(cols):
        for i, v in enumerate(col):
            f = Fraction(float(v))
            err[i] += abs(v - f)
            gens[i, j] = float(f)
    errf = np.array([float(e) for e in err])
    errf = np.where(np.array([Fraction(float(e)) < e for e in err]), up(errf), errf)
    return FZ(center=np.array(cf), gens=gens[:, np.any(gens != 0, axis=0)] if cols else gens, err=errf)
