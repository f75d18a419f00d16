"""Structural questions decided by an SMT solver on symbolic models, each answer proven or witnessed.

:func:`decide` answers, for the modes whose guards, invariants, resets, jump
maps (and, for the deadlock question, flows) are symbolic
(:mod:`hybrid.symbolic`), the questions that :func:`hybrid.check` otherwise
answers by sampling:

* **overlaps** — for every pair of transitions leaving one mode, whether both
  can be enabled at one state of the box inside the mode's invariant
  (``nondeterminism`` for equal priorities, ``priority_overlap`` otherwise);
* **deadlock** — a point of the invariant's boundary (``inv = 0``) where the
  flow leaves it (``d/dt inv < 0``, the exact Lie derivative) and no outgoing
  transition is enabled; a bare automaton (no flow) counts every boundary point;
* **reset_outside_invariant** — a jump from an enabled state that lands more
  than ``tol`` outside the target's invariant;
* **instantaneous cycles** (``reset_retriggers``, ``zeno_point``) — a cycle
  of level-triggered jumps that can follow one another at one instant, with
  the executors' priorities (:mod:`hybrid.instant`) and back to its first
  transition; robust (an open set of states does it: an error) or only on a
  set without interior (a Zeno point: info);
* **Zeno, per cycle of the mode graph** — a lower bound on the duration of one
  lap of the cycle, from the guards' separation and the rate bounds of the
  coordinates, or a witness of instantaneous cycling.

What "proven" assumes
---------------------
**Memory.**  Memory variables range over what the transitions entering a mode
can write, not over their initial values.  For every mode ``q`` an interval
hull ``H(q)`` of each memory variable is computed by a fixpoint over the
transitions (``H(init)`` holds the initial values; a transition into ``q``
adds the interval enclosure of its reset over its source's box and ``H(src)``,
and carries the variables it does not write; a variable still growing after
:data:`HULL_ROUNDS` rounds is widened to the whole line).  A query in ``q``
then states the memory *exactly* as written by one entering transition ``t``:
``m = r_t(x', m')`` for some pre-jump state ``x'`` in the source's box with
``t`` enabled there and ``m'`` in ``H(src)``, or the initial memory in the
initial mode.  This over-approximates the reachable memory, so an *exclusive*
answer is a proof; a witness is confirmed by evaluating the model's functions
at it, its memory's provenance included.
**States.** Only the declared box is considered; the question is over every
point of it (reachable or not).
**Crossing-triggered transitions** are enabled on the side their crossing ends
on (``g >= 0`` rising, ``g <= 0`` falling), as in :mod:`hybrid.check`, and never
fire after the first jump of an instant (:mod:`hybrid.instant`).
**Rates.**  The dwell bounds use ``|dx_j/dt| <= R_j`` in each mode: the rates
declared by the caller, else the interval enclosure of a symbolic flow over the
mode's box and memory hull; a coordinate without either is unbounded.
**Transcendental terms** are enclosed by intervals: unsat stays a proof; a
witness that does not re-check makes the answer "undecided".

Every solver call has a timeout; "unknown" is reported as undecided within that
many seconds, never as clean.
"""

from __future__ import annotations

import itertools
import math
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import networkx as nx

from .findings import KIND_SEVERITY, Finding, Oracle, Witness, checked_boxes, finding_number, format_g
from .errors import ExecutionError, ModelDefinitionError
from .graph import mode_graph
from .instant import MAX_JUMPS_PER_INSTANT, settle_instant
from .model import Conjunction, HybridAutomaton, Transition
from .region import Box
from .smt import Translation, all_of, any_of, check_sat, compare, context, fresh_context, rational, solver_version, to_float
from .symbolic import (
    Condition,
    Coordinate,
    Expr,
    SymbolicError,
    SymbolicReset,
    SymbolicVector,
    diff,
    enclose,
    free_symbols,
    level_form,
    minimum,
    render,
    substitute,
)
from .system import HybridSystem

__all__ = [
    "CLAIM_STATUSES",
    "DEFAULT_TIMEOUT_S",
    "HULL_ROUNDS",
    "Claim",
    "PairVerdict",
    "CycleVerdict",
    "ZenoSummary",
    "Decision",
    "decide",
    "ParameterSpace",
    "exclusive_for_all",
    "validate_options",
    "MIN_TIMEOUT_S",
]

CLAIM_STATUSES = ("proven", "found", "sampled", "undecided", "skipped")
"""How a check's answer was obtained: a proof; a re-checked witness; a search; neither; not run."""
DEFAULT_TIMEOUT_S = 5.0
"""Timeout of one solver call [s]."""
HULL_ROUNDS = 12
"""Fixpoint rounds of the memory hulls before a still-growing variable is widened to the whole line."""
RECHECK_TOL = 1e-9
"""Relative tolerance of a witness re-check (a solver's rational rounded to floats)."""
DWELL_REL = 1e-9
"""Relative safety margin taken off a minimised dwell before it is verified as a lower bound."""
BISECTIONS = 12
"""Bisection steps of a dwell bound when the optimiser's value cannot be verified."""
RETRIGGER_PROBE = 1e-3
"""Half-width (fraction of each coordinate's width) of the neighbourhood of a re-triggering state examined
to tell a modelling defect (every neighbour re-triggers) from a Zeno point (one does not), as :mod:`hybrid.check`."""


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


# ====================================================================== the symbolic view of a model
class _View:
    """The model's functions as expressions over its coordinates (``None`` where a function is not symbolic)."""

    def __init__(self, model: HybridSystem | HybridAutomaton) -> None:
        self.oracle = Oracle(model)
        self.system = self.oracle.system
        self.automaton: HybridAutomaton = self.oracle.automaton
        self.coords = self.oracle.coords
        a = self.automaton
        self.memory_names = tuple(mv.name for mv in a.memory)
        self.signals: dict[str, Expr] | None = {}
        if self.system is not None and self.system.output is not None:
            out = self.system.output
            if isinstance(out, SymbolicVector) and len(out) == len(a.variables):
                self.signals = dict(zip(a.variables, out.components))
            else:
                self.signals = None
        self._cache: dict[tuple[str, str], Any] = {}

    def _in_coords(self, e: Expr) -> Expr:
        assert self.signals is not None
        return substitute(e, coordinates=self.signals) if self.signals else e

    def condition(self, fn: Any) -> Expr | None:
        """A guard or invariant over the coordinates, or ``None`` when it is not symbolic."""
        if isinstance(fn, Conjunction):
            terms = [self.condition(t) for t in fn.terms]
            return None if any(t is None for t in terms) else minimum(*terms)  # type: ignore[arg-type]
        if isinstance(fn, Condition):
            fn = level_form(fn)
        if not isinstance(fn, Expr) or self.signals is None:
            return None
        return self._in_coords(fn)

    def guard(self, t: Transition) -> Expr | None:
        key = ("guard", t.name)
        if key not in self._cache:
            self._cache[key] = self.condition(t.guard)
        return self._cache[key]

    def invariant(self, q: str) -> Expr | None | bool:
        """The invariant over the coordinates; ``True`` for "always"; ``None`` when not symbolic."""
        key = ("inv", q)
        if key not in self._cache:
            inv = self.automaton.mode(q).invariant
            self._cache[key] = True if inv is None else self.condition(inv)
        return self._cache[key]

    def reset(self, t: Transition) -> dict[str, Expr] | None:
        """New values of the written memory over (coordinates, pre-jump memory); ``{}`` without a reset."""
        if t.reset is None:
            return {}
        if not isinstance(t.reset, SymbolicReset) or self.signals is None:
            return None
        return {k: self._in_coords(e) for k, e in t.reset.assignments.items()}

    def jump(self, t: Transition) -> tuple[Expr, ...] | None:
        """Post-jump coordinates; the identity when the transition has no jump map."""
        identity = tuple(Coordinate(n, i) for i, n in enumerate(self.coords))
        if self.system is None:
            return identity
        r = self.system.jumps.get(t.name)
        if r is None:
            return identity
        if isinstance(r, SymbolicVector) and r.kind == "jump" and len(r) == len(self.coords):
            return r.components
        return None

    def flow(self, q: str) -> tuple[Expr, ...] | None:
        if self.system is None:
            return None
        f = self.system.flows[q]
        if isinstance(f, SymbolicVector) and f.kind == "flow" and len(f) == len(self.coords):
            if any(free_symbols(c)["time"] for c in f.components):
                return None
            return f.components
        return None


