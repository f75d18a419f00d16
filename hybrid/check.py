"""Structural checks of a hybrid automaton or system, each finding with a witness.

:func:`check` answers two families of questions.

**Graph questions** (on :func:`hybrid.graph.mode_graph`, no numerics):

* ``unreachable_mode`` / ``unreachable_transition`` (warning): a mode that no
  path of transitions leads to from the initial mode, and the transitions
  leaving such a mode;
* ``sink_mode`` (warning): a mode without outgoing transition;
* ``zeno_candidate`` (info): a simple cycle of the mode graph; a cycle is
  where jumps can pile up at one instant (Zeno) or chatter.

**State-space questions**, asked over a :class:`~hybrid.region.Box` per mode
(of the continuous state ``x`` of a :class:`~hybrid.system.HybridSystem`,
whose signals are ``v = system.signals(0, x)``, or of the signals of a bare
:class:`~hybrid.model.HybridAutomaton`):

* ``nondeterminism`` (error): two transitions of one mode with the same
  priority enabled at one state of the box where the invariant holds
  (``priority_overlap``, info, when the priorities differ and resolve it);
* ``deadlock`` (error): a point of the invariant's boundary where the flow
  leaves the invariant and no outgoing transition is enabled;
* ``reset_outside_invariant`` (error): a guard state whose jump (continuous
  jump map and memory reset) lands where the target's invariant is violated;
* ``reset_retriggers`` (error): a level-triggered transition whose jump leads,
  at the same instant, through a chain of level-triggered jumps back to the
  same transition (a guard that fires again right after its own reset).
  When that happens only on a part of the guard set of measure zero (its
  neighbours in the guard set do not re-trigger: a bouncing ball at rest,
  the corner of the water tanks), it is a Zeno point of the dynamics, not a
  modelling defect, and is reported as ``zeno_point`` (info).

Each state-space question is a search: ``samples`` uniform points per mode
drawn from ``numpy.random.default_rng(seed)``, plus the box corners and
``FACE_FRACTION * samples`` points on the box's faces (jump sets such as
``h = 0`` are often faces, which interior samples never hit), then,
when no sample shows the problem, a bounded Nelder-Mead search
(:func:`scipy.optimize.minimize`) of a merit function from the ``starts``
most promising samples.  Discrete coordinates (``Box.choices``) are sampled
and enumerated by the corners, never optimised.  A search that finds nothing
is evidence, not proof; :class:`SearchSummary` says how hard it looked.

Crossing-triggered transitions (``direction != 0``) only fire on a zero
crossing of their guard, which is an instant, not a region.  The searches
treat them as enabled on the side the crossing ends on (``g >= 0`` for
``direction = +1``, ``g <= 0`` for ``direction = -1``, as
:func:`hybrid.model.transition_fires`), and every message involving one says
so.  After its own jump, a crossing-triggered guard that sits on zero does not
fire again (there was no crossing), so it is never a ``reset_retriggers``, and
the jump chains simulated for that check follow level-triggered transitions
only (smallest priority first, as :func:`hybrid.sampled.settle`).

Examples
--------
>>> from hybrid import HybridAutomaton, Mode, Transition, Box
>>> heat = Transition(name="heat", source="off", target="on", guard=lambda v, m: 19.0 - v[0])
>>> cool = Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - 21.0)
>>> thermostat = HybridAutomaton(name="thermostat", modes=(Mode(name="off"), Mode(name="on")),
...                              transitions=(heat, cool), variables=("T",))
>>> report = check(thermostat, Box(bounds={"T": (10.0, 30.0)}), samples=200)
>>> report.no_findings, sorted(report.kinds())
(True, ['zeno_candidate'])

Plain callables are sampled, which cannot decide the ``off -> on -> off`` cycle: the report is not
complete, so not clean (:mod:`hybrid.completeness`):

>>> report.clean, [reason.split(":")[0] for reason in report.incomplete]
(False, ['zeno undecided'])
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import networkx as nx
import numpy as np

from .errors import ExecutionError
from .completeness import check_statuses, incomplete_reasons, state_claims, undecided_cycles, zeno_group
from .findings import (
    KIND_SEVERITY,
    SEVERITIES,
    Finding,
    Oracle,
    SearchBudgetExceeded,
    Witness,
    checked_boxes,
    finding_number,
)
from .graph import mode_graph
from .model import HybridAutomaton
from .region import Box
from .system import HybridSystem
from .check_search import (
    BOUNDARY_MAXITER,
    BOUNDARY_PROBES,
    BOUNDARY_XTOL,
    CORNER_LIMIT,
    FACE_FRACTION,
    FD_DISPLACEMENT,
    ModeChecker,
    ModeSearch,
    NM_MAXFEV_BASE,
    NM_MAXFEV_PER_DIM,
    NM_SIMPLEX_STEP,
    RETRIGGER_PROBE,
    SNAP_DECIMALS,
    SearchSpace,
)

__all__ = [
    "SEARCH_BUDGET_S",
    "KIND_SEVERITY",
    "GRAPH_CHECKS",
    "STATE_CHECKS",
    "Witness",
    "Finding",
    "ModeSearch",
    "SearchSummary",
    "CheckReport",
    "check",
]

GRAPH_CHECKS = ("unreachable", "sink_mode", "zeno_candidate")
"""Checks run on the mode graph alone (``unreachable`` reports modes and transitions)."""

STATE_CHECKS = ("nondeterminism", "deadlock", "reset_outside_invariant", "reset_retriggers")
"""Checks that search a Box (``nondeterminism`` also reports ``priority_overlap``)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class SearchSummary:
    """What :func:`check` searched and how.

    Attributes
    ----------
    seed, samples, starts, max_cycles : int
        The arguments of the run.
    tol : float
        Tolerance of the run.
    checks : Mapping[str, str]
        For each of :data:`GRAPH_CHECKS` and :data:`STATE_CHECKS`, ``"ran"``,
        ``"ran: ..."`` with a remark, or ``"skipped: <why>"``.
    modes : tuple of ModeSearch
        One entry per mode, in declaration order.
    cycles_found : int
        Simple cycles enumerated.
    cycles_capped : bool
        Whether the enumeration stopped at ``max_cycles``.
    """

    seed: int
    samples: int
    starts: int
    max_cycles: int
    tol: float
    checks: Mapping[str, str]
    modes: tuple[ModeSearch, ...]
    cycles_found: int = 0
    cycles_capped: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "checks", MappingProxyType(dict(self.checks)))
        object.__setattr__(self, "modes", tuple(self.modes))

    def mode(self, name: str) -> ModeSearch:
        """The search summary of mode ``name``."""
        for entry in self.modes:
            if entry.mode == name:
                return entry
        raise KeyError(f"no mode {name!r} in the search summary; modes: {[m.mode for m in self.modes]}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "seed": self.seed,
            "samples": self.samples,
            "starts": self.starts,
            "max_cycles": self.max_cycles,
            "tol": finding_number(self.tol),
            "checks": dict(self.checks),
            "modes": [m.as_dict() for m in self.modes],
            "cycles_found": self.cycles_found,
            "cycles_capped": self.cycles_capped,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class CheckReport:
    """Result of :func:`check`.

    Attributes
    ----------
    automaton : str
        Name of the automaton.
    model : str
        ``"system"`` (a HybridSystem, searched over its state) or
        ``"automaton"`` (searched over its signals).
    findings : tuple of Finding
        Graph findings first, then state-space findings (decided, then sampled).
    searched : SearchSummary
    claims : Mapping[str, Claim]
        Per state-space check and ``"zeno"``: how it was answered
        (:class:`hybrid.decide.Claim`: ``proven``, ``found``, ``sampled``, ``undecided``, ``skipped``).
    zeno : ZenoSummary or None
        The cycles grouped by verdict, when decided.
    pairs : tuple of PairVerdict
        Every decided pair of transitions sharing a source mode.
    solver : str
        The SMT solver used (empty when none).
    """

    automaton: str
    model: str
    findings: tuple[Finding, ...]
    searched: SearchSummary
    claims: Mapping[str, Any] = field(default_factory=dict)
    zeno: Any = None
    pairs: tuple[Any, ...] = ()
    solver: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "findings", tuple(self.findings))
        object.__setattr__(self, "claims", MappingProxyType(dict(self.claims)))
        object.__setattr__(self, "pairs", tuple(self.pairs))

    def claim(self, check: str) -> str:
        """``"proven"``, ``"found"``, ``"sampled"``, ``"undecided"`` or ``"skipped"`` for one check."""
        return self.claims[check].status if check in self.claims else "sampled"

    @property
    def errors(self) -> tuple[Finding, ...]:
        """Findings of severity ``"error"``."""
        return tuple(f for f in self.findings if f.severity == "error")

    @property
    def warnings(self) -> tuple[Finding, ...]:
        """Findings of severity ``"warning"``."""
        return tuple(f for f in self.findings if f.severity == "warning")

    @property
    def infos(self) -> tuple[Finding, ...]:
        """Findings of severity ``"info"``."""
        return tuple(f for f in self.findings if f.severity == "info")

    @property
    def no_findings(self) -> bool:
        """No error and no warning (infos allowed); says nothing about checks that were skipped or undecided."""
        return not any(f.severity in ("error", "warning") for f in self.findings)

    @property
    def statuses(self) -> tuple[Any, ...]:
        """One :class:`hybrid.completeness.CheckStatus` per check (decided, finding, sampled, skipped, undecided)."""
        return check_statuses(self)

    @property
    def complete(self) -> bool:
        """Every check ran on every mode and gave an answer (none skipped or undecided)."""
        return not self.incomplete

    @property
    def incomplete(self) -> tuple[str, ...]:
        """``"<check> skipped|undecided: <why>"`` for each check that did not decide (empty when complete)."""
        return incomplete_reasons(self.statuses)

    @property
    def clean(self) -> bool:
        """Complete (:attr:`complete`) and no error and no warning (infos allowed)."""
        return self.complete and self.no_findings

    def completeness(self) -> dict[str, Any]:
        """JSON-ready ``{"complete", "incomplete", "statuses"}`` (kept out of :meth:`as_dict`, whose keys are fixed)."""
        statuses = self.statuses
        return {"complete": not incomplete_reasons(statuses), "incomplete": list(incomplete_reasons(statuses)),
                "statuses": {s.check: s.as_dict() for s in statuses}}

    def kinds(self, *severities: str) -> frozenset[str]:
        """Kinds of the findings, optionally only those of the given severities.

        Examples
        --------
        ``report.kinds("error", "warning")`` is what makes a report unclean.
        """
        unknown = [s for s in severities if s not in SEVERITIES]
        if unknown:
            raise ValueError(f"kinds(): unknown severity {unknown}; expected some of {list(SEVERITIES)}")
        return frozenset(f.kind for f in self.findings if not severities or f.severity in severities)

    def of_kind(self, kind: str) -> tuple[Finding, ...]:
        """Findings of one kind."""
        return tuple(f for f in self.findings if f.kind == kind)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, deterministic (same model, box and seed give an equal dict)."""
        return {
            "automaton": self.automaton,
            "model": self.model,
            "clean": self.clean,
            "counts": {s: sum(f.severity == s for f in self.findings) for s in SEVERITIES},
            "findings": [f.as_dict() for f in self.findings],
            "searched": self.searched.as_dict(),
            "claims": {k: c.as_dict() for k, c in self.claims.items()},
            "zeno": None if self.zeno is None else self.zeno.as_dict(verdicts=False),
            "pairs": [p.as_dict() for p in self.pairs],
            "solver": self.solver,
        }


# ====================================================================== graph checks
def _graph_findings(a: HybridAutomaton, max_cycles: int) -> tuple[list[Finding], int, bool]:
    graph = mode_graph(a)
    initial = a.initial_mode
    reachable = nx.descendants(graph, initial) | {initial}
    findings = []
    for q in a.mode_names:
        if q not in reachable:
            findings.append(
                Finding(
                    kind="unreachable_mode",
                    severity=KIND_SEVERITY["unreachable_mode"],
                    message=(
                        f"mode {q!r} is unreachable: no path of transitions leads to it from the initial mode "
                        f"{initial!r}; add a transition into it or remove it"
                    ),
                    modes=(q,),
                )
            )
    for t in a.transitions:
        if t.source not in reachable:
            findings.append(
                Finding(
                    kind="unreachable_transition",
                    severity=KIND_SEVERITY["unreachable_transition"],
                    message=(
                        f"transition {t.name!r} ({t.source} -> {t.target}) can never fire: its source mode "
                        f"{t.source!r} is unreachable from {initial!r}"
                    ),
                    modes=(t.source, t.target),
                    transitions=(t.name,),
                )
            )
    for q in a.mode_names:
        if graph.out_degree(q) == 0:
            findings.append(
                Finding(
                    kind="sink_mode",
                    severity=KIND_SEVERITY["sink_mode"],
                    message=(
                        f"mode {q!r} has no outgoing transition: once entered it is never left; "
                        "fine for a terminal mode (goal, fault), otherwise add a transition"
                    ),
                    modes=(q,),
                )
            )
    index = {q: i for i, q in enumerate(a.mode_names)}
    order = {t.name: i for i, t in enumerate(a.transitions)}
    # enumerate on integer labels: networkx walks sets of nodes, whose order for strings changes with
    # PYTHONHASHSEED; with ints it is fixed, so the first max_cycles cycles are the same in every process
    numbered = nx.DiGraph()
    numbered.add_nodes_from(range(len(a.mode_names)))
    numbered.add_edges_from(sorted({(index[u], index[v]) for u, v in graph.edges()}))
    cycles = [[a.mode_names[i] for i in c]
              for c in itertools.islice(nx.simple_cycles(numbered), max_cycles + 1)]
    capped = len(cycles) > max_cycles
    cycles = cycles[:max_cycles]
    normalised = []
    for cycle in cycles:
        start = min(range(len(cycle)), key=lambda i: index[cycle[i]])
        normalised.append(tuple(cycle[start:] + cycle[:start]))
    listed = []
    for cycle in sorted(set(normalised), key=lambda c: (len(c), [index[q] for q in c])):
        names: list[str] = []
        for i, q in enumerate(cycle):
            nxt = cycle[(i + 1) % len(cycle)]
            names += sorted(graph[q][nxt], key=order.__getitem__)
        listed.append((cycle, tuple(names)))
    return findings, listed, capped


SEARCH_BUDGET_S = 120.0
"""Default wall-clock budget of :func:`check`'s sampled searches [s]."""


