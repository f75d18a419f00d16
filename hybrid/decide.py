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
from collections.abc import Mapping, Sequence
from types import MappingProxyType

import networkx as nx

from .findings import KIND_SEVERITY, Finding, Witness, checked_boxes, format_g
from .errors import ModelDefinitionError
from .graph import mode_graph
from .model import HybridAutomaton, Transition
from .region import Box
from .smt import fresh_context, solver_version
from .symbolic import Coordinate, free_symbols
from .system import HybridSystem
from .decide_results import CLAIM_STATUSES, Claim, CycleVerdict, Decision, PairVerdict, ParameterSpace, ZenoSummary
from .decide_questions import BISECTIONS, DWELL_REL, HULL_ROUNDS, RECHECK_TOL, RETRIGGER_PROBE, Questions, SymbolicView

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

DEFAULT_TIMEOUT_S = 5.0
"""Timeout of one solver call [s]."""


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
    def __init__(self, qs: Questions) -> None:
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
    view = SymbolicView(model)
    validate_options(view.coords, rates, timeout_s)
    boxes = checked_boxes(view.oracle, box)
    if boxes is None:
        raise ModelDefinitionError("decide(): box = None; give the Box (or a mapping mode -> Box) to decide over")
    with fresh_context():
        qs = Questions(view, boxes, rates=rates, timeout_s=float(timeout_s), tol=float(tol),
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
    view = SymbolicView(model)
    validate_options(view.coords, None, timeout_s)
    boxes = checked_boxes(view.oracle, box)
    if boxes is None:
        raise ModelDefinitionError("exclusive_for_all(): box = None; give the Box to decide over")
    with fresh_context():
        return _parametric_pairs(view, boxes, parameters, modes, float(timeout_s), float(tol))


def _parametric_pairs(view: SymbolicView, boxes: Mapping[str, Box], parameters: ParameterSpace,
                      modes: Sequence[str] | None, timeout_s: float, tol: float) -> tuple[PairVerdict, ...]:
    qs = Questions(view, boxes, rates=None, timeout_s=timeout_s, tol=tol, max_cycles=0, parameters=parameters)
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


def _assemble(qs: Questions, zeno: bool) -> Decision:
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


def _overlap_finding(qs: Questions, p: PairVerdict, kind: str) -> Finding:
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


def _claims(qs: Questions, status: Mapping[str, list[str]], summary: ZenoSummary | None,
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