# ====================================================================== z3 frames
class _Frame:
    """One state point of a query: z3 reals for the coordinates and the memory."""

    def __init__(self, tag: str, coords: Sequence[str], memory_names: Sequence[str]) -> None:
        import z3

        self.tag = tag
        self.x = {n: z3.Real(f"{tag}.{n}", context()) for n in coords}
        self.m = {n: z3.Real(f"{tag}.m.{n}", context()) for n in memory_names}


class _Decider:
    def __init__(self, view: _View, boxes: Mapping[str, Box], *, rates: Mapping[str, float] | None,
                 timeout_s: float, tol: float, max_cycles: int, parameters: ParameterSpace | None = None) -> None:
        self.v = view
        self.a = view.automaton
        self.boxes = boxes
        self.declared_rates = dict(rates or {})
        self.timeout_s = timeout_s
        self.tol = tol
        self.max_cycles = max_cycles
        self.queries = 0
        self.solver_s = 0.0
        self.unknown: list[str] = []
        self.count = itertools.count()
        self._states: dict[tuple[Any, ...], Any] = {}
        self.param_vars: dict[str, Any] = {}
        self.param_bounds: dict[str, tuple[float, float]] = {}
        self.param_constraints: list[Any] = []
        if parameters is not None:
            self._free(parameters)
        self.hulls = self._memory_hulls()

    def _free(self, parameters: ParameterSpace) -> None:
        """Parameters as solver variables, within their bounds and under the assumptions."""
        import z3

        self.param_vars = {n: z3.Real(f"param.{n}", context()) for n in parameters.bounds}
        self.param_bounds = dict(parameters.bounds)
        for n, (lo, hi) in parameters.bounds.items():
            if math.isfinite(lo):
                self.param_constraints.append(self.param_vars[n] >= rational(lo))
            if math.isfinite(hi):
                self.param_constraints.append(self.param_vars[n] <= rational(hi))
        tr = Translation(coordinates={}, memory={}, params=self.param_vars, param_bounds=self.param_bounds,
                         prefix="param.aux")
        for c in parameters.assumptions:
            self.param_constraints.append(tr.term(c))
        self.param_constraints += tr.side

    # ------------------------------------------------------------------ solver
    def solve(self, constraints: list[Any], what: str) -> tuple[str, Any]:
        answer = check_sat([*constraints, *self.param_constraints], self.timeout_s)
        self.solver_s += answer.seconds
        self.queries += 1
        if answer.status == "unknown":
            self.unknown.append(f"{what}: undecided within {self.timeout_s:g} s ({answer.reason})")
        return answer.status, answer.model

    def minimise(self, constraints: list[Any], objective: Any, what: str) -> float | None:
        """The optimiser's minimum of ``objective`` (a candidate, verified by the caller), or ``None``."""
        import z3

        o = z3.Optimize(ctx=context())
        o.set("timeout", max(1, int(round(self.timeout_s * 1000))))
        o.add(*constraints)
        h = o.minimize(objective)
        start = _time.perf_counter()
        r = o.check()
        self.solver_s += _time.perf_counter() - start
        self.queries += 1
        if r != z3.sat:
            return None
        value = o.lower(h)
        try:
            return to_float(value)
        except Exception:  # noqa: BLE001 - an infinite or symbolic optimum: no candidate
            return None

    # ------------------------------------------------------------------ memory abstraction
    def _box_bounds(self, q: str) -> dict[str, tuple[float, float]]:
        b = self.boxes[q]
        out = {n: (float(lo), float(hi)) for n, (lo, hi) in b.bounds.items()}
        for n, values in b.choices.items():
            out[n] = (float(min(values)), float(max(values)))
        return out

    def _memory_hulls(self) -> dict[str, dict[str, tuple[float, float]] | None]:
        a = self.a
        hulls: dict[str, dict[str, tuple[float, float]] | None] = {q: None for q in a.mode_names}
        hulls[a.initial_mode] = {k: (c, c) for k, c in a.initial_memory().items()}
        growth: dict[tuple[str, str], int] = {}
        changed = True
        while changed:  # terminates: a (mode, variable) grows at most HULL_ROUNDS times before it is widened
            changed = False
            for t in a.transitions:
                src = hulls[t.source]
                if src is None or t.source not in self.boxes:
                    continue
                written = self.v.reset(t)
                bounds = self._box_bounds(t.source)
                new = {}
                for k in self.v.memory_names:
                    if k in t.writes:
                        e = None if written is None else written.get(k)
                        new[k] = ((-math.inf, math.inf) if e is None else
                                  enclose(e, bounds, src, param_bounds=self.param_bounds))
                    else:
                        new[k] = src[k]
                old = hulls[t.target]
                if old is None:
                    hulls[t.target] = new
                    changed = True
                    continue
                joined = {k: (min(old[k][0], new[k][0]), max(old[k][1], new[k][1])) for k in old}
                if joined != old:
                    for k in old:
                        if joined[k] != old[k]:
                            n = growth[(t.target, k)] = growth.get((t.target, k), 0) + 1
                            if n > HULL_ROUNDS:
                                joined[k] = (-math.inf, math.inf)
                    hulls[t.target] = joined
                    changed = True
        return hulls

    # ------------------------------------------------------------------ constraints
    def frame(self, hint: str) -> _Frame:
        return _Frame(f"{hint}#{next(self.count)}", self.v.coords, self.v.memory_names)

    def translation(self, f: _Frame, q: str) -> Translation:
        return Translation(coordinates=f.x, memory=f.m, params=self.param_vars, bounds=self._box_bounds(q),
                           memory_bounds=self.hulls[q] or {}, param_bounds=self.param_bounds, prefix=f"{f.tag}.aux")

    def box(self, f: _Frame, q: str) -> list[Any]:
        import z3

        b = self.boxes[q]
        out = []
        for n, (lo, hi) in b.bounds.items():
            out += [compare(">=", f.x[n], rational(float(lo))), compare("<=", f.x[n], rational(float(hi)))]
        for n, values in b.choices.items():
            out.append(any_of([compare("==", f.x[n], rational(float(c))) for c in values]))
        return out

    def hull(self, f: _Frame, q: str) -> list[Any]:
        out = []
        for k, (lo, hi) in (self.hulls[q] or {}).items():
            if math.isfinite(lo):
                out.append(compare(">=", f.m[k], rational(lo)))
            if math.isfinite(hi):
                out.append(compare("<=", f.m[k], rational(hi)))
        return out

    def enabled(self, tr: Translation, t: Transition, strict: bool = False) -> Any:
        g, zero = tr.term(self.v.guard(t)), rational(0.0)
        if t.direction < 0:
            return compare("<" if strict else "<=", g, zero)
        return compare(">" if strict else ">=", g, zero)

    def disabled(self, tr: Translation, t: Transition, margin: float = 0.0) -> Any:
        g = tr.term(self.v.guard(t))
        if t.direction < 0:
            return g > rational(margin) if margin else g > 0
        return g < -rational(margin) if margin else g < 0

    def inside(self, tr: Translation, q: str, strict: bool = False) -> list[Any]:
        inv = self.v.invariant(q)
        if inv is True or inv is None:
            return []
        term = tr.term(inv)
        return [term > 0 if strict else term >= 0]

    def entry(self, f: _Frame, q: str, only: Transition | None = None) -> tuple[list[Any], list[tuple[str, Any, _Frame]]]:
        """Constraints saying ``f.m`` is a memory the transitions entering ``q`` can write (module docstring).

        Returns the constraint and, per disjunct, ``(transition name or "initial", its formula, its pre-frame)``.
        """
        import z3

        if not self.v.memory_names:
            return [], []
        disjuncts: list[tuple[str, Any, _Frame | None]] = []
        if q == self.a.initial_mode and only is None:
            init = self.a.initial_memory()
            disjuncts.append(("initial", all_of([compare("==", f.m[k], rational(c)) for k, c in init.items()]), None))
        entering = [t for t in self.a.transitions if t.target == q and self.hulls[t.source] is not None
                    and t.source in self.boxes]
        if only is not None:
            entering = [only]
        for t in entering:
            p = self.frame(f"{f.tag}<{t.name}")
            tr = self.translation(p, t.source)
            parts = self.box(p, t.source) + self.hull(p, t.source) + self.inside(tr, t.source)
            if self.v.guard(t) is not None:
                parts.append(self.enabled(tr, t))
            written = self.v.reset(t)
            for k in self.v.memory_names:
                if k in t.writes:
                    if written is not None:
                        parts.append(compare("==", f.m[k], tr.term(written[k])))
                else:
                    parts.append(compare("==", f.m[k], p.m[k]))
            parts += tr.side
            disjuncts.append((t.name, all_of(parts), p))
        if not disjuncts:
            return [z3.BoolVal(False, context())], []
        return [any_of([d for _, d, _ in disjuncts])], disjuncts  # type: ignore[misc]

    def last_writers(self, q: str, k: str) -> list[Transition | None]:
        """Transitions that can have written memory ``k`` last when in ``q`` (``None``: its initial value)."""
        key = ("writers", q, k)
        if key not in self._states:
            out: list[Transition | None] = []
            starts: list[tuple[Transition | None, str]] = [(None, self.a.initial_mode)]
            starts += [(t, t.target) for t in self.a.transitions if k in t.writes and self.hulls[t.source] is not None]
            for writer, mode in starts:
                seen, stack = {mode}, [mode]
                while stack:
                    here = stack.pop()
                    for u in self.a.outgoing(here):
                        if k not in u.writes and u.target not in seen:
                            seen.add(u.target)
                            stack.append(u.target)
                if q in seen:
                    out.append(writer)
            self._states[key] = out
        return self._states[key]

    def written(self, f: _Frame, q: str, always: bool = False, names: Sequence[str] | None = None) -> list[Any]:
        """Each memory variable equals what one of its last writers can write.

        Sound like the hulls, and tighter for carried values: a value carried through modes that do
        not write it is still an image of its writer's reset, at a state where the writer was
        enabled (and, with free parameters, under the same parameters).  Used by parametric
        questions, and (``always``) to confirm a witness whose memory was carried.
        """
        import z3

        if not self.param_vars and not always:
            return []
        out = []
        for k in self.v.memory_names:
            if names is not None and k not in names:
                continue
            options = []
            for t in self.last_writers(q, k):
                if t is None:
                    options.append(compare("==", f.m[k], rational(self.a.initial_memory()[k])))
                    continue
                reset = self.v.reset(t)
                if reset is None or t.source not in self.boxes:
                    options.append(z3.BoolVal(True, context()))
                    continue
                p = self.frame(f"{f.tag}<{t.name}.{k}")
                tr = self.translation(p, t.source)
                parts = self.box(p, t.source) + self.hull(p, t.source) + self.inside(tr, t.source)
                if self.v.guard(t) is not None:
                    parts.append(self.enabled(tr, t))
                parts.append(compare("==", f.m[k], tr.term(reset[k])))
                options.append(all_of(parts + list(tr.side)))
            out.append(any_of(options))
        return out

    def state(self, q: str, only: Transition | None = None, strict: bool = False, role: str = "main",
              entry: bool = True, writers: frozenset[str] = frozenset()
              ) -> tuple[_Frame, list[Any], Translation, list[tuple[str, Any, _Frame]]]:
        """A point of ``q``: in its box, its memory reachable by the abstraction, inside its invariant.

        Frames and their constraints are built once per (mode, role) and reused by every query
        (each query is a fresh solver); the translation's domain conditions restart per query.
        """
        key = (q, None if only is None else only.name, strict, role, entry, writers)
        hit = self._states.get(key)
        if hit is None:
            # the frame, its translation and its entry formula are shared by every role whose queries hold
            # one point of the mode (each query is its own solver); only "pre" needs a frame of its own
            base_key = ("frame", q, None if only is None else only.name, "pre" if role == "pre" else "point", entry)
            base = self._states.get(base_key)
            if base is None:
                f = self.frame(f"{role} {q}")
                tr = self.translation(f, q)
                memory, disjuncts = self.entry(f, q, only) if entry else ([], [])
                base = self._states[base_key] = (f, tr, _conjoin(self.box(f, q) + self.hull(f, q) + memory),
                                                 disjuncts)
            f, tr, core, disjuncts = base
            tr.begin()
            inside = self.inside(tr, q, strict)
            last = self.written(f, q, bool(writers), sorted(writers) if writers else None)
            hit = (f, [core, _conjoin(last + inside + list(tr.side))], tr, disjuncts)
            self._states[key] = hit
        f, cons, tr, disjuncts = hit
        tr.begin()
        return f, list(cons), tr, disjuncts

    def landing(self, q: str, role: str) -> tuple[_Frame, list[Any], Translation]:
        """A point of ``q`` whose memory the caller fixes: box, hull and invariant only (cached)."""
        key = (q, "landing", False, role)
        hit = self._states.get(key)
        if hit is None:
            f = self.frame(f"{role} {q}")
            tr = self.translation(f, q)
            tr.begin()
            inside = self.inside(tr, q)
            hit = (f, [_conjoin(self.box(f, q) + self.hull(f, q) + inside + list(tr.side))], tr, [])
            self._states[key] = hit
        f, cons, tr, _ = hit
        tr.begin()
        return f, list(cons), tr

    # ------------------------------------------------------------------ witnesses
    def point(self, model: Any, f: _Frame) -> tuple[tuple[float, ...], dict[str, float]]:
        x = tuple(to_float(model.eval(f.x[n], model_completion=True)) for n in self.v.coords)
        m = {k: to_float(model.eval(f.m[k], model_completion=True)) for k in self.v.memory_names}
        return x, m

    def provenance(self, model: Any, disjuncts: list[tuple[str, Any, _Frame]], m: Mapping[str, float]
                   ) -> tuple[bool, dict[str, float], str]:
        """Re-check that ``m`` is written by an entering transition at the solver's pre-jump state."""
        if not disjuncts:
            return True, {}, ""
        for name, _formula, pre in disjuncts:  # each candidate checked numerically (no solver evaluation)
            if pre is None:
                init = self.a.initial_memory()
                if all(_close(m[k], c) for k, c in init.items()):
                    return True, {}, "initial memory"
                continue
            t = next(tr for tr in self.a.transitions if tr.name == name)
            x0, m0 = self.point(model, pre)
            o = self.v.oracle
            v0 = o.signals(x0, m0)
            g = o.guard(t, x0, v0, m0)
            _, post = o.jump(t, x0, v0, m0)
            enabled = g >= -self.tol * (1.0 + abs(g)) if t.direction >= 0 else g <= self.tol
            ok = enabled and all(_close(post[k], m[k]) for k in self.v.memory_names)
            if not ok:
                continue
            values = {f"entry {name} guard": g}
            values.update({f"entry {name} pre {n}": c for n, c in zip(self.v.coords, x0)})
            return ok, values, f"memory written by {name}"
        return False, {}, "no entering transition matches"

    def witness(self, x: tuple[float, ...], m: Mapping[str, float], values: Mapping[str, float]) -> Witness:
        o = self.v.oracle
        v = o.signals(x, m)
        return Witness(state=dict(zip(self.v.coords, x)), memory=dict(m),
                       signals=dict(zip(self.a.variables, v)), values=dict(values))


