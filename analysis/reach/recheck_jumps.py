"""The independent re-check's own zonotope jump sets, in exact rationals (no code shared with the producer).

The re-check (:mod:`analysis.reach.recheck_own`) collects, per transition, the pieces of its own tube that may
meet the guard.  When they are few (:data:`OWN_JUMP_PIECES`) and the guard ∩ invariant is one polyhedron, the
jump set is kept as a zonotope rather than as the box hull (which loses the correlations of coupled states):

1. each piece ``Z = c + Σ g_j ξ_j`` (its error box as generators, :meth:`FZ.exact`) is cut by each row
   ``a·x <= b`` of the polyhedron (paired with a row ``−a·x <= b'``): with ``s = a·x ∈ [lo, hi]`` (the exact range
   of ``a·x`` over ``Z`` met with ``[−b', b]``), ``m = (lo + hi)/2``, ``r = (hi − lo)/2`` and *any* ``λ``, every
   ``x ∈ Z`` with ``a·x ∈ [lo, hi]`` is ``x + λ(s − a·x) = c + λ(m − a·c) + Σ (g_j − λ a·g_j) ξ_j + λ r η`` with
   ``η = (s − m)/r ∈ [−1, 1]`` — a superset of ``Z ∩ {a·x <= b}``, computed in exact rationals (``λ`` a float
   suggestion read exactly: any value is sound);
2. the parts' union: ``Z₁ ∪ Z₂ ⊆ (c₁ + c₂)/2 + (c₁ − c₂)/2 μ + Σ ((g₁_j + g₂_j)/2 ξ_j + (g₁_j − g₂_j)/2 ζ_j)``
   (zero columns appended to the narrower; ``μ = ±1``, ``ζ = ±ξ`` give ``Z₁`` and ``Z₂``), exact — or, paired, the
   differences boxed (:func:`_paired_union`), which keeps the mean columns paired with the next piece's; the paired
   one is used unless its image is wider (:data:`PAIRED_WIDER`);
3. the reset ``R x + r`` applied exactly to the centre and every column.

Between the steps the exact sets are rounded to floats, every rounding moved into the error box (rounded up), and
beyond :data:`OWN_JUMP_GENERATORS` generators per state the smallest are boxed (Girard's reduction: the box of their
absolute sums, rounded up) — each a superset.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .recheck_interval import up
from .recheck_sets import FZ

__all__ = ["OWN_JUMP_PIECES", "OWN_JUMP_GENERATORS", "PAIRED_WIDER", "own_jump_set", "box_rows"]

OWN_JUMP_PIECES = 32
"""A cluster of at most this many pieces meeting the guard gets a zonotope jump set; more keep the box route."""
OWN_JUMP_GENERATORS = 80
"""Generators per state kept in the jump set (the smallest boxed beyond)."""
PAIRED_WIDER = 0.01
"""The union with the differences boxed (columns paired: :func:`_paired_union`) is used unless its image's hull is
wider than that of the union with the differences kept (:func:`_spread_union`, reduced at each union) in some
coordinate by more than this fraction (plus 10⁻¹²): the gearbox GRBX01's oblique guards give cut pieces that differ
in every column (re-check margin 0.0357 with the paired union, 0.0393 with the other); the platoon's pieces differ
little column by column (its paired union decides PLAD01-BND30, the other misses)."""

Exact = tuple[list[Fraction], list[list[Fraction]]]


def _cut(z: Exact, rows: Sequence[Any]) -> Exact | None:
    """Part 1 of the module: ``None`` when the piece is shown outside a row."""
    center, gens = z
    done: list[tuple[Fraction, ...]] = []
    for row in rows:
        a = tuple(row.normal)
        if not any(a) or a in done:
            continue
        terms = [(i, v) for i, v in enumerate(a) if v]
        ac = sum((v * center[i] for i, v in terms), Fraction(0))
        w = [sum((v * g[i] for i, v in terms if g[i]), Fraction(0)) for g in gens]
        spread = sum((abs(x) for x in w), Fraction(0))
        lo, hi = ac - spread, ac + spread
        top, bottom = min(hi, row.offset), lo
        neg = tuple(-v for v in a)
        for other in rows:
            if tuple(other.normal) == neg:
                bottom = max(bottom, -other.offset)
        done.extend([a, neg])
        if bottom > top:
            return None
        if (bottom <= lo and top >= hi) or spread == 0:
            continue
        wf = np.array([float(x) for x in w])
        gf = np.array([[float(v) for v in g] for g in gens]).T
        lam_f = (gf @ wf) / float(wf @ wf)
        if not np.all(np.isfinite(lam_f)):
            continue
        lam = [Fraction(float(v)) for v in lam_f]
        m, r = (bottom + top) / 2, (top - bottom) / 2
        new_c = [c + li * (m - ac) for c, li in zip(center, lam)]
        new_g = [[gi - li * wj for gi, li in zip(g, lam)] for g, wj in zip(gens, w)]
        if r:
            new_g.append([li * r for li in lam])
        if _width(new_g) <= _width(gens):  # a cut that widens the hull (a near-degenerate λ) is not taken
            center, gens = new_c, new_g
    return center, gens


def _width(gens: Sequence[Sequence[Fraction]]) -> Fraction:
    """The hull's total width over 2 (exact)."""
    return sum((abs(v) for g in gens for v in g), Fraction(0))


