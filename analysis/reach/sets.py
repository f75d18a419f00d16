"""Halfspaces and polyhedra in floating point with their exactness accounted for; unsafe sets.

An exact rational halfspace ``a·x <= b`` (:class:`analysis.reach.affine.Halfspace`) becomes a
:class:`FloatHalfspace`: the float normal ``a_f`` nearest to ``a``, a residual ``r >= |a − a_f|``
(componentwise) and an offset ``b_hi >= b``.  Every test below is *conservative in the
direction that keeps the reachability sound*: a set is declared outside a halfspace only when
``min a·x > b`` is proven with rounding accounted for (:func:`definitely_outside`), and boxes are
clipped only by bounds proven to hold (:func:`clip_box`).

Examples
--------
>>> import numpy as np
>>> from fractions import Fraction
>>> from analysis.reach.affine import Halfspace
>>> h = to_float(Halfspace(normal=(Fraction(1), Fraction(0)), offset=Fraction(1)))
>>> lo, hi = clip_box(np.array([0.0, 0.0]), np.array([2.0, 2.0]), (h,))
>>> float(hi[0]) >= 1.0 and float(hi[0]) - 1.0 < 1e-14
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from hybrid.errors import ParameterError

from .affine import Halfspace, Polyhedron, condition_polyhedra
from .zonotope import UNIT_ROUNDOFF, Zonotope, from_box, gamma, magnitude, round_down, round_up, support_bounds, upper

__all__ = [
    "FloatHalfspace",
    "to_float",
    "polyhedra_to_float",
    "definitely_outside",
    "box_position",
    "clip_box",
    "tighten_box",
    "UnsafeSet",
    "unsafe_set",
    "separation",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class FloatHalfspace:
    """``a·x <= b`` with ``a ∈ [normal − residual, normal + residual]`` and ``b <= offset``."""

    normal: np.ndarray
    residual: np.ndarray
    offset: float
    text: str = ""


def _float_up(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) >= q else float(round_up(f))


def to_float(h: Halfspace) -> FloatHalfspace:
    """The float form of an exact halfspace (see the module docstring)."""
    normal = np.array([float(q) for q in h.normal])
    residual = np.array([_float_up(abs(q - Fraction(f))) for q, f in zip(h.normal, normal)])
    normal.setflags(write=False)
    residual.setflags(write=False)
    return FloatHalfspace(normal=normal, residual=residual, offset=_float_up(h.offset), text=h.text)


def polyhedra_to_float(polyhedra: Sequence[Polyhedron]) -> tuple[tuple[FloatHalfspace, ...], ...]:
    """Each polyhedron as a tuple of :class:`FloatHalfspace` (a disjunction of conjunctions)."""
    return tuple(tuple(to_float(h) for h in p.halfspaces) for p in polyhedra)


def definitely_outside(z: Zonotope, h: FloatHalfspace) -> bool:
    """Whether every point of ``z`` violates ``h`` (proven: ``min_z a·x > b``)."""
    lo, _ = support_bounds(z, h.normal, h.residual)
    return lo > h.offset


@dataclass(frozen=True, slots=True, eq=False)
class HalfspaceRows:
    """The rows of a conjunction of :class:`FloatHalfspace` stacked once (for the per-segment tests).

    Attributes
    ----------
    normals, residuals : ndarray, shape (k, n)
    offsets : ndarray, shape (k,)
    oblique : tuple of FloatHalfspace
        The halfspaces with more than one non-zero coefficient.
    """

    normals: np.ndarray
    residuals: np.ndarray
    offsets: np.ndarray
    oblique: tuple[FloatHalfspace, ...]
    abs_normals: np.ndarray
    abs_offsets: np.ndarray
    exact: bool  # every residual is zero (float normals)


def halfspace_rows(halfspaces: Sequence[FloatHalfspace]) -> HalfspaceRows:
    """The :class:`HalfspaceRows` of a non-empty conjunction."""
    normals = np.array([h.normal for h in halfspaces])
    residuals = np.array([h.residual for h in halfspaces])
    offsets = np.array([h.offset for h in halfspaces])
    return HalfspaceRows(normals=normals, residuals=residuals, offsets=offsets,
                         oblique=tuple(h for h in halfspaces if np.count_nonzero(h.normal) > 1),
                         abs_normals=np.abs(normals), abs_offsets=np.abs(offsets), exact=not np.any(residuals))


def box_position(lo: np.ndarray, hi: np.ndarray, halfspaces: Sequence[FloatHalfspace],
                 rows: HalfspaceRows | None = None) -> int:
    """Where the box ``[lo, hi]`` lies against the polyhedron: ``-1`` proven outside one halfspace,
    ``1`` proven inside every halfspace, ``0`` undecided (a cheap pre-test before the zonotope's).

    Per row, ``min/max a·x`` over the box are bounded as in :func:`clip_box` (the rounding of the sums
    and the residual of a non-float normal accounted for), so ``-1`` and ``1`` are proven.  ``rows``: the
    halfspaces already stacked (:func:`halfspace_rows`), to save the stacking on every call.
    """
    if not halfspaces:
        return 1
    if rows is None:
        rows = halfspace_rows(halfspaces)
    normals, offsets = rows.normals, rows.offsets
    n = normals.shape[1]
    a_lo, a_hi = normals * lo, normals * hi
    mins = np.minimum(a_lo, a_hi).sum(axis=1)
    maxs = np.maximum(a_lo, a_hi).sum(axis=1)
    mag = np.maximum(np.abs(lo), np.abs(hi))
    # max(|a lo|, |a hi|) = |a| max(|lo|, |hi|) exactly (rounding is monotone and symmetric)
    size = (rows.abs_normals * mag).sum(axis=1)
    spread = gamma(n + 2) * (size + rows.abs_offsets)
    slack = upper(spread if rows.exact else spread + rows.residuals @ mag, n + 4)
    if np.any(mins - slack > offsets):
        return -1
    if np.all(maxs + slack < offsets):  # strict: a rounded sum equal to the offset proves nothing
        return 1
    return 0


def clip_box(lo: np.ndarray, hi: np.ndarray, halfspaces: Sequence[FloatHalfspace]
             ) -> tuple[np.ndarray, np.ndarray] | None:
    """A box containing ``[lo, hi] ∩ {a·x <= b for each halfspace}``; ``None`` when that is proven empty.

    For each halfspace and each coordinate ``i`` with ``a_i != 0``:
    ``a_i x_i <= b + r·|x| − Σ_{j≠i} min(a_j x_j)``, every term bounded with its rounding.
    """
    lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
    for h in halfspaces:
        a = h.normal
        n = a.size
        mins = np.minimum(a * lo, a * hi)
        mag = np.maximum(np.abs(lo), np.abs(hi))
        slack = float(upper(gamma(n + 2) * (np.abs(mins).sum() + np.abs(h.offset)) + h.residual @ mag, n + 4))
        total = float(mins.sum())
        if total - slack > h.offset:
            return None
        for i in range(n):
            if a[i] == 0.0:
                continue
            room = h.offset - (total - mins[i]) + slack  # >= a_i x_i for every feasible x
            room = float(round_up(round_up(room)))
            if a[i] > 0:
                hi[i] = min(hi[i], float(round_up(round_up(room / a[i]))))
            else:
                lo[i] = max(lo[i], float(round_down(round_down(room / a[i]))))
        if np.any(lo > hi):
            return None
    return lo, hi


@dataclass(frozen=True, kw_only=True, slots=True)
class UnsafeSet:
    """A named unsafe set: a union of polyhedra ``{x : a_i·x >= … }`` written as ``a·x <= b`` rows.

    Attributes
    ----------
    name : str
    polyhedra : tuple of tuple of FloatHalfspace
        The set is the union of the polyhedra (each the conjunction of its halfspaces).
    modes : tuple of str or None
        Modes in which the set is unsafe (``None``: all).
    """

    name: str
    polyhedra: tuple[tuple[FloatHalfspace, ...], ...]
    modes: tuple[str, ...] | None = None


def unsafe_set(name: str, condition: object, state_names: Sequence[str], *,
               modes: Sequence[str] | None = None) -> UnsafeSet:
    """An :class:`UnsafeSet` from a symbolic condition over the state names (e.g. ``x.h >= 1.01``).

    Raises
    ------
    ParameterError
        ``name`` empty; :class:`~analysis.reach.affine.AffineError` when the condition is not affine.
    """
    if not isinstance(name, str) or not name:
        raise ParameterError("name", name, "a non-empty string", "name the unsafe set")
    polyhedra = condition_polyhedra(condition, tuple(state_names), role=f"unsafe set {name!r}")
    return UnsafeSet(name=name, polyhedra=polyhedra_to_float(polyhedra),
                     modes=None if modes is None else tuple(modes))


def _norm_bounds(h: FloatHalfspace) -> tuple[float, float]:
    low = np.maximum(np.abs(h.normal) - h.residual, 0.0)
    high = np.abs(h.normal) + h.residual
    return (float(round_down(math.sqrt(float(round_down(low @ low) * (1 - 4 * 2.0 ** -53))))),
            float(round_up(math.sqrt(float(upper(high @ high, h.normal.size + 1))))))


def separation(z: Zonotope, lo: np.ndarray, hi: np.ndarray, polyhedron: Sequence[FloatHalfspace]) -> float:
    """A signed separation between ``z ∩ [lo, hi]`` and a polyhedron ``{a_i·x <= b_i}``.

    Positive: a proven lower bound of the Euclidean distance (some halfspace ``i`` has
    ``min a_i·x > b_i`` over the set, and the distance to the polyhedron is at least the distance to
    that halfspace, ``(min a_i·x − b_i) / ‖a_i‖``).  Zero or negative: not separated by any single
    constraint; no claim is made (the value is the largest such normalised gap).
    """
    box = from_box(lo, hi)
    best = -math.inf
    for h in polyhedron:
        low_z, _ = support_bounds(z, h.normal, h.residual)
        low_b, _ = support_bounds(box, h.normal, h.residual)
        gap = float(round_down(max(low_z, low_b) - h.offset))
        n_low, n_high = _norm_bounds(h)
        if gap > 0:
            value = float(round_down(gap / n_high)) if n_high > 0 else math.inf
        else:
            value = gap / n_low if n_low > 0 else -math.inf
        best = max(best, value)
    return best


def _dual_bounds(z: Zonotope, directions: np.ndarray, halfspaces: Sequence[FloatHalfspace],
                 multipliers: np.ndarray) -> np.ndarray:
    """Rigorous upper bounds of ``max e_d·x`` over ``z ∩ {a_k·x <= b_k}``, one per row ``e_d`` of ``directions``
    (shape ``(p, n)``), from any multipliers ``λ_d >= 0`` (rows of ``multipliers``, shape ``(p, k)``); shape ``(p,)``.

    Weak duality: ``e·x <= (e − Σ λ_k a_k)·x + Σ λ_k b_k`` on the intersection, and the first term is
    bounded by the support of ``z`` in the direction ``e − Σ λ_k a_k`` (computed with its rounding, as in
    :func:`~analysis.reach.zonotope.support_bounds`, for all directions at once: every product is a float dot
    product of the same length, so Higham's ``γ`` bounds hold row by row).
    """
    lam = np.maximum(np.asarray(multipliers, dtype=float), 0.0)
    e = np.asarray(directions, dtype=float)
    normals = np.array([h.normal for h in halfspaces])
    residuals = np.array([h.residual for h in halfspaces])
    offsets = np.array([h.offset for h in halfspaces])
    d = e - lam @ normals
    k = len(halfspaces) + 2
    residual = upper(gamma(k) * (np.abs(e) + lam @ np.abs(normals)) + lam @ residuals, k + 2)
    n = z.dimension
    s = d @ z.center
    spread = np.abs(d @ z.generators).sum(axis=1)
    err = gamma(n) * (np.abs(d) @ (np.abs(z.center) + np.abs(z.generators).sum(axis=1))) + residual @ magnitude(z)
    width = upper(spread + err + UNIT_ROUNDOFF * np.abs(s), z.order + n + 4)
    top = round_up(round_up(s + width))
    shift = lam @ offsets
    err = upper(gamma(k) * (lam @ np.abs(offsets)), k)
    return round_up(round_up(top + shift + err + UNIT_ROUNDOFF * np.abs(top + shift)))


def _multipliers(c: np.ndarray, alpha: np.ndarray, beta: np.ndarray, sweeps: int = 4) -> np.ndarray:
    """Multipliers ``λ_d >= 0`` nearly minimising the dual ``λ·β + Σ_i |c_di − (αᵀλ)_i|`` (float, a suggestion),
    one row per objective ``c_d`` (``c`` of shape ``(p, m)``, the result ``(p, k)``).

    The dual of ``max c_d·ξ`` over ``ξ ∈ [-1, 1]^m``, ``α ξ <= β`` is convex and piecewise linear in ``λ``; each
    coordinate is minimised exactly in turn (:func:`_line_minimum`).  One row: exact.  Several: cyclic descent,
    which may stop above the optimum; any ``λ >= 0`` gives a valid bound.  All objectives are minimised at once.
    """
    c = np.atleast_2d(np.asarray(c, dtype=float))
    p = c.shape[0]
    k = alpha.shape[0]
    lam = np.zeros((p, k))
    resid = c.copy()
    rows = np.arange(p)[:, None]
    lines = []
    for j in range(k):
        # a row that every ξ satisfies (β_j >= ‖α_j‖₁) is redundant: λ_j = 0 loses nothing, and it is skipped
        nz = np.nonzero(alpha[j])[0] if beta[j] < np.abs(alpha[j]).sum() else np.zeros(0, dtype=int)
        lines.append((nz, alpha[j][nz], np.abs(alpha[j][nz])))
    for _ in range(sweeps if k > 1 else 1):
        before = lam.copy()
        for j in range(k):
            nz, a_nz, w = lines[j]
            if nz.size == 0:
                continue  # λ_j = 0: the row does not depend on ξ, or it is redundant
            old = lam[:, j].copy()
            lam[:, j] = _line_minimum(resid[:, nz] + a_nz * old[:, None], a_nz, w, beta[j], rows)
            resid[:, nz] += a_nz * (old - lam[:, j])[:, None]
        if np.array_equal(lam, before):  # no multiplier moved in a whole sweep: the descent has settled
            break
    return lam


def _line_minimum(r: np.ndarray, a: np.ndarray, w: np.ndarray, beta: float, rows: np.ndarray) -> np.ndarray:
    """Per row of ``r`` (shape ``(p, m)``), a minimiser over ``λ >= 0`` of ``λ β + Σ_i |r_i − λ a_i|``, shape ``(p,)``
    (``a`` without zeros, ``w = |a|``, ``rows`` the column of row indices).

    The function is convex and piecewise linear with breakpoints ``b_i = r_i / a_i``: its right slope at 0 is
    ``β + Σ_{b_i <= 0} w_i − Σ_{b_i > 0} w_i`` and grows by ``2 w_i`` past each positive ``b_i``; the minimiser is 0
    when that slope is ``>= 0``, else the first positive breakpoint (in increasing order, by sorting) where it becomes
    ``>= 0``, else (unbounded below: the linear program is infeasible) the largest breakpoint.  A suggestion only
    (floats; :func:`_dual_bounds` is valid for any ``λ >= 0``; a NaN there only loosens the box, see
    :func:`tighten_box`).
    """
    b = r / a
    positive = b > 0.0
    key = np.where(positive, b, np.inf)
    slope0 = beta + w.sum() - 2.0 * (positive @ w)
    order = np.argsort(key, axis=1)
    bs = key[rows, order]
    finite = bs < np.inf
    ok = (slope0[:, None] + 2.0 * np.cumsum(np.where(finite, w[order], 0.0), axis=1) >= 0.0) & finite
    first = np.argmax(ok, axis=1)
    flat = rows[:, 0]
    lam = np.where(ok[flat, first], bs[flat, first], np.where(positive, b, 0.0).max(axis=1))
    return np.where(slope0 >= 0.0, 0.0, lam)


def tighten_box(z: Zonotope, lo: np.ndarray, hi: np.ndarray, halfspaces: Sequence[FloatHalfspace]
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """A box containing ``z ∩ [lo, hi] ∩ {a_k·x <= b_k}``, tighter than :func:`clip_box` (``None``: empty).

    After :func:`clip_box`, each bound ``max/min x_i`` over ``z ∩ {halfspaces}`` is bounded by
    :func:`_dual_bounds` with multipliers from :func:`_multipliers` (exact coordinate descent on the dual of the
    linear program, cheaper than a solver call): the multipliers are only a suggestion, the bound is valid for
    any of them, so an inexact choice can only make it looser, never wrong.
    """
    box = clip_box(lo, hi, halfspaces)
    if box is None or not halfspaces or z.order == 0:
        return box
    lo, hi = box
    g = z.generators
    normals = np.array([h.normal for h in halfspaces])
    offsets = np.array([h.offset for h in halfspaces])
    alpha = normals @ g
    beta = offsets - normals @ z.center
    n = z.dimension
    directions = np.vstack([np.eye(n), -np.eye(n)])  # +e_i (upper bounds), then -e_i (lower bounds)
    lam = _multipliers(directions @ g, alpha, beta)
    bounds = _dual_bounds(z, directions, halfspaces, lam)
    hi = np.fmin(hi, bounds[:n])  # a NaN bound (never expected) leaves the clipped box as it is
    lo = np.fmax(lo, -bounds[n:])
    if np.any(lo > hi):
        return None
    return lo, hi