def _conjoin(constraints: list[Any]) -> Any:
    """One formula for a cached list of constraints (one assertion instead of many)."""
    return all_of(constraints)


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= RECHECK_TOL * (1.0 + abs(a) + abs(b))


# ====================================================================== the questions
class _Questions(_Decider):
    """The checks of the module docstring, one method each."""

    def not_symbolic(self, q: str) -> str:
        """Why mode ``q`` cannot be decided (empty when every function the checks read is symbolic)."""
        v = self.v
        if v.signals is None:
            return "the output map is not symbolic"
        if v.invariant(q) is None:
            return "the invariant is not symbolic"
        for t in self.a.outgoing(q):
            if v.guard(t) is None:
                return f"the guard of {t.name!r} is not symbolic"
            if v.reset(t) is None:
                return f"the reset of {t.name!r} is not symbolic"
            if v.jump(t) is None:
                return f"the jump map of {t.name!r} is not symbolic"
            if t.target in self.boxes and v.invariant(t.target) is None:
                return f"the invariant of {t.target!r} is not symbolic"
        if v.invariant(q) is not True and v.system is not None and v.flow(q) is None:
            return "the flow is not symbolic (needed for the deadlock question)"
        return ""

    # ------------------------------------------------------------------ overlaps
    def carried(self, q: str, reads: Sequence[Any]) -> frozenset[str]:
        """The memory the functions ``reads`` read that some transition entering ``q`` only carries."""
        names: set[str] = set()
        for e in reads:
            if isinstance(e, (Expr, Condition)):
                names |= free_symbols(e)["memory"]
        out: set[str] = set()
        for t in self.a.transitions:
            if t.target == q:
                out |= names - set(t.writes)
        return frozenset(out)

    def pair(self, q: str, t1: Transition, t2: Transition) -> PairVerdict:
        same = t1.priority == t2.priority
        base = dict(mode=q, first=t1.name, second=t2.name, same_priority=same)
        if self.v.guard(t1) is None or self.v.guard(t2) is None or self.v.invariant(q) is None:
            return PairVerdict(**base, verdict="undecided", detail="a guard or the invariant is not symbolic")
        what = f"overlap of {t1.name} and {t2.name} in {q}"
        f, cons, tr, disjuncts = self.state(q)
        cons = cons + [self.enabled(tr, t1), self.enabled(tr, t2)] + tr.side
        status, model = self.solve(cons, what)
        carried = self.carried(q, [self.v.guard(t1), self.v.guard(t2), self.v.invariant(q)])
        if status == "sat" and not self.param_vars and carried:
            # the memory it reads may have been carried from a looser hull: confirm under its last writers
            f, cons, tr, disjuncts = self.state(q, role="confirm", writers=carried)
            cons = cons + [self.enabled(tr, t1), self.enabled(tr, t2)] + tr.side
            status, model = self.solve(cons, what)
        if status == "unsat":
            return PairVerdict(**base, verdict="exclusive", detail="proven: no state of the box enables both")
        if status == "unknown":
            return PairVerdict(**base, verdict="undecided",
                               detail=f"undecided within {self.timeout_s:g} s")
        x, m = self.point(model, f)
        if self.param_vars:
            return self._parametric_pair(base, model, x, m, t1, t2, disjuncts)
        o = self.v.oracle
        vv = o.signals(x, m)
        g1, g2 = o.guard(t1, x, vv, m), o.guard(t2, x, vv, m)
        inv = o.invariant(q, x, vv, m)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = _on(g1, t1, self.tol) and _on(g2, t2, self.tol) and inv >= -self.tol * (1 + abs(inv)) and ok_mem
        values.update({f"guard {t1.name}": g1, f"guard {t2.name}": g2})
        if math.isfinite(inv):
            values[f"invariant {q}"] = inv
        w = self.witness(x, m, values)
        if not ok:
            return PairVerdict(**base, verdict="undecided", witness=w,
                               detail=f"the solver's witness does not re-check ({_approx_note(tr)}); {how}")
        return PairVerdict(**base, verdict="overlap", witness=w, detail=f"witness re-checked; {how}")

    def _parametric_pair(self, base: dict[str, Any], model: Any, x: tuple[float, ...], m: Mapping[str, float],
                         t1: Transition, t2: Transition, disjuncts: list[Any]) -> PairVerdict:
        """Re-check an overlap found with free parameters: the symbolic guards (and the memory's provenance:
        the entering transition's guard and reset) evaluated with the witness's parameter values."""
        from .symbolic import Const, evaluate

        values = {n: to_float(model.eval(z, model_completion=True)) for n, z in self.param_vars.items()}
        fixed = {n: Const(c) for n, c in values.items()}

        def at(e: Any, xx: Sequence[float], mm: Mapping[str, float]) -> float:
            return float(evaluate(substitute(e, params=fixed), xx, mm))

        g = [at(self.v.guard(t), x, m) for t in (t1, t2)]
        ok = _on(g[0], t1, self.tol) and _on(g[1], t2, self.tol)
        provenance = not disjuncts
        for name, _formula, pre in disjuncts:
            if pre is None:
                init = self.a.initial_memory()
                provenance = all(_close(m[k], c) for k, c in init.items())
            else:
                t = next(tr for tr in self.a.transitions if tr.name == name)
                x0, m0 = self.point(model, pre)
                written = self.v.reset(t) or {}
                post = {k: (at(written[k], x0, m0) if k in written else m0[k]) for k in self.v.memory_names}
                provenance = (_on(at(self.v.guard(t), x0, m0), t, self.tol)  # type: ignore[arg-type]
                              and all(_close(post[k], m[k]) for k in self.v.memory_names))
            if provenance:
                break
        w = self.witness(x, m, {f"guard {t1.name}": g[0], f"guard {t2.name}": g[1],
                                **{f"param {n}": c for n, c in values.items()}})
        if not ok or not provenance:
            why = "the guards do not re-check" if not ok else (
                "its memory is not written by an entering transition with these parameters (the interval hull of "
                "the memory loses its relation to the free parameters)")
            return PairVerdict(**base, verdict="undecided", witness=w, detail=f"the parametric witness: {why}")
        return PairVerdict(**base, verdict="overlap", witness=w,
                           detail="witness re-checked with the parameter values " +
                           ", ".join(f"{n} = {format_g(c)}" for n, c in values.items()))

    # ------------------------------------------------------------------ deadlock
    def deadlock(self, q: str) -> tuple[str, Finding | None, str]:
        """``("proven"|"found"|"undecided"|"skipped", finding, detail)`` for mode ``q``."""
        inv = self.v.invariant(q)
        if inv is True:
            return "proven", None, "no invariant"
        out = self.a.outgoing(q)
        if inv is None or any(self.v.guard(t) is None for t in out):
            return "skipped", None, "invariant or a guard not symbolic"
        flow = self.v.flow(q)
        if self.v.system is not None and flow is None:
            return "skipped", None, "flow not symbolic"
        f, cons, tr, disjuncts = self.state(q)
        cons.append(tr.term(inv) == 0)
        lie = None
        if flow is not None:
            lie = _lie(inv, flow, self.v.coords)
            cons.append(tr.term(lie) <= -rational(self.tol))
        cons += [self.disabled(tr, t, self.tol) for t in out] + tr.side
        status, model = self.solve(cons, f"deadlock in {q}")
        if status == "unsat":
            return "proven", None, ""
        if status == "unknown":
            return "undecided", None, f"undecided within {self.timeout_s:g} s"
        x, m = self.point(model, f)
        o = self.v.oracle
        vv = o.signals(x, m)
        value = o.invariant(q, x, vv, m)
        guards = {t.name: o.guard(t, x, vv, m) for t in out}
        rate = None if lie is None else _evaluate_lie(lie, x, m)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = (abs(value) <= self.tol * 1e3 and all(not _on(g, t, 0.0) for t, g in zip(out, guards.values()))
              and (rate is None or rate < 0.0) and ok_mem)
        values.update({f"invariant {q}": value, **{f"guard {n}": g for n, g in guards.items()}})
        if rate is not None:
            values[f"d/dt invariant {q}"] = rate
        if not ok:
            return "undecided", None, f"witness does not re-check ({_approx_note(tr)})"
        text = self.a.mode(q).invariant_text or "inv"
        msg = (f"deadlock in mode {q!r}: at {self.v.oracle.where(x, m)} the state is on the boundary of the "
               f"invariant ({text} = {format_g(value)})"
               + ("" if rate is None else f", the flow leaves it (d/dt = {format_g(rate)})")
               + " and no outgoing transition is enabled (guards "
               + ", ".join(f"{n} = {format_g(g)}" for n, g in guards.items())
               + "); SMT witness, re-checked; widen a guard or the invariant")
        return "found", Finding(kind="deadlock", severity=KIND_SEVERITY["deadlock"], message=msg,
                                modes=(q,), witness=self.witness(x, m, values)), how

    # ------------------------------------------------------------------ resets
    def reset_outside(self, t: Transition) -> tuple[str, Finding | None, str]:
        inv_t = self.v.invariant(t.target)
        if inv_t is True:
            return "proven", None, ""
        jump, written, guard = self.v.jump(t), self.v.reset(t), self.v.guard(t)
        if inv_t is None or jump is None or written is None or guard is None:
            return "skipped", None, "a guard, reset, jump map or the target invariant is not symbolic"
        f, cons, tr, disjuncts = self.state(t.source)
        post_x = {n: tr.term(e) for n, e in zip(self.v.coords, jump)}
        post_m = {k: (tr.term(written[k]) if k in written else f.m[k]) for k in self.v.memory_names}
        after = Translation(coordinates=post_x, memory=post_m, bounds=_unbounded(self.v.coords),
                            prefix=f"{f.tag}.post")
        cons = cons + [self.enabled(tr, t), after.term(inv_t) <= -rational(self.tol)] + tr.side + after.side
        status, model = self.solve(cons, f"reset of {t.name}")
        if status == "unsat":
            return "proven", None, ""
        if status == "unknown":
            return "undecided", None, f"undecided within {self.timeout_s:g} s"
        x, m = self.point(model, f)
        o = self.v.oracle
        vv = o.signals(x, m)
        g = o.guard(t, x, vv, m)
        x2, m2 = o.jump(t, x, vv, m)
        landed = o.invariant(t.target, x2, o.signals(x2, m2), m2)
        ok_mem, values, how = self.provenance(model, disjuncts, m)
        ok = _on(g, t, self.tol) and landed < -self.tol * 0.5 and ok_mem
        values.update({f"guard {t.name}": g, f"invariant {t.target} after {t.name}": landed,
                       **{f"post {n}": c for n, c in zip(self.v.coords, x2)}})
        if not ok:
            return "undecided", None, f"witness does not re-check ({_approx_note(tr)})"
        msg = (f"the jump of {t.name!r} ({t.source} -> {t.target}) from {o.where(x, m)} lands outside the "
               f"invariant of {t.target!r} ({self.a.mode(t.target).invariant_text or 'inv'} = {format_g(landed)} < 0); "
               "SMT witness, re-checked; fix the jump map/reset or the guard")
        return "found", Finding(kind="reset_outside_invariant", severity=KIND_SEVERITY["reset_outside_invariant"],
                                message=msg, modes=(t.source, t.target), transitions=(t.name,),
                                witness=self.witness(x, m, values)), how

    # ------------------------------------------------------------------ instantaneous laps
    def lap(self, cycle: Sequence[Transition], role: str = "lap"
            ) -> tuple[str, Any, _Frame | None, list[Any]]:
        """Can the jumps of ``cycle`` follow one another at one instant and enable its first one again?"""
        if any(t.direction != 0 for t in cycle):
            return "unsat", None, None, []
        if any(self.v.guard(t) is None or self.v.jump(t) is None or self.v.reset(t) is None for t in cycle):
            return "unknown", None, None, []
        f, cons, tr, disjuncts = self.state(cycle[0].source, role=role)
        cons += self.lap_formula(f, tr, cycle)
        status, model = self.solve(cons, "instantaneous lap " + " -> ".join(t.name for t in cycle))
        return status, model, f, disjuncts

    def lap_formula(self, f: _Frame, tr: Translation, cycle: Sequence[Transition]) -> list[Any]:
        """The lap's conditions from state ``f``: each jump wins in turn (priorities), then the first is enabled."""
        cons: list[Any] = []
        m_terms = dict(f.m)
        sequence = list(cycle) + [cycle[0]]
        current = tr
        for i, t in enumerate(sequence):
            cons.append(self.enabled(current, t))
            cons += [self.disabled(current, u) for u in self.a.outgoing(t.source)
                     if u.direction == 0 and u.priority < t.priority and self.v.guard(u) is not None]
            if i == len(sequence) - 1:
                break
            jump, written = self.v.jump(t), self.v.reset(t)
            x_terms = {n: current.term(e) for n, e in zip(self.v.coords, jump)}  # type: ignore[arg-type]
            m_terms = {k: (current.term(written[k]) if k in written else m_terms[k])  # type: ignore[index]
                       for k in self.v.memory_names}
            cons += current.side
            current = Translation(coordinates=x_terms, memory=m_terms, bounds=_unbounded(self.v.coords),
                                  prefix=f"{f.tag}.j{i}")
        return cons + current.side

    def isolated(self, cycle: Sequence[Transition], w: Witness) -> tuple[str, dict[str, float]]:
        """Is there, within :data:`RETRIGGER_PROBE` of ``w`` (per coordinate width), a state enabling the
        cycle's first transition from which the lap does *not* happen?  ``("isolated", neighbour)``,
        ``("robust", {})`` (proven: every such state re-triggers) or ``("undecided", {})``."""
        import z3

        q0 = cycle[0].source
        f, cons, tr, _ = self.state(q0, role="neighbour")
        cons.append(self.enabled(tr, cycle[0]))
        cons.append(z3.Not(all_of(self.lap_formula(f, tr, cycle))))
        for n, (lo, hi) in self.boxes[q0].bounds.items():
            step = RETRIGGER_PROBE * (float(hi) - float(lo))
            c = w.state[n]
            cons += [f.x[n] >= rational(c - step), f.x[n] <= rational(c + step)]
        for n in self.boxes[q0].choices:
            cons.append(f.x[n] == rational(w.state[n]))
        for k, c in w.memory.items():
            cons.append(f.m[k] == rational(c))
        cons += tr.side
        status, model = self.solve(cons, "neighbourhood of a re-triggering state")
        if status == "sat":
            x, _ = self.point(model, f)
            return "isolated", {f"neighbour {n}": c for n, c in zip(self.v.coords, x)}
        return ("robust", {}) if status == "unsat" else ("undecided", {})

    def lap_witness(self, cycle: Sequence[Transition], model: Any, f: _Frame,
                    disjuncts: list[Any]) -> Witness | None:
        """Re-check a lap witness on the executors' instant rule: ``cycle[0]`` fires and wins again."""
        first = cycle[0]
        o = self.v.oracle
        x, m = self.point(model, f)
        vv = o.signals(x, m)
        g = o.guard(first, x, vv, m)
        if g < -self.tol * (1 + abs(g)):
            return None
        ok_mem, values, _ = self.provenance(model, disjuncts, m)
        if not ok_mem:
            return None
        x1, m1 = o.jump(first, x, vv, m)

        def signals(_q: str, state: tuple[float, ...]) -> tuple[float, ...]:
            return o.signals(state, m1)

        def fire(u: Transition, state: Any, vs: Sequence[float], mm: Mapping[str, float]) -> Any:
            return o.jump(u, state, vs, mm)

        instant = settle_instant(o.outgoing, first.target, x1, m1, signals=signals,
                                 guard=lambda u, vs, mm: o.guard(u, x1, vs, mm), fire=fire, ties="record",
                                 max_jumps=max(len(cycle) + 1, MAX_JUMPS_PER_INSTANT), stop_before=first)
        if not instant.stopped:
            return None
        values.update({f"guard {first.name}": g,
                       "chain": float(len(instant.jumps) + 1)})
        values.update({f"post {n}": c for n, c in zip(self.v.coords, x1)})
        return self.witness(x, m, values)

    # ------------------------------------------------------------------ dwell bounds
    def rates(self, q: str) -> dict[str, float]:
        """``|dx_j/dt| <= R_j`` in mode ``q``: declared, else the enclosure of a symbolic flow, else inf."""
        out = {n: math.inf for n in self.v.coords}
        flow = self.v.flow(q)
        if flow is not None and q in self.boxes:
            bounds = self._box_bounds(q)
            for n, e in zip(self.v.coords, flow):
                lo, hi = enclose(e, bounds, self.hulls[q] or {})
                out[n] = max(abs(lo), abs(hi))
        for n, r in self.declared_rates.items():
            out[n] = min(out[n], float(r))
        return out

    def dwell(self, t_in: Transition, t_out: Transition) -> tuple[float, str]:
        """Proven lower bound on the time between ``t_in`` entering a mode and ``t_out`` leaving it."""
        q = t_in.target
        rates = self.rates(q)
        if all(math.isinf(r) for r in rates.values()):
            return 0.0, "no rate bound"
        if any(self.v.guard(t) is None for t in (t_in, t_out)) or self.v.jump(t_in) is None \
                or self.v.reset(t_in) is None:
            return 0.0, "not symbolic"
        shortcut = self.independent_exit(t_in, t_out)
        if shortcut is not None:
            return shortcut
        import z3

        pre, cons, tr, _ = self.state(t_in.source, role="pre", entry=False)
        b, landing, tb = self.landing(q, "exit")
        cons.append(self.enabled(tr, t_in))
        jump, written = self.v.jump(t_in), self.v.reset(t_in)
        cons += [b.m[k] == (tr.term(written[k]) if k in written else pre.m[k])  # type: ignore[index]
                 for k in self.v.memory_names]
        a_x = {n: tr.term(e) for n, e in zip(self.v.coords, jump)}  # type: ignore[arg-type]
        after = Translation(coordinates=a_x, memory=b.m, bounds=_unbounded(self.v.coords), prefix=f"{b.tag}.a")
        cons += tr.side + self.inside(after, q) + after.side
        cons += landing + [self.enabled(tb, t_out)] + tb.side
        s = z3.Real(f"{b.tag}.s", context())
        moves = []
        for n, r in rates.items():
            if math.isinf(r):
                continue
            delta = b.x[n] - a_x[n]
            if r == 0.0:
                moves.append(delta == 0)
            else:
                moves += [delta <= s * rational(r), -delta <= s * rational(r)]
        what = f"dwell between {t_in.name} and {t_out.name}"
        candidate = self.minimise(cons + moves + [s >= 0], s, what)
        if candidate is not None and candidate <= 0.0:
            return 0.0, ""
        if candidate is None:
            status, _ = self.solve(cons + moves + [s >= 0], what)
            if status == "unsat":
                return math.inf, "infeasible"
            if status != "sat":
                return 0.0, "undecided"
        if candidate is not None and candidate > 0.0:
            bound = candidate * (1.0 - DWELL_REL)
            status, _ = self.solve(cons + moves + [s >= 0, s <= rational(bound)], what)
            if status == "unsat":
                return bound, _binding(q, t_in, t_out)
        low, high = 0.0, max((w / rates[n] for n, w in _widths(self.boxes[q]).items()
                              if rates.get(n, math.inf) not in (0.0, math.inf)), default=1.0)
        for _ in range(BISECTIONS):
            mid = 0.5 * (low + high)
            status, _ = self.solve(cons + moves + [s >= 0, s <= rational(mid)], what)
            if status == "unsat":
                low = mid
            else:
                high = mid
        return low, _binding(q, t_in, t_out) if low > 0.0 else ""

    def _symbols(self, e: Any) -> set[str]:
        if not isinstance(e, (Expr, Condition)):
            return set()
        f = free_symbols(e)
        return {f"x.{n}" for n in f["coordinates"]} | {f"m.{n}" for n in f["memory"]}

    def independent_exit(self, t_in: Transition, t_out: Transition) -> tuple[float, str] | None:
        """The dwell of a pair whose exit reads nothing the entry constrains, without the optimiser.

        When ``t_out``'s guard shares no coordinate or memory with ``t_in``'s guard and reset (nor
        with an invariant), ``t_in``'s jump is the identity and both modes have the same box, the
        query splits into two independent parts over a product of intervals: ``t_out`` can then
        fire at the very state ``t_in`` lands on (dwell 0) iff its guard holds somewhere on the box
        with the memory it reads in the source's hull, and never otherwise (infeasible).  ``None``
        when the shortcut does not apply.
        """
        q = t_in.target
        jump = self.v.jump(t_in)
        if jump is None or any(not (isinstance(e, Coordinate) and e.name == n) for e, n in zip(jump, self.v.coords)):
            return None
        if self.v.invariant(q) is not True or self.v.invariant(t_in.source) is not True:
            return None
        if self.boxes[q] != self.boxes[t_in.source]:
            return None
        written = self.v.reset(t_in) or {}
        entry = self._symbols(self.v.guard(t_in)) | {f"m.{k}" for k in t_in.writes}
        for e in written.values():
            entry |= self._symbols(e)
        exit_reads = self._symbols(self.v.guard(t_out))
        if exit_reads & entry:
            return None
        hull = self.hulls[t_in.source] or {}
        reads = sorted(n[2:] for n in exit_reads if n.startswith("m."))
        key = ("fires", t_out.name, tuple((k, hull.get(k)) for k in reads))
        if key not in self._states:
            f, cons, tr = self.landing(q, "fires")
            cons = [c for c in self.box(f, q)] + [self.enabled(tr, t_out)] + tr.side
            for k in reads:
                lo, hi = hull.get(k, (-math.inf, math.inf))
                if math.isfinite(lo):
                    cons.append(f.m[k] >= rational(lo))
                if math.isfinite(hi):
                    cons.append(f.m[k] <= rational(hi))
            status, _ = self.solve(cons, f"dwell exit {t_out.name}")
            self._states[key] = status
        status = self._states[key]
        if status == "sat":
            return 0.0, ""
        if status == "unsat":
            return math.inf, "infeasible"
        return None

    def projection(self, t: Transition, n: str, entry: bool) -> tuple[float, float]:
        """A sound interval of coordinate ``n`` over the states where ``t`` can fire (verified optimum).

        ``entry``: the source's memory as its entering transitions write it (tighter); otherwise within
        its hull only (cheaper, and as sound).
        """
        lo_box, hi_box = self._box_bounds(t.source)[n]
        guard = self.v.guard(t)
        if guard is None or n not in free_symbols(guard)["coordinates"]:
            return lo_box, hi_box
        if entry:
            f, cons, tr, _ = self.state(t.source)
        else:
            f, cons, tr = self.landing(t.source, "projection")
        cons = cons + [self.enabled(tr, t)] + tr.side
        out = []
        for sign in (1.0, -1.0):
            target = f.x[n] if sign > 0 else -f.x[n]
            best = self.minimise(cons, target, f"projection of {t.name} on {n}")
            fallback = lo_box if sign > 0 else -hi_box
            if best is None or not math.isfinite(best):
                out.append(fallback)
                continue
            margin = 1e-12 * (1.0 + abs(best))
            status, _ = self.solve(cons + [target < rational(best - margin)], f"projection of {t.name} on {n}")
            out.append(best - margin if status == "unsat" else fallback)
        return max(out[0], lo_box), min(-out[1], hi_box)