@dataclass(frozen=True, kw_only=True, slots=True)
class _Row:
    """``normal·x <= offset`` (exact)."""

    normal: tuple[Fraction, ...]
    offset: Fraction


def box_rows(box: Sequence[tuple[Fraction, Fraction]]) -> list[Any]:
    """The rows ``x_i <= hi_i``, ``−x_i <= −lo_i`` of an exact box (a superset of the guard part, met too)."""
    n = len(box)
    out = []
    for i, (lo, hi) in enumerate(box):
        e = tuple(Fraction(int(k == i)) for k in range(n))
        out += [_Row(normal=e, offset=hi), _Row(normal=tuple(-v for v in e), offset=-lo)]
    return out


def _padded(a: Exact, b: Exact) -> tuple[Exact, Exact]:
    """The two zonotopes with as many generators each (zero columns appended)."""
    (c1, g1), (c2, g2) = a, b
    zero = [Fraction(0)] * len(c1)
    m = max(len(g1), len(g2))
    return (c1, g1 + [zero] * (m - len(g1))), (c2, g2 + [zero] * (m - len(g2)))


def _spread_union(a: Exact, b: Exact) -> Exact:
    """Part 2 of the module (exact), the differences kept as generators."""
    (c1, g1), (c2, g2) = _padded(a, b)
    center = [(x + y) / 2 for x, y in zip(c1, c2)]
    cols = [[(x - y) / 2 for x, y in zip(c1, c2)]]
    for p, q in zip(g1, g2):
        cols.append([(x + y) / 2 for x, y in zip(p, q)])
        cols.append([(x - y) / 2 for x, y in zip(p, q)])
    return center, cols


def _paired_union(a: Exact, b: Exact, box: list[Fraction]) -> tuple[Exact, list[Fraction]]:
    """Part 2 of the module (exact), the differences boxed: ``(Z₁ ⊕ [−e, e]) ∪ Z₂ ⊆ c̄ + Σ ḡ_j ξ_j ⊕ [−e', e']``,
    ``c̄ = (c₁ + c₂)/2``, ``ḡ_j = (g₁_j + g₂_j)/2``, ``e' = e + |c₁ − c₂|/2 + Σ_j |g₁_j − g₂_j|/2`` (a point
    ``c₁ + Σ g₁_j ξ_j`` is ``c̄ + Σ ḡ_j ξ_j + (c₁ − c̄) + Σ (g₁_j − ḡ_j) ξ_j``; the same for ``Z₂``).  The mean
    columns keep the indices of the pieces' (their carried inputs stay in their slots:
    :mod:`analysis.reach.recheck_carry`), so the next piece pairs with them again."""
    (c1, g1), (c2, g2) = _padded(a, b)
    center = [(x + y) / 2 for x, y in zip(c1, c2)]
    spread = [e + abs(x - y) / 2 for e, x, y in zip(box, c1, c2)]
    cols = []
    for p, q in zip(g1, g2):
        cols.append([(x + y) / 2 for x, y in zip(p, q)])
        for i, (x, y) in enumerate(zip(p, q)):
            if x != y:
                spread[i] += abs(x - y) / 2
    return (center, cols), spread


