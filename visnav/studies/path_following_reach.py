"""Reachability of the sampled path-following loop of a bypass: ``|δ| < d0`` proven from a measured entry set.

The loop is equations (10)–(11) (:func:`visnav.model.path_error_rates`, :func:`visnav.model.path_following_omega`)
at ``v = v_coll`` with the control of the supervisor's sampling held for one period ``T``, written as a
symbolic hybrid automaton (one mode, a clock):

* states ``δ, α`` (the path-frame errors), ``κ = 1/(R + d0 + δ)`` (the curvature, a state so that the flow
  stays polynomial in it: ``κ̇ = −κ² δ̇``), the held samples ``δ_h, α_h, κ_h`` and the clock ``c``;
* flow: ``δ̇ = v sin α``, ``α̇ = −ω_h + v κ cos α`` with the held command
  ``ω_h = v (k δ_h + α_h + 2k sin α_h + κ_h cos α_h)`` (the side ``±1`` cancels), ``κ̇ = −v κ² sin α``,
  ``ċ = 1``, the samples constant;
* invariant ``c <= T``; at ``c >= T`` the sample: ``c := 0``, ``(δ_h, α_h, κ_h) := (δ, α, κ)``.

The proof runs in modal coordinates ``(δ, α) = V w`` (:func:`modal_basis`, the eigenvectors of the loop's
linearisation): the engine takes a box of the set at every sample, and a box in ``(δ, α)`` wraps (the
slow mode's direction is oblique), growing the set by ~0.4 % a period until it blew up at 17.9 s; in
``w`` the period's linear part is nearly diagonal.  The entry box is mapped exactly (rationals over
its corners, rounded outward) and the requirement ``|δ| = |w1 + w2| < d0`` stays affine.

Between samples the curvature terms no longer cancel (``v (κ cos α − κ_h cos α_h)``) and the command lags:
this is the loop the robot runs, not its continuous idealisation that the Lyapunov and SOS analyses
(:mod:`visnav.studies.path_following`, :mod:`visnav.studies.path_following_sos`) certify.  The flowpipe
(:mod:`analysis.reach.nonlinear`, re-checked independently: :func:`analysis.reach.verdict.reach_proof`)
proves ``always[0, H] |δ| < d0`` from the entry box, where the entry is a sample instant (the supervisor
switches to path following at a sample), so the held values equal the current ones there.

Entries (:func:`campaign_entries`, **measured**): the campaign's samples are simulated and the state where
each bypass reaches full path following is read (as :func:`visnav.studies.loop_analysis.entry_angles_from_simulation`
does for one run), with the obstacle's radius; the entry box is their hull widened by a margin, and its
coverage of the measured entries is reported as measured (a sample, not a proof that every entry of
the campaign's distribution lies in it).  The gains are the scenario's (``k``, ``v_coll``): the campaign's
gain factors change the loop and are not covered by this proof.

Nothing here prints or writes files.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from hybrid.jsonable import to_jsonable

__all__ = ["BypassEntry", "BypassReach", "campaign_entries", "modal_basis", "sampled_bypass_system", "prove_bypass",
           "bypass_reach", "default_step"]

STEP_SLACK_S = 1e-9
"""The default flowpipe step is ``(T − STEP_SLACK_S) / 2`` [s] (:func:`default_step`), not ``T / 2``."""

BOX_GRID = 1e-4
"""The entry box's bounds are rounded outward to multiples of this (m, rad): short decimals, printed exactly."""

_NOT_FOLLOWING = ("LEAVE", "FAR", "APPROACH")
"""Supervisor modes in which the path-following law no longer drives ω (AVOID, ARMED, PASSED use it)."""

STATE_NAMES = ("delta", "alpha", "kappa", "delta_h", "alpha_h", "kappa_h", "clock")


@dataclass(frozen=True, kw_only=True, slots=True)
class BypassEntry:
    """One measured entry into full path following: the sample, obstacle and radius, ``δ`` [m], ``α`` [rad],
    and the time [s] the bypass lasted until the supervisor left it (``nan`` when the run never left)."""

    sample: int
    obstacle: str
    radius_m: float
    delta_m: float
    alpha_rad: float
    duration_s: float


