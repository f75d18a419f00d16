"""The independent re-check's step for a nonlinear (smooth) mode: interval Picard and a second-order
Taylor map in centred form, in float intervals rounded outward (no set code of the producer).

The producer (:mod:`analysis.reach.nonlinear`) linearises ``f`` at every step and bounds a Lagrange
remainder with :func:`hybrid.symbolic.enclose`, float zonotopes and ``e^{Aδ}``.  The re-check uses
another method and other code.  From its own set ``Z = {c + G ξ : |ξ| <= 1} ⊕ [−e, e]`` of the
states at ``kδ`` after entry (floats, read as exact reals):

* **A-priori box** ``W`` by the interval Picard operator: ``hull(Z) + [0, δ]·f(W) ⊂ int W``, ``f``
  evaluated with :class:`analysis.interval.Interval` (error-free transformations, outward): every
  solution from ``Z`` stays in ``W`` over the step.
* **Taylor map** of order 2 with its Lagrange remainder: for ``0 <= s <= δ``,
  ``x(s) = g_s(x₀) + s³/6 · x'''(θ)`` with ``g_s(x) = x + s f(x) + s²/2 q(x)``, ``q = Df·f`` (``ẍ``)
  and ``x''' = Dq·f`` enclosed over ``W``.
* **Centred form** of ``g_s`` around ``c``:
  ``g_s(x₀) ∈ g_s(c) + Dg_s(c)(x₀ − c) + ½ s (x₀ − c)ᵀ D²f(hull Z)(x₀ − c) + s²/2 (Dq(hull Z) − Dq(c))(x₀ − c)``
  with ``Dg_s = I + s Df + s²/2 Dq`` (second order for ``f``, mean value form for the small ``s²/2 q``).  The midpoint of ``Dg_s(c)`` maps the
  generators (each computed column within ``γ_n |M||g|`` of the exact one, Higham §3.1); its radius,
  the quadratic term, the third-order term and the roundings become a box of new generators.
* **Slope form** (:meth:`SmoothStepper.slope_taylor`, for wide sets where ``Dg_s(c)`` sees no contraction, e.g.
  ``x' = −x³`` around 0): ``g_s(x₀) = g_s(c) + M(x₀ − c) + r(x₀)`` with ``M`` the float midpoint of
  ``Dg_s(hull Z)``, and ``r`` enclosed on a grid of boxes ``P`` covering the hull by the mean value theorem:
  ``r(x) ∈ g_s(p) − g_s(c) − M(p − c) + (Dg_s(P) − M)(P − p)`` for a point ``p ∈ P``
  (:func:`slope_remainder`; valid for any ``M``).
* The tube of the step is cut in ``m`` sub-steps of ``h = δ/m``, each a Taylor step from the last; the
  states of a sub-step lie in ``hull(Y_j, Y_{j+1}) ± h²/8 · max|q(W)|`` (the error of linear
  interpolation between the two ends of one solution, ``|x − L| <= h²/8 max|ẍ|``), ``∩ W``.

Scalar interval operations round each bound outward by one ulp (``math.nextafter``-style, here on
numpy arrays): an IEEE double operation rounded to nearest is within half an ulp.  Sums of
non-negative numbers are bounded above by ``(1 + 2(m+1)u)`` times the computed sum plus an underflow
term.  Derivatives are the exact symbolic ones (:func:`hybrid.symbolic.diff`: the shared model
reading).  At most :data:`MAX_GENERATORS` generators are kept (the smallest are boxed: sound).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.interval import Interval
from hybrid.symbolic import Apply, Const, Coordinate, Expr, diff

from .interval_tape import IntervalTape, TapeFallback, compile_tape
from .smooth import SmoothFlow

__all__ = ["SmoothStepper", "SmoothSet", "MAX_GENERATORS", "StepFailed", "reduced"]
# SLOPE_PIECES, slope_remainder and grid_pieces are public too (tests); kept out of __all__ so that the string
# constants Hypothesis draws from (the report's fuzzing) stay those of before

MAX_GENERATORS = 40
"""Generators the re-check's set keeps per step (the smallest beyond are boxed)."""
SLOPE_PIECES = 16
"""Boxes of the slope form's remainder (:func:`slope_remainder`): a fixed number, so a step's cost is bounded."""