# ====================================================================== entry point
def check(
    model: HybridSystem | HybridAutomaton,
    box: Box | Mapping[str, Box] | None = None,
    *,
    samples: int = 2000,
    starts: int = 8,
    seed: int = 0,
    max_cycles: int = 200,
    tol: float = 1e-9,
    method: str = "auto",
    rates: Mapping[str, float] | None = None,
    timeout_s: float = 5.0,
    budget_s: float | None = SEARCH_BUDGET_S,
) -> CheckReport:
    """Structural checks of a hybrid system or automaton, each finding with a witness.

    With ``method="auto"`` (the default), every mode whose guards, invariant,
    resets and jump maps are symbolic (:mod:`hybrid.symbolic`) is decided by an
    SMT solver (:func:`hybrid.decide.decide`: each finding's witness re-checked,
    each clean answer PROVEN), and the others are searched by sampling (SAMPLED);
    :attr:`CheckReport.claims` says which, per check.  ``method="sampled"``
    samples every mode; ``method="smt"`` decides only: the checks that need a
    mode it cannot take are ``skipped`` (:data:`hybrid.completeness.SMT_CANNOT_DECIDE`),
    never labelled sampled, and that mode's plain functions are evaluated at
    its box corners and centre only, so that one raising or returning NaN or
    None is the same :class:`ExecutionError` as with the other methods.
    :attr:`CheckReport.clean` holds only when every check ran and decided
    (:attr:`CheckReport.complete`) and nothing was found.

    Parameters
    ----------
    model : HybridSystem or HybridAutomaton
        A system is searched over its continuous state ``x`` (signals
        ``system.signals(0, x)``, flows and jump maps used); a bare automaton
        over its signals (no flow: every invariant-boundary point counts for
        the deadlock check; no continuous jump map).
    box : Box or Mapping[str, Box] or None
        Region searched, for every mode or per mode name (a mode absent from
        the mapping is not searched; the summary says so).  It must declare
        exactly the state names (system) or variables (automaton); memory it
        does not declare keeps the automaton's initial value.  ``None`` runs
        the graph checks only.
    samples : int
        Uniform samples per mode (the box corners are added).
    starts : int
        Local optimisations per question when no sample answers it.
    seed : int
        Seed of ``numpy.random.default_rng``; a fixed seed gives an identical report.
    max_cycles : int
        Most simple cycles enumerated as Zeno candidates.
    method : {"auto", "sampled", "smt"}
        How the state-space questions are answered (above).
    rates : Mapping[str, float] or None
        Declared rate bounds ``|dx_j/dt| <= rates[j]`` of coordinates, for the Zeno dwell bounds.
    timeout_s : float
        Timeout of one solver call [s]; a call that times out makes its answer "undecided".
    budget_s : float or None
        Wall-clock budget of all the sampled searches together [s]: when it runs out, the mode being
        searched and those after it are "not searched (time budget)", so their checks are skipped
        and the report incomplete (never CLEAN); ``None``: no budget.
    tol : float
        Tolerance: a boundary point has ``0 <= inv <= tol``; a deadlock needs
        every guard ``< -tol`` and ``d/dt inv < -tol``; a reset lands outside
        when the target invariant is ``< -tol``; an overlap of guards within
        ``tol`` of both being enabled is reported (and says so).

    Returns
    -------
    CheckReport

    Raises
    ------
    ModelDefinitionError
        A model of the wrong type, or a box that does not declare exactly the
        model's coordinates (or declares unknown memory).
    ExecutionError
        Invalid arguments, or a guard, invariant, reset, flow, jump map or
        output that raises or returns NaN in the box (the message names the
        function and the state; the original error is chained).

    Examples
    --------
    >>> from hybrid import HybridAutomaton, Mode, Transition, Box
    >>> a = HybridAutomaton(name="twins", modes=(Mode(name="idle"), Mode(name="a"), Mode(name="b")),
    ...     transitions=(Transition(name="to_a", source="idle", target="a", guard=lambda v, m: v[0]),
    ...                  Transition(name="to_b", source="idle", target="b", guard=lambda v, m: v[0] - 1)),
    ...     variables=("x",))
    >>> report = check(a, Box(bounds={"x": (-2.0, 2.0)}), samples=100)
    >>> sorted(report.kinds("error"))
    ['nondeterminism']
    >>> w = report.errors[0].witness
    >>> w.values["guard to_a"] >= 0 and w.values["guard to_b"] >= 0
    True
    """
    _check_arguments(samples=samples, starts=starts, max_cycles=max_cycles, seed=seed, tol=tol, method=method)
    oracle = Oracle(model)
    a = oracle.automaton
    from .decide import validate_options

    validate_options(oracle.coords, rates, timeout_s)
    boxes = checked_boxes(oracle, box)

    findings, cycles, capped = _graph_findings(a, int(max_cycles))
    checks: dict[str, str] = {
        "unreachable": "ran",
        "sink_mode": "ran",
        "zeno_candidate": f"ran: capped at max_cycles = {max_cycles} cycles" if capped else "ran",
    }
    decision = None
    if boxes is not None and method != "sampled":
        from .decide import decide

        decision = decide(model, boxes, rates=rates, timeout_s=timeout_s, tol=tol,
                          max_cycles=max(int(max_cycles), 5000))
    sampled_modes = set(a.mode_names) if decision is None else (
        set() if method == "smt" else set(decision.sampled_modes))
    undecidable = {} if decision is None or method != "smt" else dict(decision.sampled_modes)
    if budget_s is not None and (isinstance(budget_s, bool) or not isinstance(budget_s, (int, float))
                                 or not math.isfinite(budget_s) or budget_s <= 0):
        raise ExecutionError(f"check(): budget_s = {budget_s!r}; expected a time > 0 [s] or None")
    oracle.deadline = None if budget_s is None else time.monotonic() + float(budget_s)
    mode_summaries, state_findings = _sample_modes(oracle, boxes, sampled_modes, samples=int(samples),
                                                   starts=int(starts), seed=int(seed), tol=float(tol),
                                                   undecidable=undecidable)
    oracle.deadline = None
    out_of_time = [s.mode for s in mode_summaries if any(n.startswith(_OUT_OF_TIME) for n in s.notes)]
    if decision is not None:
        findings += [f for f in decision.findings
                     if not (set(f.modes) & set(decision.sampled_modes)) or method == "smt"]
    findings += state_findings
    checks.update(_state_check_remarks(a, boxes, out_of_time, budget_s))
    if decision is not None and decision.zeno is not None and not set(boxes or {}) <= sampled_modes:
        z = decision.zeno
        checks["zeno_candidate"] = (f"decided: {z.cycles} cycles of transitions"
                                    + (" (capped)" if z.capped else "") + f"; {dict(z.counts)}")
    all_sampled = decision is None or set(boxes or {}) <= sampled_modes
    undecided = cycles if all_sampled else undecided_cycles(cycles, decision)
    if undecided:
        why = (("method sampled" if method == "sampled" else "the guards, resets or jump maps are not symbolic")
               if all_sampled else "functions not symbolic, method smt" if undecidable
               else "no dwell bound and no instantaneous lap")
        findings.append(zeno_group(undecided, capped, why))
    claims = state_claims(decision, sampled_modes, boxes, findings, method, len(cycles))
    for c in STATE_CHECKS:
        if boxes is not None and claims[c].status == "skipped":
            checks[c] = f"skipped: {claims[c].detail}"
    summary = SearchSummary(
        seed=int(seed),
        samples=int(samples),
        starts=int(starts),
        max_cycles=int(max_cycles),
        tol=float(tol),
        checks=checks,
        modes=tuple(mode_summaries),
        cycles_found=len(cycles) if decision is None or decision.zeno is None else decision.zeno.cycles,
        cycles_capped=capped,
    )
    return CheckReport(
        automaton=a.name,
        model="system" if oracle.system is not None else "automaton",
        findings=tuple(findings),
        searched=summary,
        claims=claims,
        zeno=None if decision is None else decision.zeno,
        pairs=() if decision is None else decision.pairs,
        solver="" if decision is None else decision.solver,
    )