def _on(g: float, t: Transition, tol: float) -> bool:
    """Whether guard value ``g`` counts as enabled (within ``tol``) for ``t``'s direction."""
    if t.direction < 0:
        return g <= tol * (1.0 + abs(g))
    return g >= -tol * (1.0 + abs(g))


def _lie(inv: Expr, flow: Sequence[Expr], coords: Sequence[str]) -> Expr:
    total: Expr | None = None
    for n, f in zip(coords, flow):
        term = diff(inv, n) * f
        total = term if total is None else total + term
    assert total is not None
    return total


def _evaluate_lie(lie: Expr, x: Sequence[float], m: Mapping[str, float]) -> float:
    from .symbolic import evaluate

    return float(evaluate(lie, x, m))


def _unbounded(coords: Sequence[str]) -> dict[str, tuple[float, float]]:
    return {n: (-math.inf, math.inf) for n in coords}


def _widths(b: Box) -> dict[str, float]:
    return {n: float(hi) - float(lo) for n, (lo, hi) in b.bounds.items()}


def _binding(q: str, t_in: Transition, t_out: Transition) -> str:
    return f"in {q} between {t_in.name} and {t_out.name}"


def _approx_note(tr: Translation) -> str:
    if tr.approximated:
        return "transcendental terms enclosed by intervals: " + ", ".join(sorted(set(tr.approximated))[:3])
    return "rounding of the solver's rationals"


