"""Sum-of-squares certificates for the path-following loop, re-proven by interval branch and bound.

The loop is composed in CasADi from :func:`visnav.model.path_following_omega`
and :func:`visnav.model.path_error_rates` (the functions the simulation
evaluates) and put in exact normal form (:mod:`analysis.polynomial`): with
the curvature ``κ = 1/ρ`` cancelling,

    δ̇ = v sin α,    α̇ = −v (k δ + α + 2k sin α),    ω = v (k δ + α + 2k sin α + κ cos α).

Polynomialisation (the search only)
-----------------------------------
The SOS programs (:mod:`analysis.sos`) work in the scaled variables
``x = δ/d0``, ``u = α/α_b`` (``|α| <= α_b = 0.95 π``), ``s = sin α`` and
``r = 1 − cos α`` (so that the equilibrium is the origin), on the
semialgebraic set

* ``1 − x² >= 0``, ``1 − u² >= 0``, the circle ``s² + r² − 2r = 0``;
* ``m α² <= α s <= α²`` with ``m = sin α_b/α_b`` (``sin α/α`` decreases on
  ``[0, π]``): it ties ``α`` to ``s``; without the lower bound the relaxation
  contains points with ``s = 0 ≠ α`` where no ``V`` can decrease strictly;
* ``0 <= r <= min(α²/2, 1 − cos α_b)``.

``α`` itself is a variable of the programs because it enters ``α̇``; ``V``
depends on ``(x, s, r)`` only.  Any valid relaxation will do: what the
programs return is re-proven on the true functions.

Proof (the interval re-check)
-----------------------------
Every ``V`` found is rounded to dyadic rationals and mapped back exactly to
``δ, sin α, cos α``; ``V̇`` is its exact Lie derivative along the normal-form
rates.  :func:`analysis.sublevel.certify_sublevel` then proves on the strip
``|δ| <= d0, |α| <= α_b`` that ``{V <= ρ}`` does not reach the strip's
boundary and is positively invariant (``V̇ < 0`` on an annulus below
``ρ``), and :func:`analysis.sublevel.bound_on_sublevel` bounds ``|δ|`` and
``|ω|`` over the intersection of every certified set that contains the entry
(``κ = 1/(R + d0 + δ)`` over the scenario's radii ``R``, an auxiliary
variable).  Only those bounds are claimed, labelled ``"proven"`` when the
certificates hold and their re-check (:func:`analysis.sublevel.recheck_sublevel`,
:func:`analysis.sublevel.recheck_bound`) passes: in the independent scalar
arithmetic for the region and the scenario's bypass, in the search's batched
arithmetic for the gain scan (:data:`RECHECK_SCAN`).

Entry
-----
The supervisor switches to full path following at the first sample after
crossing ``d−``: the robot moves at most ``v T`` in a period, so the entry
offset lies in ``[d− − d0 − v T, d− − d0]``; the entry angle ``α0`` is the
simulated one (:func:`visnav.studies.loop_analysis.entry_angles_from_simulation`,
sampled: one run, and independent of ``k``, which acts only after the
switch).  Every set used contains the whole entry segment (its level is a
certified upper bound of ``V`` there).

Sets used along a bypass (all contain the entry segment and are certified):

* the hand-given ``V = k δ²/2 + 1 − cos α`` at its level (``V̇ <= 0``, zero on ``α = 0``);
* ``V_δ``: maximise ``γ`` with ``V <= 1`` on the entry, ``V >= γ x²`` (the
  thinnest set in ``δ``), ``V`` above the strip's boundary functions and
  ``−V̇ >= ε (x² + s²)`` on the set (:func:`analysis.sos.bounding_region`);
* ``V_ω``: the same with ``(k δ + α + 2k sin α)²``, the part of ``ω/v`` that
  vanishes at the equilibrium, instead of ``x²``;
* ``V_joint`` (the gain scan): both targets at once, each divided by its
  allowed value, so that ``γ >= 1`` would meet both requirements.

Each maximises ``γ − μ ‖v‖₁`` (``μ`` = :data:`REGULARISATION`): the optimum of
``γ`` alone is degenerate, with large coefficients that cancel on the circle,
and such a ``V`` has wide interval enclosures.

The hand ``V`` is not strictly decreasing (``V̇ = 0`` on ``α = 0``), so it is
not a feasible point of these programs with ``ε > 0``; it is intersected
with them instead, so that the bounds can only improve on the hand ones.

The largest region (:func:`certified_region`) is the volume heuristic
(:func:`analysis.sos.invariant_region`): minimise ``∫ V`` over the strip with
``V >= x²/0.98²`` and ``V >= r/(0.98 (1 − cos α_b))`` (so ``{V <= 1}`` stays
inside the strip) and ``−V̇ >= ε (x² + s²)``; its area is compared with the
largest hand-given sublevel set in the same strip,
``{k δ²/2 + 1 − cos α <= c*}``, ``c* = min(2, k d0²/2)``.

Admissible gains (:func:`sos_admissible_gains`)
------------------------------------------------
A gain is admissible when the certified bounds give clearance ``d0 − δ_max``
at least the required one and ``|ω| <= ω_max``, for every entry angle.  A
gain is *refuted* without any SDP when the continuous loop itself violates a
requirement: at the entry point (``|ω(x0)| > ω_max``, exact) or along a
numerically integrated solution from the entry (sampled evidence, labelled
so).  The others are searched on a grid, the boundaries refined by
bisection; each gain reported admissible has its own certificates (the joint
set, then the specific ones for a requirement it misses), all re-checked.
Between two such gains the claim is proven only where *k-interval*
certificates hold (``prove_intervals``): the sets found at one gain, with
``k`` a parameter of the branch and bound
(:func:`analysis.sublevel.certify_sublevel` with ``parameters``), over half
the gap (in ``log k``) on each side.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import casadi as ca
import numpy as np

from analysis.polynomial import Atom, Polynomial, normal_form
from analysis.sos import (
    SemialgebraicSet,
    SosPoly,
    bounding_region,
    invariant_region,
    monomial_basis,
)
from analysis.sublevel import (
    BoundCertificate,
    Reciprocal,
    SublevelCertificate,
    bound_on_sublevel,
    certify_sublevel,
    lie_derivative,
    recheck_bound,
    recheck_sublevel,
)
from hybrid.errors import ParameterError
from hybrid.jsonable import to_jsonable

from visnav import model
from visnav.parameters import K_PATH_RANGE
from visnav.studies.path_following import AdmissibleGains, admissible_gains, entry_bounds

__all__ = [
    "ALPHA_BOX_FRACTION",
    "DEFAULT_DEGREE",
    "EPSILON",
    "PolynomialLoop",
    "polynomial_loop",
    "CertifiedRegion",
    "certified_region",
    "InvariantSet",
    "BoundPair",
    "SosEntryBounds",
    "sos_entry_bounds",
    "GainEvaluation",
    "SosAdmissibleGains",
    "sos_admissible_gains",
    "entry_sets",
    "bounds_over",
    "best_bounds",
    "PathFollowingSos",
    "path_following_sos",
]

ALPHA_BOX_FRACTION = 0.95
"""The strip is ``|α| <= ALPHA_BOX_FRACTION · π`` (at ``|α| = π`` the heading wraps and the law jumps)."""
DEFAULT_DEGREE = 4
"""Degree of the SOS functions ``V`` in ``(x, sin α, 1 − cos α)``."""
EPSILON = 1e-2
"""Decay margin: ``−V̇ >= ε (x² + s²)`` in the SOS programs."""
REGULARISATION = 1e-3
"""``μ`` of :func:`analysis.sos.bounding_region` (moderate coefficients, cheap re-checks)."""
SHRINK = 0.98
"""Boundary functions reach 1 at this fraction of the strip (so ``V > 1`` on its faces)."""
INNER_FRACTION = 0.5
"""``ρ_in = INNER_FRACTION · ρ`` for the invariance certificates of the entry sets."""
REGION_INNER_LEVEL = 0.01
"""``ρ_in`` of the region certificate (every solution in ``{V <= 1}`` enters ``{V <= 0.01}``)."""
BOUND_TOLERANCE = 2e-3
"""Relative tolerance of the branch-and-bound maxima of the scan (decision mode, rarely reached)."""
HEADLINE_TOLERANCE = 5e-3
"""Relative tolerance of the reported bypass bounds (their certificates are re-checked box by box)."""
AREA_GRID = (401, 801)
"""Midpoint-rule grid ``(δ, α)`` of the area quadrature over the strip."""
RECHECK_SCAN = "batched"
"""Arithmetic of the re-checks of the gain scan (the region and the scenario's bypass use ``"scalar"``)."""
_PROGRAM = ("x", "u", "s", "r")


# --------------------------------------------------------------------------- the loop as polynomials


@dataclass(frozen=True, kw_only=True, slots=True)
class PolynomialLoop:
    """The closed loop in exact normal form, and its polynomialisation for the SOS programs.

    Attributes
    ----------
    k, v, d_zero : float
        Gain [1/m], speed [m/s], envelope offset d0 [m].
    radii : tuple of float
        Obstacle radii [m] (the curvature ``κ = 1/(R + d0 + δ)`` ranges over them).
    alpha_box : float
        ``α_b`` [rad]: the strip is ``|δ| <= d0``, ``|α| <= α_b``.
    rates : Mapping[str, Polynomial]
        ``δ̇``, ``α̇`` in the atoms ``δ, α, sin α, cos α`` (the curvature cancelled, checked).
    omega : Polynomial
        ``ω`` [rad/s] in the same atoms and ``kappa``.
    parametric_rates : Mapping[str, Polynomial]
        The rates with the gain as the variable ``k``.
    parametric_omega : Polynomial
    hand, hand_rate : Polynomial
        ``V = k δ²/2 + 1 − cos α`` and its exact derivative along the loop.
    curvature : Reciprocal
        ``kappa = 1/(R + d0 + δ)``, ``R`` in ``[min radii, max radii]``.
    program_rates : Mapping[str, SosPoly]
        The rates in ``(x, u, s, r)`` (module docstring).
    domain : SemialgebraicSet
        The relaxation of the strip in ``(x, u, s, r)``.
    """

    k: float
    v: float
    d_zero: float
    radii: tuple[float, ...]
    alpha_box: float
    rates: Mapping[str, Polynomial]
    omega: Polynomial
    parametric_rates: Mapping[str, Polynomial]
    parametric_omega: Polynomial
    hand: Polynomial
    hand_rate: Polynomial
    curvature: Reciprocal
    program_rates: Mapping[str, SosPoly]
    domain: SemialgebraicSet

    def strip(self, half_width: float | None = None) -> dict[str, tuple[float, float]]:
        """The box ``|δ| <= half_width`` (default d0), ``|α| <= α_b``."""
        d = self.d_zero if half_width is None else half_width
        return {"delta": (-d, d), "alpha": (-self.alpha_box, self.alpha_box)}

    def program_point(self, delta: float, alpha: float) -> dict[str, float]:
        """``(δ, α)`` in the program variables."""
        return {"x": delta / self.d_zero, "u": alpha / self.alpha_box, "s": math.sin(alpha),
                "r": 1.0 - math.cos(alpha)}

    def exact(self, terms: Mapping[tuple[int, ...], Fraction]) -> Polynomial:
        """A program polynomial in ``(x, s, r)`` as an exact polynomial in ``δ, sin α, cos α``."""
        x = Polynomial.atom("delta") * (1 / Fraction(self.d_zero))
        s, r = Polynomial.atom(Atom.sin("alpha")), 1 - Polynomial.atom(Atom.cos("alpha"))
        out = Polynomial({})
        for (i, j, m, n), c in terms.items():
            if j:
                raise ValueError(f"PolynomialLoop.exact: the monomial {(i, j, m, n)} depends on alpha itself")
            out = out + Polynomial.constant(c) * x**i * s**m * r**n
        return out

    def rate_of(self, lyapunov: Polynomial, *, parametric: bool = False) -> Polynomial:
        """Exact ``V̇`` along the loop (with ``k`` a variable when ``parametric``)."""
        return lie_derivative(lyapunov, self.parametric_rates if parametric else self.rates)


def _compose(k: Any, v: float, side: int) -> tuple[Any, Any, Any, Any, Any]:
    delta, alpha, kappa = ca.SX.sym("delta"), ca.SX.sym("alpha"), ca.SX.sym("kappa")
    omega = model.path_following_omega(delta, alpha, kappa, side, v, k, ops=ca)
    rates = model.path_error_rates(v, omega, alpha, kappa, side, ops=ca)
    return delta, alpha, kappa, omega, rates


def _normal_rates(k: float | None, v: float, side: int) -> tuple[dict[str, Polynomial], Polynomial]:
    gain = ca.SX.sym("k") if k is None else k
    delta, alpha, kappa, omega, rates = _compose(gain, v, side)
    symbols = [delta, alpha, kappa] + ([gain] if k is None else [])
    out = {name: normal_form(rate, symbols) for name, rate in zip(("delta", "alpha"), rates)}
    for name, poly in out.items():
        if poly.depends_on("kappa"):
            raise ValueError(f"path_following_sos: the curvature does not cancel in the rate of {name}: {poly}")
    return out, normal_form(omega, symbols)


def _program_rates(rates: Mapping[str, Polynomial], d_zero: float, alpha_box: float) -> dict[str, SosPoly]:
    x, u, s, r = (SosPoly.variable(n, _PROGRAM) for n in _PROGRAM)
    table = {Atom.var("delta"): x * d_zero, Atom.var("alpha"): u * alpha_box, Atom.sin("alpha"): s,
             Atom.cos("alpha"): 1 - r}

    def convert(poly: Polynomial) -> SosPoly:
        out = SosPoly.constant(0.0, _PROGRAM)
        for monomial, c in poly.terms.items():
            term = SosPoly.constant(float(c), _PROGRAM)
            for atom, power in monomial:
                term = term * table[atom] ** power
            out = out + term
        return out

    ddelta, dalpha = convert(rates["delta"]), convert(rates["alpha"])
    return {"x": ddelta * (1.0 / d_zero), "u": dalpha * (1.0 / alpha_box), "s": (1 - r) * dalpha, "r": s * dalpha}


def _domain(alpha_box: float) -> SemialgebraicSet:
    x, u, s, r = (SosPoly.variable(n, _PROGRAM) for n in _PROGRAM)
    chord = math.sin(alpha_box) / alpha_box
    return SemialgebraicSet(
        inequalities=(1 - x * x, 1 - u * u, u * s - u * u * (chord * alpha_box), u * u * alpha_box - u * s,
                      u * u * (0.5 * alpha_box**2) - r, (1.0 - math.cos(alpha_box)) - r),
        equalities=(s * s + r * r - 2 * r,),
    )


def polynomial_loop(*, k: float, v: float, d_zero: float, radii: Sequence[float], side: int = 1,
                    alpha_box: float = ALPHA_BOX_FRACTION * math.pi) -> PolynomialLoop:
    """Compose the loop from :mod:`visnav.model` and polynomialise it (module docstring).

    Raises
    ------
    ValueError
        Non-positive ``k``, ``v``, ``d_zero`` or radii, ``side`` not ±1, ``alpha_box`` outside ``(0, π)``.
    """
    for name, value in (("k", k), ("v", v), ("d_zero", d_zero)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"polynomial_loop: {name} = {value!r}; expected a finite number > 0")
    radii = tuple(float(r) for r in radii)
    if not radii or not all(math.isfinite(r) and r > 0 for r in radii):
        raise ValueError(f"polynomial_loop: radii = {radii!r}; expected one or more radii > 0 [m]")
    if side not in (-1, 1) or not 0 < alpha_box < math.pi:
        raise ValueError(f"polynomial_loop: side = {side!r}, alpha_box = {alpha_box!r}; expected ±1 and (0, pi)")
    rates, omega = _normal_rates(float(k), float(v), side)
    parametric, parametric_omega = _normal_rates(None, float(v), side)
    delta, alpha = ca.SX.sym("delta"), ca.SX.sym("alpha")
    hand = normal_form(float(k) * delta**2 / 2 + (1 - ca.cos(alpha)), [delta, alpha])
    return PolynomialLoop(
        k=float(k), v=float(v), d_zero=float(d_zero), radii=radii, alpha_box=float(alpha_box), rates=rates,
        omega=omega, parametric_rates=parametric, parametric_omega=parametric_omega, hand=hand,
        hand_rate=lie_derivative(hand, rates),
        curvature=Reciprocal(name="kappa", of="delta", offset=(min(radii) + d_zero, max(radii) + d_zero)),
        program_rates=_program_rates(rates, float(d_zero), float(alpha_box)), domain=_domain(float(alpha_box)),
    )


# --------------------------------------------------------------------------- SOS programs


def _basis(degree: int) -> tuple[tuple[int, ...], ...]:
    return monomial_basis(_PROGRAM, degree, min_degree=1, only=("x", "s", "r"), max_exponents={"r": 1})


def _boundary(loop: PolynomialLoop) -> list[SosPoly]:
    x, r = SosPoly.variable("x", _PROGRAM), SosPoly.variable("r", _PROGRAM)
    return [x * x * (1.0 / SHRINK**2), r * (1.0 / (SHRINK * (1.0 - math.cos(loop.alpha_box))))]


def _program_options(degree: int) -> dict[str, Any]:
    x, s = SosPoly.variable("x", _PROGRAM), SosPoly.variable("s", _PROGRAM)
    return {"degree": degree, "lyapunov_variables": ("x", "s", "r"), "stationary": ("x", "s"),
            "gram_caps": {"r": 1, "u": 1}, "epsilon": EPSILON, "positive": x * x + s * s, "basis": _basis(degree)}


def _moments(loop: PolynomialLoop, basis: Sequence[tuple[int, ...]]) -> list[float]:
    """``∫∫ x^i sin^m α (1 − cos α)^n`` over ``x ∈ [−1, 1]``, ``|α| <= α_b`` (Gauss–Legendre in α)."""
    nodes, weights = np.polynomial.legendre.leggauss(64)
    alpha, w = nodes * loop.alpha_box, weights * loop.alpha_box
    return [float((1 - (-1) ** (i + 1)) / (i + 1) * np.sum(w * np.sin(alpha) ** m * (1 - np.cos(alpha)) ** n))
            for i, _, m, n in basis]


def _entry_level(lyapunov: Polynomial, delta_entry: tuple[float, float], alpha0: float) -> float:
    """A certified upper bound of ``V`` on the entry segment ``δ ∈ delta_entry, α = α0``."""
    return bound_on_sublevel(lyapunov, {"delta": delta_entry, "alpha": (alpha0, alpha0)}, tolerance=1e-6).bound


def _evaluate_grid(poly: Polynomial, delta: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    values = {"var": {"delta": delta, "alpha": alpha}, "sin": {"alpha": np.sin(alpha)}, "cos": {"alpha": np.cos(alpha)}}
    out = np.zeros(np.broadcast(delta, alpha).shape)
    for monomial, c in poly.terms.items():
        term = np.full(out.shape, float(c))
        for atom, power in monomial:
            term = term * values[atom.kind][atom.variable] ** power
        out += term
    return out


def _area(poly: Polynomial, level: float, d_zero: float, alpha_limit: float) -> float:
    """Area [m rad] of ``{V <= level} ∩ {|δ| <= d0, |α| < alpha_limit}`` by the midpoint rule on :data:`AREA_GRID`."""
    nd, na = AREA_GRID
    dd, da = 2 * d_zero / nd, 2 * math.pi / na
    delta = -d_zero + dd * (np.arange(nd) + 0.5)
    alpha = -math.pi + da * (np.arange(na) + 0.5)
    grid_d, grid_a = np.meshgrid(delta, alpha, indexing="ij")
    inside = (_evaluate_grid(poly, grid_d, grid_a) <= level) & (np.abs(grid_a) < alpha_limit)
    return float(inside.sum() * dd * da)


# --------------------------------------------------------------------------- the largest region


@dataclass(frozen=True, kw_only=True, slots=True)
class CertifiedRegion:
    """The largest SOS region found, its proof, and its area against the hand-given ``V``'s.

    Attributes
    ----------
    k : float
    degree : int
    status : str
        ``"proven"`` (certificate holds and re-checks) or ``"not proven"``.
    why : str
    claim : str
        The certificate's claim (``{V <= 1}`` invariant in the strip, entered into ``{V <= 0.01}``).
    lyapunov : Polynomial or None
        ``V`` in ``δ, sin α, cos α`` (exact dyadic coefficients).
    certificate : SublevelCertificate or None
    recheck_problems : tuple of str
    area, hand_area : float
        [m rad] of ``{V <= 1}`` and of ``{k δ²/2 + 1 − cos α <= c*}`` in the strip.
    hand_level : float
        ``c* = min(2, k d0²/2)``.
    area_ratio : float
    sdp : dict
        The SDP's status and message.
    """

    k: float
    degree: int
    status: str
    why: str
    claim: str
    lyapunov: Polynomial | None
    certificate: SublevelCertificate | None
    recheck_problems: tuple[str, ...]
    area: float
    hand_area: float
    hand_level: float
    area_ratio: float
    sdp: dict[str, Any]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (the certificate's boxes summarised; :meth:`SublevelCertificate.as_dict` has them all)."""
        cert = self.certificate
        return to_jsonable({
            "k": self.k, "degree": self.degree, "status": self.status, "why": self.why, "claim": self.claim,
            "lyapunov": None if self.lyapunov is None else str(self.lyapunov),
            "boxes": None if cert is None else len(cert.boxes), "certificate_status": None if cert is None else cert.status,
            "entry_time_bound_s": None if cert is None else cert.entry_time_bound,
            "recheck_problems": list(self.recheck_problems), "area_m_rad": self.area, "hand_area_m_rad": self.hand_area,
            "hand_level": self.hand_level, "area_ratio": self.area_ratio, "area_grid": list(AREA_GRID), "sdp": self.sdp,
        })


def certified_region(loop: PolynomialLoop, *, degree: int = DEFAULT_DEGREE) -> CertifiedRegion:
    """Volume-heuristic SOS region (module docstring), proven by :func:`analysis.sublevel.certify_sublevel`."""
    options = _program_options(degree)
    result = invariant_region(loop.program_rates, boundary=_boundary(loop), domain=loop.domain,
                              moments=_moments(loop, options["basis"]), **options)
    hand_level = min(2.0, loop.k * loop.d_zero**2 / 2)
    hand_area = _area(loop.hand, hand_level, loop.d_zero, math.pi)
    sdp = {"status": result.lyapunov.status, "message": result.lyapunov.message}
    if not result.lyapunov.found:
        return CertifiedRegion(k=loop.k, degree=degree, status="not proven", why=result.lyapunov.message, claim="",
                               lyapunov=None, certificate=None, recheck_problems=(), area=0.0, hand_area=hand_area,
                               hand_level=hand_level, area_ratio=0.0, sdp=sdp)
    v = loop.exact(result.lyapunov.terms)
    rate = loop.rate_of(v)
    cert = certify_sublevel(v, rate, loop.strip(), rho_out=1.0, rho_in=REGION_INNER_LEVEL, strict=True)
    problems = recheck_sublevel(v, rate, cert, region=loop.strip()) if cert.certified else ()
    proven = cert.certified and not problems
    why = ("the branch and bound certifies the claim and its scalar re-check passes" if proven else
           f"certificate status {cert.status!r}" + (f"; re-check: {problems[0]}" if problems else ""))
    area = _area(v, 1.0, loop.d_zero, loop.alpha_box)
    return CertifiedRegion(k=loop.k, degree=degree, status="proven" if proven else "not proven", why=why,
                           claim=cert.claim, lyapunov=v, certificate=cert, recheck_problems=tuple(problems), area=area,
                           hand_area=hand_area, hand_level=hand_level,
                           area_ratio=area / hand_area if hand_area > 0 else math.inf, sdp=sdp)


# --------------------------------------------------------------------------- sets through the entry


@dataclass(frozen=True, kw_only=True, slots=True)
class InvariantSet:
    """A sublevel set ``{V <= level}`` through the entry segment and its certificate.

    Attributes
    ----------
    name : str
        ``"hand"``, ``"sos:delta"``, ``"sos:omega"`` or ``"sos:joint"``.
    certified : bool
        The branch and bound proves it positively invariant inside its box (``region``)
        (and, when re-checked, the re-check passes).
    why : str
    lyapunov, rate : Polynomial or None
        ``V`` and its exact derivative along the loop.
    level : float or None
        A certified upper bound of ``V`` on the entry segment.
    region : dict or None
        The box ``{"delta": (lo, hi), "alpha": (lo, hi)}`` the set lies in.
    certificate : SublevelCertificate or None
    recheck_problems : tuple of str or None
        ``None`` when not re-checked.
    """

    name: str
    certified: bool
    why: str
    lyapunov: Polynomial | None = None
    rate: Polynomial | None = None
    level: float | None = None
    region: dict[str, tuple[float, float]] | None = None
    certificate: SublevelCertificate | None = None
    recheck_problems: tuple[str, ...] | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        cert = self.certificate
        return to_jsonable({
            "name": self.name, "certified": self.certified, "why": self.why,
            "lyapunov": None if self.lyapunov is None else str(self.lyapunov), "level": self.level,
            "region": self.region, "boxes": None if cert is None else len(cert.boxes),
            "claim": None if cert is None else cert.claim,
            "rechecked": None if self.recheck_problems is None else not self.recheck_problems,
            "recheck_problems": None if self.recheck_problems is None else list(self.recheck_problems),
        })

    def rechecked(self, arithmetic: str = "scalar") -> InvariantSet:
        """The same set with its certificate re-checked (certified only if the re-check passes).

        ``arithmetic`` as in :func:`analysis.sublevel.recheck_sublevel`.
        """
        if not self.certified or self.lyapunov is None or self.rate is None or self.certificate is None:
            return self
        problems = tuple(recheck_sublevel(self.lyapunov, self.rate, self.certificate, region=self.region,
                                          arithmetic=arithmetic))
        return InvariantSet(name=self.name, certified=not problems,
                            why=self.why if not problems else f"re-check failed: {problems[0]}",
                            lyapunov=self.lyapunov, rate=self.rate, level=self.level, region=self.region,
                            certificate=self.certificate, recheck_problems=problems)


def _hand_set(loop: PolynomialLoop, delta_entry: tuple[float, float], alpha0: float) -> InvariantSet:
    level = _entry_level(loop.hand, delta_entry, alpha0)
    if level >= SHRINK * (1.0 - math.cos(loop.alpha_box)):
        return InvariantSet(name="hand", certified=False, why=f"level {level:.4g} reaches |alpha| = alpha_b")
    region = loop.strip(1.05 * math.sqrt(2.0 * level / loop.k))
    cert = certify_sublevel(loop.hand, loop.hand_rate, region, rho_out=level, rho_in=INNER_FRACTION * level,
                            strict=False, split_at={"alpha": (0.0,)})
    return InvariantSet(name="hand", certified=cert.certified, why=f"certificate status {cert.status!r}",
                        lyapunov=loop.hand, rate=loop.hand_rate, level=level, region=region, certificate=cert)


def _targets(loop: PolynomialLoop, delta_entry: tuple[float, float], alpha0: float,
             requirements: tuple[float, float] | None) -> dict[str, list[SosPoly]]:
    """Targets of the bounding programs in program variables.

    ``x²`` and ``p² = (k δ + α + 2k sin α)²`` (the part of ``ω/v`` vanishing at the equilibrium) are
    normalised to 1 at the entry's far end (so that ``γ`` is of order one and the regularisation
    weighs alike); ``"joint"`` uses both, normalised by the allowed values ``(δ_max, ω_max)``.
    """
    x, u, s = (SosPoly.variable(n, _PROGRAM) for n in ("x", "u", "s"))
    p = x * (loop.k * loop.d_zero) + u * loop.alpha_box + s * (2 * loop.k)
    far = loop.program_point(delta_entry[0], alpha0)
    out = {"delta": [x * x * (1.0 / max(far["x"] ** 2, 1e-12))],
           "omega": [p * p * (1.0 / max(p.evaluate(far) ** 2, 1e-12))]}
    if requirements is not None:
        d_allowed, w_allowed = requirements
        out["joint"] = [x * x * ((loop.d_zero / d_allowed) ** 2), p * p * ((loop.v / w_allowed) ** 2)]
    return out


def _sos_set(loop: PolynomialLoop, name: str, targets: list[SosPoly], delta_entry: tuple[float, float],
             alpha0: float, degree: int) -> InvariantSet:
    points = [loop.program_point(d, alpha0) for d in (delta_entry[0], 0.5 * sum(delta_entry), delta_entry[1])]
    result = bounding_region(loop.program_rates, points=points, targets=targets, boundary=_boundary(loop),
                             domain=loop.domain, regularisation=REGULARISATION, **_program_options(degree))
    if not result.lyapunov.found:
        return InvariantSet(name=name, certified=False, why=result.lyapunov.message)
    v = loop.exact(result.lyapunov.terms)
    rate = loop.rate_of(v)
    level = _entry_level(v, delta_entry, alpha0)
    cert = certify_sublevel(v, rate, loop.strip(), rho_out=level, rho_in=INNER_FRACTION * level, strict=True,
                            max_boxes=40_000)
    return InvariantSet(name=name, certified=cert.certified, why=f"certificate status {cert.status!r}", lyapunov=v,
                        rate=rate, level=level, region=loop.strip(), certificate=cert)


def entry_sets(loop: PolynomialLoop, *, delta_entry: tuple[float, float], alpha0: float,
               targets: Sequence[str] = ("delta", "omega"), requirements: tuple[float, float] | None = None,
               hand: bool = True, degree: int = DEFAULT_DEGREE) -> list[InvariantSet]:
    """The hand-given set and the SOS sets ``targets`` (``"delta"``, ``"omega"``, ``"joint"``) through the entry.

    Parameters
    ----------
    loop : PolynomialLoop
    delta_entry : (float, float)
        Entry offsets ``[lo, hi]`` [m].
    alpha0 : float
        Entry angle [rad].
    targets : sequence of str
    requirements : (float, float), optional
        Allowed ``(|δ|, |ω|)`` [m, rad/s], needed by ``"joint"``.
    hand : bool
        Include the hand-given ``V``.
    degree : int
    """
    polys = _targets(loop, delta_entry, alpha0, requirements)
    unknown = [t for t in targets if t not in polys]
    if unknown:
        raise ValueError(f"entry_sets: targets {unknown} unknown; expected among {sorted(polys)} "
                         "('joint' needs requirements)")
    out = [_hand_set(loop, delta_entry, alpha0)] if hand else []
    return out + [_sos_set(loop, f"sos:{t}", polys[t], delta_entry, alpha0, degree) for t in targets]


# --------------------------------------------------------------------------- bounds


@dataclass(frozen=True, kw_only=True, slots=True)
class BoundPair:
    """Certified bounds of ``|δ|`` and ``|ω|`` over the intersection of some certified sets.

    Attributes
    ----------
    sets : tuple of str
        Names of the sets intersected.
    certified : bool
    delta_max_m, omega_max_radps : float
        ``inf`` when nothing is certified.
    min_distance_m : float
        ``d0 − δ_max``: the clearance guaranteed.
    delta_certificate, omega_certificate : BoundCertificate or None
    recheck_problems : tuple of str or None
        ``None`` when not re-checked.
    """

    sets: tuple[str, ...]
    certified: bool
    delta_max_m: float
    omega_max_radps: float
    min_distance_m: float
    delta_certificate: BoundCertificate | None = None
    omega_certificate: BoundCertificate | None = None
    recheck_problems: tuple[str, ...] | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (``null`` for an infinite bound)."""
        def cert(c: BoundCertificate | None) -> Any:
            return None if c is None else {"bound": c.bound, "attained": c.attained, "status": c.status,
                                           "boxes": len(c.boxes)}
        return to_jsonable({
            "sets": list(self.sets), "certified": self.certified, "delta_max_m": self.delta_max_m,
            "omega_max_radps": self.omega_max_radps, "min_distance_m": self.min_distance_m,
            "delta_certificate": cert(self.delta_certificate), "omega_certificate": cert(self.omega_certificate),
            "rechecked": None if self.recheck_problems is None else not self.recheck_problems,
        })


def bounds_over(loop: PolynomialLoop, sets: Sequence[InvariantSet], *, delta_entry: tuple[float, float],
                alpha0: float, good_enough: tuple[float, float] | None = None, recheck: bool = False,
                tolerance: float = BOUND_TOLERANCE, arithmetic: str = "scalar") -> BoundPair:
    """Certified ``|δ|`` and ``|ω|`` bounds over the intersection of the certified ``sets``.

    ``good_enough = (δ_allowed, ω_allowed)`` decides the requirements without refining below them;
    ``recheck`` re-checks both certificates in ``arithmetic`` (:func:`analysis.sublevel.recheck_bound`).
    """
    used = [s for s in sets if s.certified]
    if not used:
        return BoundPair(sets=(), certified=False, delta_max_m=math.inf, omega_max_radps=math.inf,
                         min_distance_m=-math.inf)
    region = loop.strip(min(s.region["delta"][1] for s in used))  # type: ignore[index]
    pairs = [(s.lyapunov, s.level) for s in used]
    seeds = [{"delta": d, "alpha": alpha0} for d in delta_entry]
    enough = (None, None) if good_enough is None else good_enough
    bd = bound_on_sublevel(Polynomial.atom("delta"), region, sets=pairs, absolute=True, seeds=seeds,
                           tolerance=tolerance, good_enough=enough[0])
    bw = bound_on_sublevel(loop.omega, region, sets=pairs, absolute=True, aux=(loop.curvature,), seeds=seeds,
                           tolerance=tolerance, good_enough=enough[1])
    problems = None
    if recheck:
        problems = (recheck_bound(Polynomial.atom("delta"), pairs, bd, region=region, arithmetic=arithmetic)
                    + recheck_bound(loop.omega, pairs, bw, region=region, aux=(loop.curvature,),
                                    arithmetic=arithmetic))
    certified = bd.certified and bw.certified and not problems
    return BoundPair(sets=tuple(s.name for s in used), certified=certified,
                     delta_max_m=bd.bound if certified else math.inf, omega_max_radps=bw.bound if certified else math.inf,
                     min_distance_m=loop.d_zero - bd.bound if certified else -math.inf, delta_certificate=bd,
                     omega_certificate=bw, recheck_problems=problems)


@dataclass(frozen=True, kw_only=True, slots=True)
class SosEntryBounds:
    """Bounds along a bypass entered on the segment ``δ ∈ delta_entry``, ``α = α0``.

    Attributes
    ----------
    k : float
    delta_entry : (float, float)
        [m]; the nominal ``d− − d0`` is the upper end.
    alpha0 : float
        [rad].
    sets : tuple of InvariantSet
    hand_closed_form : dict
        :func:`visnav.studies.path_following.entry_bounds` at the nominal and at the far end of the segment.
    hand, sos, combined : BoundPair
        Bounds over the hand set alone, the SOS sets alone, and all certified sets; only ``combined``
        (the reported bounds) is re-checked, the other two are branch-and-bound certified comparisons.
    status : str
        ``"proven"`` when ``combined`` is certified (and, if re-checked, every re-check passes).
    why : str
    """

    k: float
    delta_entry: tuple[float, float]
    alpha0: float
    sets: tuple[InvariantSet, ...]
    hand_closed_form: dict[str, Any]
    hand: BoundPair
    sos: BoundPair
    combined: BoundPair
    status: str
    why: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable({
            "k": self.k, "delta_entry_m": list(self.delta_entry), "alpha0_rad": self.alpha0,
            "sets": [s.as_dict() for s in self.sets], "hand_closed_form": self.hand_closed_form,
            "hand": self.hand.as_dict(), "sos": self.sos.as_dict(), "combined": self.combined.as_dict(),
            "status": self.status, "why": self.why,
        })


def _closed_form(loop: PolynomialLoop, delta_entry: tuple[float, float], alpha0: float) -> dict[str, Any]:
    out = {}
    for label, d in (("nominal", delta_entry[1]), ("segment_end", delta_entry[0])):
        b = entry_bounds(k=loop.k, v=loop.v, d_zero=loop.d_zero, radius=min(loop.radii), delta0=d, alpha0=alpha0)
        out[label] = {"delta0_m": d, "valid": b.valid, "delta_max_m": b.delta_max_m,
                      "omega_max_radps": b.omega_max_radps, "min_distance_m": b.min_distance_m}
    return out


def sos_entry_bounds(loop: PolynomialLoop, *, delta_entry: tuple[float, float], alpha0: float,
                     degree: int = DEFAULT_DEGREE, recheck: bool = False) -> SosEntryBounds:
    """Tight certified bounds of ``|δ|``, ``|ω|`` along a bypass entered on the segment (module docstring).

    Parameters
    ----------
    loop : PolynomialLoop
    delta_entry : (float, float)
        ``[d− − d0 − v T, d− − d0]`` [m].
    alpha0 : float
        Entry angle [rad].
    degree : int
        Degree of the SOS functions.
    recheck : bool
        Re-check every certificate in scalar arithmetic (the label ``"proven"`` then requires it).
    """
    lo, hi = (float(d) for d in delta_entry)
    if not (lo <= hi and math.isfinite(lo) and math.isfinite(hi) and math.isfinite(alpha0)):
        raise ValueError(f"sos_entry_bounds: delta_entry = {delta_entry!r}, alpha0 = {alpha0!r}; expected "
                         "finite lo <= hi [m] and a finite angle [rad]")
    sets = entry_sets(loop, delta_entry=(lo, hi), alpha0=alpha0, degree=degree)
    if recheck:
        sets = [s.rechecked() for s in sets]
    pairs = {label: bounds_over(loop, [s for s in sets if pick(s)], delta_entry=(lo, hi), alpha0=alpha0,
                                recheck=recheck and label == "combined", tolerance=HEADLINE_TOLERANCE)
             for label, pick in (("hand", lambda s: s.name == "hand"), ("sos", lambda s: s.name != "hand"),
                                 ("combined", lambda s: True))}
    combined = pairs["combined"]
    proven = combined.certified
    why = (("every set used is certified by the branch and bound" + (" and re-checked" if recheck else ""))
           if proven else "no certified set, or a re-check failed")
    return SosEntryBounds(k=loop.k, delta_entry=(lo, hi), alpha0=float(alpha0), sets=tuple(sets),
                          hand_closed_form=_closed_form(loop, (lo, hi), alpha0), hand=pairs["hand"], sos=pairs["sos"],
                          combined=combined, status="proven" if proven else "not proven", why=why)


# --------------------------------------------------------------------------- admissible gains


@dataclass(frozen=True, kw_only=True, slots=True)
class GainEvaluation:
    """The verdict for one gain ``k`` (every entry angle).

    Attributes
    ----------
    k : float
    verdict : str
        ``"proven admissible"`` (certified bounds meet both requirements for every angle),
        ``"refuted at the entry"`` (``|ω| > ω_max`` already at an entry state, computed exactly),
        ``"refuted by simulation"`` (a numerically integrated solution of the continuous loop from the
        entry violates a requirement: sampled evidence), ``"not proven"`` (no certificate decides).
    why : str
    delta_max_m, omega_max_radps : float or None
        The certified bounds (worst over the angles) when SOS sets were searched.
    sets : tuple of str
        The sets used (of the worst angle).
    rechecked : bool
        Every certificate behind ``"proven admissible"`` passed its re-check (in :data:`RECHECK_SCAN`
        arithmetic).
    """

    k: float
    verdict: str
    why: str
    delta_max_m: float | None = None
    omega_max_radps: float | None = None
    sets: tuple[str, ...] = ()
    rechecked: bool = False

    @property
    def admissible(self) -> bool:
        """Proven admissible."""
        return self.verdict == "proven admissible"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable({"k": self.k, "verdict": self.verdict, "why": self.why, "delta_max_m": self.delta_max_m,
                            "omega_max_radps": self.omega_max_radps, "sets": list(self.sets),
                            "rechecked": self.rechecked})


@dataclass(frozen=True, kw_only=True, slots=True)
class _Problem:
    v: float
    d_zero: float
    radii: tuple[float, ...]
    delta_entry: tuple[float, float]
    angles: tuple[float, ...]
    clearance: float
    omega_max: float
    degree: int
    recheck: bool = True

    @property
    def requirements(self) -> tuple[float, float]:
        return self.d_zero - self.clearance, self.omega_max


def _omega_at(k: float, v: float, d_zero: float, radius: float, delta: float, alpha: float) -> float:
    return model.path_following_omega(delta, alpha, 1.0 / (radius + d_zero + delta), 1, v, k)


def _refute(problem: _Problem, k: float) -> GainEvaluation | None:
    """A refutation at the entry (exact) or by integrating the continuous loop (sampled), or None."""
    from scipy.integrate import solve_ivp

    for alpha0 in problem.angles:
        for radius in problem.radii:
            for delta0 in problem.delta_entry:
                w = abs(_omega_at(k, problem.v, problem.d_zero, radius, delta0, alpha0))
                if w > problem.omega_max:
                    return GainEvaluation(k=k, verdict="refuted at the entry", why=(
                        f"|omega| = {w:.4g} rad/s > {problem.omega_max:g} at the entry state delta = {delta0:.4g} m, "
                        f"alpha = {alpha0:.4g} rad (R = {radius:g} m)"))

            def rates(_t: float, y: np.ndarray, r: float = radius) -> list[float]:
                kappa = 1.0 / (r + problem.d_zero + y[0])
                w = model.path_following_omega(y[0], y[1], kappa, 1, problem.v, k)
                return list(model.path_error_rates(problem.v, w, y[1], kappa, 1))

            horizon = 20.0 / (problem.v * max(min(k, 1.0 / k), 1e-3))
            sol = solve_ivp(rates, (0.0, min(horizon, 2000.0)), [problem.delta_entry[0], alpha0], rtol=1e-8,
                            atol=1e-10, max_step=0.5)
            if not sol.success:
                continue
            closest = problem.d_zero + float(np.min(sol.y[0]))
            peak = max(abs(_omega_at(k, problem.v, problem.d_zero, radius, d, a)) for d, a in zip(*sol.y))
            if closest < problem.clearance or peak > problem.omega_max:
                return GainEvaluation(k=k, verdict="refuted by simulation", why=(
                    f"the continuous loop from delta = {problem.delta_entry[0]:.4g} m, alpha = {alpha0:.4g} rad "
                    f"(R = {radius:g} m) reaches clearance {closest:.4g} m and |omega| {peak:.4g} rad/s "
                    "(numerical integration, sampled)"))
    return None


def _evaluate_gain(problem: _Problem, k: float) -> tuple[GainEvaluation, dict[float, list[InvariantSet]]]:
    """Refute cheaply, else search certificates: joint set first, then the specific ones that are missing."""
    refuted = _refute(problem, k)
    if refuted is not None:
        return refuted, {}
    loop = polynomial_loop(k=k, v=problem.v, d_zero=problem.d_zero, radii=problem.radii)
    worst: BoundPair | None = None
    used: dict[float, list[InvariantSet]] = {}
    for alpha0 in problem.angles:
        sets, bound = _angle_sets(problem, loop, alpha0)
        used[alpha0] = sets
        if worst is None or not _meets(bound, problem):
            worst = bound
        if not _meets(bound, problem):
            break
    assert worst is not None
    ok = _meets(worst, problem)
    why = (f"certified clearance >= {worst.min_distance_m:.4g} m and |omega| <= {worst.omega_max_radps:.4g} rad/s"
           + (f" (every certificate re-checked, {RECHECK_SCAN} arithmetic)" if problem.recheck
              else " (branch and bound, not re-checked)")
           if worst.certified else "no set through the entry is certified" +
           (", or a re-check failed" if problem.recheck else ""))
    return GainEvaluation(k=k, verdict="proven admissible" if ok else "not proven", why=why,
                          delta_max_m=worst.delta_max_m, omega_max_radps=worst.omega_max_radps,
                          sets=worst.sets, rechecked=problem.recheck and ok), used


def _angle_sets(problem: _Problem, loop: PolynomialLoop, alpha0: float) -> tuple[list[InvariantSet], BoundPair]:
    """The hand and joint sets, the specific ones for a requirement the joint set misses, their bounds."""
    def bounds(sets: list[InvariantSet], recheck: bool) -> BoundPair:
        return bounds_over(loop, sets, delta_entry=problem.delta_entry, alpha0=alpha0,
                           good_enough=problem.requirements, recheck=recheck, arithmetic=RECHECK_SCAN)

    sets = entry_sets(loop, delta_entry=problem.delta_entry, alpha0=alpha0, targets=("joint",),
                      requirements=problem.requirements, degree=problem.degree)
    bound = bounds(sets, False)
    extra = [t for t, ok in (("delta", bound.delta_max_m <= problem.requirements[0]),
                             ("omega", bound.omega_max_radps <= problem.requirements[1])) if not ok]
    if extra:
        sets += entry_sets(loop, delta_entry=problem.delta_entry, alpha0=alpha0, targets=extra, hand=False,
                           degree=problem.degree)
        bound = bounds(sets, False)
    if problem.recheck and _meets(bound, problem):
        sets = [s.rechecked(RECHECK_SCAN) for s in sets]
        bound = bounds(sets, True)
    return sets, bound


def _meets(bound: BoundPair, problem: _Problem) -> bool:
    return (bound.certified and bound.delta_max_m <= problem.requirements[0]
            and bound.omega_max_radps <= problem.requirements[1])


def _prove_interval(problem: _Problem, loop: PolynomialLoop, sets: Sequence[InvariantSet], alpha0: float,
                    k_range: tuple[float, float]) -> tuple[bool, str]:
    """One set family for every ``k`` in the range: invariance with ``k`` a parameter, then the bounds."""
    usable = [s for s in sets if s.certified and s.name != "hand"]  # the hand V itself depends on k
    if not usable:
        return False, "no SOS set to carry over"
    carried = []
    for s in usable:
        rate = loop.rate_of(s.lyapunov, parametric=True)  # type: ignore[arg-type]
        region = {**s.region, "k": k_range}  # type: ignore[dict-item]
        cert = certify_sublevel(s.lyapunov, rate, region, rho_out=s.level, rho_in=INNER_FRACTION * s.level,
                                strict=True, parameters=("k",), max_boxes=40_000)
        if cert.certified and not recheck_sublevel(s.lyapunov, rate, cert, arithmetic=RECHECK_SCAN):
            carried.append(s)
    if not carried:
        return False, "no set stays invariant over the whole range"
    region = loop.strip(min(s.region["delta"][1] for s in carried))  # type: ignore[index]
    pairs = [(s.lyapunov, s.level) for s in carried]
    seeds = [{"delta": d, "alpha": alpha0} for d in problem.delta_entry]
    bd = bound_on_sublevel(Polynomial.atom("delta"), region, sets=pairs, absolute=True, seeds=seeds,
                           tolerance=BOUND_TOLERANCE, good_enough=problem.requirements[0])
    bw = bound_on_sublevel(loop.parametric_omega, {**region, "k": k_range}, sets=pairs, absolute=True,
                           aux=(loop.curvature,), seeds=[{**p, "k": k_range[1]} for p in seeds],
                           tolerance=BOUND_TOLERANCE, good_enough=problem.requirements[1], max_boxes=20_000)
    ok = (bd.certified and bw.certified and bd.bound <= problem.requirements[0]
          and bw.bound <= problem.requirements[1]
          and not recheck_bound(Polynomial.atom("delta"), pairs, bd, arithmetic=RECHECK_SCAN)
          and not recheck_bound(loop.parametric_omega, pairs, bw, aux=(loop.curvature,), arithmetic=RECHECK_SCAN))
    return ok, (f"sets {[s.name for s in carried]} of k = {loop.k:.6g}: clearance >= {problem.d_zero - bd.bound:.4g} m, "
                f"|omega| <= {bw.bound:.4g} rad/s for every k in [{k_range[0]:.6g}, {k_range[1]:.6g}]")


@dataclass(frozen=True, kw_only=True, slots=True)
class SosAdmissibleGains:
    """Gains proven admissible by the certified bounds, beside the hand-given ``V``'s.

    Attributes
    ----------
    clearance_m, omega_max_radps : float
        The requirements.
    delta_entry_m : (float, float)
        The entry segment.
    entry_angles_rad : tuple of float
    k_searched : (float, float)
    evaluations : tuple of GainEvaluation
        Every gain examined, increasing.
    proven_gains : tuple of float
        The gains proven admissible (each by its own certificates).
    interval : (float, float) or None
        ``[lowest, highest]`` proven gain of the longest run of consecutive proven gains.
    intervals_proven : tuple of dict
        ``{"k": [a, b], "proven": bool, "why": str}`` for each pair of consecutive proven gains in
        ``interval``: the sets found at ``a`` certified (``k`` a parameter of the branch and bound) for
        every ``k`` in ``[a, √(ab)]``, those found at ``b`` for ``[√(ab), b]``.
    interval_proven : bool
        Every such pair proven: then every ``k`` in ``interval`` is admissible, not only the grid.
    continuous_interval : (float, float) or None
        The longest chain of consecutive proven pairs: every ``k`` in it is proven admissible.
    lower_bracket, upper_bracket : (float, float) or None
        ``(last gain not proven, first proven)`` and ``(last proven, first not proven)``: where the
        edges of ``interval`` lie to the refinement's resolution.
    hand : dict
        :func:`visnav.studies.path_following.admissible_gains` (the hand-given ``V``'s closed-form bounds).
    finding : str
    """

    clearance_m: float
    omega_max_radps: float
    delta_entry_m: tuple[float, float]
    entry_angles_rad: tuple[float, ...]
    k_searched: tuple[float, float]
    evaluations: tuple[GainEvaluation, ...]
    proven_gains: tuple[float, ...]
    interval: tuple[float, float] | None
    intervals_proven: tuple[dict[str, Any], ...]
    interval_proven: bool
    continuous_interval: tuple[float, float] | None
    lower_bracket: tuple[float, float] | None
    upper_bracket: tuple[float, float] | None
    hand: dict[str, Any]
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable({
            "clearance_m": self.clearance_m, "omega_max_radps": self.omega_max_radps,
            "delta_entry_m": list(self.delta_entry_m), "entry_angles_rad": list(self.entry_angles_rad),
            "k_searched": list(self.k_searched), "evaluations": [e.as_dict() for e in self.evaluations],
            "proven_gains": list(self.proven_gains), "interval": self.interval,
            "intervals_proven": list(self.intervals_proven), "interval_proven": self.interval_proven,
            "continuous_interval": self.continuous_interval,
            "lower_bracket": self.lower_bracket, "upper_bracket": self.upper_bracket, "hand": self.hand,
            "finding": self.finding,
        })


def _longest_run(evaluations: Sequence[GainEvaluation]) -> list[GainEvaluation]:
    best: list[GainEvaluation] = []
    run: list[GainEvaluation] = []
    for e in evaluations:
        run = run + [e] if e.admissible else []
        if len(run) > len(best):
            best = run
    return best


def _refine(problem: _Problem, done: dict[float, tuple[GainEvaluation, Any]], steps: int) -> None:
    """Bisect (geometrically) every bracket between a proven and a non-proven gain, ``steps`` times."""
    for _ in range(steps):
        ks = sorted(done)
        brackets = [(a, b) for a, b in zip(ks, ks[1:]) if done[a][0].admissible != done[b][0].admissible]
        if not brackets:
            return
        for a, b in brackets:
            mid = math.sqrt(a * b)
            if mid not in done:
                done[mid] = _evaluate_gain(problem, mid)


def _densify(problem: _Problem, done: dict[float, tuple[GainEvaluation, Any]], max_ratio: float,
             max_inserted: int) -> None:
    """Add the geometric midpoint of the widest gap between consecutive proven gains, while wider than ``max_ratio``."""
    for _ in range(max_inserted):
        ks = sorted(done)
        gaps = [(b / a, a, b) for a, b in zip(ks, ks[1:]) if done[a][0].admissible and done[b][0].admissible]
        if not gaps or max(gaps)[0] <= max_ratio:
            return
        _, a, b = max(gaps)
        done[math.sqrt(a * b)] = _evaluate_gain(problem, math.sqrt(a * b))


def sos_admissible_gains(*, v: float, d_zero: float, radii: Sequence[float], delta_entry: tuple[float, float],
                         entry_angles: Sequence[float], clearance: float, omega_max: float,
                         k_range: tuple[float, float] = K_PATH_RANGE, extra_gains: Sequence[float] = (),
                         coarse: int = 13, refine: int = 3, prove_intervals: bool = False, max_ratio: float = 1.4,
                         recheck: bool = True, degree: int = DEFAULT_DEGREE) -> SosAdmissibleGains:
    """Scan ``k`` (log grid of ``coarse`` points, then ``refine`` bisections of each edge) with certified bounds.

    Each gain is refuted cheaply when possible (:class:`GainEvaluation`), else certified by the SOS sets
    re-proven by branch and bound, and (``recheck``) every certificate of a gain declared admissible is
    re-checked in scalar arithmetic.  With ``prove_intervals``, gaps between proven gains wider than the
    ratio ``max_ratio`` get up to six more gains, then every gap is covered by k-interval certificates
    (:class:`SosAdmissibleGains`; these are not re-checked).  The hand-given ``V``'s admissible set is computed beside it
    (:func:`visnav.studies.path_following.admissible_gains`).

    Raises
    ------
    ValueError
        No entry angle, or requirements that cannot be met at all (clearance >= d0).
    """
    if not entry_angles:
        raise ValueError("sos_admissible_gains: entry_angles is empty; give at least one entry angle [rad]")
    if not 0.0 <= clearance < d_zero or not omega_max > 0:
        raise ValueError(f"sos_admissible_gains: clearance = {clearance!r}, omega_max = {omega_max!r}; expected "
                         f"0 <= clearance < d0 = {d_zero} m and omega_max > 0 rad/s")
    problem = _Problem(v=float(v), d_zero=float(d_zero), radii=tuple(float(r) for r in radii),
                       delta_entry=(float(delta_entry[0]), float(delta_entry[1])),
                       angles=tuple(float(a) for a in entry_angles), clearance=float(clearance),
                       omega_max=float(omega_max), degree=degree, recheck=bool(recheck))
    gains = sorted({float(k) for k in np.geomspace(k_range[0], k_range[1], coarse)} | {float(k) for k in extra_gains})
    done = {k: _evaluate_gain(problem, k) for k in gains}
    _refine(problem, done, refine)
    if prove_intervals:
        _densify(problem, done, max_ratio, max_inserted=6)
    evaluations = tuple(done[k][0] for k in sorted(done))
    run = _longest_run(evaluations)
    intervals = []
    if prove_intervals:
        for a, b in zip(run, run[1:]):
            ok, why = _interval_between(problem, done, a.k, b.k)
            intervals.append({"k": [a.k, b.k], "proven": ok, "why": why})
    hand = admissible_gains(v=v, d_zero=d_zero, radius=min(radii), delta0=delta_entry[1],
                            entry_angles=list(entry_angles), clearance=clearance, omega_max=omega_max,
                            k_range=k_range)
    return _admissible_result(problem, evaluations, run, tuple(intervals), hand, k_range)


def _interval_between(problem: _Problem, done: Mapping[float, tuple[GainEvaluation, Any]], a: float,
                      b: float) -> tuple[bool, str]:
    """Cover ``[a, b]`` by ``[a, m]`` with the sets found at ``a`` and ``[m, b]`` with those at ``b``, ``m = √(ab)``."""
    middle = math.sqrt(a * b)
    reasons = []
    for k, piece in ((a, (a, middle)), (b, (middle, b))):
        loop = polynomial_loop(k=k, v=problem.v, d_zero=problem.d_zero, radii=problem.radii)
        for alpha0 in problem.angles:
            ok, why = _prove_interval(problem, loop, done[k][1][alpha0], alpha0, piece)
            if not ok:
                return False, f"k in [{piece[0]:.6g}, {piece[1]:.6g}]: {why}"
            reasons.append(why)
    return True, "; ".join(reasons)


def _admissible_result(problem: _Problem, evaluations: tuple[GainEvaluation, ...], run: list[GainEvaluation],
                       intervals: tuple[dict[str, Any], ...], hand: AdmissibleGains,
                       k_range: tuple[float, float]) -> SosAdmissibleGains:
    ks = [e.k for e in evaluations]
    interval = (run[0].k, run[-1].k) if run else None
    lower = upper = None
    if run:
        i, j = ks.index(run[0].k), ks.index(run[-1].k)
        lower = (ks[i - 1], ks[i]) if i > 0 else None
        upper = (ks[j], ks[j + 1]) if j + 1 < len(ks) else None
    interval_proven = bool(run) and (len(run) == 1 or all(d["proven"] for d in intervals) and len(intervals) > 0)
    continuous = _continuous(intervals)
    finding = _finding(problem, interval, interval_proven, continuous, lower, upper, hand, evaluations)
    return SosAdmissibleGains(
        clearance_m=problem.clearance, omega_max_radps=problem.omega_max, delta_entry_m=problem.delta_entry,
        entry_angles_rad=problem.angles, k_searched=(float(k_range[0]), float(k_range[1])), evaluations=evaluations,
        proven_gains=tuple(e.k for e in evaluations if e.admissible), interval=interval,
        intervals_proven=intervals, interval_proven=interval_proven, continuous_interval=continuous,
        lower_bracket=lower, upper_bracket=upper,
        hand=hand.as_dict(), finding=finding)


def _continuous(intervals: Sequence[dict[str, Any]]) -> tuple[float, float] | None:
    best: tuple[float, float] | None = None
    start: float | None = None
    for d in intervals:
        if d["proven"]:
            start = d["k"][0] if start is None else start
            if best is None or math.log(d["k"][1] / start) > math.log(best[1] / best[0]):
                best = (start, d["k"][1])
        else:
            start = None
    return best


def _finding(problem: _Problem, interval: tuple[float, float] | None, interval_proven: bool,
             continuous: tuple[float, float] | None, lower: tuple[float, float] | None,
             upper: tuple[float, float] | None, hand: AdmissibleGains, evaluations: Sequence[GainEvaluation]) -> str:
    req = f"clearance >= {problem.clearance:g} m and |omega| <= {problem.omega_max:g} rad/s"
    hand_text = ("the hand-given V admits none" if hand.interval is None else
                 f"the hand-given V admits k in [{hand.interval[0]:.4g}, {hand.interval[1]:.4g}]")
    if interval is None:
        return (f"no k is proven to guarantee {req} by the SOS certificates either ({hand_text}); "
                "the empty range stands, but only as 'not proven'")
    if interval_proven:
        how = "every k in it (k-interval certificates)"
    elif continuous is not None:
        how = (f"every k in [{continuous[0]:.4g}, {continuous[1]:.4g}] by k-interval certificates, the rest at "
               "each gain checked")
    else:
        how = "at each gain checked in it; between them not proven"
    edges = []
    if lower:
        edges.append(f"lower edge in ({lower[0]:.4g}, {lower[1]:.4g}]: "
                     f"{next(e.verdict for e in evaluations if e.k == lower[0])} below")
    if upper:
        edges.append(f"upper edge in [{upper[0]:.4g}, {upper[1]:.4g}): "
                     f"{next(e.verdict for e in evaluations if e.k == upper[1])} above")
    where = (f"for k = {interval[0]:.4g} 1/m (the only gain judged)" if interval[0] == interval[1] else
             f"for k in [{interval[0]:.4g}, {interval[1]:.4g}] 1/m ({how})")
    verdict = (f"while {hand_text}: the empty admissible range came from the conservative hand V and "
               "triangle-inequality bounds, not from the loop" if hand.interval is None else f"and {hand_text}")
    return (f"SOS certificates re-proven by interval branch and bound guarantee {req} {where}, {verdict}"
            + (f" ({'; '.join(edges)})" if edges else ""))


# --------------------------------------------------------------------------- the scenario


@dataclass(frozen=True, kw_only=True, slots=True)
class PathFollowingSos:
    """The SOS analysis of a scenario's path-following loop (JSON-ready through :meth:`as_dict`).

    Attributes
    ----------
    scenario : str
    k, v, d_zero_m, clearance_m, omega_limit_radps : float
        The gain, speed, envelope offset, required clearance and ``|ω|`` limit.
    radii_m : tuple of float
    delta_entry_m : (float, float)
        ``[d− − d0 − v T, d− − d0]``.
    entry_angles_rad : tuple of float
        Sampled (one simulation of the scenario).
    region : CertifiedRegion
    bypass : tuple of SosEntryBounds
        At the scenario's ``k``, one per entry angle, every certificate re-checked.
    admissible : SosAdmissibleGains
    claims : tuple of dict
        ``{"claim", "status", "why"}``: ``"proven"`` only where a branch-and-bound certificate holds
        (and is re-checked where stated), else ``"not proven"``, ``"computed"`` or ``"sampled"``.
    finding : str
    """

    scenario: str
    k: float
    v: float
    d_zero_m: float
    clearance_m: float
    omega_limit_radps: float
    radii_m: tuple[float, ...]
    delta_entry_m: tuple[float, float]
    entry_angles_rad: tuple[float, ...]
    region: CertifiedRegion
    bypass: tuple[SosEntryBounds, ...]
    admissible: SosAdmissibleGains
    claims: tuple[dict[str, str], ...]
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, deterministic (no wall-clock times)."""
        return to_jsonable({
            "scenario": self.scenario, "k": self.k, "v_mps": self.v, "d_zero_m": self.d_zero_m,
            "clearance_m": self.clearance_m, "omega_limit_radps": self.omega_limit_radps,
            "radii_m": list(self.radii_m), "delta_entry_m": list(self.delta_entry_m),
            "entry_angles_rad": list(self.entry_angles_rad), "region": self.region.as_dict(),
            "bypass": [b.as_dict() for b in self.bypass], "admissible": self.admissible.as_dict(),
            "claims": list(self.claims), "finding": self.finding,
        })


def best_bounds(bounds: SosEntryBounds) -> tuple[float, float]:
    """The smallest ``(δ_max, ω_max)`` over the hand, SOS and combined intersections (each a valid bound).

    Only the combined pair is re-checked; :meth:`SosEntryBounds.combined` is what the claims report.
    """
    pairs = [p for p in (bounds.hand, bounds.sos, bounds.combined) if p.certified]
    return (min((p.delta_max_m for p in pairs), default=math.inf),
            min((p.omega_max_radps for p in pairs), default=math.inf))


def _claims(result_region: CertifiedRegion, bypass: Sequence[SosEntryBounds], admissible: SosAdmissibleGains,
            clearance: float, omega_limit: float) -> tuple[dict[str, str], ...]:
    out = [{"claim": (f"{{V <= 1}} of the SOS V (degree {result_region.degree}) is positively invariant in the strip "
                      f"and its area is {result_region.area_ratio:.3g} times that of the largest hand-given sublevel set"),
            "status": result_region.status, "why": result_region.why}]
    for b in bypass:
        d, w = b.combined.delta_max_m, b.combined.omega_max_radps
        out.append({"claim": (f"along a bypass entered at delta in [{b.delta_entry[0]:.4g}, {b.delta_entry[1]:.4g}] m, "
                              f"alpha = {b.alpha0:.4g} rad with k = {b.k:g}: |delta| <= {d:.4g} m (clearance >= "
                              f"{b.combined.min_distance_m:.4g} m), |omega| <= {w:.4g} rad/s"),
                    "status": b.status, "why": b.why})
    out.append({"claim": "the entry angle(s)", "status": "sampled",
                "why": "taken from one simulation of the scenario, where the supervisor switches to path following"})
    if admissible.interval is not None:
        a, z = admissible.interval
        out.append({"claim": (f"clearance >= {clearance:g} m and |omega| <= {omega_limit:g} rad/s for k = {a:.4g}"
                              if a == z else
                              f"clearance >= {clearance:g} m and |omega| <= {omega_limit:g} rad/s for every k in "
                              f"[{a:.4g}, {z:.4g}]" if admissible.interval_proven else
                              f"clearance >= {clearance:g} m and |omega| <= {omega_limit:g} rad/s for each of the "
                              f"{len(admissible.proven_gains)} gains proven in [{a:.4g}, {z:.4g}]"),
                    "status": "proven",
                    "why": (f"each by its own certificates, re-checked in {RECHECK_SCAN} arithmetic (the scenario's k "
                            "also in scalar arithmetic, above)"
                            + (", and k-interval certificates between them" if admissible.interval_proven else
                               "; between them only where intervals_proven says so"))})
    if admissible.continuous_interval is not None and not admissible.interval_proven:
        a, z = admissible.continuous_interval
        out.append({"claim": (f"clearance >= {clearance:g} m and |omega| <= {omega_limit:g} rad/s for every k in "
                              f"[{a:.4g}, {z:.4g}]"), "status": "proven",
                    "why": f"k-interval certificates (k a parameter of the branch and bound), re-checked in "
                           f"{RECHECK_SCAN} arithmetic"})
    for verdict, status, why in (
            ("refuted at the entry", "computed", "|omega| of law (11) evaluated at the entry states exceeds the limit"),
            ("refuted by simulation", "sampled", "numerical integration of the continuous loop from the entry")):
        refuted = sorted(e.k for e in admissible.evaluations if e.verdict == verdict)
        if refuted:
            out.append({"claim": (f"the gain(s) k = {', '.join(f'{k:.4g}' for k in refuted)} violate a requirement "
                                  f"({verdict})"), "status": status, "why": why})
    return tuple(out)


def _entry_angles(value: Any) -> tuple[float, ...]:
    """The distinct entry angles [rad], sorted: finite, inside the strip ``|α| < ALPHA_BOX_FRACTION·π``."""
    limit = ALPHA_BOX_FRACTION * math.pi
    expected = f"a non-empty sequence of finite angles [rad] with |alpha| < {limit:.6g}"
    fix = "give the entry angle(s), e.g. from loop_analysis.entry_angles_from_simulation"
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise ParameterError("entry_angles", value, expected, fix)
    items = list(value)
    if not items or any(isinstance(a, bool) or not isinstance(a, (int, float)) or not math.isfinite(a)
                        or abs(a) >= limit for a in items):
        raise ParameterError("entry_angles", value if not items else tuple(items), expected, fix)
    return tuple(sorted({round(float(a), 12) for a in items}))


def path_following_sos(scenario: Any, *, entry_angles: Sequence[float], clearance_m: float | None = None,
                       degree: int = DEFAULT_DEGREE, scan: bool = True,
                       prove_intervals: bool = False) -> PathFollowingSos:
    """The whole SOS analysis of ``scenario``'s path following: region, bypass bounds, admissible gains.

    Parameters
    ----------
    scenario : visnav.parameters.Scenario
    entry_angles : sequence of float
        Entry angles [rad] (e.g. from :func:`visnav.studies.loop_analysis.entry_angles_from_simulation`,
        passed in so that this module does not depend on the simulation).
    clearance_m : float, optional
        Required clearance [m] (default :data:`visnav.parameters.PATH_CLEARANCE_M`).
    degree : int
    scan : bool
        Scan the gains (13-point grid and 3 refinements; else only the scenario's ``k`` is judged).
    prove_intervals : bool
        Also prove every ``k`` between the proven gains (k-interval certificates, with up to six
        more gains where the gaps are wide); on the paper scenario about 50 s more.

    Raises
    ------
    ParameterError
        (a ``ValueError``) no entry angle, an angle that is not finite or outside the strip, a degree
        that is not an even integer >= 2.
    ValueError
        A clearance not in ``[0, d0)``.
    """
    from visnav.parameters import PATH_CLEARANCE_M

    clearance = PATH_CLEARANCE_M if clearance_m is None else float(clearance_m)
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    angles = _entry_angles(entry_angles)
    if isinstance(degree, bool) or not isinstance(degree, int) or degree < 2 or degree % 2:
        raise ParameterError("degree", degree, "an even integer >= 2", "use 4 (the default) or 2")
    if not 0.0 <= clearance < env.d_zero_m:
        raise ValueError(f"path_following_sos: clearance_m = {clearance!r}; expected 0 <= clearance < d0 = "
                         f"{env.d_zero_m} m")
    radii = tuple(o.radius_m for o in scenario.obstacles) or (1.0,)
    v, k, d0 = gains.v_coll_mps, gains.k_path, env.d_zero_m
    nominal = env.d_minus_m - d0
    delta_entry = (nominal - v * scenario.sampling_period_s, nominal)
    loop = polynomial_loop(k=k, v=v, d_zero=d0, radii=radii)
    region = certified_region(loop, degree=degree)
    bypass = tuple(sos_entry_bounds(loop, delta_entry=delta_entry, alpha0=a, degree=degree, recheck=True)
                   for a in angles)
    gains = sos_admissible_gains(v=v, d_zero=d0, radii=radii, delta_entry=delta_entry, entry_angles=angles,
                                 clearance=clearance, omega_max=limits.omega_max_radps, extra_gains=(k,),
                                 degree=degree, prove_intervals=prove_intervals, coarse=13 if scan else 1,
                                 refine=3 if scan else 0, k_range=K_PATH_RANGE if scan else (k, k))
    finding = gains.finding + (f"; the SOS region is {region.area_ratio:.3g} times the hand-given one "
                               f"({region.status})")
    return PathFollowingSos(scenario=scenario.name, k=k, v=v, d_zero_m=d0, clearance_m=clearance,
                            omega_limit_radps=limits.omega_max_radps, radii_m=radii, delta_entry_m=delta_entry,
                            entry_angles_rad=angles, region=region, bypass=bypass, admissible=gains,
                            claims=_claims(region, bypass, gains, clearance, limits.omega_max_radps), finding=finding)
