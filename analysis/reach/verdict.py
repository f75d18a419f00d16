"""Verdicts from reachability: decide an STL safety requirement on a flowpipe, re-check it, give a Proof.

:func:`decide` runs :func:`analysis.reach.reach` from the problem's box of initial states and
decides the fragment (:mod:`analysis.reach.fragment`) on every segment whose time interval meets
the window ``[a, b]``: an atom ``c·x <= d`` holds on a segment when a rigorous upper bound of
``max c·x`` over the segment (the smaller of the zonotope's and the box's support, rounded
outward) is at most ``d`` (below ``d`` when strict); a conjunction when all parts hold; a
disjunction when one part holds on the whole segment; a label atom by the segment's mode.  The
*margin* is the smallest slack ``d − max c·x`` over the segments (conjunction: the smallest of the
parts; disjunction: the largest of the parts that hold), in the units of the atoms.  A flowpipe
that is not complete — inconclusive (a blow-up, a limit) or stopped by the jump bound — proves
nothing.

:func:`reach_proof` turns that into an :class:`analysis.verify.verification.Proof`: ``holds`` when the
producer decides the requirement, ``rechecked`` only when the independent re-check
(:func:`analysis.reach.recheck.recheck_flowpipe`, from the saved JSON) passes too.
:class:`ReachProof` is the picklable callable that :func:`analysis.verify.problems.hybrid_problem`
attaches to a requirement (``reach="auto"``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Any

import numpy as np

from analysis.verify.verification import Proof

from .autostep import AUTO_NORM_STEPS, auto_choices, chosen_text
from .engine import reach
from .fragment import Conj, LabelAtom, LinearAtom, Nnf, SafetyFragment, label_holds
from .model import affine_model
from .deadlock import clip_exact, clock_offsets, entry_uncovered, face_uncovered, image_covered, reached_late
from .recheck import recheck_flowpipe
from .result import ReachResult, ReachSegment
from .zonotope import from_box, round_down, support_bounds

__all__ = ["ReachDecision", "decide", "reach_proof", "ReachProof", "METHOD", "METHOD_NONLINEAR", "default_time_step",
           "default_max_jumps", "reach_proofs", "REACH_CHOICES", "scaled_fragment"]

METHOD = ("reachability (zonotope flowpipe, analysis.reach), re-checked on the re-check's own sets (outward-rounded "
          "intervals, exact rationals)")
METHOD_NONLINEAR = ("reachability (zonotope flowpipe by conservative linearisation with a Lagrange remainder, "
                    "analysis.reach.nonlinear), re-checked by interval Picard and a second-order Taylor map in "
                    "outward-rounded intervals")
"""The method of a proof whose system has a nonlinear (smooth) mode."""


MAX_SEGMENTS = 50_000
"""The flowpipe of a verdict stores at most this many segments (about 30 s with its re-check); beyond, it is
inconclusive (``"segment_limit"``) and proves nothing."""


def default_time_step(end: float) -> float:
    """``end / 1000`` [s] (``end``: the window's end, the reach horizon)."""
    return end / 1000.0


def default_max_jumps(end: float) -> int:
    """``max(50, 10·⌈end⌉)`` jumps: a bound a flowpipe must not hit (hitting it proves nothing)."""
    return max(50, 10 * math.ceil(end))


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachDecision:
    """The producer's decision: ``holds``, ``margin`` (smallest slack; ``nan`` when nothing decided),
    ``reason`` in words, the flowpipe, and the seconds taken."""

    holds: bool
    margin: float
    reason: str
    result: ReachResult | None
    seconds: float


def _atom_top(atom: LinearAtom, seg: ReachSegment) -> float:
    """A rigorous upper bound of ``max c·x`` over ``zonotope ∩ box`` (residual for a non-float ``c``)."""
    normal = np.array([float(q) for q in atom.coefficients])
    residual = np.array([abs(float(q - Fraction(f))) * 2 for q, f in zip(atom.coefficients, normal)])
    _, top_z = support_bounds(seg.zonotope, normal, residual)
    _, top_b = support_bounds(from_box(seg.lo, seg.hi), normal, residual)
    return min(top_z, top_b)


def _slack(node: Nnf, seg: ReachSegment) -> tuple[bool, float | None]:
    if isinstance(node, LabelAtom):
        return label_holds(node, seg.mode), None
    if isinstance(node, LinearAtom):
        bound = float(node.bound)
        if Fraction(bound) > node.bound:
            bound = float(np.nextafter(bound, -np.inf))
        slack = float(round_down(np.float64(bound) - np.float64(_atom_top(node, seg))))
        return (slack > 0 if node.strict else slack >= 0), slack
    results = [_slack(p, seg) for p in node.parts]
    slacks = [v for _, v in results if v is not None]
    if isinstance(node, Conj):
        return all(ok for ok, _ in results), (min(slacks) if slacks else None)
    good = [v for ok, v in results if ok]
    if good and any(v is None for v in good):
        return True, None  # a label disjunct holds: no numeric constraint on this segment
    return bool(good), (max(good) if good else (max(slacks) if slacks else None))


def decide(result: ReachResult, fragment: SafetyFragment, model: Any = None,
           initial: Mapping[str, tuple[float, float]] | None = None) -> tuple[bool, float, str]:
    """Decide the fragment on a flowpipe: (holds, margin, reason).

    With the affine ``model``, a flowpipe that leaves an invariant where no guard is shown enabled, or
    a jump landing outside the target's invariant and every guard, proves nothing (a possible deadlock:
    the executor's run would end early).  With ``initial`` (the exact initial box), the initial entry is
    checked on it rather than on the saved segment's box (which rounding makes a little wider).
    """
    if model is not None:
        given = {mode: ([[Fraction(v) for v in row] for row in b], [Fraction(v) for v in lo], [Fraction(v) for v in hi])
                 for mode, b, lo, hi in result.inputs}
        flowed, offsets = _flowed(result, model, given, initial)
        end = Fraction(fragment.end)
        for mode, parts in flowed.items():  # every state leaving an invariant is on a face within a flowed box
            why = face_uncovered(model, mode, parts, inputs=given.get(mode),
                                 late=lambda i, face, m=mode: reached_late(face, offsets[m][i], end))
            if why:
                return False, math.nan, f"not decided by reachability: {why}"
        for mode, box, pre in _entries(result, model, initial):
            why = entry_uncovered(model, mode, box)
            if why and pre is not None and image_covered(model, *pre):
                why = None
            if why:
                return False, math.nan, f"not decided by reachability: {why}"
    if not result.complete:
        bad = next(t for t in result.terminations if not t.conclusive)
        return False, math.nan, f"the flowpipe is inconclusive: {bad.detail}"
    capped = [t for t in result.terminations if t.reason == "max_jumps"]
    if capped:
        return False, math.nan, f"the flowpipe stopped at the jump bound ({capped[0].detail}): not every behaviour covered"
    margin = math.inf
    for seg in result.segments:
        if seg.t_lo > fragment.end or seg.t_hi < fragment.start:
            continue
        ok, slack = _slack(fragment.body, seg)
        if not ok:
            return False, (slack if slack is not None else math.nan), (
                f"not decided on the segment of mode {seg.mode!r} at t in [{seg.t_lo:.6g}, {seg.t_hi:.6g}] s "
                f"(slack {slack if slack is not None else 'n/a'}): the flowpipe does not prove it")
        if slack is not None:
            margin = min(margin, slack)
    return True, margin, f"holds on all {len(result.segments)} segments"


def _flowed(result: ReachResult, model: Any, given: Mapping[str, Any],
            initial: Mapping[str, tuple[float, float]] | None
            ) -> tuple[dict[str, list[Any]], dict[str, list[dict[int, Fraction]]]]:
    """The flowed boxes per mode (exact) and, for each, the clock offsets of its flowpipe
    (:func:`analysis.reach.deadlock.clock_offsets`; a flowpipe's segments follow its entry segment; the first
    entry read on the exact initial box when given, as in :func:`_entries`)."""
    flowed: dict[str, list[Any]] = {}
    offsets: dict[str, list[dict[int, Fraction]]] = {}
    current: dict[int, Fraction] = {}
    for k, seg in enumerate(result.segments):
        box = [(Fraction(float(lo)), Fraction(float(hi))) for lo, hi in zip(seg.lo, seg.hi)]
        if seg.entry:
            if k == 0 and initial is not None and seg.jumps == 0:
                box = [(Fraction(float(initial[s][0])), Fraction(float(initial[s][1]))) for s in result.state_names]
            current = clock_offsets(model, seg.mode, box, Fraction(float(seg.t_lo)), given.get(seg.mode))
            continue
        flowed.setdefault(seg.mode, []).append((box, None))
        offsets.setdefault(seg.mode, []).append(current)
    return flowed, offsets


def _entries(result: ReachResult, model: Any, initial: Mapping[str, tuple[float, float]] | None) -> list[Any]:
    """``(mode, box)`` holding each flowpipe's entry set, exactly: the initial box (when given), and after jump
    ``i − 1`` (the engine's order) the exact reset images of its ``before`` box clipped to each guard polyhedron
    (the states before a jump are in its guard; the saved boxes are rounded outward, which a face would not take)."""
    out = []
    entries = [seg for seg in result.segments if seg.entry]
    for i, seg in enumerate(entries):
        box = [(Fraction(float(lo)), Fraction(float(hi))) for lo, hi in zip(seg.lo, seg.hi)]
        if i == 0 and initial is not None and seg.jumps == 0:
            out.append((seg.mode, [(Fraction(float(initial[k][0])), Fraction(float(initial[k][1])))
                                   for k in result.state_names], None))
            continue
        t = next((t for t in model.transitions if i > 0 and i - 1 < len(result.jumps)
                  and t.name == result.jumps[i - 1].transition), None)
        if t is None:
            out.append((seg.mode, box, None))
            continue
        jump = result.jumps[i - 1]
        before = [(Fraction(float(lo)), Fraction(float(hi))) for lo, hi in zip(jump.before_lo, jump.before_hi)]
        invariant = model.modes[t.source].invariant
        # the source's invariant holds the states before only when no entry set of the source (at that depth) met
        # the guard: the engine merges entry and flowed parts into one jump
        flowed = len(invariant) == 1 and not any(
            e.mode == t.source and e.jumps == jump.jumps - 1 and any(clip_exact(
                [(Fraction(float(lo)), Fraction(float(hi))) for lo, hi in zip(e.lo, e.hi)], p.halfspaces) is not None
                for p in t.guard) for e in entries)
        for poly in t.guard:
            part = clip_exact(before, poly.halfspaces)
            if part is not None:
                rows = (*poly.halfspaces, *(invariant[0].halfspaces if flowed else ()))
                out.append((seg.mode, [(sum((min(a * l, a * h) for a, (l, h) in zip(row, part) if a), Fraction(0)) + off,
                                        sum((max(a * l, a * h) for a, (l, h) in zip(row, part) if a), Fraction(0)) + off)
                                       for row, off in zip(t.r_matrix, t.r_offset)], (t, part, rows)))
    return out


def _evidence(decision: ReachDecision, check: Any) -> str:
    """The proof's evidence in words: deterministic (no timings; :attr:`ReachDecision.seconds` has them), so a
    report that quotes it has the same bytes on every run."""
    r = decision.result
    size = f"{len(r.segments)} segments, {len(r.jumps)} jumps, step {r.time_step:g} s" if r is not None else ""
    if check is None:
        return f"reachability: {decision.reason}; {size}; not re-checked (nothing to re-check)"
    if check.passed:
        again = (f"re-checked from the saved flowpipe ({check.segments} segments, {check.jumps} jumps: "
                 f"{'; '.join(check.parts)}), exact margin {check.margin}")
    else:
        again = f"re-check FAILED ({check.failure})"
    return f"reachability: {decision.reason}, margin {decision.margin:.6g}; {size}; {again}"


def scaled_fragment(fragment: SafetyFragment, scale: Fraction) -> SafetyFragment:
    """``always[0, b·scale] φ``: the window in the time ``τ = m(p)·t`` of a time scale with ``max m = scale``.

    The end is rounded up to a float, so the scaled window holds every ``[0, b·m(p)]``.
    """
    if scale == 1:
        return fragment
    end = Fraction(fragment.end) * scale
    value = float(end)
    if Fraction(value) < end:
        value = float(np.nextafter(value, np.inf))
    return replace(fragment, end=value)


def _decide_mode(system: Any, fragment: SafetyFragment, initial: Mapping[str, tuple[float, float]],
                 mode: str | None, step: float, jumps: int, cache: dict[Any, ReachResult] | None,
                 engine: Mapping[str, Any] | None = None, kappas: Sequence[float] = ()
                 ) -> tuple[ReachDecision, Any, float]:
    """One start mode: the flowpipe, the producer's decision, the re-check (or None) and its seconds.  With
    ``kappas``, the steps of fast modes are chosen from the dynamics (:mod:`analysis.reach.autostep`), one choice
    after the other until one is proven and re-checked."""
    if not kappas:
        return _attempt(system, fragment, initial, mode, step, jumps, cache, engine)
    try:
        model = affine_model(system, nonlinear=True)
    except Exception:  # noqa: BLE001 - the attempt raises the same error where its callers expect it
        return _attempt(system, fragment, initial, mode, step, jumps, cache, engine)
    end = max(fragment.end, 1e-9)
    outcome = None
    for kappa, options in auto_choices(model, end, min(step, end), dict(engine or {}), tuple(kappas), MAX_SEGMENTS):
        outcome = _attempt(system, fragment, initial, mode, step, jumps, cache, options)
        text = chosen_text(kappa, options, engine)
        if text:
            outcome = (replace(outcome[0], reason=f"{outcome[0].reason}{text}"), *outcome[1:])
        if outcome[0].holds and outcome[1] is not None and outcome[1].passed:
            break
    return outcome if outcome is not None else _attempt(system, fragment, initial, mode, step, jumps, cache, engine)


def _attempt(system: Any, fragment: SafetyFragment, initial: Mapping[str, tuple[float, float]],
             mode: str | None, step: float, jumps: int, cache: dict[Any, ReachResult] | None,
             engine: Mapping[str, Any] | None = None) -> tuple[ReachDecision, Any, float]:
    """One flowpipe with these options, the producer's decision, the re-check (or None) and its seconds."""
    end = max(fragment.end, 1e-9)
    start = time.perf_counter()
    extra = dict(engine or {})
    if "mode_time_steps" in extra:
        extra["mode_time_steps"] = {k: min(float(v), end) for k, v in extra["mode_time_steps"].items()}
    key = (end, min(step, end), jumps, mode, tuple(sorted((k, tuple(v)) for k, v in initial.items())),
           repr(sorted(extra.items())))
    result = None if cache is None else cache.get(key)
    if result is None:
        result = reach(system, dict(initial), horizon=end, time_step=min(step, end), initial_mode=mode,
                       max_jumps=jumps, max_segments=MAX_SEGMENTS, **extra)
        if cache is not None:
            cache[key] = result
    holds, margin, reason = decide(result, fragment, affine_model(system, nonlinear=True), initial)
    decision = ReachDecision(holds=holds, margin=margin, reason=reason, result=result,
                             seconds=time.perf_counter() - start)
    if not holds:
        return decision, None, 0.0
    start = time.perf_counter()
    check = recheck_flowpipe(result.to_json(), system, initial, fragment, initial_mode=mode)
    return decision, check, time.perf_counter() - start


def reach_proof(system: Any, fragment: SafetyFragment, initial: Mapping[str, tuple[float, float]], *,
                initial_mode: str | None = None, time_step: float | None = None,
                max_jumps: int | None = None, cache: dict[Any, ReachResult] | None = None,
                starts: Sequence[tuple[str, Any]] | None = None, scale: Fraction = Fraction(1),
                scale_text: str = "", splits: Mapping[str, int] | None = None,
                engine: Mapping[str, Any] | None = None) -> tuple[Proof, ReachDecision]:
    """Decide and re-check ``fragment`` over the initial box; the :class:`Proof` and the producer's decision.

    Parameters
    ----------
    system : hybrid.system.HybridSystem or AffineHybridModel
        Symbolic and affine (or its affine reading, e.g. with parameters as constant states).
    fragment : SafetyFragment
    initial : mapping {state: (lo, hi)}
        The box of initial states.
    initial_mode : str or None
    time_step : float or None
        ``δ`` [s]; default :func:`default_time_step` of the window's end.
    max_jumps : int or None
        Default :func:`default_max_jumps`.
    cache : dict or None
        Flowpipes already computed, by their settings (the requirements of one problem with the same
        window share one flowpipe; each is decided and re-checked on its own).
    starts : sequence of (mode, box) or None
        Start from each mode with its box ``((name, lo, hi), ...)`` (every one must prove the requirement);
        default ``((initial_mode, initial),)``.
    scale, scale_text : Fraction, str
        A common time scale ``m(p)`` of the flows (:mod:`analysis.reach.parameters`): the window's end is
        multiplied by ``scale = max m`` and the flows are those divided by ``m``.
    splits : mapping {state: int} or None
        Cut the initial box (of every start) into this grid (:func:`analysis.reach.split.split_box`); each
        piece is decided and re-checked on its own, and the proof holds when every piece's does (the pieces
        cover the box, checked exactly).
    engine : mapping or None
        Options of :func:`analysis.reach.reach` for long or hybrid runs: ``mode_time_steps`` ({mode: step},
        scaled like ``time_step``), ``jump_cluster``, ``merge_segments`` (the re-check takes the first two as
        its schedule).
    """
    if splits and any(k != 1 for k in dict(splits).values()):
        return _split_proof(system, fragment, initial, dict(splits), initial_mode=initial_mode,
                            time_step=time_step, max_jumps=max_jumps, cache=cache, starts=starts, scale=scale,
                            scale_text=scale_text, engine=engine)
    engine = dict(engine or {})
    if "mode_time_steps" in engine:
        engine["mode_time_steps"] = {k: float(v) * float(scale) for k, v in engine["mode_time_steps"].items()}
    jumps = default_max_jumps(max(fragment.end, 1e-9)) if max_jumps is None else max_jumps  # jumps: the same events
    fragment = scaled_fragment(fragment, scale)  # in both times; the window and the step scale
    end = max(fragment.end, 1e-9)
    step = default_time_step(end) if time_step is None else time_step * float(scale)
    begin = [(m, {k: (lo, hi) for k, lo, hi in b}) for m, b in starts] if starts else [(initial_mode, dict(initial))]
    modes = [m for m, _ in begin]
    kappas = AUTO_NORM_STEPS if time_step is None and "mode_time_steps" not in engine else AUTO_NORM_STEPS[:1]
    runs = [(m, *_decide_mode(system, fragment, b, m, step, jumps, cache, engine, kappas)) for m, b in begin]
    bad = next((r for r in runs if not r[1].holds), None)
    holds = bad is None
    chosen = bad if bad is not None else min(runs, key=lambda r: r[1].margin)
    decision = chosen[1]
    rechecked = holds and all(c is not None and c.passed for _, _, c, _ in runs)
    parts = [(f"from mode {m!r}: " if len(runs) > 1 else "") + _evidence(d, c) for m, d, c, _ in runs]
    assumptions = [f"the initial box {dict(initial)}" if len(begin) == 1 else
                   "the initial box " + "; ".join(f"in mode {m!r} {b}" for m, b in begin), f"the window [{fragment.start:g}, {fragment.end:g}] s",
                   "the mathematical semantics of the model (exact flows and guards; see docs/reachability.md)"]
    if len(runs) > 1:
        assumptions.append(f"every start mode {list(modes)} (the initial mode depends on the point)")
    if scale_text:
        assumptions.append(f"the flows are {scale_text} times flows free of it, {scale_text} > 0 on the box: the "
                           f"window is read in the time tau = {scale_text}·t, [0, {fragment.end:g}] (the flows "
                           f"divided by {scale_text})")
    margin = None if not math.isfinite(decision.margin) else float(decision.margin)
    method = _method(affine_model(system, nonlinear=True))
    proof = Proof(holds=holds, method=method, evidence=" | ".join(parts), rechecked=rechecked,
                  assumptions=tuple(assumptions), margin=margin)
    return proof, decision


def _method(model: Any) -> str:
    return METHOD_NONLINEAR if any(m.smooth is not None for m in model.modes.values()) else METHOD


def _split_proof(system: Any, fragment: SafetyFragment, initial: Mapping[str, tuple[float, float]],
                 splits: dict[str, int], *, initial_mode: str | None, starts: Sequence[tuple[str, Any]] | None,
                 **options: Any) -> tuple[Proof, ReachDecision]:
    """:func:`reach_proof` on every piece of the split box of every start (mode, box); holds (and is re-checked)
    when every piece is.  ``options`` (step, jumps, cache, time scale) go to each piece unchanged."""
    from .split import covers, split_box

    begin = [(m, {k: (lo, hi) for k, lo, hi in b}) for m, b in starts] if starts else [(initial_mode, dict(initial))]
    jobs = []
    for mode, box in begin:
        pieces = split_box(box, splits)
        if not covers(box, pieces):  # by construction; checked so that a wrong split can never prove
            return Proof(holds=False, method=METHOD, evidence="the split pieces do not cover the initial box",
                         rechecked=False), ReachDecision(holds=False, margin=math.nan, reason="split", result=None,
                                                         seconds=0.0)
        jobs += [(mode, piece) for piece in pieces]
    start = time.perf_counter()
    proofs = [reach_proof(system, fragment, piece, initial_mode=mode, **options) for mode, piece in jobs]
    holds = all(p.holds for p, _ in proofs)
    rechecked = holds and all(p.rechecked for p, _ in proofs)
    margin = min(d.margin for _, d in proofs) if holds else math.nan
    first_bad = next((p for p, _ in proofs if not (p.holds and p.rechecked)), None)
    where = "; ".join(f"{k}: {v}" for k, v in splits.items())
    whose = "the initial box" if len(begin) == 1 else f"the initial box of each of {len(begin)} start modes"
    evidence = (f"{whose} split into {len(jobs)} pieces ({where}), covering it exactly; "
                + (f"every piece proven and re-checked, smallest margin {margin:.6g}; piece 1: {proofs[0][0].evidence}"
                   if rechecked else f"a piece is not proven or not re-checked: {first_bad.evidence}"))
    decision = ReachDecision(holds=holds, margin=margin, reason=f"split into {len(jobs)} pieces", result=None,
                             seconds=time.perf_counter() - start)
    assumptions = [f"the initial box {dict(initial)}" if len(begin) == 1 else
                   "the initial box " + "; ".join(f"in mode {m!r} {b}" for m, b in begin),
                   *proofs[0][0].assumptions[1:]]  # the window (in the scaled time), semantics, time scale
    if len(begin) > 1:
        assumptions.append(f"every start mode {[m for m, _ in begin]} (the initial mode depends on the point)")
    return Proof(holds=holds, method=proofs[0][0].method, evidence=evidence, rechecked=rechecked,
                 assumptions=tuple(assumptions), margin=float(margin) if holds and math.isfinite(margin) else None
                 ), decision


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachProof:
    """``() -> Proof`` for one requirement of a problem (picklable when the system is)."""

    system: Any
    fragment: SafetyFragment
    initial: tuple[tuple[str, float, float], ...]
    initial_mode: str | None = None
    time_step: float | None = None
    max_jumps: int | None = None
    refused: str | None = None
    starts: tuple[tuple[str, Any], ...] | None = None
    scale: Fraction = Fraction(1)
    scale_text: str = ""
    cache: dict[Any, ReachResult] | None = field(default=None, compare=False, repr=False)
    splits: tuple[tuple[str, int], ...] | None = None
    engine: tuple[tuple[str, Any], ...] = ()

    def __call__(self) -> Proof:
        """The proof (never raises: a model or option reachability cannot handle gives a proof that does not hold)."""
        from hybrid.errors import ModelDefinitionError, ParameterError

        if self.refused is not None:
            return Proof(holds=False, method=METHOD, evidence=self.refused, rechecked=False)
        try:
            proof, _ = reach_proof(self.system, self.fragment, {k: (lo, hi) for k, lo, hi in self.initial},
                                   initial_mode=self.initial_mode, time_step=self.time_step,
                                   max_jumps=self.max_jumps, cache=self.cache, starts=self.starts,
                                   scale=self.scale, scale_text=self.scale_text,
                                   splits=None if self.splits is None else dict(self.splits),
                                   engine=dict(self.engine))
        except (ParameterError, ModelDefinitionError) as exc:
            return Proof(holds=False, method=METHOD, evidence=f"not decided by reachability: {exc}", rechecked=False)
        return proof


REACH_CHOICES = ("auto", True, False)


def _checked_options(reach_mode: Any, options: Mapping[str, Any] | None, where: str) -> dict[str, Any]:
    from analysis.verify.verification import ProblemError

    if reach_mode not in REACH_CHOICES or isinstance(reach_mode, int) and not isinstance(reach_mode, bool):
        raise ProblemError(f"{where}: reach", reach_mode, "'auto', True or False",
                           "write reach='auto' (the default), True (required) or False (falsification only)")
    opts = dict(options or {})
    unknown = sorted(set(opts) - {"time_step", "max_jumps", "splits", *ENGINE_OPTIONS})
    if unknown:
        raise ProblemError(f"{where}: reach_options", opts, "keys time_step [s], max_jumps, splits, "
                           "mode_time_steps, jump_cluster and merge_segments", f"remove {unknown}")
    _check_engine(opts, where)
    splits = opts.get("splits")
    if splits is not None and not (isinstance(splits, Mapping) and all(
            isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) and v >= 1
            for k, v in splits.items())):
        raise ProblemError(f"{where}: reach_options['splits']", splits, "a mapping {state: whole number >= 1}",
                           "give e.g. splits={'x': 4}, or leave it out")
    step = opts.get("time_step")
    if step is not None and (isinstance(step, bool) or not isinstance(step, (int, float))
                             or not math.isfinite(step) or step <= 0):
        raise ProblemError(f"{where}: reach_options['time_step']", step, "a finite step > 0 [s]",
                           "give e.g. time_step=0.01, or leave it out (the window's end / 1000)")
    jumps = opts.get("max_jumps")
    if jumps is not None and (isinstance(jumps, bool) or not isinstance(jumps, int) or jumps < 0):
        raise ProblemError(f"{where}: reach_options['max_jumps']", jumps, "a whole number >= 0",
                           "give e.g. max_jumps=100, or leave it out")
    return opts


