"""Initial sets of :func:`analysis.reach.reach`: zonotopes, boxes, polytopes (vertices or halfspaces).

A polytope given by halfspaces (a symbolic condition over the state names, e.g.
``(x.p + x.q <= 1.0) & (x.p >= 0.0) & (x.q >= 0.0)``) is enclosed in its bounding box, each bound
proven in exact rationals: a linear program (scipy's HiGHS) suggests the active constraints of
``max ±x_i``, and the multipliers ``λ >= 0`` with ``A_Sᵀ λ = ±e_i`` are then solved *exactly*; weak
duality gives ``±x_i <= λ·b_S`` for every point of the polytope.  A bound that cannot be proven so is
refused (give a box instead), never guessed.

Examples
--------
>>> from hybrid.symbolic import coordinates
>>> x = coordinates("p", "q")
>>> z = initial_zonotope((x.p + x.q <= 1.0) & (x.p >= 0.0) & (x.q >= 0.0), ("p", "q"))
>>> [float(v) for v in z.center], z.order
([0.5, 0.5], 2)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any

import numpy as np

from hybrid.errors import ParameterError
from hybrid.model import Conjunction
from hybrid.symbolic import Condition, Expr

from .affine import Halfspace, condition_polyhedra
from .zonotope import Zonotope, from_box, round_down, round_up

__all__ = ["ReachError", "initial_zonotope", "polytope_box"]


class ReachError(ParameterError):
    """A parameter of :func:`analysis.reach.reach` is invalid (named, with what was expected and the fix)."""


_FIX = "give finite bounds for every state (reachability needs a bounded initial set)"


def _expected(names: Sequence[str]) -> str:
    return (f"a bounded set over ({', '.join(names)}): a Zonotope, a box {{name: (lo, hi)}} with finite lo <= hi, "
            "polytope vertices of shape (k, n), or a bounded polytope written as a symbolic condition")


def initial_zonotope(initial: Any, names: Sequence[str]) -> Zonotope:
    """The initial set as a zonotope over the states ``names`` (see :func:`analysis.reach.reach`).

    Raises
    ------
    ReachError
        Wrong dimension, a missing or unknown state, ``lo > hi``, NaN or inf, an unbounded or empty
        polytope.
    """
    n = len(names)
    if isinstance(initial, Zonotope):
        if initial.dimension != n or not initial.is_finite():
            raise ReachError("initial", initial, _expected(names), _FIX)
        return initial
    if isinstance(initial, (Condition, Expr, Conjunction)):
        polyhedra = condition_polyhedra(initial, tuple(names), role="initial set")
        if len(polyhedra) != 1:
            raise ReachError("initial", initial, "one polytope (a conjunction of affine comparisons)",
                             "split a disjunction into separate runs")
        lo, hi = polytope_box(polyhedra[0].halfspaces, n)
        return from_box(lo, hi)
    if isinstance(initial, Mapping):
        if set(initial) != set(names):
            raise ReachError("initial", dict(initial), _expected(names), f"give bounds for exactly {list(names)}")
        try:
            bounds = np.array([[float(initial[k][0]), float(initial[k][1])] for k in names])
        except (TypeError, ValueError, IndexError):
            raise ReachError("initial", dict(initial), _expected(names), _FIX) from None
        if not np.all(np.isfinite(bounds)) or np.any(bounds[:, 0] > bounds[:, 1]):
            raise ReachError("initial", dict(initial), _expected(names), _FIX)
        return from_box(bounds[:, 0], bounds[:, 1])
    try:
        vertices = np.asarray(initial, dtype=float)
    except (TypeError, ValueError):
        raise ReachError("initial", initial, _expected(names), _FIX) from None
    if vertices.ndim != 2 or vertices.shape[1] != n or vertices.shape[0] == 0 or not np.all(np.isfinite(vertices)):
        raise ReachError("initial", initial, _expected(names), _FIX)
    return from_box(vertices.min(axis=0), vertices.max(axis=0))


def polytope_box(rows: Sequence[Halfspace], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Proven bounds ``lo <= x <= hi`` (floats, rounded outward) of the polytope ``{a·x <= b for each row}``.

    Raises
    ------
    ReachError
        The polytope is empty or unbounded, or a bound could not be proven exactly.
    """
    from scipy.optimize import linprog

    a = np.array([[float(q) for q in h.normal] for h in rows]).reshape(len(rows), n)
    b = np.array([float(h.offset) for h in rows])
    lo, hi = np.empty(n), np.empty(n)
    for i in range(n):
        for sign in (1, -1):
            c = np.zeros(n)
            c[i] = -sign
            res = linprog(c, A_ub=a, b_ub=b, bounds=[(None, None)] * n, method="highs")
            if res.status in (2, 3):
                what = "empty" if res.status == 2 else f"unbounded along {'+' if sign > 0 else '-'}x{i}"
                raise ReachError("initial", f"polytope of {len(rows)} halfspaces", "a bounded, non-empty polytope",
                                 f"the polytope is {what}: add the missing bounds")
            bound = _proven_bound(rows, n, i, sign, np.asarray(res.ineqlin.marginals) if res.status == 0 else None)
            if sign > 0:
                hi[i] = float(round_up(float(bound))) if Fraction(float(bound)) < bound else float(bound)
            else:
                value = -bound
                lo[i] = float(round_down(float(value))) if Fraction(float(value)) > value else float(value)
    return lo, hi


def _proven_bound(rows: Sequence[Halfspace], n: int, i: int, sign: int, marginals: np.ndarray | None) -> Fraction:
    """``λ·b_S`` with ``λ >= 0`` and ``A_Sᵀ λ = sign·e_i`` exactly (so ``sign·x_i <= λ·b_S`` on the polytope)."""
    if marginals is not None:
        weights = -marginals
        support = [k for k in range(len(rows)) if weights[k] > 1e-12 * max(1.0, float(np.max(weights)))]
        lam = _solve_exact([rows[k].normal for k in support], n, i, sign)
        if lam is not None and all(v >= 0 for v in lam):
            return sum((v * rows[k].offset for v, k in zip(lam, support)), Fraction(0))
    raise ReachError("initial", f"polytope of {len(rows)} halfspaces", "a polytope whose bounding box can be proven",
                     "give the initial set as a box {name: (lo, hi)} or by its vertices")


def _solve_exact(normals: Sequence[Sequence[Fraction]], n: int, i: int, sign: int) -> list[Fraction] | None:
    """A solution of ``Σ_k λ_k normals[k] = sign·e_i`` in rationals (free unknowns 0), or ``None``."""
    m = len(normals)
    rows = [[Fraction(normals[k][j]) for k in range(m)] + [Fraction(sign if j == i else 0)] for j in range(n)]
    pivots, r = [], 0
    for col in range(m):
        p = next((k for k in range(r, n) if rows[k][col] != 0), None)
        if p is None:
            continue
        rows[r], rows[p] = rows[p], rows[r]
        rows[r] = [v / rows[r][col] for v in rows[r]]
        for k in range(n):
            if k != r and rows[k][col] != 0:
                f = rows[k][col]
                rows[k] = [v - f * w for v, w in zip(rows[k], rows[r])]
        pivots.append(col)
        r += 1
    if any(rows[k][m] != 0 for k in range(r, n)):
        return None
    lam = [Fraction(0)] * m
    for k, col in enumerate(pivots):
        lam[col] = rows[k][m]
    return lam
