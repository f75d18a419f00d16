"""The sets behind :mod:`visnav.studies.path_following_sos`: the path-following loop as polynomials
(:class:`PolynomialLoop`), its SOS-certified region (:func:`certified_region`), the invariant entry sets
(:func:`entry_sets`) and the bounds over them (:func:`bounds_over`, :func:`sos_entry_bounds`), with the
constants of those programs.

:mod:`visnav.studies.path_following_sos` re-exports every public name.
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
from hybrid.jsonable import to_jsonable
from visnav import model
from visnav.studies.path_following import entry_bounds

# Helpers shared with visnav.studies.path_following_sos have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
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
    "entry_sets",
    "bounds_over",
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
