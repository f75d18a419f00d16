"""Verdicts of a verification problem: proven, falsified or not falsified, per requirement and overall.

:func:`verify` tries each requirement's proof (a certificate re-checked
outside the tool that produced it gives ``proven``), then searches the box
(:func:`analysis.verify.falsification.falsify`) for the others and gives

``falsified``
    a point where the requirement is violated (boolean semantics: robustness
    < 0, or 0 on a strict comparison), with its shrunk counterexample;
``not_falsified``
    none found: how many simulations, the lowest robustness seen and where,
    and how the box was covered (per parameter, the share of ten equal bins
    that a simulated point fell in);
``proven``
    a proof holds over the whole box (the search still runs as a cross-check
    and a violation found would be reported as a contradiction, never hidden);
``incomplete``
    no violation found, but at least one simulation ended before it could
    decide the requirement (Zeno, a deadlock, a jump limit, a stop not
    declared final, a divergence, an error of the model's code): the search
    is not judged as if it were complete (``undecided`` says how many runs
    and why).

The overall verdict (:data:`OVERALL`) is ``falsified`` when one requirement
is; else ``error`` when the model's own code raised during a simulation (a
defect of the model, not a numerical blow-up); else ``diverged`` when a
simulation diverged numerically; else ``incomplete`` when a requirement is;
else ``proven`` when every requirement is proven; else ``not_falsified``.
Only ``proven`` and ``not_falsified`` are passes (:data:`PASSES`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid.jsonable import to_jsonable

from analysis.verify.falsification import DEFAULT_TIMEOUT_S, Evaluation, FalsificationError, Outcome, Runner, Search, falsify
from analysis.verify.verification import Proof, VerificationProblem

__all__ = ["VERDICTS", "OVERALL", "PASSES", "Counterexample", "Coverage", "RequirementVerdict",
           "VerificationResult", "verify", "coverage_of", "decided_by"]

VERDICTS = ("proven", "falsified", "not_falsified", "incomplete")
OVERALL = ("proven", "not_falsified", "falsified", "diverged", "incomplete", "error")
PASSES = ("proven", "not_falsified")
"""The overall verdicts that pass; every other one fails a test (:func:`analysis.verify.testing.assert_verified`)."""
COVERAGE_BINS = 10


@dataclass(frozen=True, kw_only=True, slots=True)
class Counterexample:
    """A point violating one requirement.

    Attributes
    ----------
    unit : tuple of float
        Unit coordinates (0 nominal, ±1 the box's ends).
    point : Mapping[str, float]
        Parameter values.
    robustness : float
    evaluation : int
        Index of the simulation that found it.
    how : str
        How it was found and shrunk.
    time : float
        Where the robustness is decided (:meth:`analysis.stl.Formula.explain`): its lowest instant [s].
    first_time : float or None
        The first instant the requirement is seen violated (:meth:`analysis.stl.Formula.first_violation`) [s].
    atom : str
        The atomic comparison that decides it there.
    atom_value : float
        That atom's robustness at that instant.
    window : tuple of float or None
        ``(a, b)`` [s] when ``time`` is the best instant of an ``eventually`` (:attr:`analysis.stl.Explanation.window`):
        the requirement was never reached within ``[a, b]``, and came closest at ``time``; ``None``: ``time`` is
        where it is violated most.
    """

    unit: tuple[float, ...]
    point: Mapping[str, float]
    robustness: float
    evaluation: int
    how: str
    time: float
    atom: str
    atom_value: float
    first_time: float | None = None
    window: tuple[float, float] | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class Coverage:
    """How a search covered the box: per parameter, the range simulated and the bins hit."""

    parameters: tuple[str, ...]
    lows: tuple[float, ...]
    highs: tuple[float, ...]
    bins_hit: tuple[float, ...]
    points: int

    def as_dict(self) -> dict[str, Any]:
        return {"points": self.points, "bins": COVERAGE_BINS, "parameters": [
            {"name": n, "low_seen": lo, "high_seen": hi, "bins_hit": b}
            for n, lo, hi, b in zip(self.parameters, self.lows, self.highs, self.bins_hit)]}


@dataclass(frozen=True, kw_only=True, slots=True)
class RequirementVerdict:
    """The verdict on one requirement."""

    name: str
    formula: str
    description: str
    verdict: str
    robustness: float | None
    nominal_robustness: float | None
    simulations: int
    lowest_at: Mapping[str, float] | None
    counterexample: Counterexample | None
    proof: Proof | None
    history: tuple[float, ...]
    undecided: int = 0
    undecided_reasons: tuple[str, ...] = ()
    searched: int | None = None
    """Simulations the search ran in all (complete or not); ``None``: ``simulations``."""

    @property
    def decided_by(self) -> str:
        """Which method decided the verdict, in words (:func:`decided_by`)."""
        return decided_by(self)

    def as_dict(self) -> dict[str, Any]:
        return to_jsonable({
            "name": self.name, "formula": self.formula, "description": self.description, "verdict": self.verdict,
            "decided_by": self.decided_by,
            "robustness": self.robustness, "nominal_robustness": self.nominal_robustness,
            "simulations": self.simulations, "lowest_at": self.lowest_at,
            "counterexample": None if self.counterexample is None else self.counterexample,
            "proof": self.proof, "undecided": self.undecided, "undecided_reasons": list(self.undecided_reasons),
        }, nonfinite="string")


@dataclass(frozen=True, kw_only=True, slots=True)
class VerificationResult:
    """Everything :func:`verify` found; ``as_dict`` is the ``--json`` object.

    Robustness can be infinite (a label atom, ``true``): JSON writes it as the
    strings ``"inf"`` / ``"-inf"`` (:mod:`hybrid.jsonable`'s policy for values read back).
    """

    problem: str
    source: str
    method: str
    seed: int
    budget: int
    verdict: str
    requirements: tuple[RequirementVerdict, ...]
    simulations: int
    invalid: int
    invalid_reasons: tuple[str, ...]
    diverged: tuple[Mapping[str, Any], ...]
    coverage: Coverage
    evaluations: tuple[Evaluation, ...]
    ended_early: tuple[Mapping[str, Any], ...] = ()
    errors: tuple[Mapping[str, Any], ...] = ()
    gradients: str = ""
    """How ``whitebox`` differentiated the robustness (:func:`analysis.verify.falsification_gradient.gradient_source`);
    empty for the other methods."""

    @property
    def passed(self) -> bool:
        """Whether the overall verdict is a pass (:data:`PASSES`)."""
        return self.verdict in PASSES

    def requirement(self, name: str) -> RequirementVerdict:
        for r in self.requirements:
            if r.name == name:
                return r
        raise KeyError(f"no requirement {name!r}; known: {[r.name for r in self.requirements]}")

    def as_dict(self, *, evaluations: bool = False) -> dict[str, Any]:
        out = {
            "problem": self.problem, "source": self.source, "verdict": self.verdict, "method": self.method,
            "seed": self.seed, "budget": self.budget, "simulations": self.simulations,
            "invalid": self.invalid, "invalid_reasons": list(self.invalid_reasons),
            "diverged": [dict(d) for d in self.diverged], "coverage": self.coverage.as_dict(),
            "ended_early": [dict(d) for d in self.ended_early], "errors": [dict(d) for d in self.errors],
            "requirements": [r.as_dict() for r in self.requirements],
        }
        if self.gradients:
            out["gradients"] = self.gradients
        if evaluations:
            out["evaluations"] = [e.as_dict() for e in self.evaluations]
        return to_jsonable(out, nonfinite="string")


def _method_name(proof: Proof) -> str:
    """The proof's method in a few words: ``reachability``, or its method up to the first comma."""
    method = proof.method.strip()
    return "reachability" if method.startswith("reachability") else (method.split(",")[0] or "proof")


def decided_by(verdict: RequirementVerdict) -> str:
    """Which method decided a requirement's verdict, in words.

    ``reachability (re-checked)`` (a proof's method, re-checked) for ``proven``;
    ``falsification (N simulations)`` otherwise (``; M ended early`` when incomplete), followed for a
    proof that was attempted and did not prove it by what it gave: ``reachability: inconclusive, margin
    m`` (the smallest slack it found, which proves nothing), ``...: not decided`` (no margin), or
    ``...: holds, not re-checked``.
    """
    proof = verdict.proof
    if verdict.verdict == "proven" and proof is not None:
        return f"{_method_name(proof)} (re-checked)"
    text = f"falsification ({verdict.simulations if verdict.searched is None else verdict.searched} simulations"
    text += f"; {verdict.undecided} ended early)" if verdict.verdict == "incomplete" and verdict.undecided else ")"
    if proof is None:
        return text
    if proof.proven:  # the search found a violation the proof excludes: both are shown, never one hidden
        return f"{text}; {_method_name(proof)}: proven (re-checked), contradicted by the search"
    if proof.holds:
        return f"{text}; {_method_name(proof)}: holds, not re-checked"
    if proof.margin is not None:
        return f"{text}; {_method_name(proof)}: inconclusive, margin {proof.margin:.4g}"
    return f"{text}; {_method_name(proof)}: not decided"


def coverage_of(problem: VerificationProblem, evaluations: Sequence[Evaluation]) -> Coverage:
    """Per parameter: the lowest and highest value simulated and the share of :data:`COVERAGE_BINS` bins hit."""
    simulated = [e for e in evaluations if e.outcome.status != "invalid"]
    lows, highs, hits = [], [], []
    for i, p in enumerate(problem.parameters):
        values = np.array([p.at(e.unit[i]) for e in simulated]) if simulated else np.empty(0)
        lows.append(float(values.min()) if values.size else float("nan"))
        highs.append(float(values.max()) if values.size else float("nan"))
        if p.high == p.low or not values.size:
            hits.append(1.0 if values.size else 0.0)
            continue
        bins = np.clip(((values - p.low) / (p.high - p.low) * COVERAGE_BINS).astype(int), 0, COVERAGE_BINS - 1)
        hits.append(len(set(bins.tolist())) / COVERAGE_BINS)
    return Coverage(parameters=tuple(p.name for p in problem.parameters), lows=tuple(lows), highs=tuple(highs),
                    bins_hit=tuple(hits), points=len(simulated))


def _running_min(evaluations: Sequence[Evaluation], r: int) -> tuple[float, ...]:
    best = float("inf")
    out = []
    for e in evaluations:
        if e.outcome.status == "ok":
            best = min(best, e.outcome.robustness[r])
        out.append(best)
    return tuple(out)


def _counterexample(problem: VerificationProblem, search: Search, r: int, unit: tuple[float, ...],
                    how: str) -> Counterexample:
    e = search.evaluations[search.seen[unit]]
    trace = problem.trace(problem.point(unit))
    formula = problem.parsed[r].formula
    why = formula.explain(trace)
    return Counterexample(unit=unit, point=problem.point(unit), robustness=e.outcome.robustness[r],
                          evaluation=e.index, how=how, time=float(why.time), atom=str(why.atom),
                          atom_value=float(why.value), first_time=formula.first_violation(trace), window=why.window)


def _proofs(problem: VerificationProblem) -> dict[str, Proof]:
    return {name: make() for name, make in problem.proofs.items()}


def _verdict(problem: VerificationProblem, search: Search, r: int, falsified: Mapping[int, Any],
             proof: Proof | None) -> RequirementVerdict:
    req = problem.requirements[r]
    ok = [e for e in search.evaluations if e.outcome.status == "ok"]
    lowest = search.lowest(r)
    nominal = search.evaluations[0] if search.evaluations and search.evaluations[0].phase == "nominal" else None
    counterexample = _counterexample(problem, search, r, *falsified[r]) if r in falsified else None
    undecided = [e for e in search.evaluations if e.outcome.status not in ("ok", "invalid") and not e.violates(r)
                 and not e.outcome.decided(r)]
    if counterexample is not None:
        verdict = "falsified"
    elif proof is not None and proof.proven:
        verdict = "proven"
    elif undecided:
        verdict = "incomplete"
    else:
        verdict = "not_falsified"
    return RequirementVerdict(
        name=req.name, formula=req.formula, description=req.description, verdict=verdict,
        robustness=None if lowest is None else lowest.outcome.robustness[r],
        nominal_robustness=None if nominal is None or nominal.outcome.status != "ok"
        else nominal.outcome.robustness[r],
        simulations=len(ok), lowest_at=None if lowest is None else problem.point(lowest.unit),
        counterexample=counterexample, proof=proof, history=_running_min(search.evaluations, r),
        undecided=len(undecided),
        searched=sum(e.outcome.status != "invalid" for e in search.evaluations),
        undecided_reasons=tuple(dict.fromkeys(f"{e.outcome.status}: {e.outcome.detail}" for e in undecided))[:5],
    )


def _overall(verdicts: Sequence[RequirementVerdict], evaluations: Sequence[Evaluation]) -> str:
    statuses = {e.outcome.status for e in evaluations}
    if any(v.verdict == "falsified" for v in verdicts):
        return "falsified"
    if "error" in statuses:
        return "error"
    if "diverged" in statuses:
        return "diverged"
    if any(v.verdict == "incomplete" for v in verdicts):
        return "incomplete"
    if all(v.verdict == "proven" for v in verdicts):
        return "proven"
    return "not_falsified"


def _ends(problem: VerificationProblem, evaluations: Sequence[Evaluation], statuses: Sequence[str],
          limit: int = 20) -> tuple[dict[str, Any], ...]:
    """The first ``limit`` evaluations with one of ``statuses``: where, how and when they ended."""
    out = []
    for e in evaluations:
        if e.outcome.status in statuses:
            out.append({"point": problem.point(e.unit), "status": e.outcome.status, "end": e.outcome.end,
                        "end_time": e.outcome.end_time, "detail": e.outcome.detail, "evaluation": e.index,
                        **({"traceback": e.outcome.traceback} if e.outcome.traceback else {})})
        if len(out) >= limit:
            break
    return tuple(out)


def verify(
    problem: VerificationProblem,
    *,
    budget: int,
    seed: int = 0,
    method: str = "guided",
    cache: Mapping[tuple[float, ...], Outcome] | None = None,
    on_evaluation: Callable[[Evaluation], None] | None = None,
    runner: Runner | None = None,
    timeout_s: float | None = DEFAULT_TIMEOUT_S,
) -> VerificationResult:
    """Prove what can be proven, falsify what can be falsified, within ``budget`` simulations.

    Parameters are those of :func:`analysis.verify.falsification.falsify`.
    """
    if isinstance(budget, int) and not isinstance(budget, bool) and budget < problem.min_budget:
        raise FalsificationError("budget", budget, f"at least {problem.min_budget} simulations for problem "
                                 f"{problem.name!r} (one per coordinate of its input signals' control points)",
                                 f"give a budget of at least {problem.min_budget}, or fewer control points")
    proofs = _proofs(problem)
    search, falsified = falsify(problem, budget=budget, seed=seed, method=method, cache=cache,
                                on_evaluation=on_evaluation, runner=runner, timeout_s=timeout_s)
    verdicts = tuple(_verdict(problem, search, r, falsified, proofs.get(req.name))
                     for r, req in enumerate(problem.requirements))
    invalid = [e for e in search.evaluations if e.outcome.status == "invalid"]
    diverged = tuple({"point": problem.point(e.unit), "status": e.outcome.status, "detail": e.outcome.detail,
                      "evaluation": e.index}
                     for e in search.evaluations if e.outcome.status == "diverged")
    return VerificationResult(
        problem=problem.name, source=problem.source, method=method, seed=seed, budget=budget,
        verdict=_overall(verdicts, search.evaluations), requirements=verdicts,
        ended_early=_ends(problem, search.evaluations, ("incomplete", "zeno", "timeout")),
        errors=_ends(problem, search.evaluations, ("error",), limit=5),
        simulations=search.used, invalid=len(invalid),
        invalid_reasons=tuple(dict.fromkeys(e.outcome.detail for e in invalid))[:5],
        diverged=diverged, coverage=coverage_of(problem, search.evaluations),
        evaluations=tuple(search.evaluations), gradients=_gradients(problem, method),
    )


def _gradients(problem: VerificationProblem, method: str) -> str:
    if method != "whitebox":
        return ""
    from analysis.verify.falsification_gradient import gradient_source

    return gradient_source(problem)