# ====================================================================== Zeno over the cycles
def _travel(intervals: Sequence[tuple[float, float]]) -> float:
    """Least distance a point moving on a line covers to visit ``intervals`` in order (exact, greedy)."""
    lo, hi = intervals[0]
    cost = 0.0
    for a, b in intervals[1:]:
        if b < lo:
            cost, lo, hi = cost + (lo - b), b, b
        elif a > hi:
            cost, lo, hi = cost + (a - hi), a, a
        else:
            lo, hi = max(lo, a), min(hi, b)
    return cost


def _mode_cycles(a: HybridAutomaton, max_cycles: int) -> tuple[list[tuple[Transition, ...]], bool]:
    """Cycles of transitions (every choice of parallel edges), deterministic order, at most ``max_cycles``."""
    graph = mode_graph(a)
    index = {q: i for i, q in enumerate(a.mode_names)}
    numbered = nx.DiGraph()
    numbered.add_nodes_from(range(len(a.mode_names)))
    numbered.add_edges_from(sorted({(index[u], index[v]) for u, v in graph.edges()}))
    between: dict[tuple[str, str], list[Transition]] = {}
    for t in a.transitions:
        between.setdefault((t.source, t.target), []).append(t)
    out: list[tuple[Transition, ...]] = []
    for cycle in nx.simple_cycles(numbered):
        start = min(range(len(cycle)), key=cycle.__getitem__)
        modes = [a.mode_names[i] for i in cycle[start:] + cycle[:start]]
        hops = [between[(modes[i], modes[(i + 1) % len(modes)])] for i in range(len(modes))]
        for choice in itertools.product(*hops):
            out.append(tuple(choice))
            if len(out) > max_cycles:
                break
        if len(out) > max_cycles:
            break
    capped = len(out) > max_cycles
    out = out[:max_cycles]
    order = {t.name: i for i, t in enumerate(a.transitions)}
    out.sort(key=lambda c: (len(c), [index[t.source] for t in c], [order[t.name] for t in c]))
    return out, capped