ENGINE_OPTIONS = ("mode_time_steps", "jump_cluster", "merge_segments")
"""``reach_options`` keys passed to :func:`analysis.reach.reach` as they are (long and hybrid runs)."""


def _check_engine(opts: Mapping[str, Any], where: str) -> None:
    from analysis.verify.verification import ProblemError

    steps = opts.get("mode_time_steps")
    if steps is not None and not (isinstance(steps, Mapping) and all(
            isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0 for k, v in steps.items())):
        raise ProblemError(f"{where}: reach_options['mode_time_steps']", steps, "a mapping {mode: step > 0 [s]}",
                           "give e.g. mode_time_steps={'fast': 0.001}, or leave it out")
    for name in ("jump_cluster", "merge_segments"):
        value = opts.get(name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ProblemError(f"{where}: reach_options[{name!r}]", value, "a whole number >= 1",
                               f"give e.g. {name}=25, or leave it out")


def reach_proofs(system: Any, parsed: Any, initial: Mapping[str, Any], *, reach_mode: Any = "auto",
                 initial_mode: Any = None, builder: bool = False, options: Mapping[str, Any] | None = None,
                 where: str = "problem", box: Sequence[Any] = ()) -> dict[str, Any]:
    """The reachability proofs of a problem's requirements: ``{requirement name: ReachProof}``.

    Parameters
    ----------
    system : HybridSystem, callable or other
        The problem's system, or (``builder``) the function building it from the point.
    parsed : sequence of ParsedRequirement
        ``problem.parsed``.
    initial : mapping {state: Parameter or float}
        The problem's initial states (a Parameter gives its ``[low, high]``).
    reach_mode : "auto", True or False
        ``False``: none.  ``"auto"``: a proof for each requirement in the fragment when the system is
        symbolic and affine.  ``True``: also for smooth nonlinear flows (polynomials, sin, cos:
        :mod:`analysis.reach.nonlinear`), and a system reachability cannot read raises.
    builder : bool
        The problem's system is built by a function of the parameters: they are read as constant states
        (:mod:`analysis.reach.parameters`); when they cannot be, each requirement in the fragment gets a
        proof that does not hold and says why.
    options : mapping or None
        ``time_step`` [s], ``max_jumps`` and ``splits`` of :func:`reach_proof`; ``mode_time_steps``,
        ``jump_cluster`` and ``merge_segments`` of :func:`analysis.reach.reach` (:data:`ENGINE_OPTIONS`).
    box : sequence of Parameter
        Every coordinate of the problem's box (``problem.parameters``), for ``builder``.

    Raises
    ------
    analysis.verify.verification.ProblemError
        ``reach=True`` with a system reachability cannot read, or bad options.
    """
    from analysis.verify.verification import ProblemError

    from .affine import AffineError
    from .fragment import NotInFragment, safety_fragment
    from .parameters import ParameterRoute, initial_modes, reach_setup

    opts = _checked_options(reach_mode, options, where)
    if reach_mode is False:
        return {}
    why = None
    try:
        # "auto": affine systems only; True: smooth nonlinear flows too
        setup = reach_setup(system, initial, box, builder=builder, nonlinear=reach_mode is True)
        declared = _declared(system, box) if builder else bool(getattr(system.automaton, "initial_mode_given", True))
        modes = initial_modes(setup, initial_mode, declared)
    except AffineError as exc:
        if reach_mode is True:
            raise ProblemError(f"{where}: reach", True, "a symbolic, affine HybridSystem (reachability needs a "
                               f"symbolic model): {exc}",
                               "write the flows with hybrid.symbolic.flow_map(...), the resets with jump_map(...), "
                               "guards and invariants as symbolic conditions (coordinates('x').x >= 1.0); or "
                               "use reach='auto' or False (falsification still runs)") from None
        return {}
    except ParameterRoute as exc:
        setup, modes, why = None, (), f"not decided by reachability: {exc}"
    out: dict[str, Any] = {}
    shared: dict[Any, ReachResult] = {}
    names = setup.model.state_names if setup is not None else tuple(initial)
    for p in parsed:
        try:
            fragment = safety_fragment(p.formula.tree, names, ("mode",))
        except NotInFragment:
            continue
        if setup is None:
            out[p.name] = ReachProof(system=None, fragment=fragment, initial=(), refused=why)
            continue
        out[p.name] = ReachProof(system=setup.model, fragment=fragment, initial=setup.box,
                                 initial_mode=modes[0][0], starts=modes, time_step=opts.get("time_step"),
                                 max_jumps=opts.get("max_jumps"), scale=setup.scale, scale_text=setup.scale_text,
                                 cache=shared, splits=None if opts.get("splits") is None
                                 else tuple(sorted(opts["splits"].items())),
                                 engine=tuple((k, opts[k]) for k in ENGINE_OPTIONS if opts.get(k) is not None))
    return out


def _declared(system: Any, box: Sequence[Any]) -> bool:
    """Whether the built automaton declares its initial mode (the probe at the nominal point)."""
    try:
        probe = system({p.name: p.at(0.0) for p in box})
    except Exception:  # the user's builder; hybrid_problem built this probe already
        return False
    return bool(getattr(probe.automaton, "initial_mode_given", True))
