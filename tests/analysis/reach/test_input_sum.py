"""Input sums reduced in place (analysis.reach.input_sum; the re-check's own analysis.reach.recheck_carry) and the
aligned fold of zonotope jump sets (analysis.reach.jumpsets.fold).

Yardsticks: the unreduced sum itself (its support in any direction ``ℓ`` is ``Σ |ℓ·g|``, exact up to rounding), and
sampled points of the folded parts with membership by a linear program (``zonotope_contains``).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.reach.input_sum import add_in_place
from analysis.reach.jumpsets import fold, paired_fold
from analysis.reach.recheck_carry import carry
from analysis.reach.recheck_sets import FZ
from analysis.reach.result import zonotope_contains
from analysis.reach.zonotope import Zonotope, reduce_order


def _stream(seed: int, steps: int = 40, n: int = 4, q: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    phi = np.eye(n) + 0.05 * rng.normal(size=(n, n))
    v = rng.normal(size=(n, q))
    out = []
    for _ in range(steps):
        out.append(v.copy())
        v = phi @ v
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_the_in_place_sum_holds_the_whole_sum_and_is_girards_set_on_the_axes(seed):
    n, limit = 4, 12
    gens, box = np.zeros((n, 0)), np.zeros(n)
    girard = Zonotope(center=np.zeros(n), generators=np.zeros((n, 0)))
    every = []
    rng = np.random.default_rng(seed + 10)
    for new in _stream(seed):
        before = gens.copy()
        gens, box = add_in_place(gens, box, new, limit)
        girard = reduce_order(Zonotope(center=np.zeros(n), generators=np.hstack([girard.generators, new])),
                              (limit + n) // n)
        every.append(new)
        assert gens.shape[1] <= limit
        if before.shape[1] == limit:  # saturated: a kept column stays at its index
            same = [j for j in range(limit) if np.array_equal(before[:, j], gens[:, j])]
            assert len(same) >= limit - new.shape[1]
        whole = np.hstack(every)
        for ell in [*np.eye(n), *rng.normal(size=(6, n))]:
            exact = np.abs(ell @ whole).sum()
            ours = np.abs(ell @ gens).sum() + np.abs(ell) @ box
            assert ours >= exact * (1 - 1e-12)
        # on the axes the box reduction is exact: the same support as the unreduced sum and as Girard's
        axis = np.abs(gens).sum(axis=1) + box
        assert np.allclose(axis, np.abs(whole).sum(axis=1), rtol=1e-9)
        assert np.allclose(axis, np.abs(girard.generators).sum(axis=1), rtol=1e-9)


@pytest.mark.parametrize("seed", [2, 3])
def test_the_recheck_carry_holds_the_whole_sum_and_keeps_slots(seed):
    n, keep = 4, 4
    gens, box = np.zeros((n, 0)), np.zeros(n)
    every = []
    rng = np.random.default_rng(seed + 10)
    for new in _stream(seed):
        before = gens.copy()
        p = FZ(center=np.zeros(n), gens=new, err=np.full(n, 1e-9))
        gens, box = carry(gens, box, p, keep)
        every.append(new)
        assert gens.shape[1] <= (keep - 1) * n
        if before.shape[1] == (keep - 1) * n:
            same = [j for j in range(gens.shape[1]) if np.array_equal(before[:, j], gens[:, j])]
            assert len(same) >= before.shape[1] - new.shape[1]
        whole = np.hstack(every)
        for ell in [*np.eye(n), *rng.normal(size=(6, n))]:
            assert np.abs(ell @ gens).sum() + np.abs(ell) @ box >= np.abs(ell @ whole).sum() * (1 - 1e-12)


@pytest.mark.parametrize("seed", [4, 5])
def test_the_fold_holds_every_part_and_pairs_their_columns(seed):
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(3, 6))
    parts = [Zonotope(center=0.1 * k + rng.normal(size=3) * 0.01, generators=base + 0.01 * rng.normal(size=(3, 6)))
             for k in range(3)]
    kept, both = None, None
    for part in parts:
        kept = paired_fold(kept, part)
        both = fold(both, part, 2)
    for part in parts:
        for xi in rng.uniform(-1, 1, size=(200, 6)):
            x = part.center + part.generators @ xi
            assert zonotope_contains(kept, x, tol=1e-9)
            assert zonotope_contains(both.paired, x, tol=1e-9) and zonotope_contains(both.reduced, x, tol=1e-9)
    assert both.reduced.order <= 2 * 3 and np.array_equal(both.paired.generators, kept.generators)
    # columns paired by index: the fold is about as wide as one part (the differences are small), where a union
    # that pairs unrelated columns would add up both
    width = np.abs(kept.generators).sum(axis=1)
    one = np.abs(base).sum(axis=1)
    assert np.all(width <= one + 0.1 + 0.1 * 3 * 6)
    shuffled = paired_fold(parts[0], Zonotope(center=parts[1].center, generators=parts[1].generators[:, ::-1]))
    assert np.abs(shuffled.generators).sum(axis=1).sum() > width.sum()
