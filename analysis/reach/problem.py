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
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from .fragment import NotInFragment, safety_fragment
from .initial import ReachError
from .parameters import ReachSetup, Start, initial_modes, reach_setup
from .engine import reach
from .recheck import recheck_flowpipe
from .result import ReachResult
from .verdict import MAX_SEGMENTS, decide, default_max_jumps, scaled_fragment

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
    """

    problem: str
    setup: ReachSetup
    horizon: float
    time_step: float
    max_jumps: int
    runs: tuple[tuple[str, tuple[tuple[str, float, float], ...], ReachResult], ...]
    requirements: tuple[RequirementReach, ...]

    @property
    def complete(self) -> bool:
        """Every flowpipe is complete (no inconclusive end)."""
        return all(r.complete for _, _, r in self.runs)

    def to_json(self) -> str:
        """The flowpipes (:meth:`ReachResult.to_json`) and the verdicts, deterministic (no timings)."""
        s = self.setup
        data = {"format": FORMAT, "version": 1, "problem": self.problem, "horizon": self.horizon,
                "time_step": self.time_step, "max_jumps": self.max_jumps, "complete": self.complete,
                "state_names": list(s.model.state_names), "parameters_as_states": list(s.parameters),
                "time_scale": None if not s.scale_text else {"factor": s.scale_text, "max": float(s.scale),
                                                             "flowpipe_time": "tau = factor * t"},
                "starts": [{"mode": m, "box": [[n, lo, hi] for n, lo, hi in box], "flowpipe": json.loads(r.to_json())}
                           for m, box, r in self.runs],
                "requirements": [q.as_dict() for q in self.requirements]}
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
        ``0 < δ <= horizon`` [s]; default ``horizon / 1000``.
    max_jumps : int or None
        Default :func:`analysis.reach.verdict.default_max_jumps` of the horizon.
    progress : callable or None
        ``progress(share)`` with the share of the work done in ``[0, 1]`` (time reached over the horizon,
        summed over the start modes).

    Raises
    ------
    ReachError
        A bad option, or a problem that is not a continuous-time hybrid problem.
    analysis.reach.affine.AffineError, analysis.reach.parameters.ParameterRoute
        The model cannot be read (not symbolic, not affine, parameters that are not constant states).
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
    step = _checked("time_step", end / 1000.0 if time_step is None else time_step, lambda v: 0 < v <= end,
                    f"a finite step 0 < time_step <= horizon = {end:g} [s]", f"give e.g. {end / 1000.0:g}")
    jumps = default_max_jumps(end) if max_jumps is None else max_jumps
    if isinstance(jumps, bool) or not isinstance(jumps, int) or jumps < 0:
        raise ReachError("max_jumps", jumps, "a whole number >= 0", "give e.g. 100")
    fixed = sim.fixed_system
    setup = reach_setup(fixed if fixed is not None else sim.build, sim.initial, problem.parameters,
                        builder=fixed is None)
    probe = fixed if fixed is not None else sim.build({p.name: p.at(0.0) for p in problem.parameters})
    starts = initial_modes(setup, sim.initial_mode, bool(probe.automaton.initial_mode_given))
    runs = _flowpipes(setup, starts, end, step, jumps, progress)
    verdicts = tuple(_requirement(p, problem.requirements[i], setup, runs) for i, p in enumerate(problem.parsed))
    return ProblemReach(problem=problem.name, setup=setup, horizon=end, time_step=step, max_jumps=jumps,
                        runs=runs, requirements=verdicts)


def _flowpipes(setup: ReachSetup, starts: tuple[Start, ...], end: float, step: float, jumps: int,
               progress: Callable[[float], None] | None) -> tuple[Any, ...]:
    scale = setup.scale
    tau_end = _up(Fraction(end) * scale)
    tau_step = min(float(Fraction(step) * scale), tau_end)
    scaled = f"on the model's time scale (τ = {setup.scale_text or 1}·t, at most {float(scale):g}·t)"
    if not math.isfinite(tau_end):  # refused in the user's values, not the scaled ones
        raise ReachError("horizon", end, f"a horizon that stays finite {scaled}", "give a shorter horizon")
    if not tau_step > 0.0:
        raise ReachError("time_step", step, f"a step 0 < time_step <= horizon = {end:g} [s] that stays > 0 {scaled}",
                         f"give e.g. time_step = {end / 1000.0:g}")
    out = []
    for i, (mode, box) in enumerate(starts):
        report = None if progress is None else (
            lambda t, i=i: progress((i + min(t / tau_end, 1.0)) / len(starts)))
        result = reach(setup.model, {n: (lo, hi) for n, lo, hi in box}, horizon=tau_end, time_step=tau_step,
                       initial_mode=mode, max_jumps=jumps, max_segments=MAX_SEGMENTS, progress=report)
        out.append((mode, box, result))
    if progress is not None:
        progress(1.0)
    return tuple(out)


def _requirement(parsed: Any, req: Any, setup: ReachSetup, runs: tuple[Any, ...]) -> RequirementReach:
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
        checks.append(recheck_flowpipe(result.to_json(), setup.model, initial, fragment, initial_mode=mode))
    margin = min(margins)
    failed = next((c for c in checks if not c.passed), None)
    if failed is not None:
        return verdict("not_rechecked", f"the producer decided it, the re-check FAILED: {failed.failure}", margin)
    again = min(float(c.margin) for c in checks if c.margin is not None) if any(
        c.margin is not None for c in checks) else None
    return verdict("proven", f"holds on every segment of {len(runs)} flowpipe(s), re-checked", margin, again)