class _Zeno:
    def __init__(self, qs: _Questions) -> None:
        self.qs = qs
        self._dwell: dict[tuple[str, str], tuple[float, str]] = {}
        self._proj: dict[tuple[str, str, bool], tuple[float, float]] = {}
        self.findings: list[Finding] = []

    def dwell(self, t_in: Transition, t_out: Transition) -> tuple[float, str]:
        key = (t_in.name, t_out.name)
        if key not in self._dwell:
            self._dwell[key] = self.qs.dwell(t_in, t_out)
        return self._dwell[key]

    def projection(self, t: Transition, n: str, entry: bool) -> tuple[float, float]:
        key = (t.name, n, entry)
        if key not in self._proj:
            self._proj[key] = self.qs.projection(t, n, entry)
        return self._proj[key]

    def travel_bound(self, cycle: Sequence[Transition]) -> tuple[float, str]:
        """(distance a coordinate must travel in one lap) / (its largest rate along the lap), for the first
        coordinate that gives a positive bound (coordinates read by the most guards of the lap first).

        The guard sets are projected with the memory in its hulls first, and, when no coordinate gives
        a positive bound, again with the memory as the entering transitions write it."""
        qs = self.qs
        jumps = [qs.v.jump(t) for t in cycle]
        if any(j is None for j in jumps):
            return 0.0, ""
        reads = {n: sum(n in free_symbols(qs.v.guard(t))["coordinates"] for t in cycle) for n in qs.v.coords}
        order = sorted((i for i, n in enumerate(qs.v.coords) if reads[n] >= 2), key=lambda i: -reads[qs.v.coords[i]])
        for entry in (False, True):
            for i in order:
                n = qs.v.coords[i]
                if any(not (isinstance(j[i], Coordinate) and j[i].name == n) for j in jumps):  # type: ignore[index]
                    continue  # a jump moves this coordinate: its path is not continuous
                rate = max(qs.rates(t.target)[n] for t in cycle)
                if math.isinf(rate) or rate <= 0.0:
                    continue
                path = [self.projection(t, n, entry) for t in cycle]
                distance = _travel(path + [path[0]])
                if distance > 0.0:
                    return distance / rate, f"{n} must travel {format_g(distance)} per lap at <= {format_g(rate)} per s"
        return 0.0, ""

    def verdict(self, cycle: tuple[Transition, ...]) -> CycleVerdict:
        modes = tuple(t.source for t in cycle)
        names = tuple(t.name for t in cycle)
        total, parts = 0.0, []
        for i, t in enumerate(cycle):
            d, where = self.dwell(t, cycle[(i + 1) % len(cycle)])
            total += d
            if d > 0.0:
                parts.append((d, where))
        if math.isinf(total):
            return CycleVerdict(modes=modes, transitions=names, verdict="infeasible", dwell_s=math.inf,
                                binding="no execution takes these transitions in this order (proven)")
        travel, where_travel = self.travel_bound(cycle) if total == 0.0 else (0.0, "")
        if max(total, travel) > 0.0:
            if travel > total:
                return CycleVerdict(modes=modes, transitions=names, verdict="non_zeno", dwell_s=travel,
                                    binding=where_travel)
            top = max(parts)
            return CycleVerdict(modes=modes, transitions=names, verdict="non_zeno", dwell_s=total,
                                binding=f"dwell >= {format_g(top[0])} s {top[1]}")
        return self.instantaneous(cycle, modes, names)

    def instantaneous(self, cycle: tuple[Transition, ...], modes: tuple[str, ...], names: tuple[str, ...]
                      ) -> CycleVerdict:
        qs = self.qs
        status, model, f, disjuncts = qs.lap(cycle)
        w = qs.lap_witness(cycle, model, f, disjuncts) if status == "sat" else None  # type: ignore[arg-type]
        if w is None:
            reason = (NO_LAP + " but no positive dwell bound from the guards and rates: "
                      "declare rate bounds, or this cycle may accumulate (Zeno behaviour over time)")
            if status != "unsat":
                reason = ("undecided: " + (f"the solver timed out ({qs.timeout_s:g} s)" if status == "unknown"
                                           else "a lap witness did not re-check"))
            return CycleVerdict(modes=modes, transitions=names, verdict="undecided", dwell_s=0.0, binding=reason)
        shape, neighbour = qs.isolated(cycle, w)
        robust = shape != "isolated"
        kind = "reset_retriggers" if robust else "zeno_point"
        chain = " -> ".join(names)
        text = ("and so does every state near it that enables the first jump (proven)" if shape == "robust" else
                "(its neighbourhood undecided)" if shape == "undecided" else
                "but a state next to it does not (a Zeno point of the dynamics, not a modelling defect)")
        if neighbour:
            w = Witness(state=w.state, memory=w.memory, signals=w.signals, values={**w.values, **neighbour})
        self.findings.append(Finding(
            kind=kind, severity=KIND_SEVERITY[kind],
            message=(f"the jumps {chain} can follow one another at one instant and enable {names[0]!r} again from "
                     f"{qs.v.oracle.where(tuple(w.state.values()), w.memory)}, {text}; SMT witness, re-checked on "
                     "the executors' instant rule"
                     + ("; make the reset leave the guard (hysteresis) or use a crossing guard" if robust else "")),
            modes=modes, transitions=names, witness=w))
        return CycleVerdict(modes=modes, transitions=names, verdict="instantaneous" if robust else "zeno_point",
                            dwell_s=0.0, binding="instantaneous lap", witness=w)

    def summary(self) -> ZenoSummary:
        qs = self.qs
        cycles, capped = _mode_cycles(qs.a, qs.max_cycles)
        verdicts = []
        for c in cycles:
            if any(qs.hulls[t.source] is None or t.source not in qs.boxes for t in c):
                verdicts.append(CycleVerdict(modes=tuple(t.source for t in c), transitions=tuple(t.name for t in c),
                                             verdict="undecided", dwell_s=0.0,
                                             binding="a mode of the cycle is not searched (no box or unreachable)"))
                continue
            verdicts.append(self.verdict(c))
        counts = {k: sum(v.verdict == k for v in verdicts)
                  for k in ("non_zeno", "infeasible", "instantaneous", "zeno_point", "undecided")}
        proven = [v for v in verdicts if v.verdict == "non_zeno"]
        low = min(proven, key=lambda v: v.dwell_s) if proven else None
        rates = {q: qs.rates(q) for q in qs.a.mode_names if q in qs.boxes}
        return ZenoSummary(cycles=len(verdicts), counts=counts, min_dwell_s=None if low is None else low.dwell_s,
                           binding="" if low is None else low.binding,
                           binding_cycle=() if low is None else low.transitions, capped=capped,
                           rates=MappingProxyType(rates), verdicts=tuple(verdicts))


