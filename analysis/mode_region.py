"""Region of attraction of one mode's equilibrium, as a proven claim about the hybrid system.

For a mode ``q`` whose flow ``f_q``, invariant terms and outgoing guard terms are polynomials in
the state, :func:`mode_region_of_attraction` finds a set ``S = {x ∈ B : V(x) <= c}`` around the
mode's equilibrium ``x*`` and proves that **every execution that is in mode q (memory m) with its
state in S stays in q forever and converges to an equilibrium x_e of f_q next to x*** (``x_e = x*``
when ``f_q(x*) = 0`` exactly).

Search (numeric only)
---------------------
``V`` is quadratic from the linearisation (``AᵀP + PA = −I``), or of degree 4, 6, ... by a
bilinear SOS alternation started from it (:mod:`analysis.sos`, Drake's formulation
``(zᵀz)^d (V − ρ) + λ V̇`` SOS); the largest level ``ρ`` is :func:`analysis.sos.region_of_attraction`'s
(or the alternation's); rays from ``x*`` estimate the set's extent and the levels where an
invariant term reaches 0 or a guard term reaches 0.  None of this is claimed.

Proof (the only thing claimed)
------------------------------
``V`` is rounded to dyadic rationals; the polynomials are exact (:func:`analysis.polynomial.normal_form`
of the user's traced functions, shifted to ``z = x − x*`` in exact rational arithmetic).  At a level
``c`` (shrunk, then bisected, until everything below holds):

1. :func:`analysis.sublevel.certify_sublevel` (strict): ``S`` does not meet the faces of ``B``,
   every ``{V <= ρ}``, ``c_in <= ρ <= c``, is positively invariant and ``V̇ < 0`` on the annulus.
   The decreasing boxes that limit the entry time are then bisected further (the certificate keeps
   its form and claim, with sharper rate bounds), and the annulus is cut into geometric layers
   ``ρ_0 = c_in < ... < ρ_K = c``: every point with ``V`` in layer ``k`` lies in a decreasing box
   whose ``V`` enclosure meets the layer, so ``V̇ <= −m_k`` there, and every solution in ``S``
   enters ``K = {x ∈ B : V <= c_in}`` within ``T = Σ_k (ρ_{k+1} − ρ_k)/m_k`` and stays there
   (never more than the certificate's own ``(c − c_in)/min_k m_k``);
2. :func:`analysis.sublevel.bound_on_sublevel`: every term ``h`` of the mode's invariant has
   ``−h < 0`` on ``S``; for every outgoing transition some term ``g`` of its guard has ``g < 0`` on
   ``S`` (so no transition is enabled anywhere in ``S``: the execution can neither be forced out nor
   choose to jump, whatever the semantics, and the memory stays ``m``);
3. the inner argument, with ``W(z) = zᵀPz`` (``P`` rational, from the linearisation) and
   ``E = {W <= c_w}`` inside the cube ``|z_i| <= r``: exactly, ``P ≻ 0``,
   ``M = −(AᵀP + PA) ⪰ μ I``, every entry of ``P·(Df(z) − A) + (Df(z) − A)ᵀ·P`` is bounded on the
   cube by the sum of its coefficients' magnitudes times ``r^degree``, whose Frobenius norm is
   ``<= σ < μ``; so ``P·Df + Dfᵀ·P ⪯ −(μ − σ) I`` on the cube (the flow contracts in the metric
   ``W``), and by branch and bound ``W < c_w`` on ``K``.  Two solutions in ``K`` then approach each
   other, ``W(a − b)(t) <= e^{−κ t} W(a − b)(0)`` with ``κ = (μ − σ)/λ_max(P)``; ``K`` being compact
   and positively invariant, it holds a unique equilibrium ``x_e`` to which every solution in ``K``
   converges, and ``Ẇ(x_e − x*) = 0`` gives ``‖x_e − x*‖ <= 2‖P f(x*)‖/(μ − σ)`` (0 when
   ``f(x*) = 0`` exactly).

Every certificate is then re-checked from its written boxes alone in the scalar arithmetic of
:mod:`analysis.interval` (:func:`analysis.sublevel.recheck_sublevel`, :func:`~analysis.sublevel.recheck_bound`;
the layers' ``V`` enclosures by :func:`analysis.certificate.enclose`), and the inner argument is
recomputed exactly from its stored rationals (:func:`recheck_mode_region`, which also traces the
system again: the certificates are about *its* functions).

The flow and every guard/invariant term are traced with CasADi symbols (``x[0]``, ``v[1] * 2``,
:mod:`hybrid.symbolic` expressions, conjunctions :func:`hybrid.all_of` or symbolic ``&`` split
into their terms, guards and invariants read through the output map) and the traced polynomial
is compared with the float function at two probe points.  Every outgoing transition counts,
self-loops included; its direction (rising/falling) does not matter, since a guard negative
throughout ``S`` can neither be nonnegative nor cross zero there.

Statuses: ``"proven"`` (all of the above, re-checked), ``"not proven"`` (a search or a proof failed:
``why`` says which, at which level), ``"not applicable"`` (no Hurwitz equilibrium inside the mode,
a non-polynomial flow/invariant/guard, a non-autonomous flow, too many states).

Examples
--------
>>> from hybrid import HybridAutomaton, HybridSystem, Mode
>>> a = HybridAutomaton(name="vdp", modes=(Mode(name="q"),), transitions=(), variables=("x", "y"),
...                     initial_mode="q")
>>> s = HybridSystem(automaton=a, state_names=("x", "y"),
...                  flows={"q": lambda t, x, m: (-x[1], x[0] + (x[0] ** 2 - 1) * x[1])})
>>> r = mode_region_of_attraction(s, "q")
>>> r.status, 2.0 < r.level < 2.4, r.rechecked
('proven', True, True)
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.linalg as la
from scipy.optimize import minimize

from analysis import exact
from analysis.equilibria import mode_equilibrium
from analysis.polynomial import Atom, Polynomial
from analysis.sos import (
    SosPoly,
    SosProgram,
    box_moments,
    from_polynomial,
    monomial_basis,
    region_of_attraction,
    to_polynomial,
)
from analysis.sublevel import (
    ARITHMETICS,
    BoundCertificate,
    SublevelCertificate,
    bound_on_sublevel,
    certify_sublevel,
    lie_derivative,
    recheck_bound,
    recheck_sublevel,
)
from hybrid import HybridSystem
from hybrid.errors import ParameterError
from analysis.mode_polynomials import (
    ModePolynomials,
    NotPolynomialError,
    check_system_mode,
    linear_part,
    mode_memory,
    mode_polynomials,
    quadratic_matrix,
    state_point,
    substitute_exact,
)
from analysis.mode_region_bounds import Matrix, inner_data, inner_problems, sharpen_layers, time_bound, time_problems

__all__ = [
    "MODE_REGION_FORMAT",
    "MODE_REGION_STATUSES",
    "DEFAULT_MAX_BOXES",
    "NotPolynomialError",
    "ModePolynomials",
    "ModeRegion",
    "mode_polynomials",
    "mode_region_of_attraction",
    "recheck_mode_region",
]

MODE_REGION_FORMAT = "analysis.mode_region/1"
"""``"format"`` of :meth:`ModeRegion.as_dict`."""
MODE_REGION_STATUSES = ("proven", "not proven", "not applicable")
"""Statuses of :class:`ModeRegion`."""
DEFAULT_MAX_BOXES = 200_000
"""Default budget of box evaluations of each branch-and-bound search."""

_LADDER = (1.0, 0.9, 0.75, 0.55, 0.35, 0.2, 0.1)
"""Fractions of the estimated level tried in turn until the proofs hold."""
_SOS_BACKOFF = 0.97
"""The SOS level is where ``V̇`` touches ``{V = ρ}``; the proof starts a little below it."""
_TERM_BACKOFF = 0.98
"""Likewise below the level where an invariant or guard term is estimated to reach 0."""
_BOX_SCALE = 1.25
"""The box ``B`` is the estimated extent of ``S`` times this (then 1.5 times more if ``S`` reaches it)."""
_SEED = 20240607
"""Seed of the ray directions (determinism)."""
_GRID = 256
"""Points per ray of the first-crossing scan (then bisection)."""


# --------------------------------------------------------------------------- validation


def _check_int(name: str, value: Any, minimum: int, fix: str, *, even: bool = False) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum or (even and value % 2):
        kind = "an even integer" if even else "an integer"
        raise ParameterError(name, value, f"{kind} >= {minimum}", fix)
    return value


def _check_positive(name: str, value: Any, fix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise ParameterError(name, value, "a finite number > 0", fix)
    return float(value)


# --------------------------------------------------------------------------- numeric helpers (search only)


def _numeric(poly: Polynomial, variables: Sequence[str]) -> Callable[[np.ndarray], np.ndarray]:
    """Float evaluation of ``poly`` on points, shape (N, n) -> (N,)."""
    index = {v: i for i, v in enumerate(variables)}
    terms = [(float(c), [(index[a.variable], p) for a, p in m]) for m, c in poly.terms.items()]

    def evaluate(z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(z)
        out = np.zeros(z.shape[0])
        with np.errstate(over="ignore", invalid="ignore"):
            for c, factors in terms:
                term = np.full(z.shape[0], c)
                for i, p in factors:
                    term = term * z[:, i] ** p
                out = out + term
        return out

    return evaluate


def _quadratic_form(p: np.ndarray, variables: Sequence[str]) -> Polynomial:
    """The rounded (dyadic) quadratic form ``zᵀPz`` as an exact polynomial."""
    n = len(variables)
    terms = {tuple(2 * (k == i) for k in range(n)): float(p[i, i]) for i in range(n)}
    terms.update({tuple(int(k in (i, j)) for k in range(n)): 2.0 * float(p[i, j])
                  for i in range(n) for j in range(i + 1, n)})
    return to_polynomial(SosPoly.from_terms(variables, terms))


def _sos_rates(polys: ModePolynomials) -> dict[str, SosPoly]:
    atoms = {Atom.var(v): v for v in polys.variables}
    return {v: from_polynomial(polys.rates[v], polys.variables, atoms) for v in polys.variables}


def _directions(n: int) -> np.ndarray:
    """Unit directions from ``x*``: the axes, a fine circle in 2-D, fixed-seed random ones otherwise."""
    axes = np.vstack([np.eye(n), -np.eye(n)])
    if n == 1:
        return axes
    if n == 2:
        theta = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
        return np.vstack([axes, np.column_stack([np.cos(theta), np.sin(theta)])])
    g = np.random.default_rng(_SEED).standard_normal((600 * n, n))
    return np.vstack([axes, g / np.linalg.norm(g, axis=1, keepdims=True)])


def _first_crossing(bad: Callable[[np.ndarray], np.ndarray], dirs: np.ndarray, t_max: float) -> np.ndarray:
    """Per direction the first ``t <= t_max`` with ``bad(t u)`` (scan then bisection), ``inf`` if none."""
    n = dirs.shape[1]
    ts = np.linspace(0.0, t_max, _GRID + 1)[1:]
    hit = bad((dirs[:, None, :] * ts[None, :, None]).reshape(-1, n)).reshape(dirs.shape[0], _GRID)
    any_hit = hit.any(axis=1)
    k = np.argmax(hit, axis=1)
    hi = np.where(any_hit, ts[k], np.inf)
    lo = np.where(k > 0, ts[np.maximum(k - 1, 0)], 0.0)
    rows = np.nonzero(any_hit)[0]
    a, b = lo[rows], hi[rows]
    for _ in range(40):
        mid = 0.5 * (a + b)
        inside = bad(dirs[rows] * mid[:, None])
        a, b = np.where(inside, a, mid), np.where(inside, mid, b)
    hi[rows] = b
    return hi


def _level_radius(vfun: Callable[[np.ndarray], np.ndarray], c: float, dirs: np.ndarray) -> np.ndarray:
    """Per direction the distance from ``x*`` where ``V`` first reaches ``c``."""
    t_max = 1.0
    for _ in range(80):
        if np.all(vfun(dirs * t_max) >= c):
            break
        t_max *= 2.0
    return _first_crossing(lambda z: vfun(z) >= c, dirs, t_max)


def _extent_box(vfun: Callable[[np.ndarray], np.ndarray], c: float, dirs: np.ndarray, scale: float
                ) -> np.ndarray:
    """``(n, 2)`` box: ``scale`` times the extent of ``{V <= c}`` along the rays, rounded outward to 4 digits."""
    pts = dirs * _level_radius(vfun, c, dirs)[:, None]
    lo, hi = scale * pts.min(axis=0), scale * pts.max(axis=0)
    return np.column_stack([_round_out(lo, -1), _round_out(hi, 1)])


def _round_out(x: np.ndarray, direction: int) -> np.ndarray:
    out = []
    for value in x.tolist():
        if value == 0.0:
            out.append(direction * 1e-9)
            continue
        q = 10.0 ** (math.floor(math.log10(abs(value))) - 3)
        out.append((math.ceil(value / q) if direction > 0 else math.floor(value / q)) * q)
    return np.array(out)


# --------------------------------------------------------------------------- numeric search of V and the level


@dataclass(frozen=True, kw_only=True, slots=True)
class _Candidate:
    """The numeric search's outcome: ``V`` (exact, rounded), its SOS level (``inf``: none), what happened."""

    lyapunov: Polynomial | None
    level: float
    message: str


