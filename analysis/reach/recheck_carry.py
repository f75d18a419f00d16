"""The re-check's carried inputs ``S_{k+1} = S_k ⊕ P_k``, reduced without moving their columns (no engine code).

The own re-check (:mod:`analysis.reach.recheck_own`) adds its mapped one-step input set ``P_k`` to the carried sum
each step.  Beyond ``keep`` generators per state the smallest (Girard's cost ``‖g‖₁ − ‖g‖∞``) are boxed: the box
of their absolute sums, rounded up, joins the error box (a superset).  The survivors keep their indices and the
surviving new generators fill the freed ones, so consecutive pieces hold the same generators at the same indices:
the union of the pieces that meet a guard (:mod:`analysis.reach.recheck_jumps`, which pairs columns by index) then
only boxes what changed between them.  Removing the boxed columns and shifting the rest (the former rule) paired
unrelated columns there.
"""

from __future__ import annotations

import numpy as np

from .recheck_interval import add_up, sum_up
from .recheck_sets import FZ

__all__ = ["carry", "KEPT_INPUTS", "KEPT_JUMP_INPUTS"]

KEPT_INPUTS = 20
"""Generators of the carried inputs per state (the last slot's worth for the box) in a mode without transitions."""
KEPT_JUMP_INPUTS = 80
"""The same in a mode with outgoing transitions: the carried inputs enter its own zonotope jump sets, and a boxed
generator mapped by the target's flow loses its correlations (the platoon PLAD01-BND30 needed more than 20)."""


def carry(s_gens: np.ndarray, s_box: np.ndarray, p: FZ, keep: int) -> tuple[np.ndarray, np.ndarray]:
    """``S_{k+1} = S_k ⊕ P_k`` with at most ``(keep − 1) n`` generators (``n`` states) and its error box.

    Parameters
    ----------
    s_gens : ndarray, shape (n, k)
    s_box : ndarray, shape (n,)
        ``S_k = s_gens ξ ⊕ [−s_box, s_box]``.
    p : FZ
        ``P_k`` (zero centre).
    keep : int
        ``>= 1``: generators per state.

    Returns
    -------
    (ndarray, ndarray)
        The generators (survivors at their indices while the count does not shrink) and the error box.
    """
    n = s_box.size
    limit = (keep - 1) * n
    k = s_gens.shape[1]
    gens = np.hstack([s_gens, p.gens])
    box = add_up(s_box, p.err)
    if gens.shape[1] <= limit:
        return gens, box
    absg = np.abs(gens)
    drop = np.argsort(absg.sum(axis=0) - absg.max(axis=0), kind="stable")[:gens.shape[1] - limit]
    box = add_up(box, sum_up(absg[:, drop], axis=1))
    alive = np.ones(gens.shape[1], dtype=bool)
    alive[drop] = False
    freed = np.flatnonzero(~alive[:k])
    fresh = np.flatnonzero(alive[k:]) + k
    fill = min(freed.size, fresh.size)
    out = s_gens.copy()
    out[:, freed[:fill]] = gens[:, fresh[:fill]]
    if fill < freed.size:
        out = np.delete(out, freed[fill:], axis=1)
    return np.hstack([out, gens[:, fresh[fill:]]]), box
