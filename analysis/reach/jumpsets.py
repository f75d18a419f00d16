"""Zonotope jump sets: the guard part of a few segments kept as a zonotope, mapped by the reset.

The engine (:mod:`analysis.reach.engine`) collects, per transition, the segments that may meet its guard.  Their
box hull loses the correlations of the coupled states at the switch; when the segments are few
(:data:`JUMP_ZONOTOPES`), the jump set is kept as a zonotope instead:

1. **Guard part** (:func:`strip_meet`).  For a row ``a·x <= b`` of the guard ∩ invariant (paired with a row
   ``−a·x <= b'`` when there is one) the values ``s = a·x`` over ``Z ∩ guard`` lie in a strip
   ``[m − r, m + r]`` (``m ± r`` holds ``[max(min_Z a·x, −b'), min(max_Z a·x, b)]``, rigorous bounds).  For
   *any* vector ``λ``, every ``x = c + Gξ`` of ``Z`` with ``a·x = s`` satisfies
   ``x = x + λ (s − a·x) = (I − λ aᵀ) x + λ s``, so ``Z ∩ strip ⊆ (I − λ aᵀ) Z ⊕ λ [m − r, m + r]``
   (Girard and Le Guernic, "Zonotope/hyperplane intersection for hybrid systems reachability analysis",
   HSCC 2008, with a strip instead of a hyperplane).  ``λ = G Gᵀ a / (aᵀ G Gᵀ a)`` makes ``a·x`` of the result
   exactly the strip (``aᵀ λ = 1``).  The matrix ``I − λ aᵀ`` is computed in floats and applied as an interval
   matrix (its rounding as the radius), the shift's roundings join an error box: the result is a superset.
   A row whose normal is not a float (a residual) is not intersected (a superset still).
2. **Union** (:func:`union_hull`).  ``Z₁ ∪ Z₂ ⊆ (c₁ + c₂)/2 + (c₁ − c₂)/2 μ + (G₁ + G₂)/2 ξ + (G₁ − G₂)/2 ζ``
   for any ``G₁, G₂`` of the same width (zero columns appended to the narrower): ``μ = 1, ζ = ξ`` gives
   ``Z₁``, ``μ = −1, ζ = −ξ`` gives ``Z₂``.  Roundings (``<= 2u`` of each entry) join an error box.  Of a cluster
   two folds are kept (:class:`JumpFold`): the paired one boxes everything after the mean columns, which then stay
   paired with the next part's (:func:`paired_fold`), the reduced one keeps the whole union reduced to the run's
   order; the engine takes the paired one unless it is too wide.
3. **Reset** (:func:`reset_image`).  The affine reset ``R x + r`` as an interval-matrix map of the augmented
   zonotope (``R``, ``r`` exact rationals, their float roundings as the radius,
   :func:`analysis.reach.zonotope.linear_map`).  The image keeps the columns of the jump set one for one
   (``c₂ = fl(R c + r)``, ``G₂ = fl(R G)``) and a box ``d`` bounding every rounding: for the exact image
   ``c₁ = R c + r``, ``G₁ = R G``, ``|c₁ − c₂| + Σ_j |G₁_j − G₂_j| <= d`` — what the re-check's well-formedness
   test checks in exact rationals (:mod:`analysis.reach.recheck_schedule`).

Every step over-approximates; none under-approximates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .sets import FloatHalfspace
from .zonotope import (UNIT_ROUNDOFF, Zonotope, box_generators, interval_hull, linear_map, reduce_order,
                       support_bounds, upper, with_error)

__all__ = ["JUMP_ZONOTOPES", "JUMP_ORDER", "strip_meet", "union_hull", "reset_image", "ResetImage", "JumpFold",
           "paired_fold", "fold", "reduce_jump", "meet_box"]

JUMP_ZONOTOPES = 8
"""A jump set of at most this many segments is kept as a zonotope (their union); more: the box hull."""
JUMP_ORDER = 80
"""Generators per state kept in a jump set (Girard's reduction of the folded guard parts, once, before the reset) and
in the input sum of a mode that may jump (:mod:`analysis.reach.input_sum`): the target's flowpipe never reduces its
start set again, so the cap bounds a chain of jumps (unbounded, the thermostat over its rates doubled its generators
at each of its jumps until it ran out of memory)."""


def strip_meet(z: Zonotope, halfspaces: Sequence[Any]) -> Zonotope | None:
    """A zonotope holding ``z ∩ {a·x <= b for each halfspace}`` (module, part 1); ``None``: proven empty.

    Parameters
    ----------
    z : Zonotope
        Dimension ``n``.
    halfspaces : sequence of analysis.reach.sets.FloatHalfspace
        One polyhedron (a conjunction).

    Returns
    -------
    Zonotope or None
        Dimension ``n``; ``z`` itself when no row cuts it.
    """
    done: list[np.ndarray] = []
    for h in halfspaces:
        a = h.normal
        if np.any(h.residual) or not np.any(a) or any(np.array_equal(a, d) for d in done):
            continue
        low, high = support_bounds(z, a)
        if low > h.offset:
            return None
        top, bottom = min(high, h.offset), low
        for o in halfspaces:  # a paired row −a·x <= b' bounds a·x from below by −b' (b' an upper bound: weaker)
            if not np.any(o.residual) and np.array_equal(o.normal, -a):
                bottom = max(bottom, -o.offset)
        done.extend([a, -a])
        if bottom > top:
            return None
        if bottom <= low and top >= high:
            continue  # the strip holds z: nothing to cut
        cut = _cut(z, a, bottom, top)
        if cut is not None and _width(cut) <= _width(z):
            z = cut  # a cut that widens the hull (a near-degenerate λ) is not taken: z itself is a superset too
    return z


def _width(z: Zonotope) -> float:
    lo, hi = interval_hull(z)
    return float(np.sum(hi - lo))


def _cut(z: Zonotope, a: np.ndarray, bottom: float, top: float) -> Zonotope | None:
    """``(I − λ aᵀ) z ⊕ λ [bottom, top]`` (module, part 1) with every rounding in an error box; ``None``: no
    usable ``λ`` (``a·x`` constant over the generators, or not finite) — the caller keeps ``z``."""
    g = z.generators
    w = g.T @ a
    norm = float(w @ w)
    if not np.isfinite(norm) or norm <= 0.0:
        return None
    lam = (g @ w) / norm
    if not np.all(np.isfinite(lam)):
        return None
    n = a.size
    outer = np.outer(lam, a)
    p = np.eye(n) - outer
    # |(δ_ij − λ_i a_j) − fl(δ_ij − fl(λ_i a_j))| <= u |λ_i a_j| + u |fl(...)| (one product, one difference)
    pr = upper(UNIT_ROUNDOFF * (np.abs(outer) + np.abs(p)), 3)
    image, err = linear_map(z, p, pr)
    mid = 0.5 * bottom + 0.5 * top
    radius = float(np.nextafter(np.nextafter(max(top - mid, mid - bottom), np.inf), np.inf))
    shift = lam * mid
    spread = lam * radius
    center = image.center + shift
    err = err + upper(UNIT_ROUNDOFF * (np.abs(shift) + np.abs(spread) + np.abs(center)), 4)
    gens = [image.generators, spread.reshape(-1, 1)] if radius > 0 else [image.generators]
    out = Zonotope.of_arrays(center, np.hstack([*gens, box_generators(upper(err, 2))]))
    return out if out.is_finite() else None


def union_hull(first: Zonotope, second: Zonotope) -> Zonotope:
    """A zonotope holding ``first ∪ second`` (module, part 2), with ``2m + 1`` generators plus an error box."""
    g1, g2 = first.generators, second.generators
    m = max(g1.shape[1], g2.shape[1])
    n = first.dimension
    g1 = np.hstack([g1, np.zeros((n, m - g1.shape[1]))])
    g2 = np.hstack([g2, np.zeros((n, m - g2.shape[1]))])
    mean_c = (first.center + second.center) * 0.5
    half_c = (first.center - second.center) * 0.5
    mean_g = (g1 + g2) * 0.5
    half_g = (g1 - g2) * 0.5
    rounding = upper(2.0 * UNIT_ROUNDOFF * (np.abs(mean_c) + np.abs(half_c) + np.abs(mean_g).sum(axis=1)
                                           + np.abs(half_g).sum(axis=1)), 2 * m + 4)
    return Zonotope.of_arrays(mean_c, np.hstack([mean_g, half_c.reshape(-1, 1), half_g, box_generators(rounding)]))


@dataclass(frozen=True, kw_only=True, slots=True)
class ResetImage:
    """A reset's image of a zonotope jump set: ``start = center + generators ξ ⊕ [−box, box]`` (module, part 3).

    Attributes
    ----------
    before : Zonotope
        The jump set in the source (dimension ``n``).
    center : ndarray, shape (n,)
    generators : ndarray, shape (n, m)
        Column ``j`` is the float image of column ``j`` of ``before``.
    box : ndarray, shape (n,)
        Bounds every rounding and the reset's conversion to floats.
    """

    before: Zonotope
    center: np.ndarray
    generators: np.ndarray
    box: np.ndarray

    def start(self) -> Zonotope:
        """The start set of the target's flowpipe."""
        return with_error(Zonotope.of_arrays(self.center, self.generators), self.box)

    def hull(self) -> tuple[np.ndarray, np.ndarray]:
        """Outward bounds of :meth:`start`."""
        return interval_hull(self.start())


def reset_image(before: Zonotope, matrix: Sequence[Sequence[Fraction]], offset: Sequence[Fraction]) -> ResetImage:
    """The image of ``before`` under ``x ↦ R x + r`` (exact rationals ``R``, ``r``), module part 3."""
    n = before.dimension
    rc = np.array([[float(q) for q in row] + [float(off)] for row, off in zip(matrix, offset)]
                  + [[0.0] * n + [1.0]])
    rr = np.zeros_like(rc)
    for i, row in enumerate(matrix):
        for j, q in enumerate([*row, offset[i]]):
            rr[i, j] = float(np.nextafter(float(abs(q - Fraction(rc[i, j]))), np.inf))
    aug = Zonotope.of_arrays(np.append(before.center, 1.0), np.vstack([before.generators, np.zeros((1, before.order))]))
    image, err = linear_map(aug, rc, rr)
    return ResetImage(before=before, center=image.center[:n].copy(), generators=image.generators[:n].copy(),
                      box=err[:n].copy())


def meet_box(z: Zonotope, lo: np.ndarray, hi: np.ndarray) -> Zonotope | None:
    """A zonotope holding ``z ∩ [lo, hi]``: :func:`strip_meet` with the rows ``±x_i <= ±bound`` of the coordinates
    where the hull of ``z`` exceeds the box (``None``: proven empty)."""
    zlo, zhi = interval_hull(z)
    n = z.dimension
    rows = []
    zero = np.zeros(n)
    excess = np.maximum(lo - zlo, 0.0) + np.maximum(zhi - hi, 0.0)
    for i in np.nonzero(excess > 1e-6 * (zhi - zlo))[0]:  # a rounding-level excess is not worth a cut
        e = np.zeros(n)
        e[i] = 1.0
        rows += [FloatHalfspace(normal=e, residual=zero, offset=float(hi[i])),
                 FloatHalfspace(normal=-e, residual=zero, offset=float(-lo[i]))]
    return strip_meet(z, rows) if rows else z


@dataclass(frozen=True, kw_only=True, slots=True)
class JumpFold:
    """Two folds of a cluster's guard parts, both holding their union (the jump picks one: :func:`reset_candidates`).

    Attributes
    ----------
    paired : Zonotope
        :func:`paired_fold`: the mean columns keep the parts' indices, their differences boxed.  Tight when the parts
        are consecutive segments that differ little column by column (the platoon's input sums).
    reduced : Zonotope
        :func:`union_hull` kept whole and reduced to the run's order (Girard) at each fold: the differences stay
        generators.  Tight when the cut parts differ in every column (oblique guards: the gearbox GRBX01).
    """

    paired: Zonotope
    reduced: Zonotope


def paired_fold(kept: Zonotope | None, part: Zonotope) -> Zonotope:
    """``kept ∪ part`` as one zonotope whose first columns stay paired with those of the parts (``part`` itself when
    ``kept`` is ``None``).

    :func:`union_hull` gives ``[(G₁+G₂)/2, (c₁−c₂)/2, (G₁−G₂)/2, rounding box]``; everything after the ``m`` mean
    columns (``m`` the wider part's count) is boxed (Girard's box of those columns, sound).  The mean columns keep the
    parts' indices, so the next part pairs with them again (consecutive segments hold the same generators at the
    same indices: :mod:`analysis.reach.input_sum`).  Nothing is reduced here: :func:`reduce_jump` caps the fold once.
    """
    if kept is None:
        return part
    union = union_hull(kept, part)
    m = max(kept.order, part.order)
    rest = union.generators[:, m:]
    return Zonotope.of_arrays(union.center, np.hstack(
        [union.generators[:, :m], box_generators(upper(np.abs(rest).sum(axis=1), rest.shape[1]))]))


def fold(kept: JumpFold | None, part: Zonotope, order: int) -> JumpFold:
    """Both folds of ``kept ∪ part`` (:class:`JumpFold`); the reduced one starts from ``part`` reduced to
    :data:`JUMP_ORDER` and reduces each union to ``order``."""
    if kept is None:
        return JumpFold(paired=part, reduced=reduce_order(part, max(order, JUMP_ORDER)))
    return JumpFold(paired=paired_fold(kept.paired, part), reduced=reduce_order(union_hull(kept.reduced, part), order))


def reduce_jump(z: Zonotope) -> Zonotope:
    """The folded jump set reduced to :data:`JUMP_ORDER` generators per state (Girard's reduction, sound)."""
    return reduce_order(z, JUMP_ORDER)
