"""The results of :func:`hybrid.decide.decide` and :func:`hybrid.decide.exclusive_for_all`: claims, verdicts per
pair of transitions and per cycle, the Zeno summary and the decision; and the parameter space of a parametric
question.

:mod:`hybrid.decide` re-exports every name (import them from there).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from .findings import Finding, Witness, finding_number
from .errors import ModelDefinitionError
from .symbolic import Condition

__all__ = [
    "CLAIM_STATUSES",
    "Claim",
    "PairVerdict",
    "CycleVerdict",
    "ZenoSummary",
    "Decision",
    "ParameterSpace",
]


CLAIM_STATUSES = ("proven", "found", "sampled", "undecided", "skipped")
"""How a check's answer was obtained: a proof; a re-checked witness; a search; neither; not run."""


# ====================================================================== results
@dataclass(frozen=True, kw_only=True, slots=True)
class ParameterSpace:
    """Named parameters (:func:`hybrid.symbolic.param`) left free for a parametric question.

    Attributes
    ----------
    bounds : Mapping[str, (lo, hi)]
        The range of every free parameter (closed; ``inf`` allowed).
    assumptions : tuple of Condition
        Symbolic conditions over the parameters (e.g. ``d_minus < d_zero``), the model's validation rules.
    description : str
        The assumptions in words, for reports.
    """

    bounds: Mapping[str, tuple[float, float]]
    assumptions: tuple[Condition, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        bounds = {}
        for name, pair in dict(self.bounds).items():
            try:
                lo, hi = (float(pair[0]), float(pair[1]))
            except (TypeError, ValueError, IndexError):
                raise ModelDefinitionError(f"ParameterSpace.bounds[{name!r}] = {pair!r}; expected (lower, upper)") from None
            if not lo <= hi:
                raise ModelDefinitionError(f"ParameterSpace.bounds[{name!r}] = {pair!r}: expected lower <= upper")
            bounds[name] = (lo, hi)
        if not bounds:
            raise ModelDefinitionError("ParameterSpace: no free parameter; name at least one in bounds")
        for c in self.assumptions:
            if not isinstance(c, Condition):
                raise ModelDefinitionError(f"ParameterSpace.assumptions: {c!r} is not a symbolic condition")
        object.__setattr__(self, "bounds", MappingProxyType(bounds))
        object.__setattr__(self, "assumptions", tuple(self.assumptions))


@dataclass(frozen=True, kw_only=True, slots=True)
class Claim:
    """The answer to one check over the whole model.

    Attributes
    ----------
    check : str
        ``nondeterminism``, ``deadlock``, ``reset_outside_invariant``, ``reset_retriggers``, ``zeno``.
    status : str
        One of :data:`CLAIM_STATUSES`.
    method : str
        How: the solver and what re-checked it, or the sampling.
    assumptions : tuple of str
        What a ``proven`` answer assumes.
    detail : str
        Counts, modes left to sampling, undecided questions.
    """

    check: str
    status: str
    method: str
    assumptions: tuple[str, ...] = ()
    detail: str = ""

    def __post_init__(self) -> None:
        if self.status not in CLAIM_STATUSES:
            raise ValueError(f"Claim.status = {self.status!r}; expected one of {CLAIM_STATUSES}")
        object.__setattr__(self, "assumptions", tuple(self.assumptions))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {"check": self.check, "status": self.status, "method": self.method,
                "assumptions": list(self.assumptions), "detail": self.detail}


@dataclass(frozen=True, kw_only=True, slots=True)
class PairVerdict:
    """Whether two transitions of one mode can be enabled together.

    Attributes
    ----------
    mode, first, second : str
    same_priority : bool
    verdict : str
        ``"overlap"`` (witness re-checked), ``"exclusive"`` (proven) or ``"undecided"``.
    witness : Witness or None
    detail : str
    """

    mode: str
    first: str
    second: str
    same_priority: bool
    verdict: str
    witness: Witness | None = None
    detail: str = ""

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {"mode": self.mode, "first": self.first, "second": self.second,
                "same_priority": self.same_priority, "verdict": self.verdict,
                "witness": None if self.witness is None else self.witness.as_dict(), "detail": self.detail}


@dataclass(frozen=True, kw_only=True, slots=True)
class CycleVerdict:
    """The Zeno answer for one cycle of transitions.

    Attributes
    ----------
    modes, transitions : tuple of str
        The cycle, starting at its first transition's source.
    verdict : str
        ``"non_zeno"`` (a lap lasts at least ``dwell_s``, proven), ``"instantaneous"``
        (its jumps can follow one another at one instant on an open set of states: witness),
        ``"zeno_point"`` (only on a set without interior: witness), ``"infeasible"`` (no execution
        takes its transitions in this order: proven) or ``"undecided"``.
    dwell_s : float
        Proven lower bound on one lap [s] (``0`` unless ``non_zeno``; ``inf`` when infeasible).
    binding : str
        Where the bound comes from.
    witness : Witness or None
    """

    modes: tuple[str, ...]
    transitions: tuple[str, ...]
    verdict: str
    dwell_s: float
    binding: str = ""
    witness: Witness | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {"modes": list(self.modes), "transitions": list(self.transitions), "verdict": self.verdict,
                "dwell_s": finding_number(self.dwell_s), "binding": self.binding,
                "witness": None if self.witness is None else self.witness.as_dict()}


@dataclass(frozen=True, kw_only=True, slots=True)
class ZenoSummary:
    """The cycles of the mode graph grouped by verdict.

    Attributes
    ----------
    cycles : int
        Cycles of transitions examined.
    counts : Mapping[str, int]
        Cycles per verdict.
    min_dwell_s : float or None
        Smallest proven lap duration among the ``non_zeno`` cycles.
    binding : str
        Where that smallest bound binds.
    binding_cycle : tuple of str
        The transitions of that cycle.
    capped : bool
        Whether the enumeration stopped at ``max_cycles``.
    rates : Mapping[str, Mapping[str, float]]
        Rate bound of every coordinate used, per mode (``inf``: unbounded).
    verdicts : tuple of CycleVerdict
    """

    cycles: int
    counts: Mapping[str, int]
    min_dwell_s: float | None
    binding: str
    binding_cycle: tuple[str, ...]
    capped: bool
    rates: Mapping[str, Mapping[str, float]]
    verdicts: tuple[CycleVerdict, ...]

    def as_dict(self, *, verdicts: bool = True) -> dict[str, Any]:
        """JSON-ready copy (``verdicts=False`` leaves out the per-cycle list)."""
        out: dict[str, Any] = {
            "cycles": self.cycles, "counts": dict(self.counts),
            "min_dwell_s": None if self.min_dwell_s is None else finding_number(self.min_dwell_s),
            "binding": self.binding, "binding_cycle": list(self.binding_cycle), "capped": self.capped,
            "rates": {q: {k: finding_number(r) for k, r in rs.items()} for q, rs in self.rates.items()},
        }
        if verdicts:
            out["verdicts"] = [v.as_dict() for v in self.verdicts]
        return out


@dataclass(frozen=True, kw_only=True, slots=True)
class Decision:
    """Result of :func:`decide`.

    Attributes
    ----------
    findings : tuple of Finding
        Each with a witness re-checked on the model's own functions.
    claims : Mapping[str, Claim]
        One per check.
    pairs : tuple of PairVerdict
        Every pair of transitions sharing a source mode (both symbolic).
    zeno : ZenoSummary or None
    memory_hulls : Mapping[str, Mapping[str, tuple[float, float]] or None]
        The memory abstraction per mode (``None``: no entering transition reaches it).
    sampled_modes : Mapping[str, str]
        Modes (or checks in them) the solver could not take, with why.
    queries : int
        Solver calls.
    solver_s : float
        Time spent in the solver [s].
    solver : str
        Solver name and version.
    """

    findings: tuple[Finding, ...]
    claims: Mapping[str, Claim]
    pairs: tuple[PairVerdict, ...]
    zeno: ZenoSummary | None
    memory_hulls: Mapping[str, Mapping[str, tuple[float, float]] | None]
    sampled_modes: Mapping[str, str]
    queries: int
    solver_s: float
    solver: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "claims": {k: c.as_dict() for k, c in self.claims.items()},
            "pairs": [p.as_dict() for p in self.pairs],
            "zeno": None if self.zeno is None else self.zeno.as_dict(),
            "memory_hulls": {q: None if h is None else {k: [finding_number(a), finding_number(b)] for k, (a, b) in h.items()}
                             for q, h in self.memory_hulls.items()},
            "sampled_modes": dict(self.sampled_modes),
            "queries": self.queries,
            "solver": self.solver,
        }