def _lyapunov_matrix(a: np.ndarray) -> np.ndarray:
    """``P`` with ``AᵀP + PA = −I`` (symmetrised)."""
    p = la.solve_continuous_lyapunov(a.T, -np.eye(a.shape[0]))
    return 0.5 * (p + p.T)


def _sos_level(rates: Mapping[str, SosPoly], v: SosPoly) -> tuple[float | None, str]:
    """``region_of_attraction``'s level (``inf`` when the SDP is unbounded), or ``None`` and the message."""
    roa = region_of_attraction(rates, v, multiplier_degree=2)
    if roa.status == "unbounded" or (roa.found and roa.rho is not None and roa.rho > 1e12):
        return math.inf, "the SOS level is unbounded (no finite region-of-attraction bound from the SDP)"
    if not roa.found or roa.rho is None or not roa.rho > 0:
        return None, f"SOS region-of-attraction search: {roa.message} (solver status {roa.outcome.solver_status})"
    return float(roa.rho), f"SOS level {roa.rho:.6g} ({roa.outcome.solver}, {roa.status})"


def _rho_step(rates: Mapping[str, SosPoly], v: SosPoly) -> tuple[float | None, SosPoly | None, int]:
    """Max ``ρ`` with ``(zᵀz)^d (V − ρ) + λ V̇`` SOS; returns ``ρ``, the multiplier ``λ`` and ``d``."""
    variables = v.variables
    vdot = v.lie_derivative(rates)
    d = max(0, math.ceil((2 + vdot.degree - v.degree) / 2))
    program = SosProgram(variables)
    rho = cp.Variable()
    norm = sum((SosPoly.variable(x, variables) ** 2 for x in variables), SosPoly.constant(0.0, variables)) ** d
    lam = program.free_polynomial(monomial_basis(variables, 2))
    top = max(norm.degree + v.degree, 2 + vdot.degree)
    rho_poly = SosPoly.from_terms(variables, {(0,) * len(variables): rho})
    program.add_sos(norm * v - rho_poly * norm + lam * vdot, half_basis=monomial_basis(variables, (top + 1) // 2))
    outcome = program.solve(rho, sense="maximize")
    if not outcome.ok or rho.value is None or not float(rho.value) > 0:
        return None, None, d
    return float(rho.value), lam.value(), d


def _v_step(rates: Mapping[str, SosPoly], lam: SosPoly, d: int, degree: int, box: np.ndarray) -> SosPoly | None:
    """Given ``λ``, the ``V`` of ``degree`` with ``(zᵀz)^d (V − 1) + λ V̇`` SOS and least ``∫_box V``."""
    variables = lam.variables
    program = SosProgram(variables)
    v = program.free_polynomial(monomial_basis(variables, degree, min_degree=2))
    vdot = v.lie_derivative(rates)
    norm = sum((SosPoly.variable(x, variables) ** 2 for x in variables), SosPoly.constant(0.0, variables))
    top = max(2 * d + degree, lam.degree + vdot.degree)
    program.add_sos(norm ** d * (v - 1.0) + lam * vdot, half_basis=monomial_basis(variables, (top + 1) // 2))
    program.add_nonnegative(v - 1e-3 * norm, zero_at_origin=True)
    moments = box_moments({x: (float(a), float(b)) for x, (a, b) in zip(variables, box)}, v.monomials, variables)
    outcome = program.solve(moments @ v.coefficients)
    return v.value() if outcome.ok else None


def _volume(vfun: Callable[[np.ndarray], np.ndarray], level: float, dirs: np.ndarray) -> float:
    """Relative size of ``{V <= level}``: the mean of ``radius^n`` over the rays (numeric, for comparisons)."""
    return float(np.mean(_level_radius(vfun, level, dirs) ** dirs.shape[1]))


def _alternate(polys: ModePolynomials, rates: Mapping[str, SosPoly], v0: SosPoly, degree: int,
               iterations: int) -> _Candidate:
    """Bilinear alternation ``ρ``-step / ``V``-step from the quadratic ``v0``; keeps the largest set found."""
    variables, dirs = polys.variables, _directions(len(polys.variables))
    rho, lam, d = _rho_step(rates, v0)
    if rho is None:
        return _Candidate(lyapunov=None, level=math.nan, message="SOS alternation: the first rho-step failed")
    best_v, best_rho = to_polynomial(v0), rho
    best_size = _volume(_numeric(best_v, variables), best_rho, dirs)
    v, improved = v0, False
    for _ in range(iterations):
        box = _extent_box(_numeric(to_polynomial(v), variables), rho, dirs, 1.5)
        if not np.all(np.isfinite(box)):
            break
        try:
            candidate = _v_step(rates, lam, d, degree, box)
            if candidate is None:
                break
            rho, lam, d = _rho_step(rates, candidate)
        except (ParameterError, ValueError, ArithmeticError):  # a numeric failure ends the search
            break
        if rho is None:
            break
        v = candidate
        exact = to_polynomial(v)
        size = _volume(_numeric(exact, variables), rho, dirs)
        if size > best_size:
            best_v, best_rho, best_size, improved = exact, rho, size, True
    kept = "" if improved else "; it did not enlarge the set, the quadratic V is kept"
    return _Candidate(lyapunov=best_v, level=best_rho,
                      message=f"SOS alternation (degree {degree}, {iterations} iterations): level {best_rho:.6g}{kept}")


def _search(polys: ModePolynomials, p: np.ndarray, degree: int, iterations: int) -> _Candidate:
    """Numeric ``V`` (quadratic from ``P`` or of higher degree by SOS) and its SOS level."""
    rates = _sos_rates(polys)
    w = _quadratic_form(p, polys.variables)
    v0 = from_polynomial(w, polys.variables, {Atom.var(z): z for z in polys.variables})
    level, message = _sos_level(rates, v0)
    if level is None:
        return _Candidate(lyapunov=None, level=math.nan, message=message)
    if degree == 2 or not math.isfinite(level):
        return _Candidate(lyapunov=w, level=level, message="quadratic V from the linearisation; " + message)
    return _alternate(polys, rates, v0, degree, iterations)


def _term_limit(vfun: Callable[[np.ndarray], np.ndarray], margin: Callable[[np.ndarray], np.ndarray],
                dirs: np.ndarray, t_max: float) -> float:
    """Estimated least ``V`` where ``margin >= 0`` (the term would fail): rays, then a local polish."""
    if margin(np.zeros((1, dirs.shape[1])))[0] >= 0.0:
        return 0.0
    t = _first_crossing(lambda z: margin(z) >= 0.0, dirs, t_max)
    hit = np.isfinite(t)
    if not hit.any():
        return math.inf
    pts = dirs[hit] * t[hit][:, None]
    values = vfun(pts)
    k = int(np.argmin(values))
    best = float(values[k])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(lambda z: float(vfun(z[None, :])[0]), pts[k], method="SLSQP",
                       constraints=[{"type": "ineq", "fun": lambda z: float(margin(z[None, :])[0])}],
                       options={"maxiter": 200})
    if res.success and margin(res.x[None, :])[0] >= -1e-12 and float(vfun(res.x[None, :])[0]) < best:
        best = float(vfun(res.x[None, :])[0])
    return max(best, 0.0)


def _start_level(polys: ModePolynomials, v: Polynomial, sos_level: float, max_extent: float
                 ) -> tuple[float, str]:
    """The first level tried: below the SOS level, the terms' estimated limits and the extent cap."""
    variables, dirs = polys.variables, _directions(len(polys.variables))
    vfun = _numeric(v, variables)
    cube = dirs * (max_extent / np.abs(dirs).max(axis=1))[:, None]
    cap = 0.98 * float(vfun(cube).min())
    level, why = min(_SOS_BACKOFF * sos_level, cap), ("SOS level" if _SOS_BACKOFF * sos_level <= cap
                                                      else f"extent cap |Δx_i| <= {max_extent:g}")
    t_max = float(_level_radius(vfun, level, dirs).max())
    margins = [(label, -h) for label, h in polys.invariant_terms]
    for name, terms in polys.guards:
        limits = [_term_limit(vfun, _numeric(g, variables), dirs, t_max) for _, g in terms]
        k = int(np.argmax(limits))
        if _TERM_BACKOFF * limits[k] < level:
            level, why = _TERM_BACKOFF * limits[k], f"{terms[k][0]} (estimated)"
    for label, m in margins:
        limit = _term_limit(vfun, _numeric(m, variables), dirs, t_max)
        if _TERM_BACKOFF * limit < level:
            level, why = _TERM_BACKOFF * limit, f"{label} (estimated)"
    return level, why


# --------------------------------------------------------------------------- proofs at one level


@dataclass(frozen=True, kw_only=True, slots=True)
class _Context:
    """Everything a proof attempt needs (fixed across levels)."""

    polys: ModePolynomials
    lyapunov: Polynomial
    rate: Polynomial
    vfun: Callable[[np.ndarray], np.ndarray]
    inner: Mapping[str, Any]
    inner_ratio: float
    dirs: np.ndarray
    max_boxes: int


@dataclass(frozen=True, kw_only=True, slots=True)
class _Proof:
    """The certificates of one level (not yet re-checked)."""

    level: float
    inner_level: float
    region: dict[str, tuple[float, float]]
    sublevel: SublevelCertificate
    inner: BoundCertificate
    invariant: tuple[tuple[int, str, BoundCertificate], ...]
    guards: tuple[tuple[str, int, str, BoundCertificate], ...]
    time: dict[str, Any]

    @property
    def boxes_examined(self) -> int:
        return (self.sublevel.boxes_examined + self.inner.boxes_examined
                + sum(c.boxes_examined for *_, c in self.invariant) + sum(c.boxes_examined for *_, c in self.guards))


def _floor6(x: float) -> float:
    """``x`` rounded down to 6 significant digits (so that the claim prints the exact level)."""
    if not x > 0:
        return x
    q = 10.0 ** (math.floor(math.log10(x)) - 5)
    y = math.floor(x / q) * q
    return float(f"{y:.6g}") if float(f"{y:.6g}") <= x else math.nextafter(float(f"{y:.6g}"), 0.0)


def _inner_level(ctx: _Context, c: float, region: Mapping[str, tuple[float, float]]
                 ) -> tuple[float, BoundCertificate] | str:
    """An inner level ``c_in < c`` with ``W < c_w`` proven on ``{V <= c_in}`` (halved until it holds)."""
    c_w = ctx.inner["c_w"]
    c_in = _floor6(min(ctx.inner_ratio * float(c_w), 0.5 * c))
    last = None
    for _ in range(6):
        cert = bound_on_sublevel(ctx.inner["W"], region, sets=[(ctx.lyapunov, c_in)], good_enough=0.999 * float(c_w),
                                 max_boxes=ctx.max_boxes)
        if cert.certified and Fraction(cert.bound) < c_w:
            return c_in, cert
        last = cert.bound
        c_in = _floor6(0.5 * c_in)
    return (f"inner argument: W < c_w = {float(c_w):.6g} not proven on {{V <= c_in}} down to c_in = {c_in:.3g} "
            f"(bound {last:.6g})")


def _negative_on(poly: Polynomial, ctx: _Context, region: Mapping[str, tuple[float, float]], c: float
                 ) -> BoundCertificate:
    return bound_on_sublevel(poly, region, sets=[(ctx.lyapunov, c)], good_enough=-1e-12, max_boxes=ctx.max_boxes)


def _term_certificates(ctx: _Context, c: float, region: Mapping[str, tuple[float, float]]
                       ) -> tuple[tuple[tuple[int, str, BoundCertificate], ...],
                                  tuple[tuple[str, int, str, BoundCertificate], ...]] | str:
    """Invariant terms ``> 0`` and, per outgoing transition, one guard term ``< 0`` on ``S`` (bounds)."""
    invariant = []
    for k, (label, h) in enumerate(ctx.polys.invariant_terms):
        cert = _negative_on(-h, ctx, region, c)
        if not (cert.certified and cert.bound < 0.0):
            return f"{label} > 0 on S not proven (upper bound of -term: {cert.bound:.6g} >= 0)"
        invariant.append((k, label, cert))
    guards = []
    for name, terms in ctx.polys.guards:
        bounds = []
        for k, (label, g) in enumerate(terms):
            cert = _negative_on(g, ctx, region, c)
            if cert.certified and cert.bound < 0.0:
                guards.append((name, k, label, cert))
                break
            bounds.append(f"{cert.bound:.6g}")
        else:
            return (f"guard of transition {name!r}: no term proven < 0 on S (upper bounds {', '.join(bounds)}): "
                    "the transition may be enabled in S")
    return tuple(invariant), tuple(guards)


def _sublevel_reason(cert: SublevelCertificate) -> str:
    if cert.status == "counterexample" and cert.counterexample:
        point = {k: float(f"{v:.6g}") for k, v in cert.counterexample["point"].items()}
        return f"dV/dt > 0 proven at {point} in the annulus (the level is too high for this V)"
    if cert.status == "reaches_boundary":
        return "the set reaches the faces of the box B"
    return f"invariance not decided ({cert.status}, {cert.boxes_examined} boxes)"


def _attempt(ctx: _Context, c: float) -> _Proof | str:
    """All proofs at level ``c`` (module docstring), or why one failed."""
    names = ctx.polys.variables
    base = _extent_box(ctx.vfun, c, ctx.dirs, _BOX_SCALE)
    if not np.all(np.isfinite(base)):
        return f"the set {{V <= {c:.6g}}} is unbounded along some direction"
    sub, inner, c_in, region = None, None, 0.0, {}
    for grow in (1.0, 1.5):
        region = {z: (float(grow * lo), float(grow * hi)) for z, (lo, hi) in zip(names, base)}
        found = _inner_level(ctx, c, region)
        if isinstance(found, str):
            return found
        c_in, inner = found
        sub = certify_sublevel(ctx.lyapunov, ctx.rate, region, rho_out=c, rho_in=c_in, strict=True,
                               max_boxes=ctx.max_boxes)
        if sub.status != "reaches_boundary":
            break
    if not sub.certified:
        return "sublevel: " + _sublevel_reason(sub)
    sub = sharpen_layers(ctx.lyapunov, ctx.rate, sub)
    terms = _term_certificates(ctx, c, region)
    if isinstance(terms, str):
        return terms
    return _Proof(level=c, inner_level=c_in, region=region, sublevel=sub, inner=inner, invariant=terms[0],
                  guards=terms[1], time=time_bound(ctx.lyapunov, sub))


def _prove(ctx: _Context, c0: float, refine: int) -> tuple[_Proof | None, list[dict[str, Any]]]:
    """Shrink the level along :data:`_LADDER` until the proofs hold, then bisect up ``refine`` times."""
    attempts: list[dict[str, Any]] = []
    proof, failed = None, None
    for fraction in _LADDER:
        c = _floor6(c0 * fraction)
        result = _attempt(ctx, c)
        attempts.append({"level": c, "result": "proven" if isinstance(result, _Proof) else result})
        if isinstance(result, _Proof):
            proof = result
            break
        failed = c
    if proof is None or failed is None:
        return proof, attempts
    for _ in range(refine):
        c = _floor6(0.5 * (proof.level + failed))
        if not proof.level < c < failed:
            break
        result = _attempt(ctx, c)
        attempts.append({"level": c, "result": "proven" if isinstance(result, _Proof) else result})
        if isinstance(result, _Proof):
            proof = result
        else:
            failed = c
    return proof, attempts


# --------------------------------------------------------------------------- the result


@dataclass(frozen=True, kw_only=True, slots=True)
class ModeRegion:
    """Outcome of :func:`mode_region_of_attraction` (the module docstring states what is proven).

    Attributes
    ----------
    mode : str
    status : str
        One of :data:`MODE_REGION_STATUSES`.
    why : str
        Why not proven / not applicable (empty when proven).
    claim : str
        The precise statement proven (empty unless ``"proven"``).
    equilibrium : tuple of float or None, shape (n,)
        ``x*`` in state units.
    memory : dict
        Memory values the claim is about (constant: no transition fires in ``S``).
    degree : int
        Requested degree of ``V``.
    state_names, variables : tuple of str
        The state names and the shifted coordinates ``Δx = x − x*`` of the certificates.
    lyapunov : str
        ``V`` in the state names, exact (dyadic coefficients; empty when none was found).
    lyapunov_terms : tuple of (tuple of int, str)
        ``V`` in the shifted coordinates: exponents and exact coefficient ``"p/q"`` per monomial.
    level, inner_level : float or None
        ``c`` and ``c_in`` (``S = {x ∈ B : V <= c}``).
    box : dict of str -> (float, float)
        ``B`` in state coordinates, ``x* + [lo, hi]`` rounded outward [state units] (the certificates'
        box is the exact one, in the shifted coordinates).
    certificates : dict
        ``"sublevel"`` (:meth:`SublevelCertificate.as_dict`), ``"invariant"``, ``"guards"`` (bound
        certificates per term) and ``"inner"`` (its bound certificate and exact rationals).
    rechecked : bool
        Every certificate re-checked independently (scalar interval arithmetic; exact rationals).
    time_bound_s : float or None
        Every execution from ``S`` enters ``{V <= c_in}`` within this time [s].
    convergence_rate : float or None
        ``κ`` [1/s]: ``W(x(t) − x_e) <= e^{−κ (t − t1)} W(x(t1) − x_e)`` once inside ``{V <= c_in}``.
    equilibrium_radius : float or None
        ``‖x_e − x*‖₂ <=`` this (0: ``x_e = x*``) [state units].
    search : str
        What the numeric search did (SOS level, what limited the first level tried).
    attempts : tuple of dict
        ``{"level", "result"}`` per level tried: ``"proven"`` or which proof failed.
    boxes_examined : int
        Boxes of the certificates of the proven level.
    """

    mode: str
    status: str
    why: str = ""
    claim: str = ""
    equilibrium: tuple[float, ...] | None = None
    memory: dict[str, float] = field(default_factory=dict)
    degree: int = 2
    state_names: tuple[str, ...] = ()
    variables: tuple[str, ...] = ()
    lyapunov: str = ""
    lyapunov_terms: tuple[tuple[tuple[int, ...], str], ...] = ()
    level: float | None = None
    inner_level: float | None = None
    box: dict[str, tuple[float, float]] = field(default_factory=dict)
    certificates: dict[str, Any] = field(default_factory=dict)
    rechecked: bool = False
    time_bound_s: float | None = None
    convergence_rate: float | None = None
    equilibrium_radius: float | None = None
    search: str = ""
    attempts: tuple[dict[str, Any], ...] = ()
    boxes_examined: int = 0

    def lyapunov_polynomial(self) -> Polynomial | None:
        """``V`` as an exact polynomial in the shifted coordinates :attr:`variables` (``None`` without one)."""
        return _from_terms(self.lyapunov_terms, self.variables) if self.lyapunov_terms else None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (no NaN), deterministic; exact numbers of the certificates as hex floats / ``"p/q"``."""
        return {
            "format": MODE_REGION_FORMAT, "mode": self.mode, "status": self.status, "why": self.why,
            "claim": self.claim, "equilibrium": None if self.equilibrium is None else list(self.equilibrium),
            "memory": dict(self.memory), "degree": self.degree, "state_names": list(self.state_names),
            "variables": list(self.variables), "lyapunov": self.lyapunov,
            "lyapunov_terms": [[list(e), c] for e, c in self.lyapunov_terms], "level": self.level,
            "inner_level": self.inner_level, "box": {k: [lo, hi] for k, (lo, hi) in self.box.items()},
            "certificates": self.certificates, "rechecked": self.rechecked, "time_bound_s": self.time_bound_s,
            "convergence_rate": self.convergence_rate, "equilibrium_radius": self.equilibrium_radius,
            "search": self.search, "attempts": [dict(a) for a in self.attempts],
            "boxes_examined": self.boxes_examined,
        }


def _exact_terms(poly: Polynomial, variables: Sequence[str]) -> tuple[tuple[tuple[int, ...], str], ...]:
    rows = []
    for monomial, c in poly.terms.items():
        powers = dict((a.variable, p) for a, p in monomial)
        rows.append((tuple(powers.get(v, 0) for v in variables), str(c)))
    return tuple(sorted(rows))


def _from_terms(rows: Sequence[Sequence[Any]], variables: Sequence[str]) -> Polynomial:
    out: dict[tuple[tuple[Atom, int], ...], Fraction] = {}
    for exps, c in rows:
        key = tuple((Atom.var(v), int(e)) for v, e in sorted(zip(variables, exps)) if int(e))
        out[key] = out.get(key, Fraction(0)) + Fraction(str(c))
    return Polynomial(out)


def _inner_dict(inner: Mapping[str, Any], cert: BoundCertificate, variables: Sequence[str]) -> dict[str, Any]:
    data = {k: str(inner[k]) for k in ("r", "mu", "sigma", "lambda_max", "c_w", "kappa", "epsilon")}
    data["W"] = [[list(e), c] for e, c in _exact_terms(inner["W"], variables)]
    data["certificate"] = cert.as_dict()
    return data


def _inner_from(data: Mapping[str, Any], variables: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {k: Fraction(str(data[k])) for k in ("r", "mu", "sigma", "lambda_max", "c_w", "kappa",
                                                               "epsilon")}
    out["W"] = _from_terms(data["W"], variables)
    return out


def _state_box(polys: ModePolynomials, region: Mapping[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    out = {}
    for name, x, (lo, hi) in zip(polys.state_names, polys.equilibrium, region.values()):
        out[name] = (math.nextafter(x + lo, -math.inf), math.nextafter(x + hi, math.inf))
    return out


def _state_lyapunov(polys: ModePolynomials, v: Polynomial) -> str:
    table = {z: Polynomial.atom(n) - Fraction(x) for z, n, x in zip(polys.variables, polys.state_names,
                                                                      polys.equilibrium)}
    return str(substitute_exact(v, table))


def _shown(polys: ModePolynomials, poly: Polynomial, *, define: bool = True) -> str:
    """``poly`` in the state names when ``x* = 0``, else in the shifted names (readable, still exact)."""
    if not any(polys.equilibrium):
        return _state_lyapunov(polys, poly)
    if not define:
        return str(poly)
    shifts = ", ".join(f"{z} = {n} - {x!r}" for z, n, x in zip(polys.variables, polys.state_names, polys.equilibrium))
    return f"{poly} with {shifts}"


def _safe(x: float, direction: int, digits: int = 4) -> str:
    """``x`` to ``digits`` significant digits, rounded up (``direction > 0``) or down: the weaker claim."""
    if x == 0 or not math.isfinite(x):
        return repr(x)
    q = 10.0 ** (math.floor(math.log10(abs(x))) - digits + 1)
    y = (math.ceil(x / q) if direction > 0 else math.floor(x / q)) * q
    text = f"{y:.{digits}g}"
    while (float(text) < x) if direction > 0 else (float(text) > x):
        y += direction * q
        text = f"{y:.{digits}g}"
    return text


def _claim_box(polys: ModePolynomials, proof: _Proof) -> str:
    """``B`` exactly (the certificate's floats), in the shifted coordinates unless ``x* = 0``."""
    shifted = any(polys.equilibrium)
    names = polys.variables if shifted else polys.state_names
    box = " x ".join(f"{n} in [{lo!r}, {hi!r}]" for n, (lo, hi) in zip(names, proof.region.values()))
    return box + (" (" + ", ".join(f"{z} = {n} - x*_{n}" for z, n in zip(polys.variables, polys.state_names)) + ")"
                  if shifted else "")


def _claim(polys: ModePolynomials, proof: _Proof, v: Polynomial, inner: Mapping[str, Any]) -> str:
    q, c, c_in = polys.mode, proof.level, proof.inner_level
    xstar = ", ".join(f"{n}={x!r}" for n, x in zip(polys.state_names, polys.equilibrium))
    terms = dict(polys.guards)
    positive = [f"{label}: {_shown(polys, polys.invariant_terms[k][1], define=False)} > 0"
                for k, label, _ in proof.invariant]
    negative = [f"{name!r}: {label}: {_shown(polys, terms[name][k][1], define=False)} < 0"
                for name, k, label, _ in proof.guards]
    invariant = (f"every term of the invariant of {q!r} is > 0 on S ({'; '.join(positive)})" if positive
                 else f"mode {q!r} has no invariant")
    guards = (f"every transition leaving {q!r} has a guard term < 0 on S ({'; '.join(negative)})" if negative
              else f"no transition leaves {q!r}")
    eps = inner["epsilon"]
    target = ("x_e = x* (f(x*) = 0 exactly)" if eps == 0
              else f"|x_e - x*| <= {_safe(float(eps), 1, 3)} (2-norm; f vanishes at x* only up to rounding)")
    return (
        f"In mode {q!r} with memory {dict(polys.memory)}, about x* = ({xstar}): let V(x) = {_shown(polys, v)}, "
        f"B = {_claim_box(polys, proof)} and S = {{x in B : V(x) <= {c!r}}}. S does not meet the boundary of B "
        f"and is positively invariant under the flow of {q!r}; {invariant}; {guards}. So no transition is enabled "
        f"in S, and every execution that is in {q!r} with its state in S stays in {q!r} at all later times "
        f"(no jump is forced or possible; the memory stays constant). dV/dt < 0 on {{{c_in!r} <= V <= {c!r}}}: the "
        f"execution enters {{x in B : V(x) <= {c_in!r}}} within {_safe(proof.time['bound'], 1)} s and stays there. "
        f"That set lies in {{W(x) < {_safe(float(inner['c_w']), 1)}}} with "
        f"W(x) = {_shown(polys, inner['W'], define=False)}, "
        f"where the flow contracts: P Df + Df' P <= -{_safe(float(inner['mu'] - inner['sigma']), -1, 3)} I with "
        f"d'Pd the quadratic form of W. The execution therefore converges to the unique equilibrium x_e of the flow "
        f"in that set, (x(t) - x_e)'P(x(t) - x_e) <= exp(-{_safe(float(inner['kappa']), -1, 3)} (t - t1)) "
        f"(x(t1) - x_e)'P(x(t1) - x_e) after the entry time t1, and {target}. Proven by interval branch and bound "
        "on the exact polynomials (V with dyadic coefficients) and exact rational arithmetic; every certificate "
        "re-checked independently.")


def _assemble(polys: ModePolynomials, proof: _Proof, candidate: _Candidate, inner: Mapping[str, Any], degree: int,
              search: str, attempts: Sequence[dict[str, Any]]) -> ModeRegion:
    v = candidate.lyapunov
    assert v is not None
    lyapunov = _state_lyapunov(polys, v)
    box = _state_box(polys, proof.region)
    certificates = {
        "sublevel": proof.sublevel.as_dict(),
        "time": proof.time,
        "inner": _inner_dict(inner, proof.inner, polys.variables),
        "invariant": [{"index": k, "term": label, "certificate": c.as_dict()} for k, label, c in proof.invariant],
        "guards": [{"transition": name, "index": k, "term": label, "certificate": c.as_dict()}
                   for name, k, label, c in proof.guards],
    }
    return ModeRegion(
        mode=polys.mode, status="proven", claim=_claim(polys, proof, v, inner),
        equilibrium=polys.equilibrium, memory=dict(polys.memory), degree=degree, state_names=polys.state_names,
        variables=polys.variables, lyapunov=lyapunov, lyapunov_terms=_exact_terms(v, polys.variables),
        level=proof.level, inner_level=proof.inner_level, box=box, certificates=certificates,
        time_bound_s=proof.time["bound"], convergence_rate=float(inner["kappa"]),
        equilibrium_radius=float(inner["epsilon"]) if inner["epsilon"] == 0 else math.nextafter(
            float(inner["epsilon"]), math.inf),
        search=search, attempts=tuple(attempts), boxes_examined=proof.boxes_examined)


def _recheck_bound_entry(poly: Polynomial, sets: Sequence[tuple[Polynomial, float]], entry: Mapping[str, Any],
                         region: Mapping[str, tuple[float, float]], what: str, below: Fraction | float,
                         arithmetic: str) -> list[str]:
    problems = [f"{what}: {p}" for p in recheck_bound(poly, sets, entry, region=region, arithmetic=arithmetic)]
    try:
        bound = float.fromhex(entry["bound"])
    except (KeyError, TypeError, ValueError):
        return problems + [f"{what}: no readable bound"]
    if not Fraction(bound) < Fraction(below):
        problems.append(f"{what}: the bound {bound!r} is not below {float(below)!r}")
    return problems


def _recheck_core(polys: ModePolynomials, data: Mapping[str, Any], arithmetic: str) -> list[str]:
    """Reasons why the claim of ``data`` (a :meth:`ModeRegion.as_dict`) does not hold for ``polys``."""
    z = polys.variables
    v = _from_terms(data["lyapunov_terms"], z)
    rate = lie_derivative(v, polys.rates)
    level, inner_level, certs = float(data["level"]), float(data["inner_level"]), data["certificates"]
    sub = certs["sublevel"]
    problems = [f"sublevel: {p}" for p in recheck_sublevel(v, rate, sub, arithmetic=arithmetic)]
    try:
        region = dict(zip(sub["variables"], SublevelCertificate.from_dict(sub).region))
        if float.fromhex(sub["rho_out"]) != level or float.fromhex(sub["rho_in"]) != inner_level:
            problems.append("sublevel: its levels differ from the claim's level and inner level")
        problems += time_problems(v, SublevelCertificate.from_dict(sub), certs["time"], data["time_bound_s"])
    except (KeyError, TypeError, ValueError, ParameterError) as err:
        return problems + [f"unreadable sublevel certificate: {err}"]
    if tuple(region) != z:
        problems.append(f"sublevel: variables {tuple(region)} differ from {z}")
    inner = _inner_from(certs["inner"], z)
    problems += [f"inner: {p}" for p in inner_problems(polys, inner)]
    problems += _recheck_bound_entry(inner["W"], [(v, inner_level)], certs["inner"]["certificate"], region, "inner",
                                     inner["c_w"], arithmetic)
    seen = {int(e["index"]): e for e in certs["invariant"]}
    for k, (label, h) in enumerate(polys.invariant_terms):
        if k not in seen:
            problems.append(f"no certificate for {label}")
            continue
        problems += _recheck_bound_entry(-h, [(v, level)], seen[k]["certificate"], region, label, 0.0, arithmetic)
    guards = {e["transition"]: e for e in certs["guards"]}
    for name, terms in polys.guards:
        entry = guards.get(name)
        if entry is None or not 0 <= int(entry["index"]) < len(terms):
            problems.append(f"no certificate that the guard of transition {name!r} is disabled on S")
            continue
        label, g = terms[int(entry["index"])]
        problems += _recheck_bound_entry(g, [(v, level)], entry["certificate"], region, label, 0.0, arithmetic)
    return problems


def recheck_mode_region(system: HybridSystem, region: ModeRegion | Mapping[str, Any], *,
                        arithmetic: str = "scalar") -> tuple[str, ...]:
    """Reasons why ``region`` does not prove its claim about ``system`` (empty tuple: it does).

    The mode's polynomials are traced again from ``system`` at the stored equilibrium and memory, ``V``
    is read from its exact coefficients, and every certificate is re-checked from its written boxes
    (:func:`analysis.sublevel.recheck_sublevel`, :func:`analysis.sublevel.recheck_bound`) and the
    inner argument from its stored rationals, exactly.

    Parameters
    ----------
    system : HybridSystem
    region : ModeRegion or its ``as_dict()``
    arithmetic : str
        ``"scalar"`` (independent of the search's arithmetic) or ``"batched"``.
    """
    arithmetic = _check_arithmetic(arithmetic)
    data = region.as_dict() if isinstance(region, ModeRegion) else region
    if not isinstance(data, Mapping) or data.get("format") != MODE_REGION_FORMAT:
        return (f"not a ModeRegion.as_dict() (format {MODE_REGION_FORMAT!r})",)
    if data.get("status") != "proven":
        return (f"the region does not claim a proof (status {data.get('status')!r})",)
    try:
        polys = mode_polynomials(system, data["mode"], data["equilibrium"], memory=data["memory"])
        return tuple(_recheck_core(polys, data, arithmetic))
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as err:
        return (f"unreadable region: {type(err).__name__}: {err}",)


# --------------------------------------------------------------------------- the entry point


def _equilibrium(system: HybridSystem, mode: str, equilibrium: np.ndarray | None, guess: np.ndarray | None,
                 memory: Mapping[str, float]) -> tuple[float, ...] | str:
    """``x*``: a Hurwitz equilibrium of ``mode`` inside its invariant, or why not."""
    start = equilibrium if equilibrium is not None else guess
    e = mode_equilibrium(system, mode, guess=None if start is None else tuple(start.tolist()), memory=memory)
    if e.kind == "none" or e.point is None:
        return e.finding
    if equilibrium is not None and e.point != tuple(equilibrium.tolist()):
        return (f"the given point {tuple(equilibrium.tolist())} is not an equilibrium of mode {mode!r} "
                f"(|f(x)|_inf > 1e-9; Newton moves it to {tuple(float(f'{c:.9g}') for c in e.point)})")
    if e.kind != "equilibrium":
        return e.finding
    if not e.hurwitz:
        eig = ", ".join(f"{m.real:.3g}{m.imag:+.3g}j" for m in e.modes)
        return (f"the equilibrium {tuple(float(f'{c:.6g}') for c in e.point)} of mode {mode!r} is not "
                f"exponentially stable (Jacobian eigenvalues {eig}: not Hurwitz); a region of attraction needs a "
                "Hurwitz linearisation")
    return e.point


@dataclass(frozen=True, kw_only=True, slots=True)
class _Options:
    """The validated options of :func:`mode_region_of_attraction`."""

    degree: int
    max_boxes: int
    max_extent: float
    iterations: int
    refine: int
    arithmetic: str


def _check_arithmetic(arithmetic: Any) -> str:
    if arithmetic not in ARITHMETICS:
        raise ParameterError("arithmetic", arithmetic, f"one of {ARITHMETICS}",
                             "use 'scalar' (independent re-check) or 'batched' (fast)")
    return str(arithmetic)


def _check_options(degree: Any, max_dimension: Any, max_boxes: Any, max_extent: Any, iterations: Any,
                   refine: Any, arithmetic: Any) -> _Options:
    _check_int("max_dimension", max_dimension, 1, "use e.g. 4 (branch and bound grows fast with the dimension)")
    return _Options(
        degree=_check_int("degree", degree, 2, "use 2 (quadratic V) or 4", even=True),
        max_boxes=_check_int("max_boxes", max_boxes, 1000, f"use e.g. {DEFAULT_MAX_BOXES}"),
        max_extent=_check_positive("max_extent", max_extent, "give the largest |x_i - x*_i| of interest, e.g. 100"),
        iterations=_check_int("iterations", iterations, 0, "use e.g. 4 SOS alternations"),
        refine=_check_int("refine", refine, 0, "use e.g. 2 bisection steps"),
        arithmetic=_check_arithmetic(arithmetic))


def _refused(mode: str, status: str, why: str, **known: Any) -> ModeRegion:
    return ModeRegion(mode=mode, status=status, why=why, **known)


def mode_region_of_attraction(
    system: HybridSystem,
    mode: str,
    *,
    equilibrium: Sequence[float] | None = None,
    guess: Sequence[float] | None = None,
    memory: Mapping[str, float] | None = None,
    degree: int = 2,
    max_dimension: int = 4,
    max_boxes: int = DEFAULT_MAX_BOXES,
    max_extent: float = 100.0,
    iterations: int = 4,
    refine: int = 2,
    arithmetic: str = "scalar",
) -> ModeRegion:
    """A proven region of attraction of ``mode``'s equilibrium for the hybrid system (module docstring).

    Parameters
    ----------
    system : HybridSystem
    mode : str
    equilibrium : sequence of float, shape (n,), optional
        ``x*`` [state units]; checked to be an equilibrium (``|f(x*)|_inf <= 1e-9``).
    guess : sequence of float, shape (n,), optional
        Start of Newton's method for ``x*`` (default: the origin); not with ``equilibrium``.
    memory : Mapping, optional
        Memory values (default: the automaton's initial memory).
    degree : int
        Even degree ``>= 2`` of ``V`` (2: from the linearisation; 4, 6: SOS alternation).
    max_dimension : int
        Larger systems are "not applicable" (the branch and bound grows exponentially with ``n``).
    max_boxes : int
        Budget of each branch-and-bound search.
    max_extent : float
        Largest ``|x_i − x*_i|`` of the set [state units] when nothing else bounds it.
    iterations : int
        SOS alternations for ``degree >= 4``.
    refine : int
        Bisection steps up from the first proven level of the ladder.
    arithmetic : str
        Arithmetic of the final re-check (:data:`analysis.sublevel.ARITHMETICS`): ``"scalar"``
        (independent of the search's; seconds per ten thousand boxes) or ``"batched"``.

    Returns
    -------
    ModeRegion
        ``status`` ``"proven"``, ``"not proven"`` (``why``: the failing search or proof per level) or
        ``"not applicable"`` (``why``).

    Raises
    ------
    ParameterError
        Not a system, unknown mode, wrong-length or non-finite ``equilibrium``/``guess``, both given,
        bad ``memory``, odd or ``< 2`` ``degree``, bad ``max_dimension``, ``max_boxes``, ``max_extent``,
        ``iterations``, ``refine`` or ``arithmetic``.
    """
    check_system_mode(system, mode)
    options = _check_options(degree, max_dimension, max_boxes, max_extent, iterations, refine, arithmetic)
    x_eq = None if equilibrium is None else state_point("equilibrium", equilibrium, system)
    x_guess = None if guess is None else state_point("guess", guess, system)
    if x_eq is not None and x_guess is not None:
        raise ParameterError("guess", tuple(x_guess.tolist()), "None when equilibrium is given",
                             "give either equilibrium= (checked) or guess= (Newton's start)")
    mem = mode_memory(system, memory)
    known = {"memory": mem, "degree": degree, "state_names": system.state_names}
    if system.dimension > max_dimension:
        return _refused(mode, "not applicable", (
            f"the system has {system.dimension} states > max_dimension = {max_dimension}: interval branch and "
            "bound grows exponentially with the dimension; raise max_dimension to try anyway"), **known)
    xstar = _equilibrium(system, mode, x_eq, x_guess, mem)
    if isinstance(xstar, str):
        return _refused(mode, "not applicable", xstar, **known)
    known["equilibrium"] = xstar
    try:
        polys = mode_polynomials(system, mode, xstar, memory=mem)
    except NotPolynomialError as err:
        return _refused(mode, "not applicable", f"the {err.parameter} is not polynomial in the state "
                        f"({err.value}): {err.fix}", **known)
    return _region(polys, options, known)


def _region(polys: ModePolynomials, options: _Options, known: dict[str, Any]) -> ModeRegion:
    known["variables"] = polys.variables
    a = np.array(linear_part(polys.rates, polys.variables), dtype=float)
    if not np.linalg.eigvals(a).real.max() < 0:
        return _refused(polys.mode, "not applicable", "the exact Jacobian at x* is not Hurwitz", **known)
    p = _lyapunov_matrix(a)
    candidate = _search(polys, p, options.degree, options.iterations)
    if candidate.lyapunov is None:
        return _refused(polys.mode, "not proven", candidate.message, search=candidate.message, **known)
    v = candidate.lyapunov
    c0, limited = _start_level(polys, v, candidate.level, options.max_extent)
    search = f"{candidate.message}; first level {c0:.6g}, limited by {limited}"
    known.update(search=search, lyapunov=_state_lyapunov(polys, v),
                 lyapunov_terms=_exact_terms(v, polys.variables))
    if not c0 > 0:
        return _refused(polys.mode, "not applicable", (
            f"x* lies on the boundary of where the mode may be kept ({limited.removesuffix(' (estimated)')} is 0 "
            "there): no neighbourhood of x* stays in the mode"), **known)
    dirs = _directions(len(polys.variables))
    vfun = _numeric(v, polys.variables)
    extent = _extent_box(vfun, c0, dirs, 1.0)
    if not np.all(np.isfinite(extent)):
        return _refused(polys.mode, "not proven", f"the set {{V <= {c0:.6g}}} is unbounded along some direction",
                        **known)
    w = _quadratic_form(p, polys.variables)
    inner = inner_data(polys, w, float(np.abs(extent).max()))
    if isinstance(inner, str):
        return _refused(polys.mode, "not proven", inner, **known)
    ctx = _Context(polys=polys, lyapunov=v, rate=lie_derivative(v, polys.rates), vfun=vfun, inner=inner,
                   inner_ratio=_inner_ratio(v, w, polys.variables), dirs=dirs, max_boxes=options.max_boxes)
    proof, attempts = _prove(ctx, c0, options.refine)
    if proof is None:
        tried = "; ".join(f"at V <= {a['level']:.6g}: {a['result']}" for a in attempts)
        return _refused(polys.mode, "not proven", f"no level proven ({tried})", attempts=tuple(attempts), **known)
    region = _assemble(polys, proof, candidate, inner, options.degree, search, attempts)
    problems = _recheck_core(polys, region.as_dict(), options.arithmetic)
    if problems:
        return _refused(polys.mode, "not proven", "re-check failed: " + "; ".join(problems[:5]),
                        attempts=tuple(attempts), **known)
    return ModeRegion(**{**{name: getattr(region, name) for name in ModeRegion.__slots__}, "rechecked": True})


def _inner_ratio(v: Polynomial, w: Polynomial, variables: Sequence[str]) -> float:
    """``c_in / c_w`` to try first: ``{V <= c_in}`` inside ``{W < c_w}`` for the quadratic parts, with margin."""
    if v == w:
        return 0.9
    pv = np.array(quadratic_matrix(v, variables), dtype=float)
    pw = np.array(quadratic_matrix(w, variables), dtype=float)
    if not np.linalg.eigvalsh(pv).min() > 0:
        return 0.01
    gamma = float(np.linalg.eigvals(np.linalg.solve(pv, pw)).real.max())
    return 0.5 / max(gamma, 1e-12)
