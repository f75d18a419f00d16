"""The flowpipe's accumulated input term ``Σ_{j<k} Φ^j V``, reduced without moving its columns.

The input sum of the flowpipe (:mod:`analysis.reach.flowpipe`) grows by the mapped one-step set each step and is
reduced by Girard's method (HSCC 2005, §3.4): the generators with the smallest ``‖g‖₁ − ‖g‖∞`` are replaced by the
box of their absolute sums (an over-approximation).  :func:`analysis.reach.zonotope.reduce_order` keeps the survivors
in their order and removes the boxed ones, so a column's index changes whenever one before it is boxed.  Consecutive
segments then hold the same generators at different indices, and the union of the segments that meet a guard
(:func:`analysis.reach.jumpsets.union_hull`, which pairs columns by index) averages unrelated columns: the zonotope
jump set of the platoon PLAD01 came out twice as wide as the box route's and was dropped (docs/reachability.md,
"Zonotope jump sets").  Here the boxed generators are removed from the same ranking, but the survivors keep their
slots and the surviving new generators fill the freed ones, so two consecutive sums differ only in the slots that
changed.  The set is the same as Girard's (same ranking, same box): only the column order differs.
"""

from __future__ import annotations

import numpy as np

from .zonotope import upper

__all__ = ["add_in_place"]


def add_in_place(kept: np.ndarray, box: np.ndarray, new: np.ndarray, limit: int) -> tuple[np.ndarray, np.ndarray]:
    """``kept ⊕ new ⊕ [−box, box]`` with at most ``limit`` generators besides the box (module docstring).

    Parameters
    ----------
    kept : ndarray, shape (n, k)
        The sum's generators so far.
    box : ndarray, shape (n,)
        ``>= 0``: the box of the generators boxed so far.
    new : ndarray, shape (n, q)
        The generators to add.
    limit : int
        ``>= 0``: the most generators kept (the smallest by Girard's cost are boxed beyond).

    Returns
    -------
    (ndarray of shape (n, <= limit), ndarray of shape (n,))
        The generators, survivors of ``kept`` at their indices (while the count does not shrink), and the box (the
        absolute sums of the boxed generators added, rounded up).
    """
    k = kept.shape[1]
    every = np.hstack([kept, new])
    total = every.shape[1]
    if total <= limit:
        return every, box
    absg = np.abs(every)
    cost = absg.sum(axis=0) - absg.max(axis=0)
    boxed = np.argsort(cost, kind="stable")[: total - max(limit, 0)]
    box = upper(box + absg[:, boxed].sum(axis=1), boxed.size + 1)
    alive = np.ones(total, dtype=bool)
    alive[boxed] = False
    freed = np.flatnonzero(~alive[:k])
    fresh = np.flatnonzero(alive[k:]) + k
    fill = min(freed.size, fresh.size)
    out = kept.copy()
    out[:, freed[:fill]] = every[:, fresh[:fill]]
    if fill < freed.size:  # fewer new survivors than freed slots: the rest of the freed slots go
        out = np.delete(out, freed[fill:], axis=1)
    if fill < fresh.size:
        out = np.hstack([out, every[:, fresh[fill:]]])
    return out, box
