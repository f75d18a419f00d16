"""Reachability of a whole verification problem: its flowpipes and a verdict per requirement.

:func:`problem_reach` takes a problem of :func:`analysis.verify.problems.hybrid_problem` (a symbolic
:class:`~hybrid.system.HybridSystem`, or a function building one from the parameters: the
parameters become constant states, :mod:`analysis.reach.parameters`), computes one flowpipe per
start mode over the problem's whole box, and decides each requirement of the STL safety fragment
on it (:func:`analysis.reach.verdict.decide`), re-checking every decision that holds
(:func:`analysis.reach.recheck.recheck_flowpipe`).  Statuses (:data:`STATUSES`):

``proven``
    decided on every start's flowpipe and re-checked from its JSON;
``not_rechecked``
    the producer decided it but the re-check failed (not a proof);
``met``
    every flowpipe is complete and one meets the requirement's unsafe set: the over-approximation
    reaches it (the system may or may not: a search for a counterexample decides that);
``inconclusive``
    the flowpipe is inconclusive (a blow-up, a limit, the jump bound) or a deadlock is possible;
``not_in_fragment``
    reachability does not decide this formula (the reason says why).

Steps: an explicit ``time_step`` is used as it is (no other step).  Without one, the run is scheduled as
``visnav verify`` schedules its proofs (:func:`analysis.reach.verdict.reach_proof`): the problem's own
``reach_options`` (``time_step``, e.g. a SpaceEx ``sampling-time``; ``max_jumps``; ``mode_time_steps``,
``jump_cluster``, ``merge_segments``) and the steps of fast modes chosen from the dynamics
(:func:`analysis.reach.autostep.auto_choices`), one choice after the other until every requirement in the
fragment is proven (re-checked); the flowpipes and verdicts of the first such choice are kept, else those of the
choice with the most proven requirements (the first of equals).  :attr:`ProblemReach.options` and
:attr:`ProblemReach.steps_chosen` name the steps of the kept flowpipes.

Inputs: a SpaceEx problem with bounded non-deterministic inputs (:func:`analysis.spaceex.spaceex_problem`) is read
as ``visnav verify`` reads it (:func:`analysis.spaceex_route.problem_input_route`): the model with every input at 0,
each input ``u(t) ∈ [low, high]`` entering as ``B u`` (any measurable signal, not the simulated pieces), the
flowpipes of :func:`analysis.spaceex_reach.input_flowpipe` and the re-check with the inputs.  The steps follow the
same schedule with the ladder :data:`analysis.reach.autostep.AUTO_INPUT_STEPS`; :attr:`ProblemReach.inputs` names
the bounds.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from .fragment import NotInFragment, safety_fragment
from .initial import ReachError
from .parameters import ReachSetup, Start, initial_modes, reach_setup
from .engine import reach
from .recheck import recheck_flowpipe
from .result import ReachResult
from .autostep import AUTO_INPUT_STEPS, AUTO_NORM_STEPS, auto_choices, chosen_text
from .verdict import ENGINE_OPTIONS, MAX_SEGMENTS, decide, default_max_jumps, scaled_fragment

__all__ = ["STATUSES", "RequirementReach", "ProblemReach", "problem_reach"]

STATUSES = ("proven", "not_rechecked", "met", "inconclusive", "not_in_fragment")
FORMAT = "visnav-reach"


@dataclass(frozen=True, kw_only=True, slots=True)
class RequirementReach:
    """One requirement's reachability verdict (``status`` in :data:`STATUSES`; ``margin`` in its units)."""

    name: str
    formula: str
    status: str
    margin: float | None
    recheck_margin: float | None
    reason: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (margins as floats or null; the re-check's exact margin as a string)."""
        return {"name": self.name, "formula": self.formula, "status": self.status, "margin": self.margin,
                "recheck_margin": self.recheck_margin, "reason": self.reason}


@dataclass(frozen=True, kw_only=True, slots=True)
class ProblemReach:
    """The flowpipes of a problem (one per start mode) and its requirements' verdicts.

    Attributes
    ----------
    horizon, time_step : float
        In the problem's time [s].  With a time scale (``scale_text``), the flowpipes are in the time
        ``τ = m(p)·t`` up to ``horizon·scale``.
    runs : tuple of (mode, box, ReachResult)
    options : mapping
        The engine options of the flowpipes (``mode_time_steps`` in the flowpipes' time [s], ``jump_cluster``,
        ``merge_segments``); empty with the base step alone.
    steps_chosen : str
        How the steps were chosen, in words (``""`` with an explicit step).
    inputs : tuple of (name, low, high)
        The bounded non-deterministic inputs the flowpipes cover (any signal within the bounds); empty without.
    """

    problem: str
    setup: ReachSetup
    horizon: float
    time_step: float
    max_jumps: int
    runs: tuple[tuple[str, tuple[tuple[str, float, float], ...], ReachResult], ...]
    requirements: tuple[RequirementReach, ...]
    options: Mapping[str, Any] = field(default_factory=dict)
    steps_chosen: str = ""
    inputs: tuple[tuple[str, float, float], ...] = ()

    @property
    def complete(self) -> bool:
        """Every flowpipe is complete (no inconclusive end)."""
        return all(r.complete for _, _, r in self.runs)

    def to_json(self) -> str:
        """The flowpipes (:meth:`ReachResult.to_json`) and the verdicts, deterministic (no timings)."""
        s = self.setup
        data = {"format": FORMAT, "version": 1, "problem": self.problem, "horizon": self.horizon,
                "time_step": self.time_step, "max_jumps": self.max_jumps, "complete": self.complete,
                "options": dict(self.options), "steps_chosen": self.steps_chosen,
                "state_names": list(s.model.state_names), "parameters_as_states": list(s.parameters),
                "time_scale": None if not s.scale_text else {"factor": s.scale_text, "max": float(s.scale),
                                                             "flowpipe_time": "tau = factor * t"},
                "starts": [{"mode": m, "box": [[n, lo, hi] for n, lo, hi in box], "flowpipe": json.loads(r.to_json())}
                           for m, box, r in self.runs],
                "requirements": [q.as_dict() for q in self.requirements]}
        if self.inputs:  # absent without inputs: the JSON of other problems is unchanged
            data["inputs"] = [{"name": n, "low": lo, "high": hi, "signal": "any measurable signal within the bounds"}
                              for n, lo, hi in self.inputs]
        return json.dumps(data, sort_keys=True, allow_nan=False, default=_plain)


def _plain(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    raise TypeError(f"not JSON: {value!r}")


def _checked(name: str, value: Any, test: Callable[[float], bool], expected: str, fix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not test(value):
        raise ReachError(name, value, expected, fix)
    return float(value)


def _up(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) >= q else math.nextafter(f, math.inf)


def problem_reach(problem: Any, *, horizon: float | None = None, time_step: float | None = None,
                  max_jumps: int | None = None, progress: Callable[[float], None] | None = None) -> ProblemReach:
    """Flowpipes of ``problem`` over its whole box and a verdict per requirement (see the module docstring).

    Parameters
    ----------
    problem : analysis.verify.verification.VerificationProblem
        Made by :func:`analysis.verify.problems.hybrid_problem`.
    horizon : float or None
        [s]; default the problem's horizon.
    time_step : float or None
        ``0 < δ <= horizon`` [s], used alone; default: the problem's ``reach_options`` and steps chosen from the
        dynamics (see the module), from the base step ``reach_options["time_step"]`` or ``horizon / 1000``.
    max_jumps : int or None
        Default the problem's ``reach_options["max_jumps"]``, else
        :func:`analysis.reach.verdict.default_max_jumps` of the horizon.
    progress : callable or None
        ``progress(share)`` with the share of the work done in ``[0, 1]`` (time reached over the horizon,
        summed over the start modes).

    Raises
    ------
    ReachError
        A bad option, or a problem that is not a continuous-time hybrid problem.
    analysis.reach.affine.AffineError, analysis.reach.parameters.ParameterRoute
        The model cannot be read (not symbolic, not affine — an input times a state —, parameters that are not
        constant states).
    """
    from analysis.verify.problems import HybridSimulation

    sim = problem.simulate
    if not isinstance(sim, HybridSimulation):
        raise ReachError("problem", problem.name, "a problem of analysis.verify.problems.hybrid_problem (a continuous-time "
                         "hybrid system; reachability needs a symbolic model)",
                         "build it with hybrid_problem(system=HybridSystem(...) with hybrid.symbolic flows, guards "
                         "and jump maps, ...)")
    end = _checked("horizon", problem.horizon if horizon is None else horizon, lambda v: v > 0,
                   "a finite horizon > 0 [s]", "give a horizon in seconds, e.g. 10")
    given = {} if time_step is not None else dict(getattr(sim, "reach_options", None) or {})
    base = given.get("time_step")
    step = _checked("time_step", end / 1000.0 if time_step is None and base is None else
                    time_step if time_step is not None else min(float(base), end), lambda v: 0 < v <= end,
                    f"a finite step 0 < time_step <= horizon = {end:g} [s]", f"give e.g. {end / 1000.0:g}")
    jumps = max_jumps if max_jumps is not None else given.get("max_jumps", default_max_jumps(end))
    if isinstance(jumps, bool) or not isinstance(jumps, int) or jumps < 0:
        raise ReachError("max_jumps", jumps, "a whole number >= 0", "give e.g. 100")
    setup, probe, route = _setup(problem, sim)
    matrices = None if route is None else route.matrices
    starts = initial_modes(setup, sim.initial_mode, bool(probe.automaton.initial_mode_given))
    engine = {k: given[k] for k in ENGINE_OPTIONS if given.get(k) is not None}
    if "mode_time_steps" in engine:  # in the flowpipes' time, as the step
        engine["mode_time_steps"] = {k: float(v) * float(setup.scale) for k, v in engine["mode_time_steps"].items()}
    choices: list[tuple[float | None, dict[str, Any]]] = [(None, engine)]
    if time_step is None:
        ladder = AUTO_NORM_STEPS if route is None else AUTO_INPUT_STEPS
        kappas = ladder if base is None and "mode_time_steps" not in engine else ladder[:1]
        tau_end = _up(Fraction(end) * setup.scale)
        choices = auto_choices(setup.model, tau_end, min(float(Fraction(step) * setup.scale), tau_end), engine,
                               kappas, MAX_SEGMENTS) or choices
    best = None
    for kappa, options in choices:
        runs = _flowpipes(setup, starts, end, step, jumps, progress, options, matrices)
        verdicts = tuple(_requirement(p, problem.requirements[i], setup, runs, route)
                         for i, p in enumerate(problem.parsed))
        text = chosen_text(kappa, options, engine).strip()[1:-1]
        proven = sum(v.status == "proven" for v in verdicts)
        if best is None or proven > best[0]:
            best = (proven, runs, verdicts, options, text)
        if all(v.status in ("proven", "not_in_fragment") for v in verdicts):
            break
    _, runs, verdicts, options, text = best
    return ProblemReach(problem=problem.name, setup=setup, horizon=end, time_step=step, max_jumps=jumps,
                        runs=runs, requirements=verdicts, options=options, steps_chosen=text,
                        inputs=() if route is None else tuple((i.name, i.low, i.high) for i in route.inputs))


def _setup(problem: Any, sim: Any) -> tuple[ReachSetup, Any, Any]:
    """``(setup, probe system, input route or None)``: a model with inputs is read without them (its ``B u``
    apart), its parameters of the simulated signals left out; others as the problem gives them."""
    from analysis.spaceex_route import problem_input_route

    route = problem_input_route(problem)
    if route is not None:
        return reach_setup(route.system, sim.initial, (), builder=False), route.system, route
    fixed = sim.fixed_system
    setup = reach_setup(fixed if fixed is not None else sim.build, sim.initial, problem.parameters,
                        builder=fixed is None)
    probe = fixed if fixed is not None else sim.build({p.name: p.at(0.0) for p in problem.parameters})
    return setup, probe, None


def _flowpipes(setup: ReachSetup, starts: tuple[Start, ...], end: float, step: float, jumps: int,
               progress: Callable[[float], None] | None, options: Mapping[str, Any],
               matrices: Mapping[str, Any] | None = None) -> tuple[Any, ...]:
    scale = setup.scale
    tau_end = _up(Fraction(end) * scale)
    tau_step = min(float(Fraction(step) * scale), tau_end)
    scaled = f"on the model's time scale (τ = {setup.scale_text or 1}·t, at most {float(scale):g}·t)"
    if not math.isfinite(tau_end):  # refused in the user's values, not the scaled ones
        raise ReachError("horizon", end, f"a horizon that stays finite {scaled}", "give a shorter horizon")
    if not tau_step > 0.0:
        raise ReachError("time_step", step, f"a step 0 < time_step <= horizon = {end:g} [s] that stays > 0 {scaled}",
                         f"give e.g. time_step = {end / 1000.0:g}")
    options = dict(options)
    if "mode_time_steps" in options:
        options["mode_time_steps"] = {k: min(float(v), tau_end) for k, v in options["mode_time_steps"].items()}
    out = []
    for i, (mode, box) in enumerate(starts):
        report = None if progress is None else (
            lambda t, i=i: progress((i + min(t / tau_end, 1.0)) / len(starts)))
        initial = {n: (lo, hi) for n, lo, hi in box}
        if matrices is None:
            result = reach(setup.model, initial, horizon=tau_end, time_step=tau_step, initial_mode=mode,
                           max_jumps=jumps, max_segments=MAX_SEGMENTS, progress=report, **options)
        else:
            from analysis.spaceex_reach import input_flowpipe
            from analysis.spaceex_relaxed import relaxed_flowpipe

            result = relaxed_flowpipe(setup.model, matrices, initial, mode, horizon=tau_end, time_step=tau_step)
            if result is None:  # not an arbitrary-switching group: the hybrid loop
                result = input_flowpipe(setup.model, matrices, initial, horizon=tau_end, time_step=tau_step,
                                        initial_mode=mode, max_jumps=jumps, options=options, progress=report)
        out.append((mode, box, result))
    if progress is not None:
        progress(1.0)
    return tuple(out)


def _requirement(parsed: Any, req: Any, setup: ReachSetup, runs: tuple[Any, ...], route: Any = None
                 ) -> RequirementReach:
    """The verdict of one requirement; with an input route, re-checked as ``verify`` re-checks it: from the
    input-free system itself (read again by the re-checker) with the inputs."""
    def verdict(status: str, reason: str, margin: float | None = None, again: float | None = None) -> RequirementReach:
        return RequirementReach(name=req.name, formula=req.formula, status=status, margin=margin,
                                recheck_margin=again, reason=reason)

    try:
        fragment = scaled_fragment(safety_fragment(parsed.formula.tree, setup.model.state_names, ("mode",)),
                                   setup.scale)
    except NotInFragment as exc:
        return verdict("not_in_fragment", str(exc))
    horizon = min(r.horizon for _, _, r in runs)
    if fragment.end > horizon:
        return verdict("inconclusive", f"the window ends at {fragment.end:g} s, after the flowpipe's horizon "
                                       f"{horizon:g} s: give a longer horizon")
    margins, checks = [], []
    for mode, box, result in runs:
        initial = {n: (lo, hi) for n, lo, hi in box}
        holds, margin, reason = decide(result, fragment, setup.model, initial)
        where = f"from mode {mode!r}: " if len(runs) > 1 else ""
        if not holds:
            met = (result.complete and not any(t.reason == "max_jumps" for t in result.terminations)
                   and reason.startswith("not decided on the segment"))
            return verdict("met" if met else "inconclusive", where + reason,
                           margin if math.isfinite(margin) else None)
        margins.append(margin)
        checks.append(_recheck(result, setup, route, initial, fragment, mode))
    margin = min(margins)
    failed = next((c for c in checks if not c.passed), None)
    if failed is not None:
        return verdict("not_rechecked", f"the producer decided it, the re-check FAILED: {failed.failure}", margin)
    again = min(float(c.margin) for c in checks if c.margin is not None) if any(
        c.margin is not None for c in checks) else None
    inputs = "" if route is None else " with the inputs"
    groups = sorted({" and ".join(map(repr, g)) for g in (dict(r.schedule).get("relaxed_group") for _, _, r in runs)
                     if g})
    relaxed = "".join(f" (the arbitrary-switching relaxation of {g}: ẋ ∈ conv{{A_i x + c_i}} + B U, any "
                      f"switches; its own re-check)" for g in groups)
    return verdict("proven", f"holds on every segment of {len(runs)} flowpipe(s){relaxed}, re-checked{inputs}",
                   margin, again)


def _recheck(result: ReachResult, setup: ReachSetup, route: Any, initial: Mapping[str, tuple[float, float]],
             fragment: Any, mode: str) -> Any:
    """The independent re-check of one start's flowpipe: the relaxation's own
    (:func:`analysis.reach.recheck_relaxed.recheck_relaxed`) for a relaxed flowpipe, else
    :func:`analysis.reach.recheck.recheck_flowpipe`; both read the saved JSON and the model again."""
    if route is not None and dict(result.schedule).get("relaxed_group"):
        from .recheck_relaxed import recheck_relaxed

        return recheck_relaxed(result.to_json(), route.system, initial, fragment, initial_mode=mode,
                               inputs=route.matrices)
    return recheck_flowpipe(result.to_json(), setup.model if route is None else route.system, initial, fragment,
                            initial_mode=mode, inputs=None if route is None else route.matrices)