def _check_arguments(*, samples: Any, starts: Any, max_cycles: Any, seed: Any, tol: Any, method: Any) -> None:
    """Raise :class:`ExecutionError` on an invalid argument of :func:`check` (the others are checked where used)."""
    for name, value, low in (("samples", samples, 1), ("starts", starts, 0), ("max_cycles", max_cycles, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ExecutionError(f"check(): {name} = {value!r}; expected an int >= {low}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ExecutionError(f"check(): seed = {seed!r}; expected an int")
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol >= 0.0):
        raise ExecutionError(f"check(): tol = {tol!r}; expected a finite number >= 0")
    if method not in CHECK_METHODS:
        raise ExecutionError(f"check(): method = {method!r}; expected one of {list(CHECK_METHODS)}")


def _state_check_remarks(a: HybridAutomaton, boxes: dict[str, Box] | None, out_of_time: list[str],
                         budget_s: float | None) -> dict[str, str]:
    """How each state check of :func:`check` ran: skipped without a box, else ran (naming the modes not searched:
    no box, or the sampled search's time budget ran out)."""
    checks: dict[str, str] = {}
    if boxes is None:
        reason = "skipped: no box given; pass a Box (or a mapping mode -> Box) to search the state space"
        checks.update({c: reason for c in STATE_CHECKS})
    else:
        missing = [q for q in a.mode_names if q not in boxes]
        parts = ([f"modes {missing} not searched (no box)"] if missing else []) + (
            [f"modes {out_of_time} not searched (the sampled search's time budget of {budget_s:g} s ran out)"]
            if out_of_time else [])
        remark = "ran: " + "; ".join(parts) if parts else "ran"
        checks.update({c: remark for c in STATE_CHECKS})
        if not any(t.direction == 0 for t in a.transitions):
            checks["reset_retriggers"] = "ran: no level-triggered transition (crossing guards do not re-fire)"
    return checks


CHECK_METHODS = ("auto", "sampled", "smt")
"""How :func:`check` answers the state-space questions."""


def _sample_modes(oracle: Oracle, boxes: dict[str, Box] | None, modes: set[str], *, samples: int, starts: int,
                  seed: int, tol: float, undecidable: Mapping[str, str]) -> tuple[list[ModeSearch], list[Finding]]:
    """The sampled searches of the modes in ``modes`` (the others: decided, or not searched).

    A mode in ``undecidable`` (``method="smt"``: its functions are not symbolic) is neither decided nor
    sampled: its plain functions are evaluated at the box corners and centre only, so that one that
    raises or returns NaN or None is the same :class:`ExecutionError` as with the sampled search.
    """
    a = oracle.automaton
    if boxes is None:
        return [ModeSearch(mode=q, box=None, notes=("not searched: no box given",)) for q in a.mode_names], []
    checker = ModeChecker(oracle, samples=samples, starts=starts, tol=tol)
    rngs = np.random.default_rng(seed).spawn(len(a.mode_names))
    initial = a.initial_memory()
    summaries, findings = [], []
    for q, rng in zip(a.mode_names, rngs):
        if q not in boxes:
            summaries.append(ModeSearch(mode=q, box=None,
                                        notes=("not searched: the box mapping has no entry for this mode",)))
            continue
        if q in undecidable:
            before = oracle.calls
            _probe(oracle, SearchSpace.build(q, boxes[q], oracle.coords, initial))
            summaries.append(ModeSearch(mode=q, box=boxes[q].describe(), function_calls=oracle.calls - before,
                                        notes=(f"not decided ({undecidable[q]}) and not sampled (method smt); "
                                               "functions evaluated at the box corners and centre only",)))
            continue
        if q not in modes:
            summaries.append(ModeSearch(mode=q, box=boxes[q].describe(),
                                        notes=("decided by the SMT solver (not sampled)",)))
            continue
        space = SearchSpace.build(q, boxes[q], oracle.coords, initial)
        before = oracle.calls
        try:
            found, summary = checker.search_mode(space, rng)
        except SearchBudgetExceeded:
            summaries.append(ModeSearch(mode=q, box=boxes[q].describe(), function_calls=oracle.calls - before,
                                        notes=(f"{_OUT_OF_TIME} ran out after {oracle.calls - before} function "
                                               "calls in this mode: its checks are not covered (raise the budget, "
                                               "or write the model symbolically to have it decided)",)))
            continue
        findings += found
        summaries.append(summary)
    return summaries, findings


_OUT_OF_TIME = "not searched: the sampled search's time budget"
"""How a mode the sampled search had no time left for is noted (its checks are skipped)."""


def _probe(oracle: Oracle, space: SearchSpace) -> None:
    """Evaluate every function of ``space.mode`` at the corners and the centre of its box (raises as the search)."""
    q = space.mode
    centre = np.where(np.isnan(space.lower), 0.0, (space.lower + space.upper) / 2.0)
    corners = space.corners()
    centre[len(space.box.bounds):len(space.box.names)] = corners[0][len(space.box.bounds):len(space.box.names)]
    for p in (*corners, centre):
        x, m = space.split(p)
        v = oracle.signals(x, m)
        oracle.invariant(q, x, v, m)
        if oracle.system is not None:
            oracle.flow(q, x, m)
        for t in oracle.outgoing[q]:
            oracle.guard(t, x, v, m)
            oracle.jump(t, x, v, m)
