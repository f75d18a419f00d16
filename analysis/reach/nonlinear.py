"""Flowpipes of smooth nonlinear flows ``ẋ = f(x)`` by conservative linearisation (Althoff 2008; CORA).

Per time step ``[kδ, (k+1)δ]``, from a zonotope ``R_k`` holding the states at ``kδ`` after entry:

1. **Linearise** at ``x* = c_k + f(c_k)·δ/2`` (``c_k`` the centre of ``R_k``; CORA's choice, the middle
   of the step): ``A ≈ Df(x*)`` and ``c = f̃ − A x*`` with ``f̃ ≈ f(x*)``, all floats (any ``A`` and ``c``
   are allowed: the remainder below is computed for the ones used).
2. **Remainder.** ``f(x) = A x + c + L(x)`` with
   ``L(x) = (f(x*) − f̃) + (f̃ − A x* − c) + (Df(x*) − A)(x − x*) + ½ (x − x*)ᵀ H(ξ) (x − x*)``
   (Taylor with the Lagrange remainder; ``ξ`` on the segment from ``x*`` to ``x``).  Over a box ``Ω``
   holding ``x*`` and the states of the step, ``L(Ω)`` is enclosed by interval arithmetic with
   outward rounding: ``f(x*)`` and ``Df(x*)`` by :func:`hybrid.symbolic.enclose`'s arithmetic on the point,
   every Hessian entry ``∂²f_i/∂x_j∂x_k`` by the same over ``Ω`` (compiled once per mode:
   :mod:`analysis.reach.enclose_compiled`, the same floats), products and sums rounded outward.
3. **Fixed point.** The step is the affine flow ``ẋ = A x + c + u``, ``u(t) ∈ U`` (a box), computed
   with the sound affine machinery (:func:`analysis.reach.float_series.float_dynamics` and
   :func:`~analysis.reach.flowpipe.first_segment`: ``e^{Aδ}`` in floats with an a-priori rounding bound):
   its tube ``Ω(U)`` over ``[0, δ]``.  When ``L(box Ω(U)) ⊂ int U``, the tube holds every solution of
   the nonlinear flow over the step; otherwise ``U`` is enlarged to the hull with ``L`` (times 1.5) and
   the step redone, at most :data:`MAX_ITERATIONS` times.
4. **Next set.** ``R_{k+1} = e^{Aδ} R_k ⊕ V`` (``V`` every state change a full step of input in ``U``
   can cause), order-reduced (Girard's box method).

*Why the fixed point is sound.* Let ``x(t)`` solve the nonlinear flow from ``x₀ ∈ R_k`` and
``t* = sup{t ≤ δ : x([0, t]) ⊂ Ω}`` (``Ω = box Ω(U)``; ``x₀ ∈ Ω``).  On ``[0, t*]``, ``u(t) = L(x(t))``
lies in ``L(Ω) ⊂ int U``; ``u`` is continuous, so it stays in ``U`` a little beyond ``t*``, and ``x`` is
there a solution of the affine flow with an input in ``U``: it lies in ``Ω(U) ⊂ Ω``.  So ``t* = δ``
(and the solution exists on the step, being bounded).  Hence every state of the step is in the tube,
and the state at ``δ`` is in ``R_{k+1}``.

**Adaptive step** (:func:`adaptive_segments`, ``reach(..., adaptive_step=...)``): the same step with
``δ_k = δ · 2^j`` chosen per step from the remainder's growth with the step (:func:`_growth`), the local times
kept exact (rationals), the remainder box kept tight (``_one_step(..., tight=...)``); every step is the
fixed step above for its own ``δ_k``, so the choice changes precision and cost, never soundness.

A step whose remainder does not converge, or whose numbers are not finite, ends the flowpipe
inconclusively: the generator yields the reason (a string) instead of a zonotope, and the engine
records ``"blow_up"`` with ``inconclusive: the over-approximation blew up at t = … s in mode …``.
No splitting is done (neither of the step nor of the set): a run that does not converge is
reported, not refined (with adaptive steps a failing step is first retried shorter, down to ``δ/8``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np

from hybrid.symbolic import Const, enclose

from .enclose_compiled import compile_enclosure
from .float_series import float_dynamics
from .flowpipe import ModeDynamics, first_segment
from .series import MAX_NORM_STEP
from .smooth import SmoothFlow
from .zonotope import (
    UNIT_ROUNDOFF,
    Zonotope,
    from_box,
    gamma,
    interval_hull,
    linear_map,
    reduce_order,
    upper,
    with_error,
)

__all__ = ["MAX_ITERATIONS", "QUADRATIC_GENERATORS", "smooth_segments", "adaptive_segments", "remainder_box",
           "ADAPTIVE_LEVELS", "ADAPTIVE_RATIO"]

MAX_ITERATIONS = 12
"""Enlargements of the remainder box tried per step before the flowpipe is declared blown up."""

QUADRATIC_GENERATORS = 40
"""The tube is reduced to about this many generators before its quadratic form is bounded."""

WIDE_FLOOR = 1e-3
"""A set is *wide* (linearised with the midpoint of ``Df`` over it) when the Jacobian's spread over it exceeds the
norm of ``Df(x*)`` and this floor (per unit of the state's time scale)."""

MEAN_VALUE_PIECES = 16
"""At most this many pieces of the box in the mean-value remainder of a wide set (:func:`_mean_value`)."""

_GROW = 1.5
"""Factor by which the remainder box's radius is enlarged after a failed iteration."""

_TIGHT = 1.05
"""Factor on the remainder found that gives the next box in a tight retry (``_one_step(..., tight=k)``)."""


def _down(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, -np.inf)


def _up(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, np.inf)


def _mul(alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward-rounded interval product (elementwise)."""
    p = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    p = np.where(np.isnan(p), 0.0, p)  # 0 * inf: a real factor is finite, the product is 0
    return _down(p.min(axis=0)), _up(p.max(axis=0))


class _Evaluator:
    """Float and interval evaluations of one :class:`SmoothFlow` (memoised compiled functions)."""

    def __init__(self, flow: SmoothFlow) -> None:
        self.flow = flow
        self.n = len(flow.names)
        self.f_float = list(flow.components)  # called as e(v, m): compiled once
        # the distinct Hessian entries (j <= k), with their multiplicity 1 or 2 in the quadratic form
        self.pairs = [(j, k) for j in range(self.n) for k in range(j, self.n)]
        self.pair_index = (np.array([j for j, _ in self.pairs], dtype=int),
                           np.array([k for _, k in self.pairs], dtype=int))
        self.pair_diagonal = self.pair_index[0] == self.pair_index[1]
        # constant Jacobian and Hessian entries (most of them, for sparse flows) are read once
        self.j_const = np.zeros((self.n, self.n))
        self.j_vary = []
        for i in range(self.n):
            for j in range(self.n):
                entry = flow.jacobian[i][j]
                if isinstance(entry, Const):
                    self.j_const[i, j] = float(entry.value)
                else:
                    self.j_vary.append((i, j))
        self.curvature: np.ndarray | None = None
        self.h_const = np.zeros((self.n,) * 3)
        self.h_vary = []
        for i in range(self.n):
            for j, k in self.pairs:
                entry = flow.hessian[i][j][k]
                if isinstance(entry, Const):
                    self.h_const[i, j, k] = self.h_const[i, k, j] = float(entry.value)
                else:
                    self.h_vary.append((i, j, k))
        # the enclosures compiled once (the same floats as enclose's tree walk; None: walk the tree)
        names = flow.names
        j_roots = [flow.jacobian[i][j] for i, j in self.j_vary]
        self.f_tape = compile_enclosure(flow.components, names)
        self.point_tape = compile_enclosure(list(flow.components) + j_roots, names)
        self.j_tape = compile_enclosure(j_roots, names)
        self.h_tape = compile_enclosure([flow.hessian[i][j][k] for i, j, k in self.h_vary], names)
        self.j_index = tuple(np.array(v, dtype=int) for v in zip(*self.j_vary)) if self.j_vary else None
        if self.h_vary:
            hi_, hj, hk = (np.array(v, dtype=int) for v in zip(*self.h_vary))
            self.h_index = (np.concatenate([hi_, hi_]), np.concatenate([hj, hk]), np.concatenate([hk, hj]))
        else:
            self.h_index = None

    def box(self, lo: np.ndarray, hi: np.ndarray) -> dict[str, tuple[float, float]]:
        return {name: (float(a), float(b)) for name, a, b in zip(self.flow.names, lo, hi)}

    def point_enclosures(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Enclosures of ``f(x)`` and ``Df(x)`` at a float point: (f_lo, f_hi, J_lo, J_hi)."""
        if self.point_tape is not None:
            xs = x.tolist()
            lows, highs = self.point_tape(xs, xs)
            n = self.n
            j_lo, j_hi = self.j_const.copy(), self.j_const.copy()
            if self.j_index is not None:
                j_lo[self.j_index], j_hi[self.j_index] = lows[n:], highs[n:]
            return np.array(lows[:n]), np.array(highs[:n]), j_lo, j_hi
        bounds = self.box(x, x)
        shared: dict = {}  # subtrees common to the entries enclosed once (the same numbers)
        f = np.array([enclose(e, bounds, shared=shared) for e in self.flow.components])
        j_lo, j_hi = self.jacobian(x, x, shared=shared)
        return f[:, 0], f[:, 1], j_lo, j_hi

    def f_point(self, x: np.ndarray) -> np.ndarray:
        """Enclosures of ``f(x)`` at a float point, shape (n, 2)."""
        if self.f_tape is not None:
            xs = x.tolist()
            lows, highs = self.f_tape(xs, xs)
            return np.array([lows, highs]).T
        bounds = self.box(x, x)
        return np.array([enclose(e, bounds) for e in self.flow.components])

    def jacobian(self, lo: np.ndarray, hi: np.ndarray, shared: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures of every ``∂f_i/∂x_j`` over the box ``[lo, hi]``: (lo, hi), each shape (n, n).

        ``shared``: a memo of subtree enclosures over this same box (see :func:`hybrid.symbolic.enclose`)."""
        j_lo, j_hi = self.j_const.copy(), self.j_const.copy()
        if self.j_tape is not None and shared is None:
            if self.j_index is not None:
                j_lo[self.j_index], j_hi[self.j_index] = self.j_tape(lo.tolist(), hi.tolist())
            return j_lo, j_hi
        bounds = self.box(lo, hi)
        shared = {} if shared is None else shared
        for i, j in self.j_vary:
            j_lo[i, j], j_hi[i, j] = enclose(self.flow.jacobian[i][j], bounds, shared=shared)
        return j_lo, j_hi

    def hessian(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures of every ``∂²f_i/∂x_j∂x_k`` over the box ``[lo, hi]``: (lo, hi), each shape (n, n, n)."""
        h_lo, h_hi = self.h_const.copy(), self.h_const.copy()
        if self.h_tape is not None:
            if self.h_index is not None:
                lows, highs = self.h_tape(lo.tolist(), hi.tolist())
                h_lo[self.h_index], h_hi[self.h_index] = lows + lows, highs + highs
        else:
            bounds = self.box(lo, hi)
            shared: dict = {}  # subtrees common to the entries enclosed once (the same numbers)
            for i, j, k in self.h_vary:
                h_lo[i, j, k], h_hi[i, j, k] = enclose(self.flow.hessian[i][j][k], bounds, shared=shared)
                h_lo[i, k, j], h_hi[i, k, j] = h_lo[i, j, k], h_hi[i, j, k]
        self.curvature = np.maximum(np.abs(h_lo), np.abs(h_hi))  # the latest |H| (a hint for _linearise)
        return h_lo, h_hi

    def quadratic(self, d_lo: np.ndarray, d_hi: np.ndarray, h_lo: np.ndarray, h_hi: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """An enclosure of ``½ dᵀ H d`` for ``d ∈ [d_lo, d_hi]``, ``H ∈ [h_lo, h_hi]`` (interval form).

        The products of every pair ``(j, k)`` are formed at once (elementwise the same operations as one pair at a
        time); the terms are then added pair by pair, each addition rounded outward."""
        pj, pk = self.pair_index
        live = np.any(h_lo[:, pj, pk] != 0.0, axis=0) | np.any(h_hi[:, pj, pk] != 0.0, axis=0)
        if not np.any(live):  # a zero column of the Hessian adds nothing
            return np.zeros(self.n), np.zeros(self.n)
        pj, pk, diag = pj[live], pk[live], self.pair_diagonal[live]
        aj_lo, aj_hi, ak_lo, ak_hi = d_lo[pj], d_hi[pj], d_lo[pk], d_hi[pk]
        sq_hi = _up(np.maximum(aj_lo ** 2, aj_hi ** 2))
        sq_lo = np.where((aj_lo <= 0.0) & (0.0 <= aj_hi), 0.0, _down(np.minimum(aj_lo ** 2, aj_hi ** 2)))
        m_lo, m_hi = _mul(aj_lo, aj_hi, ak_lo, ak_hi)
        p_lo, p_hi = np.where(diag, sq_lo, m_lo), np.where(diag, sq_hi, m_hi)
        weight = np.where(diag, 0.5, 1.0)  # ½ (H_jk + H_kj) d_j d_k = H_jk d_j d_k off the diagonal
        t_lo, t_hi = _mul(h_lo[:, pj, pk] * weight, h_hi[:, pj, pk] * weight, np.broadcast_to(p_lo, (self.n, pj.size)),
                          np.broadcast_to(p_hi, (self.n, pj.size)))
        out_lo, out_hi = np.zeros(self.n), np.zeros(self.n)
        for q in range(pj.size):
            out_lo, out_hi = _down(out_lo + t_lo[:, q]), _up(out_hi + t_hi[:, q])
        return out_lo, out_hi


def _quadratic_zonotope(gens: np.ndarray, h_lo: np.ndarray, h_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An enclosure of ``½ dᵀ H_i d`` over ``d ∈ {G ξ : |ξ| <= 1}`` and ``H_i ∈ [h_lo_i, h_hi_i]``, per ``i``.

    ``dᵀ H d = ξᵀ (Gᵀ H G) ξ``.  With ``M = Gᵀ H_c G`` computed in floats and ``R`` bounding its rounding
    (Higham: ``γ_n`` per product) plus ``|G|ᵀ H_r |G|``, the form lies in
    ``[−Σ_a max(0, −(M_aa − R_aa)) − Σ_{a≠b} (|M_ab| + R_ab), Σ_a max(0, M_aa + R_aa) + Σ_{a≠b} (|M_ab| + R_ab)]``
    (``ξ_a² ∈ [0, 1]``, ``ξ_a ξ_b ∈ [−1, 1]``): tighter than the interval form for thin, slanted sets.
    """
    n, m = gens.shape
    absg = np.abs(gens)
    mask = 1.0 - np.eye(m)  # x·0 = 0 and x·1 = x exactly: the off-diagonal sum below has m² terms
    # every row i at once (stacked matrix products: each entry is the same dot product of length n, in some order)
    hc = 0.5 * h_lo + 0.5 * h_hi
    hr = upper(np.maximum(hc - h_lo, h_hi - hc), 1)
    p = hc @ gens
    mat = gens.T @ p
    rad = upper(gamma(n) * (absg.T @ np.abs(p) + absg.T @ (np.abs(hc) @ absg)) + absg.T @ (hr @ absg), 4 * n + 4)
    diag, rdiag = np.diagonal(mat, axis1=1, axis2=2), np.diagonal(rad, axis1=1, axis2=2)
    off = upper(((np.abs(mat) + rad) * mask).sum(axis=(1, 2)), m * m + 1)
    top = upper(np.maximum(diag + rdiag, 0.0).sum(axis=1), m + 1)
    bottom = upper(np.maximum(rdiag - diag, 0.0).sum(axis=1), m + 1)
    return _down(-0.5 * upper(bottom + off, 2)), _up(0.5 * upper(top + off, 2))


def remainder_box(ev: _Evaluator, xstar: np.ndarray, lin: tuple[np.ndarray, ...], lo: np.ndarray,
                  hi: np.ndarray, tube: Zonotope | None = None) -> tuple[np.ndarray, np.ndarray]:
    """An enclosure of ``L(x) = f(x) − A x − c`` over the box ``[lo, hi]`` (which must hold ``x*``).

    ``lin = (A, c, const_lo, const_hi, jrad)``: the float ``A``, ``c``; an enclosure of
    ``(f(x*) − f̃) + (f̃ − A x* − c)``; a bound of ``|Df(x*) − A|``.  Two enclosures, both valid, are
    intersected: the Taylor form ``(Df(x*) − A) d + ½ dᵀ H(ξ) d`` (``d = x − x*``; with ``tube``, a zonotope
    holding the states inside the box, the quadratic term is also bounded on the zonotope and the tighter
    bound kept), and the mean-value form ``(Df(ξ) − A) d`` with ``Df`` enclosed over the box.
    """
    a, _, k_lo, k_hi, jrad, wide = lin
    d_lo, d_hi = _down(lo - xstar), _up(hi - xstar)
    mag = np.maximum(np.abs(d_lo), np.abs(d_hi))
    first = upper(jrad @ mag, ev.n + 1)
    h_lo, h_hi = ev.hessian(lo, hi)
    q_lo, q_hi = ev.quadratic(d_lo, d_hi, h_lo, h_hi)
    if tube is not None:
        # d = (c − x*) + G ξ lies in {[G, c − x*, rounding box] ξ'}: the offset as one more generator (|ξ₀| <= 1)
        tube = reduce_order(tube, max(1, QUADRATIC_GENERATORS // ev.n))  # its cost grows with the square
        offset = tube.center - xstar
        slack = upper(UNIT_ROUNDOFF * np.abs(offset), 1)
        gens = np.hstack([tube.generators, offset.reshape(-1, 1), np.diag(slack)])
        z_lo, z_hi = _quadratic_zonotope(gens, h_lo, h_hi)
        q_lo, q_hi = np.maximum(q_lo, z_lo), np.minimum(q_hi, z_hi)
    t_lo, t_hi = _down(q_lo - first), _up(q_hi + first)
    if wide:
        m_lo, m_hi = _mean_value(ev, a, xstar, lo, hi)
        t_lo, t_hi = np.maximum(t_lo, m_lo), np.minimum(t_hi, m_hi)
    return _down(k_lo + t_lo), _up(k_hi + t_hi)


def _mean_value(ev: _Evaluator, a: np.ndarray, xstar: np.ndarray, lo: np.ndarray, hi: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """An enclosure of ``f(x) − f(x*) − A (x − x*)`` over ``x ∈ [lo, hi]`` (outward rounded, shape (n,)).

    The box is cut into ``k`` equal pieces along every coordinate (``kⁿ <= MEAN_VALUE_PIECES``).  On a piece ``P``
    with midpoint ``m``: ``f(x) − f(x*) − A(x − x*) = [f(m) − f(x*) − A(m − x*)] + (Df(ξ) − A)(x − m)`` with ``ξ``
    on the segment from ``m`` to ``x``, in ``P`` (the mean value theorem, one ``ξ`` per row); the bracket is
    enclosed at the points, the rest by ``Df`` enclosed over ``P``.  The union over the pieces is returned: on a
    wide set the pieces follow the curvature that one interval Jacobian over the whole box misses.
    """
    n = ev.n
    k = max(1, int(math.floor(MEAN_VALUE_PIECES ** (1.0 / n) + 1e-9)))
    f_star = ev.f_point(xstar)
    cuts = [np.linspace(lo[i], hi[i], k + 1) for i in range(n)]
    out_lo, out_hi = np.full(n, np.inf), np.full(n, -np.inf)
    for index in itertools.product(range(k), repeat=n):
        p_lo = np.array([cuts[i][j] if j > 0 else lo[i] for i, j in enumerate(index)])
        p_hi = np.array([cuts[i][j + 1] if j + 1 < k else hi[i] for i, j in enumerate(index)])
        m = 0.5 * p_lo + 0.5 * p_hi
        f_m = ev.f_point(m)
        # A (m − x*): m − x* in [g_lo, g_hi] (the float midpoint within g_hi − g_lo of it), the product rounded
        g_lo, g_hi = _down(m - xstar), _up(m - xstar)
        dm = np.maximum(np.abs(g_lo), np.abs(g_hi))
        am = a @ (0.5 * g_lo + 0.5 * g_hi)
        am_rad = upper(np.abs(a) @ (g_hi - g_lo) + gamma(n + 2) * (np.abs(a) @ dm) + 1e-300, n + 4)
        b_lo = _down(_down(_down(f_m[:, 0] - f_star[:, 1]) - am) - am_rad)
        b_hi = _up(_up(_up(f_m[:, 1] - f_star[:, 0]) - am) + am_rad)
        j_lo, j_hi = ev.jacobian(p_lo, p_hi)
        e_lo, e_hi = _down(j_lo - a), _up(j_hi - a)
        d_lo, d_hi = _down(p_lo - m), _up(p_hi - m)
        q_lo, q_hi = _mul(e_lo, e_hi, np.broadcast_to(d_lo, (n, n)), np.broadcast_to(d_hi, (n, n)))
        for j in range(n):  # each addition rounded outward
            b_lo, b_hi = _down(b_lo + q_lo[:, j]), _up(b_hi + q_hi[:, j])
        out_lo, out_hi = np.minimum(out_lo, b_lo), np.maximum(out_hi, b_hi)
    return out_lo, out_hi


def _linearise(ev: _Evaluator, start: Zonotope, step: float) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """``x*`` and ``(A, c, const_lo, const_hi, jrad)`` (see :func:`remainder_box`).

    ``A`` is the midpoint of ``Df`` enclosed over the start set's box moved to ``x*``: the slope of the flow
    across the set, not only at ``x*`` (for a thin set the two agree; for a wide one, e.g. ``ẋ = −x³`` around
    0, ``Df(x*)`` can miss the contraction of the set's edges and the remainder, an input to the affine
    step, then outgrows it).  Any float ``A`` is sound: the remainder is enclosed for the ``A`` used.
    """
    n = ev.n
    center = start.center
    fc = np.array([f(center, {}) for f in ev.f_float], dtype=float)
    xstar = center + fc * (0.5 * step) if np.all(np.isfinite(fc)) else center.copy()
    f_lo, f_hi, j_lo, j_hi = ev.point_enclosures(xstar)
    ftil = 0.5 * f_lo + 0.5 * f_hi
    a = 0.5 * j_lo + 0.5 * j_hi
    wide = False
    radius = np.abs(start.generators).sum(axis=1)
    # the previous step's |H| (over a box near this one) bounds the spread roughly: a set clearly thin by it (with a
    # factor 2 of room) skips the enclosure over the box; any A is sound, this only saves time
    hint = ev.curvature
    thin = hint is not None and bool(np.all(np.isfinite(hint))) and \
        2.0 * float(np.max((hint @ radius).sum(axis=1))) <= max(float(np.max(np.abs(a).sum(axis=1))), WIDE_FLOOR)
    if ev.j_vary and not thin:
        s_lo, s_hi = ev.jacobian(xstar - radius, xstar + radius)
        spread = 0.5 * s_hi - 0.5 * s_lo
        wide = bool(np.all(np.isfinite(spread))
                    and np.max(spread.sum(axis=1)) > max(np.max(np.abs(a).sum(axis=1)), WIDE_FLOOR))
        if wide:
            a = 0.5 * s_lo + 0.5 * s_hi
    jrad = upper(np.maximum(np.maximum(a - j_lo, j_hi - a), 0.0), 1)
    ax = a @ xstar
    c = ftil - ax
    # |f̃ − A x* − c| <= γ_{n+1}(|f̃| + |A||x*|) + u|c| (the dot product, then the subtraction)
    cerr = upper(gamma(n + 2) * (np.abs(ftil) + np.abs(a) @ np.abs(xstar) + np.abs(c)), n + 4)
    k_lo = _down(_down(f_lo - ftil) - cerr)
    k_hi = _up(_up(f_hi - ftil) + cerr)
    return xstar, (a, c, k_lo, k_hi, jrad, wide)


def _tube(mode: str, lin: tuple[np.ndarray, ...], u_lo: np.ndarray, u_hi: np.ndarray, start: Zonotope,
          step: float) -> tuple[ModeDynamics, Zonotope, Zonotope]:
    """The affine step ``ẋ = A x + c + u``, ``u ∈ [u_lo, u_hi]``: (dynamics, the augmented start, tube Ω)."""
    a, c = lin[0], lin[1]
    u = from_box(u_lo, u_hi)
    # the input's centre joins the constant; that sum's rounding widens the (now centred) input
    const = c + u.center
    radius = upper(np.abs(u.generators).sum(axis=1) + UNIT_ROUNDOFF * np.abs(const), 2)
    biggest = float(np.max(np.abs(np.append(const, 1.0))))
    scale = 2.0 ** math.ceil(math.log2(biggest))
    dyn = float_dynamics(mode, a, const, scale, step, radius)
    aug = Zonotope(center=np.append(start.center, scale),
                   generators=np.vstack([start.generators, np.zeros((1, start.order))]))
    return dyn, aug, first_segment(dyn, aug)


def _one_step(ev: _Evaluator, mode: str, start: Zonotope, step: float, order: int,
              guess: tuple[np.ndarray, np.ndarray] | None, tight: int = 0
              ) -> tuple[Zonotope, Zonotope, tuple[np.ndarray, np.ndarray]] | str:
    """(tube, next set, the remainder found) of one step, or the reason it failed.

    ``tight``: after a failed check, the first ``tight`` retries take the remainder found (widened by
    :data:`_TIGHT`) as the next box instead of enlarging the last one by :data:`_GROW` (the accepted box, and so
    the next set, stays close to the remainder: any box passing the check is sound)."""
    n = ev.n
    xstar, lin = _linearise(ev, start, step)
    if not (np.all(np.isfinite(xstar)) and all(np.all(np.isfinite(v)) for v in lin)):
        return "the linearisation is not finite"
    norm = float(np.max(np.abs(lin[0]).sum(axis=1)))
    if norm * step > MAX_NORM_STEP:
        return (f"the Jacobian's norm {norm:.3g} times the step {step:g} s exceeds {MAX_NORM_STEP:g} "
                f"(use time_step <= {MAX_NORM_STEP / norm:.3g})")
    u_lo, u_hi = (lin[2], lin[3]) if guess is None else (np.minimum(guess[0], lin[2]), np.maximum(guess[1], lin[3]))
    for attempt in range(MAX_ITERATIONS):
        mid, rad = 0.5 * u_lo + 0.5 * u_hi, 0.5 * u_hi - 0.5 * u_lo
        rad = _up(rad * 1.05 + 1e-15 + 1e-12 * np.abs(mid))  # strictly inside needs room
        u_lo, u_hi = _down(mid - rad), _up(mid + rad)
        dyn, aug, tube = _tube(mode, lin, u_lo, u_hi, start, step)
        if not tube.is_finite():
            return "the tube is not finite"
        states = tube.project(n)
        lo, hi = interval_hull(states)
        lo, hi = np.minimum(lo, xstar), np.maximum(hi, xstar)
        l_lo, l_hi = remainder_box(ev, xstar, lin, lo, hi, states)
        if not (np.all(np.isfinite(l_lo)) and np.all(np.isfinite(l_hi))):
            return "the Lagrange remainder is not finite"
        if np.all(u_lo < l_lo) and np.all(l_hi < u_hi):
            image, err = linear_map(aug, dyn.phi.center, dyn.phi.radius)
            gens = [image.generators, dyn.input_step.generators]
            nxt = with_error(Zonotope(center=image.center, generators=np.hstack(gens)), err).project(n)
            return tube, reduce_order(nxt, order), (l_lo, l_hi)
        if attempt < tight:
            mid, rad = 0.5 * l_lo + 0.5 * l_hi, _TIGHT * (0.5 * l_hi - 0.5 * l_lo)
            u_lo, u_hi = np.minimum(lin[2], mid - rad), np.maximum(lin[3], mid + rad)
            continue
        mid, rad = 0.5 * u_lo + 0.5 * u_hi, 0.5 * u_hi - 0.5 * u_lo
        u_lo = np.minimum(u_lo, mid - _GROW * rad - (l_hi - l_lo))
        u_lo = np.minimum(u_lo, l_lo)
        u_hi = np.maximum(np.maximum(u_hi, mid + _GROW * rad + (l_hi - l_lo)), l_hi)
    widest = float(np.max(l_hi - l_lo))
    return (f"the Lagrange remainder of the linearisation did not converge in {MAX_ITERATIONS} enlargements "
            f"(width {widest:.3g}); shorten time_step or the initial set")


PADDING = 1e-10
"""Relative padding of the stored tubes (plus 1e-14 absolute): an exact coordinate (a held sample, a constant)
then has room for the independent re-check's own rounding bounds, which differ from the producer's."""


def _padded(tube: Zonotope, n: int, spread: float = 0.0) -> Zonotope:
    """``tube ⊕ [−ε, ε]`` on the state coordinates, ``ε = PADDING (|c| + radius) + spread · radius + 1e-14``
    (larger: still sound)."""
    lo, hi = interval_hull(tube.project(n))
    eps = upper(PADDING * np.maximum(np.abs(lo), np.abs(hi)) + 1e-14, 3)
    if spread > 0.0:  # adaptive steps only (fixed steps keep the numbers above, bit for bit)
        eps = upper(eps + spread * (0.5 * hi - 0.5 * lo), 3)
    pad = np.vstack([np.diag(eps), np.zeros((tube.dimension - n, n))])
    return Zonotope(center=tube.center, generators=np.hstack([tube.generators, pad]))


def smooth_segments(flow: SmoothFlow, mode: str, start: Zonotope, step: float, order: int
                    ) -> Iterator[Zonotope | str]:
    """Tubes ``Ω_0, Ω_1, ...`` (augmented by a constant coordinate, dimension ``n + 1``), one per step of
    local time ``[kδ, (k+1)δ]``; endless.  A string instead of a tube is the reason the step could not be
    enclosed (the caller ends the flowpipe inconclusively)."""
    ev = _Evaluator(flow)
    current = start
    guess = None
    while True:
        with np.errstate(over="ignore", invalid="ignore"):  # non-finite numbers are caught and reported
            out = _one_step(ev, mode, current, step, order, guess)
        if isinstance(out, str):
            yield out
            return
        tube, current, found = out
        guess = found
        yield _padded(tube, ev.n)


ADAPTIVE_LEVELS = (-3, 3)
"""The adaptive step is ``time_step · 2^j`` with ``j`` in this range (both ends included)."""

ADAPTIVE_RATIO = 1.4
"""The adaptive step's rule: ``δ_k ≈ ratio · time_step · (g_ref / g_k)^ADAPTIVE_EXPONENT`` (rounded down to a power
of two times ``time_step``), ``g`` the growth rate of :func:`_growth`, ``g_ref`` its value at the flowpipe's start;
``ratio`` defaults to this."""

ADAPTIVE_EXPONENT = 0.35
"""The exponent of the adaptive step's rule (measured on VDP: docs/reachability.md, "Adaptive step")."""

TIGHT_RETRIES = 5
"""Tight retries of the adaptive step's remainder check (``_one_step(..., tight=...)``)."""

ADAPTIVE_PADDING = 0.02
"""The stored tubes of adaptive steps are widened by this fraction of their radius (room for the independent
re-check, whose own sets are not as tight as the producer's with its tight remainder boxes)."""


def _growth(ev: _Evaluator, start: Zonotope) -> float:
    """``max_i Σ_jk |H_ijk| r_j |f_k(c)| / 2`` (``H`` the latest Hessian enclosure, ``r`` the set's radii, ``c`` its
    centre): the rate at which the remainder grows with the step — the cross term of the quadratic form between
    the set and its motion over the step.  A heuristic: it only chooses the next step."""
    if ev.curvature is None:
        return 0.0
    fc = np.abs(np.array([f(start.center, {}) for f in ev.f_float], dtype=float))
    radius = np.abs(start.generators).sum(axis=1)
    value = 0.5 * float(np.max(np.einsum("ijk,j,k->i", ev.curvature, radius, fc)))
    return value if math.isfinite(value) else math.inf


def _trend(found: tuple[np.ndarray, np.ndarray], last: tuple[np.ndarray, np.ndarray] | None
           ) -> tuple[np.ndarray, np.ndarray]:
    """The next step's first remainder box: ``found`` moved and widened as it moved and widened since ``last`` (a
    guess only: the step checks whatever box it uses; a guess too small costs one more iteration, one too large
    loosens the next set)."""
    if last is None:
        return found
    mid, rad = 0.5 * found[0] + 0.5 * found[1], 0.5 * found[1] - 0.5 * found[0]
    shift = mid - (0.5 * last[0] + 0.5 * last[1])
    grow = np.maximum(rad - (0.5 * last[1] - 0.5 * last[0]), 0.0)
    return np.minimum(found[0], mid + shift - rad - grow), np.maximum(found[1], mid + shift + rad + grow)


def _next_level(level: int, rate: float, reference: float, ratio: float) -> int:
    """The next step's level: the largest ``j`` with ``2^j <= ratio · (reference / rate)^ADAPTIVE_EXPONENT``, at most
    one above ``level``, within :data:`ADAPTIVE_LEVELS`."""
    low, high = ADAPTIVE_LEVELS
    if not math.isfinite(rate):
        return low
    want = high if rate <= 0.0 else math.floor(math.log2(ratio * (reference / rate) ** ADAPTIVE_EXPONENT))
    return max(low, min(high, level + 1, want))


def adaptive_segments(flow: SmoothFlow, mode: str, start: Zonotope, step: float, order: int, *,
                      ratio: float = ADAPTIVE_RATIO) -> Iterator[tuple[Zonotope, int, int] | str]:
    """Like :func:`smooth_segments` with the step ``δ_k = step · 2^j`` chosen per step (docs/reachability.md,
    "Adaptive step"): yields ``(tube, a, b)``, the tube (augmented, dimension ``n + 1``) over the local times
    ``[a·u, b·u]`` with ``u = step · 2^ADAPTIVE_LEVELS[0]`` (exact) and the integers ``a = (δ_0 + … + δ_{k−1})/u``,
    ``b − a = δ_k/u`` (a power of two); or, once, the reason a step failed at every level down to the lowest (the
    caller ends the flowpipe inconclusively).

    Every step is the sound step of :func:`smooth_segments` for its own ``δ_k`` (a float, ``step`` times a power
    of two: exact), so the choice of ``δ_k`` changes the precision and the cost, never the soundness."""
    ev = _Evaluator(flow)
    current, guess, last, level, count, reference = start, None, None, 0, 0, 0.0
    while True:
        while True:
            delta = math.ldexp(step, level)
            with np.errstate(over="ignore", invalid="ignore"):
                out = _one_step(ev, mode, current, delta, order, guess, TIGHT_RETRIES)
            if not isinstance(out, str) or level <= ADAPTIVE_LEVELS[0]:
                break
            level -= 1  # a step that does not converge is retried shorter
        if isinstance(out, str):
            yield out
            return
        tube, nxt, found = out
        guess, last = _trend(found, last), found
        rate = _growth(ev, current)
        reference = reference if reference > 0.0 or not math.isfinite(rate) else rate
        span = 1 << (level - ADAPTIVE_LEVELS[0])
        yield _padded(tube, ev.n, ADAPTIVE_PADDING), count, count + span
        count += span
        current = nxt
        level = _next_level(level, rate, reference, ratio) if reference > 0.0 else level