def _rounded(z: Exact, keep: int) -> FZ:
    """The exact set as an :class:`FZ` (each number rounded to the nearest float, the roundings in the error box),
    the smallest generators beyond ``keep`` boxed (Girard's reduction)."""
    center, gens = z
    n = len(center)
    err = [Fraction(0)] * n
    cf = np.zeros(n)
    for i, v in enumerate(center):
        cf[i] = float(v)
        err[i] += abs(v - Fraction(cf[i]))
    cols = [g for g in gens if any(g)]
    gf = np.zeros((n, len(cols)))
    for j, g in enumerate(cols):
        for i, v in enumerate(g):
            if v:
                gf[i, j] = float(v)
                err[i] += abs(v - Fraction(gf[i, j]))
    if len(cols) > keep:  # the boxed generators become diagonal generators (mapped as generators: no wrapping)
        cost = np.abs(gf).sum(axis=0) - np.abs(gf).max(axis=0)
        order = np.argsort(cost, kind="stable")
        drop = order[:len(cols) - keep + n]
        boxed = [sum((abs(Fraction(gf[i, j])) for j in drop), Fraction(0)) for i in range(n)]
        diag = np.zeros((n, n))
        for i, v in enumerate(boxed):
            diag[i, i] = float(v)
            if Fraction(diag[i, i]) < v:
                diag[i, i] = float(up(diag[i, i]))
        gf = np.hstack([gf[:, np.sort(order[len(cols) - keep + n:])], diag[:, np.diag(diag) > 0]])
    ef = np.array([float(e) for e in err])
    ef = np.where([Fraction(float(e)) < e for e in err], up(ef), ef)
    return FZ(center=cf, gens=gf, err=ef)


def own_jump_set(pieces: Sequence[FZ], rows: Sequence[Any], matrix: Sequence[Sequence[Fraction]],
                 offset: Sequence[Fraction], box: Sequence[tuple[Fraction, Fraction]] | None = None) -> FZ | None:
    """The re-check's zonotope jump set of a cluster, mapped by the reset (module); ``None``: every piece is shown
    outside the guard (the caller keeps its box route).

    Parameters
    ----------
    pieces : sequence of FZ
        The cluster's tube pieces (dimension ``n``).
    rows : sequence of halfspaces
        The guard ∩ the source's invariant (one polyhedron; exact ``normal`` and ``offset``).
    matrix, offset : exact rationals
        The reset ``R`` (``n × n``) and ``r``.
    box : list of (Fraction, Fraction) or None
        A box holding the guard part (the cluster's own box route): the set is cut by its faces too.

    Returns
    -------
    FZ or None
        A set holding the reset image of every state of the pieces in the rows.
    """
    n = len(matrix)
    keep = OWN_JUMP_GENERATORS * n
    parts = [part for part in (_cut(piece.exact(), rows) for piece in pieces) if part is not None]
    if not parts:
        return None
    union, spread = parts[0], [Fraction(0)] * n
    for part in parts[1:]:
        union, spread = _paired_union(union, part, spread)
    paired = _rounded((union[0], union[1] + [[v if i == k else Fraction(0) for i in range(n)]
                                             for k, v in enumerate(spread) if v]), keep)
    kept = _rounded(parts[0], keep)
    for part in parts[1:]:
        kept = _rounded(_spread_union(kept.exact(), _rounded(part, keep).exact()), keep)
    paired, kept = _finish(paired, matrix, offset, box, keep), _finish(kept, matrix, offset, box, keep)
    if paired is None or kept is None:
        return None  # the box's faces show the guard part empty
    plo, phi = paired.hull()
    klo, khi = kept.hull()
    return kept if bool(np.any(phi - plo > (khi - klo) * (1.0 + PAIRED_WIDER) + 1e-12)) else paired


def _finish(kept: FZ, matrix: Sequence[Sequence[Fraction]], offset: Sequence[Fraction],
            box: Sequence[tuple[Fraction, Fraction]] | None, keep: int) -> FZ | None:
    """The union cut by the faces of ``box`` (``None``: shown empty) and mapped by the exact reset."""
    if box is not None:  # the cluster's box holds the guard part too: cut by its faces (a superset still)
        met = _cut(kept.exact(), box_rows(box))
        if met is None:
            return None
        kept = _rounded(met, keep)
    center, gens = kept.exact()
    image_c = [sum((a * center[k] for k, a in enumerate(row) if a), Fraction(0)) + off
               for row, off in zip(matrix, offset)]
    image_g = [[sum((a * g[k] for k, a in enumerate(row) if a and g[k]), Fraction(0)) for row in matrix] for g in gens]
    return _rounded((image_c, image_g), keep)
