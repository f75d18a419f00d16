"""The book of a falsification search: what one simulation gave (:class:`Outcome`), one simulated point
(:class:`Evaluation`) and the budget, cache and evaluations of a search (:class:`Search`).

Shared by :mod:`analysis.verify.falsification` (which re-exports every name) and
:mod:`analysis.verify.falsification_search`; it imports neither.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from hybrid.jsonable import float_from_json, to_jsonable

from analysis.verify.verification import VerificationProblem

__all__ = ["Outcome", "Evaluation", "BudgetExhausted", "Search", "unit_key"]


@dataclass(frozen=True, kw_only=True, slots=True)
class Outcome:
    """What one simulation gave: a status (:data:`STATUSES`) and every requirement's robustness and truth value.

    Attributes
    ----------
    status : str
    robustness : tuple of float
        Per requirement, on the trace as simulated (empty when no trace came back); on a run that
        ended early, the robustness of the prefix (a search heuristic, not a verdict).
    satisfied : tuple of bool or None
        Per requirement: its truth value, ``None`` when the run ended before deciding it.
    detail : str
        Why the run is not ``ok`` (the cause, the time, the mode).
    end : str
        How the run ended (``"end_time"``, ``"final:success"``, ``"zeno"``, ...); empty when unknown.
    end_time : float or None
        When it ended [s] (the trace's last sample).
    traceback : str
        The model's own traceback, for ``error``.
    gradient : tuple of tuple of float
        Per requirement, the gradient of its robustness in unit coordinates (shape ``(k,)``) from the model's
        sensitivities (an empty tuple for a requirement whose gradient could not be formed); empty when the run
        computed none (:meth:`Search.run_gradient`).
    gradient_method : str
        How ``gradient`` was obtained (``"sensitivities"``), and why a requirement has none; empty without one.
    """

    status: str
    robustness: tuple[float, ...] = ()
    satisfied: tuple[bool | None, ...] = ()
    detail: str = ""
    end: str = ""
    end_time: float | None = None
    traceback: str = ""
    gradient: tuple[tuple[float, ...], ...] = ()
    gradient_method: str = ""

    @property
    def evaluated(self) -> bool:
        """Whether the requirements were evaluated on a trace (complete or cut short)."""
        return bool(self.robustness)

    def decided(self, r: int) -> bool:
        """Whether requirement ``r`` was decided by this run."""
        return self.evaluated and self.satisfied[r] is not None


@dataclass(frozen=True, kw_only=True, slots=True)
class Evaluation:
    """One simulated point of a search.

    Attributes
    ----------
    index : int
        Order of simulation (0 is the first); the budget is ``index < budget``.
    phase : str
        ``"nominal"``, ``"start"``, ``"surrogate"``, ``"local"``, ``"gradient"``, ``"descent"``, ``"shrink"``,
        ``"monte-carlo"``, ``"dual-annealing"`` (:data:`PHASES`).
    unit : tuple of float
        Unit coordinates in ``[-1, 1]`` (:meth:`analysis.verify.verification.Parameter.at`).
    outcome : Outcome
    """

    index: int
    phase: str
    unit: tuple[float, ...]
    outcome: Outcome

    def violates(self, r: int) -> bool:
        """Whether requirement ``r`` is violated here, decided (boolean semantics; every continuation of a
        run that ended early violates it too)."""
        return self.outcome.evaluated and self.outcome.satisfied[r] is False

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (infinite robustness as ``"inf"``/``"-inf"``, read back by :meth:`from_dict`)."""
        o = self.outcome
        data = {"index": self.index, "phase": self.phase, "unit": list(self.unit), "status": o.status,
                "robustness": list(o.robustness), "satisfied": list(o.satisfied), "detail": o.detail,
                "end": o.end, "end_time": o.end_time, "traceback": o.traceback}
        if o.gradient or o.gradient_method:  # only a sensitivity run has them (older journals read unchanged)
            data["gradient"], data["gradient_method"] = [list(g) for g in o.gradient], o.gradient_method
        return to_jsonable(data, nonfinite="string")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Evaluation:
        """Inverse of :meth:`as_dict` (values as :func:`hybrid.jsonable.float_from_json` reads them)."""
        end_time = data.get("end_time")
        outcome = Outcome(status=str(data["status"]),
                          robustness=tuple(float_from_json(v, where="robustness") for v in data["robustness"]),
                          satisfied=tuple(None if v is None else bool(v) for v in data["satisfied"]),
                          detail=str(data["detail"]), end=str(data.get("end", "")),
                          end_time=None if end_time is None else float_from_json(end_time, where="end_time"),
                          traceback=str(data.get("traceback", "")),
                          gradient=tuple(tuple(float_from_json(v, where="gradient") for v in g)
                                         for g in data.get("gradient", ())),
                          gradient_method=str(data.get("gradient_method", "")))
        return cls(index=int(data["index"]), phase=str(data["phase"]),
                   unit=tuple(float(v) for v in data["unit"]), outcome=outcome)


def unit_key(unit: Iterable[float]) -> tuple[float, ...]:
    """The cache key of a unit point: floats, ``-0.0`` written ``0.0``."""
    return tuple(0.0 if u == 0 else float(u) for u in unit)


class BudgetExhausted(Exception):
    """The search's (or the phase's) budget of simulations is spent (:meth:`Search.run`)."""


@dataclass
class Search:
    """The book of one search: budget, cache, evaluations in order (mutable, owned by one search).

    ``evaluator(problem, unit, timeout_s) -> Outcome`` simulates a point (:func:`analysis.verify.falsification.evaluate`).
    """

    problem: VerificationProblem
    budget: int
    evaluator: Callable[[VerificationProblem, tuple[float, ...], float | None], Outcome]
    cache: dict[tuple[float, ...], Outcome] = field(default_factory=dict)
    on_evaluation: Callable[[Evaluation], None] | None = None
    timeout_s: float | None = None
    evaluations: list[Evaluation] = field(default_factory=list)
    seen: dict[tuple[float, ...], int] = field(default_factory=dict)
    differentiated: dict[tuple[float, ...], int] = field(default_factory=dict)

    @property
    def used(self) -> int:
        return len(self.evaluations)

    def run(self, unit: Sequence[float], phase: str, limit: int | None = None) -> Evaluation:
        """Evaluate ``unit`` (from the cache when known); :class:`BudgetExhausted` past ``limit`` simulations."""
        key = unit_key(unit)
        if key in self.seen:
            return self.evaluations[self.seen[key]]
        if self.used >= min(self.budget, self.budget if limit is None else limit):
            raise BudgetExhausted
        outcome = self.cache.get(key)
        if outcome is None:
            outcome = self.evaluator(self.problem, key, self.timeout_s)
        elif outcome.gradient or outcome.gradient_method:  # a resumed sensitivity run: this is a plain one
            outcome = replace(outcome, gradient=(), gradient_method="")
        return self._append(key, phase, outcome, self.seen)

    def run_gradient(self, unit: Sequence[float], phase: str,
                     evaluator: Callable[[VerificationProblem, tuple[float, ...], float | None], Outcome]
                     ) -> Evaluation:
        """Evaluate ``unit`` with ``evaluator``, a simulation with sensitivities (:attr:`Outcome.gradient`): one
        more simulation, counted, even when the point was simulated plainly before; a point this search already
        differentiated, or one a resumed journal holds with its gradient, is not simulated again.
        :class:`BudgetExhausted` past the budget."""
        key = unit_key(unit)
        if key in self.differentiated:
            return self.evaluations[self.differentiated[key]]
        if self.used >= self.budget:
            raise BudgetExhausted
        outcome = self.cache.get(key)
        if outcome is None or not outcome.gradient_method:
            outcome = evaluator(self.problem, key, self.timeout_s)
        evaluation = self._append(key, phase, outcome, self.differentiated)
        self.seen.setdefault(key, evaluation.index)
        return evaluation

    def _append(self, key: tuple[float, ...], phase: str, outcome: Outcome, index: dict) -> Evaluation:
        evaluation = Evaluation(index=self.used, phase=phase, unit=key, outcome=outcome)
        index[key] = evaluation.index
        self.evaluations.append(evaluation)
        if self.on_evaluation is not None:
            self.on_evaluation(evaluation)
        return evaluation

    def violated(self, r: int) -> list[Evaluation]:
        return [e for e in self.evaluations if e.violates(r)]

    def lowest(self, r: int) -> Evaluation | None:
        """The evaluation with the lowest robustness of requirement ``r`` (first on ties)."""
        best = None
        for e in self.evaluations:
            if e.outcome.status == "ok" and (best is None or e.outcome.robustness[r] < best.outcome.robustness[r]):
                best = e
        return best