# ====================================================================== entry point
def decide(
    model: HybridSystem | HybridAutomaton,
    box: Box | Mapping[str, Box],
    *,
    rates: Mapping[str, float] | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    tol: float = 1e-9,
    max_cycles: int = 5000,
    zeno: bool = True,
) -> Decision:
    """Decide the structural questions of the module docstring with an SMT solver.

    Parameters
    ----------
    model : HybridSystem or HybridAutomaton
        Its symbolic functions are decided; the others are listed in
        :attr:`Decision.sampled_modes` (``hybrid.check`` samples them).
    box : Box or Mapping[str, Box]
        The region of every mode (or per mode), over the state names (system) or variables (automaton).
    rates : Mapping[str, float] or None
        Declared bounds ``|dx_j/dt| <= rates[j]`` (per second) of coordinates, for the dwell bounds.
    timeout_s : float
        Timeout of each solver call [s].
    tol : float
        Margin of the deadlock and reset questions (as :func:`hybrid.check`) and of witness re-checks.
    max_cycles : int
        Most cycles of transitions examined for Zeno.
    zeno : bool
        Whether to examine the cycles.

    Returns
    -------
    Decision

    Raises
    ------
    ModelDefinitionError
        A box that does not match the model, a rate that is not a number >= 0, bad arguments.
    """
    view = _View(model)
    validate_options(view.coords, rates, timeout_s)
    boxes = checked_boxes(view.oracle, box)
    if boxes is None:
        raise ModelDefinitionError("decide(): box = None; give the Box (or a mapping mode -> Box) to decide over")
    with fresh_context():
        qs = _Questions(view, boxes, rates=rates, timeout_s=float(timeout_s), tol=float(tol),
                        max_cycles=int(max_cycles))
        return _assemble(qs, zeno)


MIN_TIMEOUT_S = 0.001
"""The solver's clock counts milliseconds: a shorter timeout is refused rather than silently lengthened."""


def validate_options(coords: Sequence[str], rates: Mapping[str, float] | None, timeout_s: float) -> None:
    """Refuse rates that are not ``{coordinate: number >= 0}`` and a timeout below :data:`MIN_TIMEOUT_S`."""
    if (isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not math.isfinite(timeout_s)
            or timeout_s < MIN_TIMEOUT_S):
        raise ModelDefinitionError(
            f"timeout_s = {timeout_s!r}; expected a number of seconds >= {MIN_TIMEOUT_S} (the solver counts ms)")
    if rates is None:
        return
    if not isinstance(rates, Mapping):
        raise ModelDefinitionError(f"rates = {rates!r}; expected a mapping coordinate name -> rate bound per second")
    for n, r in rates.items():
        if n not in coords:
            raise ModelDefinitionError(f"rates names {n!r}, not a coordinate; coordinates: {list(coords)}")
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not (r >= 0.0):
            raise ModelDefinitionError(f"rates[{n!r}] = {r!r}; expected a rate >= 0 per second (inf: unbounded)")


