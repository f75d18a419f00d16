"""Initial sets split into a grid of boxes that cover them exactly (for flowpipes that are too loose whole).

The conservative linearisation of :mod:`analysis.reach.nonlinear` adds a remainder that grows with
the square of the set's width; cutting the initial box into ``k_1 × … × k_n`` pieces and running
one flowpipe per piece trades time for precision (CORA and JuliaReach do the same on the ARCH
nonlinear benchmarks).  A property proven on every piece holds on their union, which is the whole
box: :func:`split_box` makes consecutive pieces share their cut (the same float), and
:func:`covers` checks that exactly.

Examples
--------
>>> pieces = split_box({"x": (0.0, 1.0), "y": (2.0, 3.0)}, {"x": 2})
>>> [p["x"] for p in pieces], covers({"x": (0.0, 1.0), "y": (2.0, 3.0)}, pieces)
([(0.0, 0.5), (0.5, 1.0)], True)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

from .initial import ReachError

__all__ = ["split_box", "covers", "MAX_PIECES"]

MAX_PIECES = 4096
"""Largest number of pieces a split may make."""


def _checked(box: Mapping[str, tuple[float, float]], splits: Mapping[str, int]) -> None:
    for name, (lo, hi) in box.items():
        if not (math.isfinite(float(lo)) and math.isfinite(float(hi)) and float(lo) <= float(hi)):
            raise ReachError("initial", dict(box), "a box {name: (lo, hi)} with finite lo <= hi",
                             f"give finite bounds for {name!r}")
    count = 1
    for name, k in splits.items():
        if name not in box or isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise ReachError("splits", dict(splits), f"{{state: whole number >= 1}} over {list(box)}",
                             "give e.g. splits={'x': 4}")
        count *= k
    if count > MAX_PIECES:
        raise ReachError("splits", dict(splits), f"at most {MAX_PIECES} pieces in all", "split fewer times")


def split_box(box: Mapping[str, tuple[float, float]], splits: Mapping[str, int]
              ) -> tuple[dict[str, tuple[float, float]], ...]:
    """The grid of ``splits[name]`` equal pieces per named coordinate (1 for the others), in lexicographic order.

    Raises
    ------
    ReachError
        A malformed box or split (naming it).
    """
    _checked(box, splits)
    axes = []
    for name, (lo, hi) in box.items():
        k = splits.get(name, 1)
        lo, hi = float(lo), float(hi)
        cuts = [lo] + [lo + (hi - lo) * i / k for i in range(1, k)] + [hi]
        cuts = [min(max(c, lo), hi) for c in cuts]
        axes.append([(name, (a, b)) for a, b in zip(cuts, cuts[1:])])
    return tuple(dict(combo) for combo in itertools.product(*axes))


def covers(box: Mapping[str, tuple[float, float]], pieces: Sequence[Mapping[str, tuple[float, float]]]) -> bool:
    """Whether the pieces form a grid whose union is ``box`` (exact: every comparison is of floats).

    Per coordinate the distinct intervals must chain from ``lo`` to ``hi`` (each starting where the last
    ended), and the pieces must be exactly their product.
    """
    names = list(box)
    chains = []
    for name in names:
        parts = sorted({tuple(p[name]) for p in pieces})
        lo, hi = box[name]
        if not parts or parts[0][0] != lo or parts[-1][1] != hi:
            return False
        if any(a[1] != b[0] or a[0] > a[1] for a, b in zip(parts, parts[1:])) or parts[-1][0] > parts[-1][1]:
            return False
        chains.append(parts)
    seen = {tuple(tuple(p[name]) for name in names) for p in pieces}
    return seen == set(itertools.product(*chains))
