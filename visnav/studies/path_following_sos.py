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
from typing import Any

import numpy as np

from analysis.polynomial import Polynomial
from analysis.sublevel import bound_on_sublevel, certify_sublevel, recheck_bound, recheck_sublevel
from hybrid.errors import ParameterError
from hybrid.jsonable import to_jsonable

from visnav import model
from visnav.parameters import K_PATH_RANGE
from visnav.studies.path_following import AdmissibleGains, admissible_gains
from visnav.studies.path_following_sets import (
    ALPHA_BOX_FRACTION,
    AREA_GRID,
    BOUND_TOLERANCE,
    BoundPair,
    CertifiedRegion,
    DEFAULT_DEGREE,
    EPSILON,
    HEADLINE_TOLERANCE,
    INNER_FRACTION,
    InvariantSet,
    PolynomialLoop,
    RECHECK_SCAN,
    REGION_INNER_LEVEL,
    REGULARISATION,
    SHRINK,
    SosEntryBounds,
    bounds_over,
    certified_region,
    entry_sets,
    polynomial_loop,
    sos_entry_bounds,
)

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