@dataclass(frozen=True, kw_only=True, slots=True)
class BypassReach:
    """The result of :func:`prove_bypass`.

    Attributes
    ----------
    k, v_mps, d_zero_m, period_s : float
        The loop's gain [1/m], speed [m/s], envelope offset [m] and sampling period [s].
    radius_m : (float, float)
        Obstacle radii covered [m].
    entry_box : dict
        ``{"delta_m": (lo, hi), "alpha_rad": (lo, hi)}``: the set proven from.
    coverage : dict
        ``{"claim": "measured", "entries": N, "inside": M, "samples": S, "seed": s}``.
    horizon_s : float
        The window ``H`` [s] after entry.
    status : str
        ``"proven"`` (the flowpipe decides it and the independent re-check passed), ``"not proven"``.
    margin_m : float
        Smallest slack of ``|δ| < limit`` over the flowpipe [m] (``nan`` if not decided); the limit is ``d0``
        unless :func:`prove_bypass` was given another.
    delta_bound_m : float
        ``limit − margin``: the proven bound of ``|δ|`` over the window [m] (``nan`` if not proven).
    evidence : str
    time_step_s : float
        The flowpipe's step [s].
    segments, jumps : int
        The flowpipe's segments and jumps (samples), each re-checked.
    seconds : float
        Wall clock of the proof (flowpipes and re-checks) [s].
    """

    k: float
    v_mps: float
    d_zero_m: float
    period_s: float
    radius_m: tuple[float, float]
    entry_box: dict[str, tuple[float, float]]
    coverage: dict[str, Any]
    horizon_s: float
    status: str
    margin_m: float
    delta_bound_m: float
    evidence: str
    time_step_s: float
    segments: int
    jumps: int
    seconds: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return to_jsonable({
            "k": self.k, "v_mps": self.v_mps, "d_zero_m": self.d_zero_m, "period_s": self.period_s,
            "radius_m": list(self.radius_m), "entry_box": {k: list(v) for k, v in self.entry_box.items()},
            "coverage": self.coverage, "horizon_s": self.horizon_s, "status": self.status,
            "margin_m": self.margin_m, "delta_bound_m": self.delta_bound_m, "evidence": self.evidence,
            "time_step_s": self.time_step_s, "segments": self.segments, "jumps": self.jumps, "seconds": self.seconds,
        })


def campaign_entries(scenario: Any, *, samples: int, seed: int = 0) -> tuple[BypassEntry, ...]:
    """The measured entries of ``samples`` draws of the default campaign around ``scenario`` (one simulation each).

    A draw with no valid scenario or no bypass gives no entry.
    """
    import numpy as np

    from visnav.geometry import proximity
    from visnav.simulation import simulate
    from visnav.studies.campaign import CampaignSpec, sample_scenario
    from visnav.supervisor import split_mode

    spec = CampaignSpec(scenario=scenario, samples=samples, seed=seed)
    out = []
    for i in range(samples):
        drawn = sample_scenario(spec, i).scenario
        if drawn is None:
            continue
        trace = simulate(drawn).trace
        events = list(trace.events)
        for n, event in enumerate(events):
            if (split_mode(event.source)[0], split_mode(event.target)[0]) != ("APPROACH", "AVOID"):
                continue
            row = int(np.searchsorted(trace.times, event.time))
            x, y, theta, _ = trace.states[row]
            memory = dict(event.memory)
            obstacle = drawn.obstacles[int(memory["obstacle"])]
            prox = proximity(x, y, theta, obstacle, int(memory["side"]))
            leave = next((e.time for e in events[n + 1:] if split_mode(e.target)[0] in _NOT_FOLLOWING), math.nan)
            out.append(BypassEntry(sample=i, obstacle=obstacle.name, radius_m=float(obstacle.radius_m),
                                   delta_m=float(prox.d_coll - drawn.envelopes.d_zero_m), alpha_rad=float(prox.alpha),
                                   duration_s=float(leave - event.time)))
    return tuple(out)