def exclusive_for_all(
    model: HybridSystem | HybridAutomaton,
    box: Box | Mapping[str, Box],
    parameters: ParameterSpace,
    *,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    tol: float = 1e-9,
    modes: Sequence[str] | None = None,
) -> tuple[PairVerdict, ...]:
    """Which pairs of transitions sharing a source mode are exclusive for *every* admissible parameter value.

    ``modes`` restricts the question to those source modes (default: every mode with a box).

    The named parameters of :class:`ParameterSpace` are free solver variables
    (within their bounds, under the assumptions); every other constant keeps its
    value.  ``exclusive`` is then a proof for the whole parameter space; an
    ``overlap`` witness gives the parameter values too, and is re-checked by
    evaluating the model's symbolic functions with those values substituted.

    Examples
    --------
    "exclusive for every d− < d0 < d+ and every hysteresis h > 0" is
    ``exclusive_for_all(system, box, ParameterSpace(bounds=..., assumptions=(d_minus < d_zero, ...)))``.
    """
    view = _View(model)
    validate_options(view.coords, None, timeout_s)
    boxes = checked_boxes(view.oracle, box)
    if boxes is None:
        raise ModelDefinitionError("exclusive_for_all(): box = None; give the Box to decide over")
    with fresh_context():
        return _parametric_pairs(view, boxes, parameters, modes, float(timeout_s), float(tol))


def _parametric_pairs(view: _View, boxes: Mapping[str, Box], parameters: ParameterSpace,
                      modes: Sequence[str] | None, timeout_s: float, tol: float) -> tuple[PairVerdict, ...]:
    qs = _Questions(view, boxes, rates=None, timeout_s=timeout_s, tol=tol, max_cycles=0, parameters=parameters)
    out = []
    unknown = [q for q in (modes or ()) if q not in view.automaton.mode_names]
    if unknown:
        raise ModelDefinitionError(f"exclusive_for_all(): unknown mode(s) {unknown}; modes: {list(view.automaton.mode_names)}")
    for q in view.automaton.mode_names:
        if q not in boxes or qs.hulls[q] is None or (modes is not None and q not in modes):
            continue
        for t1, t2 in itertools.combinations(view.automaton.outgoing(q), 2):
            out.append(qs.pair(q, t1, t2))
    return tuple(out)


def _assemble(qs: _Questions, zeno: bool) -> Decision:
    a = qs.a
    findings: list[Finding] = []
    pairs: list[PairVerdict] = []
    sampled: dict[str, str] = {}
    status: dict[str, list[str]] = {k: [] for k in ("nondeterminism", "deadlock", "reset_outside_invariant")}
    searched = [q for q in a.mode_names if q in qs.boxes and qs.hulls[q] is not None]
    for q in searched:
        reason = qs.not_symbolic(q)
        if reason:
            sampled[q] = reason
    for q in searched:
        out = a.outgoing(q)
        for t1, t2 in itertools.combinations(out, 2):
            p = qs.pair(q, t1, t2)
            pairs.append(p)
            if p.verdict == "undecided":
                if "not symbolic" in p.detail:
                    sampled[q] = p.detail
                    status["nondeterminism"].append("skipped")
                else:
                    status["nondeterminism"].append("undecided")
            elif p.verdict == "overlap":
                kind = "nondeterminism" if p.same_priority else "priority_overlap"
                findings.append(_overlap_finding(qs, p, kind))
                if p.same_priority:
                    status["nondeterminism"].append("found")
        s, finding, detail = qs.deadlock(q)
        status["deadlock"].append(s)
        if s == "skipped":
            sampled.setdefault(q, detail)
        if finding is not None:
            findings.append(finding)
        for t in out:
            s, finding, detail = qs.reset_outside(t)
            status["reset_outside_invariant"].append(s)
            if s == "skipped":
                sampled.setdefault(q, detail)
            if finding is not None:
                findings.append(finding)
    summary = None
    if zeno:
        z = _Zeno(qs)
        summary = z.summary()
        findings += z.findings
    claims = _claims(qs, status, summary, sampled, findings)
    return Decision(findings=tuple(findings), claims=MappingProxyType(claims), pairs=tuple(pairs), zeno=summary,
                    memory_hulls=MappingProxyType({q: None if h is None else MappingProxyType(h)
                                                   for q, h in qs.hulls.items()}),
                    sampled_modes=MappingProxyType(sampled), queries=qs.queries, solver_s=qs.solver_s,
                    solver=solver_version())


def _overlap_finding(qs: _Questions, p: PairVerdict, kind: str) -> Finding:
    assert p.witness is not None
    w = p.witness
    where = qs.v.oracle.where(tuple(w.state.values()), w.memory)
    if kind == "nondeterminism":
        text = (f"transitions {p.first!r} and {p.second!r} of mode {p.mode!r} have the same priority and are both "
                f"enabled at {where}; SMT witness, re-checked; give them distinct priorities or exclusive guards")
    else:
        text = (f"transitions {p.first!r} and {p.second!r} of mode {p.mode!r} are both enabled at {where}; "
                "their priorities decide which fires (SMT witness, re-checked)")
    return Finding(kind=kind, severity=KIND_SEVERITY[kind], message=text, modes=(p.mode,),
                   transitions=(p.first, p.second), witness=w)


NO_LAP = "no instantaneous lap (proven)"
"""How a cycle's verdict begins when its lap is proven to take time but no dwell bound was found."""
MEMORY_ASSUMPTION = ("memory ranges over what the transitions entering each mode can write "
                     "(interval hulls by fixpoint, the entering reset stated exactly)")
BOX_ASSUMPTION = "every state of the declared box (reachable or not)"


def _claims(qs: _Questions, status: Mapping[str, list[str]], summary: ZenoSummary | None,
            sampled: Mapping[str, str], findings: Sequence[Finding]) -> dict[str, Claim]:
    method = f"{solver_version()} on the symbolic model; witnesses re-evaluated on the model's functions"
    kinds = {f.kind for f in findings}
    assumptions = (BOX_ASSUMPTION, MEMORY_ASSUMPTION)
    out = {}
    note = "" if not sampled else f"modes left to sampling: {sorted(sampled)}"
    for check, results in status.items():
        found = check in kinds
        if found:
            s = "found"
        elif sampled and "skipped" in results:
            s = "sampled"
        elif "undecided" in results:
            s = "undecided"
        else:
            s = "proven"
        detail = note
        if s == "undecided":
            n = results.count("undecided")
            detail = "; ".join(x for x in (f"{n} question(s) without an answer (the solver's unknown or its "
                                            f"timeout of {qs.timeout_s:g} s)", note) if x)
        out[check] = Claim(check=check, status=s, method=method, assumptions=assumptions, detail=detail)
    retrig = "reset_retriggers" in kinds
    if summary is not None:
        c = summary.counts
        undecided = c["undecided"]
        zs = ("found" if c["instantaneous"] or c["zeno_point"] else
              ("undecided" if undecided or summary.capped else "proven"))
        detail = (f"{summary.cycles} cycles: {c['non_zeno']} with a proven dwell bound, {c['infeasible']} "
                  f"infeasible, {c['instantaneous']} instantaneous, {c['zeno_point']} with a Zeno point, "
                  f"{undecided} undecided")
        first = next((v for v in summary.verdicts if v.verdict == "undecided"), None)
        if first is not None:  # why, on the first undecided cycle
            detail = (f"{undecided} of {summary.cycles} cycles undecided, e.g. {' -> '.join(first.transitions)}: "
                      f"{first.binding} ({detail})")
        if summary.min_dwell_s is not None:
            detail += f"; smallest dwell bound {format_g(summary.min_dwell_s)} s ({summary.binding})"
        out["zeno"] = Claim(check="zeno", status=zs, method=method, detail=detail,
                            assumptions=assumptions + ("rate bounds |dx/dt| <= R per mode (declared or from the flow)",))
        laps = sum(v.verdict == "undecided" and not v.binding.startswith(NO_LAP) for v in summary.verdicts)
        rs = "found" if retrig else ("undecided" if laps or summary.capped else "proven")
        out["reset_retriggers"] = Claim(check="reset_retriggers", status=rs,
                                        method=method, assumptions=assumptions, detail=(f"{laps} cycle(s) whose lap was not decided (instantaneous laps "
                                                "of cycles)" if laps else "instantaneous laps of cycles"))
    return out