_U = 2.0 ** -53
_TINY = 2.0 ** -1000


class StepFailed(Exception):
    """The re-check could not enclose a step (its message says why)."""


def _dn(x: Any) -> np.ndarray:
    return np.nextafter(x, -np.inf)


def _upn(x: Any) -> np.ndarray:
    return np.nextafter(x, np.inf)


def _sum_up(x: np.ndarray, axis: int | None = None) -> np.ndarray:
    """An upper bound of the exact sum of non-negative floats."""
    count = x.size if axis is None else x.shape[axis]
    return _upn(np.sum(x, axis=axis) * (1.0 + 2.0 * (count + 2) * _U) + (count + 2) * _TINY)


def _iadd(a: tuple[Any, Any], b: tuple[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    return _dn(np.asarray(a[0]) + b[0]), _upn(np.asarray(a[1]) + b[1])


def _imul(a: tuple[Any, Any], b: tuple[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    alo, ahi, blo, bhi = (np.asarray(v, dtype=float) for v in (a[0], a[1], b[0], b[1]))
    p = np.stack(np.broadcast_arrays(alo * blo, alo * bhi, ahi * blo, ahi * bhi))
    p = np.where(np.isnan(p), 0.0, p)
    return _dn(p.min(axis=0)), _upn(p.max(axis=0))


def _isquare(a: tuple[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(a[0], dtype=float), np.asarray(a[1], dtype=float)
    top = _upn(np.maximum(lo * lo, hi * hi))
    bottom = np.where((lo <= 0) & (hi >= 0), 0.0, _dn(np.minimum(lo * lo, hi * hi)))
    return bottom, top


@dataclass(slots=True)
class SmoothSet:
    """``{center + gens ξ : |ξ| <= 1} ⊕ [−err, err]`` with float numbers read as exact reals."""

    center: np.ndarray  # (n,)
    gens: np.ndarray  # (n, m)
    err: np.ndarray  # (n,)

    def radius(self) -> np.ndarray:
        """An upper bound of the set's half-widths."""
        return _sum_up(np.hstack([np.abs(self.gens), self.err.reshape(-1, 1)]), axis=1)

    def hull(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``lo <= x <= hi`` over the set (outward)."""
        r = self.radius()
        return _dn(self.center - r), _upn(self.center + r)


def _evaluate(roots: Sequence[Expr], lo: np.ndarray, hi: np.ndarray,
              tape: IntervalTape | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Enclosures of each root over the box with :class:`Interval` (one memo for all roots); with ``tape`` (the
    roots compiled, :mod:`analysis.reach.interval_tape`) the same numbers, vectorised."""
    if tape is not None:
        try:
            out_lo, out_hi = tape.evaluate(lo, hi)
        except TapeFallback:
            pass  # node by node below: the same numbers, and the same errors
        else:
            if not (np.all(np.isfinite(out_lo)) and np.all(np.isfinite(out_hi))):
                raise StepFailed("an enclosure of the flow or of its derivatives is not finite")
            return out_lo, out_hi
    memo: dict[int, Interval] = {}

    def ev(node: Any) -> Interval:
        key = id(node)
        if key in memo:
            return memo[key]
        if isinstance(node, Const):
            out = Interval.point(float(node.value))
        elif isinstance(node, Coordinate):
            out = Interval(float(lo[node.index]), float(hi[node.index]))
        elif isinstance(node, Apply):
            out = _apply(node, [ev(a) for a in node.args])
        else:
            raise StepFailed(f"the re-check cannot evaluate {node!r}")
        memo[key] = out
        return out

    values = [ev(r) for r in roots]
    out_lo = np.array([v.lo for v in values], dtype=float)
    out_hi = np.array([v.hi for v in values], dtype=float)
    if not (np.all(np.isfinite(out_lo)) and np.all(np.isfinite(out_hi))):
        raise StepFailed("an enclosure of the flow or of its derivatives is not finite")
    return out_lo, out_hi


def _apply(node: Apply, args: list[Interval]) -> Interval:
    op = node.op
    if op == "add":
        return args[0] + args[1]
    if op == "sub":
        return args[0] - args[1]
    if op == "mul":
        return args[0] * args[1]
    if op == "neg":
        return -args[0]
    if op == "div":
        return args[0] / args[1]
    if op == "pow":
        return args[0] ** int(node.args[1].value)  # type: ignore[attr-defined]
    if op == "sin":
        return args[0].sin()
    if op == "cos":
        return args[0].cos()
    raise StepFailed(f"the re-check has no interval rule for {op}()")


def _dot(a: Sequence[Expr], b: Sequence[Expr]) -> Expr:
    out: Expr = a[0] * b[0]
    for x, y in zip(a[1:], b[1:]):
        out = out + x * y
    return out


class SmoothStepper:
    """The re-check's step for one smooth flow (see the module docstring)."""

    def __init__(self, flow: SmoothFlow) -> None:
        n = len(flow.names)
        self.n = n
        f, jac, hess = flow.components, flow.jacobian, flow.hessian
        q = [_dot(list(jac[i]), f) for i in range(n)]
        dq = [[diff(q[i], x) for x in flow.names] for i in range(n)]
        third = [_dot(dq[i], f) for i in range(n)]
        self.f = list(f)
        self.at_point = list(f) + q + [e for row in jac for e in row] + [e for row in dq for e in row]
        self.over_hull = [e for a in hess for b in a for e in b] + [e for row in dq for e in row]
        self.over_w = list(f) + third + q
        self.fq = list(f) + q
        self.slopes = [e for row in jac for e in row] + [e for row in dq for e in row]
        # each list compiled once (the re-check's vectorised evaluation, same numbers as Interval's)
        self.tapes = {id(roots): compile_tape(roots) for roots in (self.f, self.at_point, self.over_hull, self.over_w,
                                                                 self.fq, self.slopes)}

    def picard(self, lo: np.ndarray, hi: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
        """A box ``W`` with ``[lo, hi] + [0, δ] f(W) ⊂ int W``."""
        f_lo, f_hi = _evaluate(self.f, lo, hi, self.tapes[id(self.f)])
        reach_lo, reach_hi = _imul((0.0, step), (f_lo, f_hi))
        w_lo, w_hi = _dn(lo + np.minimum(reach_lo, 0.0)), _upn(hi + np.maximum(reach_hi, 0.0))
        for _ in range(12):
            grow = np.maximum(w_hi - w_lo, 1e-9 * (1.0 + np.abs(w_lo) + np.abs(w_hi))) / 8.0
            w_lo, w_hi = _dn(w_lo - grow), _upn(w_hi + grow)
            f_lo, f_hi = _evaluate(self.f, w_lo, w_hi, self.tapes[id(self.f)])
            reach_lo, reach_hi = _imul((0.0, step), (f_lo, f_hi))
            i_lo, i_hi = _dn(lo + np.minimum(reach_lo, 0.0)), _upn(hi + np.maximum(reach_hi, 0.0))
            if np.all(w_lo < i_lo) and np.all(i_hi < w_hi):
                return w_lo, w_hi
            w_lo, w_hi = np.minimum(w_lo, i_lo), np.maximum(w_hi, i_hi)
        raise StepFailed("no a-priori box found by the Picard operator (the step is too large for the re-check)")

    def prepare(self, z: SmoothSet, step: float) -> dict[str, Any]:
        """The enclosures a step needs: at the centre, over the set's hull, over ``W``."""
        n = self.n
        lo, hi = z.hull()
        w = self.picard(lo, hi, step)
        p_lo, p_hi = _evaluate(self.at_point, z.center, z.center, self.tapes[id(self.at_point)])
        h_lo, h_hi = _evaluate(self.over_hull, lo, hi, self.tapes[id(self.over_hull)])
        w_lo, w_hi = _evaluate(self.over_w, *w, tape=self.tapes[id(self.over_w)])
        cut = [0, n, 2 * n, 2 * n + n * n, 2 * n + 2 * n * n]
        part = [(p_lo[a:b], p_hi[a:b]) for a, b in zip(cut, cut[1:])]
        return {"f": part[0], "q": part[1], "jac": tuple(v.reshape(n, n) for v in part[2]),
                "dq": tuple(v.reshape(n, n) for v in part[3]),
                "hess": (h_lo[: n ** 3].reshape(n, n, n), h_hi[: n ** 3].reshape(n, n, n)),
                "dq_hull": (h_lo[n ** 3:].reshape(n, n), h_hi[n ** 3:].reshape(n, n)),
                "d": (_dn(lo - z.center), _upn(hi - z.center)), "w": w,
                "fw": (w_lo[:n], w_hi[:n]), "third": (w_lo[n:2 * n], w_hi[n:2 * n]),
                "qw": (w_lo[2 * n:], w_hi[2 * n:])}

    def taylor(self, z: SmoothSet, s: float, pre: dict[str, Any]) -> SmoothSet:
        """``Y_s``: a set holding every state at local time ``s`` (a float in ``[0, δ]``) after ``Z``."""
        n = self.n
        s2 = _isquare((s, s))
        half = _imul(s2, (0.5, 0.5))
        s3 = _imul(_imul(s2, (s, s)), (1.0 / 6.0 - 2 * _U, 1.0 / 6.0 + 2 * _U))
        # g_s(c): interval vector
        g = _iadd(_iadd((z.center, z.center), _imul((s, s), pre["f"])), _imul(half, pre["q"]))
        # ½ s dᵀ H d (the s²/2 q part is in mean-value form below)
        coef = _imul(_imul((s, s), (0.5, 0.5)), pre["hess"])
        d_lo, d_hi = pre["d"]
        prod = _imul((d_lo[:, None], d_hi[:, None]), (d_lo[None, :], d_hi[None, :]))
        sq = _isquare((d_lo, d_hi))
        diag = np.eye(n, dtype=bool)
        prod = (np.where(diag, np.diag(sq[0]), prod[0]), np.where(diag, np.diag(sq[1]), prod[1]))
        terms = _imul(coef, (prod[0][None], prod[1][None]))
        quad = _interval_sum(terms[0].reshape(n, -1), terms[1].reshape(n, -1))
        if z.gens.shape[1]:
            cols = np.hstack([z.gens, np.diag(z.err)])
            z_lo, z_hi = _form_on_generators(cols, coef)
            quad = (np.maximum(quad[0], z_lo), np.minimum(quad[1], z_hi))
        third = _imul(s3, pre["third"])
        # s²/2 (q(x) − q(c) − Dq(c) d) ∈ s²/2 (Dq(hull) − Dq(c)) d  (mean value theorem, per component)
        slope = _iadd(pre["dq_hull"], (-pre["dq"][1], -pre["dq"][0]))
        mv = _imul(_imul(half, slope), (d_lo[None, :], d_hi[None, :]))
        total = _iadd(_iadd(_iadd(g, quad), third), _interval_sum(mv[0], mv[1]))
        # Dg_s(c) = I + s Df(c) + s²/2 Dq(c)
        m_lo, m_hi = _iadd(_iadd((np.eye(n), np.eye(n)), _imul((s, s), pre["jac"])), _imul(half, pre["dq"]))
        mid = 0.5 * m_lo + 0.5 * m_hi
        rad = _upn(np.maximum(mid - m_lo, m_hi - mid))
        return _assemble(z, total, mid, rad)

    def is_wide(self, pre: dict[str, Any]) -> bool:
        """Whether the Jacobian's spread over the set's hull, ``Σ_k |D²f_{·,·,k}| |d_k|``, exceeds ``|Df(c)|`` (∞-norms,
        and ``10⁻³``): the centred form then sees too little of the contraction across the set (a precision
        heuristic only; it orders the attempts, both forms being sound)."""
        d = np.maximum(np.abs(pre["d"][0]), np.abs(pre["d"][1]))
        hess = np.maximum(np.abs(pre["hess"][0]), np.abs(pre["hess"][1]))
        spread = float(np.max(np.sum(hess @ d, axis=1)))
        jac = np.maximum(np.abs(pre["jac"][0]), np.abs(pre["jac"][1]))
        return spread > max(float(np.max(np.sum(jac, axis=1))), 1e-3)

    def slope_taylor(self, z: SmoothSet, s: float, pre: dict[str, Any], pieces: int = SLOPE_PIECES) -> SmoothSet:
        """``Y_s`` like :meth:`taylor`, in slope (mean-value) form: the linear part is the midpoint ``M`` of
        ``Dg_s`` over the set's hull (the contraction across a wide set, where ``Dg_s(c)`` sees none), and the
        remainder ``r(x) = g_s(x) − g_s(c) − M(x − c)`` is enclosed on ``pieces`` boxes covering the hull
        (:func:`slope_remainder`)."""
        n = self.n
        lo, hi = z.hull()
        half = _imul(_isquare((s, s)), (0.5, 0.5))
        s3 = _imul(_imul(_isquare((s, s)), (s, s)), (1.0 / 6.0 - 2 * _U, 1.0 / 6.0 + 2 * _U))
        g = _iadd(_iadd((z.center, z.center), _imul((s, s), pre["f"])), _imul(half, pre["q"]))
        d_lo, d_hi = self.slope_matrix(lo, hi, s)
        mid = 0.5 * d_lo + 0.5 * d_hi
        r = slope_remainder(self, z.center, g, mid, lo, hi, s, pieces)
        total = _iadd(_iadd(g, r), _imul(s3, pre["third"]))
        return _assemble(z, total, mid, np.zeros((n, n)))

    def g_at(self, point: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
        """An interval vector holding ``g_s(p) = p + s f(p) + s²/2 q(p)`` at the float point ``p``."""
        n = self.n
        v_lo, v_hi = _evaluate(self.fq, point, point, self.tapes[id(self.fq)])
        half = _imul(_isquare((s, s)), (0.5, 0.5))
        return _iadd(_iadd((point, point), _imul((s, s), (v_lo[:n], v_hi[:n]))), _imul(half, (v_lo[n:], v_hi[n:])))

    def slope_matrix(self, lo: np.ndarray, hi: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
        """An interval matrix holding ``Dg_s(x) = I + s Df(x) + s²/2 Dq(x)`` for every ``x`` in the box."""
        n = self.n
        v_lo, v_hi = _evaluate(self.slopes, lo, hi, self.tapes[id(self.slopes)])
        half = _imul(_isquare((s, s)), (0.5, 0.5))
        jac = (v_lo[: n * n].reshape(n, n), v_hi[: n * n].reshape(n, n))
        dq = (v_lo[n * n:].reshape(n, n), v_hi[n * n:].reshape(n, n))
        return _iadd(_iadd((np.eye(n), np.eye(n)), _imul((s, s), jac)), _imul(half, dq))


def slope_remainder(stepper: SmoothStepper, center: np.ndarray, g_center: tuple[np.ndarray, np.ndarray],
                    matrix: np.ndarray, lo: np.ndarray, hi: np.ndarray, s: float,
                    pieces: int) -> tuple[np.ndarray, np.ndarray]:
    """An interval vector holding ``r(x) = g_s(x) − g_s(c) − M(x − c)`` for every ``x`` in ``[lo, hi]``.

    The box is cut into a grid of at most ``pieces`` boxes ``P`` (:func:`grid_pieces`: they cover it, float edges
    shared).  On ``P`` with a float point ``p ∈ P``, the mean value theorem per component along the segment
    ``[p, x] ⊂ P`` gives ``r(x) = r(p) + (Dg_s(ζ) − M)(x − p)`` with ``Dg_s(ζ)`` in the interval matrix
    ``Dg_s(P)``, and ``r(p) = g_s(p) − g_s(c) − M(p − c)``: every term enclosed (outward), the union over the
    pieces kept as its hull.

    Parameters
    ----------
    stepper : SmoothStepper
    center : ndarray, shape (n,)
        ``c`` (floats, exact reals).
    g_center : (ndarray, ndarray), shapes (n,)
        An interval vector holding ``g_s(c)``.
    matrix : ndarray, shape (n, n)
        ``M``: any float matrix (the enclosure is valid for every ``M``; its midpoint choice is for precision).
    lo, hi : ndarray, shape (n,)
        The box (every ``x`` of the set lies in it).
    s : float
        The local time ``s`` [s].
    pieces : int
        The most boxes of the grid.
    """
    n = center.size
    out_lo, out_hi = np.full(n, np.inf), np.full(n, -np.inf)
    for p_lo, p_hi in grid_pieces(lo, hi, pieces):
        point = 0.5 * p_lo + 0.5 * p_hi
        point = np.minimum(np.maximum(point, p_lo), p_hi)
        gp = stepper.g_at(point, s)
        shift = (_dn(point - center), _upn(point - center))
        lin = _imul((matrix, matrix), (shift[0][None, :], shift[1][None, :]))
        lin = _interval_sum(lin[0], lin[1])
        base = _iadd(_iadd(gp, (-g_center[1], -g_center[0])), (-lin[1], -lin[0]))
        d_lo, d_hi = stepper.slope_matrix(p_lo, p_hi, s)
        slope = _iadd((d_lo, d_hi), (-matrix, -matrix))
        dx = (_dn(p_lo - point), _upn(p_hi - point))
        spread = _imul(slope, (dx[0][None, :], dx[1][None, :]))
        part = _iadd(base, _interval_sum(spread[0], spread[1]))
        out_lo, out_hi = np.minimum(out_lo, part[0]), np.maximum(out_hi, part[1])
    if not (np.all(np.isfinite(out_lo)) and np.all(np.isfinite(out_hi))):
        raise StepFailed("the slope form's remainder is not finite")
    return out_lo, out_hi


def grid_pieces(lo: np.ndarray, hi: np.ndarray, pieces: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Boxes covering ``[lo, hi]`` (shapes (n,)): a grid, the widest cells halved first, at most ``pieces`` cells.

    Along each coordinate the edges ``lo = e_0 <= e_1 <= … <= e_k = hi`` are floats shared by neighbouring cells,
    so the cells cover the box exactly.
    """
    n = lo.size
    counts = np.ones(n, dtype=int)
    width = np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)
    while int(np.prod(counts)) * 2 <= pieces:
        k = int(np.argmax(width / counts))
        if not width[k] > 0:
            break
        counts[k] *= 2
    edges = []
    for i in range(n):
        e = lo[i] + width[i] * (np.arange(counts[i] + 1) / counts[i])
        e[0], e[-1] = lo[i], hi[i]
        edges.append(np.minimum(np.maximum.accumulate(np.maximum(e, lo[i])), hi[i]))
    out = []
    for index in np.ndindex(*counts):
        out.append((np.array([edges[i][j] for i, j in enumerate(index)]),
                    np.array([edges[i][j + 1] for i, j in enumerate(index)])))
    return out


def _assemble(z: SmoothSet, total: tuple[np.ndarray, np.ndarray], mid: np.ndarray, rad: np.ndarray) -> SmoothSet:
    """``total ⊕ [mid ± rad](x − c)`` over ``x ∈ z`` as a set: ``mid`` maps the generators (each computed column
    within ``γ_n |mid||g|`` of the exact one), the radius, the error box and the roundings join ``total``'s box."""
    n = z.center.size
    gens = mid @ z.gens
    absg = _sum_up(np.abs(z.gens), axis=1) if z.gens.shape[1] else np.zeros(n)
    mag = _upn(absg + z.err)
    rounding = _upn(_upn(((n + 2) * _U / (1 - (n + 2) * _U)) * (np.abs(mid) @ absg)) * (1 + 4 * (n + 2) * _U)
                    + (n + 2) * _TINY)
    spread = _upn((rad @ mag + np.abs(mid) @ z.err) * (1 + 4 * (n + 2) * _U) + (n + 2) * _TINY)
    center = 0.5 * total[0] + 0.5 * total[1]
    box = _upn(np.maximum(center - total[0], total[1] - center))
    err = _upn(_upn(box + rounding) + spread)
    return SmoothSet(center=center, gens=gens, err=err)


def _form_on_generators(cols: np.ndarray, coef: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``dᵀ C_i d`` over ``d = cols·ξ``, ``|ξ| <= 1``, ``C_i ∈ [coef_lo_i, coef_hi_i]`` (shape (n, n, n)).

    ``dᵀ C d = ξᵀ (colsᵀ C cols) ξ``; the float product ``F`` of the midpoint is within ``R`` of the exact
    one (``γ_n`` per product, plus ``|cols|ᵀ C_r |cols|`` for the radius), and
    ``ξᵀ F ξ ∈ [−Σ_a (R_aa − F_aa)⁺ − Σ_{a≠b} (|F_ab| + R_ab), Σ_a (F_aa + R_aa)⁺ + Σ_{a≠b} (|F_ab| + R_ab)]``.
    """
    n, m = cols.shape
    absc = np.abs(cols)
    gam = (n + 2) * _U / (1 - (n + 2) * _U)
    off_mask = ~np.eye(m, dtype=bool)
    lo, hi = np.empty(n), np.empty(n)
    for i in range(n):
        cc = 0.5 * coef[0][i] + 0.5 * coef[1][i]
        cr = _upn(np.maximum(cc - coef[0][i], coef[1][i] - cc))
        p = cc @ cols
        form = cols.T @ p
        rad = _upn((gam * (absc.T @ np.abs(p) + absc.T @ (np.abs(cc) @ absc)) + absc.T @ (cr @ absc))
                   * (1 + 8 * (n + 2) * _U) + (n + 2) * _TINY)
        off = _sum_up((np.abs(form) + rad)[off_mask])
        d, r = np.diag(form), np.diag(rad)
        top = _sum_up(np.maximum(_upn(d + r), 0.0))
        bottom = _sum_up(np.maximum(_upn(r - d), 0.0))
        lo[i], hi[i] = -_upn(bottom + off), _upn(top + off)
    return lo, hi


def _interval_sum(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row sums of intervals, rounded outward (bounds of the exact sums)."""
    count = lo.shape[1]
    slack_lo = (2.0 * (count + 2) * _U) * np.abs(lo).sum(axis=1) * (1 + 4 * (count + 2) * _U) + (count + 2) * _TINY
    slack_hi = (2.0 * (count + 2) * _U) * np.abs(hi).sum(axis=1) * (1 + 4 * (count + 2) * _U) + (count + 2) * _TINY
    return _dn(lo.sum(axis=1) - _upn(slack_lo)), _upn(hi.sum(axis=1) + _upn(slack_hi))


def reduced(z: SmoothSet) -> SmoothSet:
    """The error box folded into generators, then the smallest generators beyond :data:`MAX_GENERATORS` boxed."""
    n = z.center.size
    keep = z.err > 0
    box = np.zeros((n, int(keep.sum())))
    box[np.nonzero(keep)[0], np.arange(box.shape[1])] = z.err[keep]
    cols = np.hstack([z.gens, box])
    if cols.shape[1] > MAX_GENERATORS:
        absc = np.abs(cols)
        order = np.argsort(absc.sum(axis=0) - absc.max(axis=0), kind="stable")
        cut = cols.shape[1] - MAX_GENERATORS + n
        boxed = _sum_up(absc[:, order[:cut]], axis=1)
        cols = np.hstack([cols[:, np.sort(order[cut:])], np.diag(boxed)])
    return SmoothSet(center=z.center.copy(), gens=cols, err=np.zeros(n))