def modal_basis(*, k: float, v: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """``V`` with ``(δ, α) = V (w1, w2)``: the eigenvectors of the loop's linearisation at the origin,
    ``[[0, v], [−v k, −v (1 + 2k)]]``, scaled to a unit ``δ`` component (real for ``k > 0``, ``v > 0``), their
    ``α`` components rounded to multiples of 1/64 (so ``det V`` is exact).

    In these coordinates the linear part of one period is nearly diagonal, so the box a sample takes of
    the set (the engine's jump sets are boxes) wraps far less than in ``(δ, α)``.
    """
    import numpy as np

    values, vectors = np.linalg.eig(np.array([[0.0, v], [-v * k, -v * (1.0 + 2.0 * k)]]))
    if np.any(np.abs(values.imag) > 0) or np.any(np.abs(vectors[0]) < 1e-12):
        raise ValueError(f"modal_basis: k = {k!r}, v = {v!r} give complex or degenerate modes; expected k, v > 0")
    order = np.argsort(-values.real)  # slow mode first
    cols = [vectors[:, i].real / vectors[0, i].real for i in order]
    # α-components rounded to 1/64: the determinant α2 − α1 is then an exact float, so the flow written
    # with it (sampled_bypass_system) is exactly the loop in these coordinates
    return ((1.0, 1.0), (round(float(cols[0][1]) * 64) / 64, round(float(cols[1][1]) * 64) / 64))


def sampled_bypass_system(*, k: float, v: float, period: float,
                          basis: tuple[tuple[float, float], tuple[float, float]] | None = None) -> Any:
    """The symbolic hybrid automaton of the sampled loop (module docstring); states :data:`STATE_NAMES`.

    With ``basis`` ``V``, the first two states (and their samples) are the modal coordinates ``w`` with
    ``(δ, α) = V w`` (:func:`modal_basis`): the same automaton in other coordinates.
    """
    from hybrid import HybridAutomaton, Mode, Transition
    from hybrid.symbolic import coordinates, cos, flow_map, jump_map, sin
    from hybrid.system import HybridSystem

    x = coordinates(*STATE_NAMES)
    (a, b), (c, d) = basis if basis is not None else ((1.0, 0.0), (0.0, 1.0))
    delta, alpha = a * x.delta + b * x.alpha, c * x.delta + d * x.alpha
    delta_h, alpha_h = a * x.delta_h + b * x.alpha_h, c * x.delta_h + d * x.alpha_h
    held = v * (k * delta_h + alpha_h + 2.0 * k * sin(alpha_h) + x.kappa_h * cos(alpha_h))
    rate_delta, rate_alpha = v * sin(alpha), -held + v * x.kappa * cos(alpha)
    det = a * d - b * c  # exact for modal_basis (dyadic entries); otherwise the flow is the loop up to rounding
    flow = flow_map((d * rate_delta - b * rate_alpha) / det, (a * rate_alpha - c * rate_delta) / det,
                    -v * x.kappa ** 2 * sin(alpha), 0.0 * x.clock, 0.0 * x.clock, 0.0 * x.clock, 1.0 + 0.0 * x.clock)
    sample = jump_map(x.delta, x.alpha, x.kappa, x.delta, x.alpha, x.kappa, 0.0 * x.clock)
    automaton = HybridAutomaton(
        name="sampled path following", variables=STATE_NAMES, initial_mode="follow",
        modes=(Mode(name="follow", invariant=x.clock <= period),),
        transitions=(Transition(name="sample", source="follow", target="follow", guard=x.clock >= period),))
    return HybridSystem(automaton=automaton, state_names=STATE_NAMES, flows={"follow": flow},
                        jumps={"sample": sample})


def _modal_box(box: dict[str, tuple[float, float]], basis: tuple[tuple[float, float], tuple[float, float]]
               ) -> tuple[tuple[float, float], tuple[float, float]]:
    """A float box holding ``V⁻¹ [δ box × α box]`` (exact rationals over the corners, rounded outward)."""
    from fractions import Fraction

    (a, b), (c, d) = (tuple(Fraction(v) for v in row) for row in basis)
    det = a * d - b * c
    corners = [(Fraction(p), Fraction(q)) for p in box["delta_m"] for q in box["alpha_rad"]]
    w1 = [(d * p - b * q) / det for p, q in corners]
    w2 = [(a * q - c * p) / det for p, q in corners]

    def outward(values: list[Fraction]) -> tuple[float, float]:
        lo, hi = float(min(values)), float(max(values))
        lo = lo if Fraction(lo) <= min(values) else math.nextafter(lo, -math.inf)
        hi = hi if Fraction(hi) >= max(values) else math.nextafter(hi, math.inf)
        return lo, hi

    return outward(w1), outward(w2)


def _entry_box(entries: Sequence[BypassEntry], margin_delta: float, margin_alpha: float
               ) -> dict[str, tuple[float, float]]:
    """The entries' hull widened by the margins, its bounds rounded outward to :data:`BOX_GRID` (a larger box
    whose bounds are short decimals; where the rounding of the grid's floats would cut into the hull, the
    hull's own bound is kept)."""
    from fractions import Fraction

    def outward(values: list[float], margin: float) -> tuple[float, float]:
        lo, hi = min(values) - margin, max(values) + margin
        grid_lo = round(math.floor(lo / BOX_GRID) * BOX_GRID, 4)
        grid_hi = round(math.ceil(hi / BOX_GRID) * BOX_GRID, 4)
        # the floats on the decimals' outer side: the box proven holds the box its decimals print
        if Fraction(grid_lo) > Fraction(repr(grid_lo)):
            grid_lo = math.nextafter(grid_lo, -math.inf)
        if Fraction(grid_hi) < Fraction(repr(grid_hi)):
            grid_hi = math.nextafter(grid_hi, math.inf)
        return min(grid_lo, lo), max(grid_hi, hi)

    return {"delta_m": outward([e.delta_m for e in entries], margin_delta),
            "alpha_rad": outward([e.alpha_rad for e in entries], margin_alpha)}


def default_step(period: float) -> float:
    """The flowpipe step [s] for the sampling period ``period``: ``(period − STEP_SLACK_S) / 2``.

    The sample at ``c = T`` then falls strictly inside the third step of each period (the second ends
    ``STEP_SLACK_S`` before it, far beyond the engine's padding of the clock, ~5e-12 s), so one segment
    meets the sample's guard and the jump's time interval starts ``1e-9`` s before the sample: the flowpipe
    stays in step with the samples (``T / 5`` drifted a step a period: 790 samples for 632 periods).
    """
    return (period - STEP_SLACK_S) / 2.0


def prove_bypass(scenario: Any, *, entries: Sequence[BypassEntry], horizon_s: float,
                 margin_delta_m: float = 0.005, margin_alpha_rad: float = 0.05, time_step: float | None = None,
                 splits: dict[str, int] | None = None, samples: int | None = None, seed: int = 0,
                 limit_m: float | None = None) -> BypassReach:
    """Prove ``|δ| < d0`` (or ``< limit_m``) over ``[0, horizon_s]`` after entry for every entry in the hull of
    ``entries`` (widened).

    Parameters
    ----------
    scenario : visnav.parameters.Scenario
        Gains ``k``, ``v_coll``, ``d0`` and the period.
    entries : sequence of BypassEntry
        The measured entries (:func:`campaign_entries`); the box is their hull widened by the margins.
    horizon_s : float
        Window after entry [s] (e.g. the longest measured bypass).
    margin_delta_m, margin_alpha_rad : float
        Widening of the hull [m], [rad].
    time_step : float or None
        Flowpipe step [s]; default :func:`default_step` (``(T − 1e-9)/2``).
    splits : dict or None
        Split of the entry box (``{"alpha": 2}``) for :func:`analysis.reach.verdict.reach_proof`.
    samples, seed : int or None
        Recorded in the coverage (how the entries were drawn).
    limit_m : float or None
        The bound of ``|δ|`` to prove [m]; default ``d0`` (the loop keeps ``d0`` in its curvature either way).
    """
    from analysis.reach import safety_fragment
    from analysis.reach.verdict import reach_proof
    from analysis.stl.syntax import parse_tree

    if not entries:
        raise ValueError("prove_bypass: no entries; give the measured entries of campaign_entries()")
    env, gains = scenario.envelopes, scenario.gains
    k, v, d0, period = gains.k_path, gains.v_coll_mps, env.d_zero_m, scenario.sampling_period_s
    limit = d0 if limit_m is None else float(limit_m)
    if not (math.isfinite(limit) and limit > 0.0):
        raise ValueError(f"prove_bypass: limit_m = {limit_m!r}; expected a finite bound > 0 [m] (or None for d0)")
    box = _entry_box(entries, margin_delta_m, margin_alpha_rad)
    radii = (min(e.radius_m for e in entries), max(e.radius_m for e in entries))
    (d_lo, d_hi), (a_lo, a_hi) = box["delta_m"], box["alpha_rad"]
    # κ = 1/(R + d0 + δ) over the box and the radii, widened by 1e-15 relative (> the two roundings)
    k_lo = 1.0 / (radii[1] + d0 + d_hi) * (1.0 - 1e-15)
    k_hi = 1.0 / (radii[0] + d0 + d_lo) * (1.0 + 1e-15)
    initial = {"delta": (d_lo, d_hi), "alpha": (a_lo, a_hi), "kappa": (k_lo, k_hi), "delta_h": (d_lo, d_hi),
               "alpha_h": (a_lo, a_hi), "kappa_h": (k_lo, k_hi), "clock": (0.0, 0.0)}
    inside = sum(1 for e in entries if d_lo <= e.delta_m <= d_hi and a_lo <= e.alpha_rad <= a_hi
                 and radii[0] <= e.radius_m <= radii[1])
    basis = modal_basis(k=k, v=v)
    w1, w2 = _modal_box(box, basis)
    initial.update({"delta": w1, "alpha": w2, "delta_h": w1, "alpha_h": w2})
    (a, b) = basis[0]
    requirement = safety_fragment(parse_tree(f"always[0, {horizon_s!r}] (abs({a!r} * delta + {b!r} * alpha) < {limit!r})"),
                                  STATE_NAMES)
    system = sampled_bypass_system(k=k, v=v, period=period, basis=basis)
    step = time_step or default_step(period)
    start = time.perf_counter()
    # a period's jump may happen up to one step early in the flowpipe's times: bound the jumps accordingly
    proof, decision = reach_proof(system, requirement, initial, time_step=step,
                                  max_jumps=int(math.ceil(horizon_s / (period - step))) + 5, splits=splits)
    proven = proof.holds and proof.rechecked
    margin = decision.margin if proof.holds else math.nan
    return BypassReach(k=k, v_mps=v, d_zero_m=d0, period_s=period, radius_m=radii, entry_box=box,
                       coverage={"claim": "measured", "entries": len(entries), "inside": inside,
                                 "samples": samples, "seed": seed},
                       horizon_s=float(horizon_s), status="proven" if proven else "not proven", margin_m=margin,
                       delta_bound_m=(limit - margin) if proven else math.nan, evidence=proof.evidence,
                       time_step_s=step, segments=len(decision.result.segments) if decision.result else 0,
                       jumps=len(decision.result.jumps) if decision.result else 0, seconds=time.perf_counter() - start)


def bypass_reach(scenario: Any, *, samples: int = 40, seed: int = 0, time_step: float | None = None) -> BypassReach:
    """The case study: measure the campaign's entries (``samples`` draws), then prove ``|δ| < d0`` from their
    widened hull over the longest measured bypass (rounded up to a whole period).

    The window is measured, like the entries: a bypass of the campaign's distribution that lasts longer is
    covered only up to it (said in the result's coverage).
    """
    entries = campaign_entries(scenario, samples=samples, seed=seed)
    if not entries:
        raise ValueError(f"bypass_reach: no bypass in {samples} samples of the campaign (seed {seed}); raise samples")
    period = scenario.sampling_period_s
    finite = [e.duration_s for e in entries if math.isfinite(e.duration_s)]
    longest = max(finite) if finite else 10.0 * period
    # whole periods, and never below the measured bypass (its duration is a difference of float instants)
    horizon = max(math.ceil(longest / period - 1e-9) * period, longest)
    out = prove_bypass(scenario, entries=entries, horizon_s=horizon, time_step=time_step, samples=samples, seed=seed)
    coverage = {**out.coverage, "longest_bypass_s": longest, "unfinished_bypasses": len(entries) - len(finite)}
    return BypassReach(k=out.k, v_mps=out.v_mps, d_zero_m=out.d_zero_m, period_s=out.period_s, radius_m=out.radius_m,
                       entry_box=out.entry_box, coverage=coverage, horizon_s=out.horizon_s, status=out.status,
                       margin_m=out.margin_m, delta_bound_m=out.delta_bound_m, evidence=out.evidence,
                       time_step_s=out.time_step_s, segments=out.segments, jumps=out.jumps, seconds=out.seconds)
