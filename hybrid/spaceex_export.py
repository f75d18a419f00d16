"""SpaceEx export: a symbolic HybridSystem as one flat SpaceEx component (XML) and its configuration (.cfg).

Written from the symbolic trees (:mod:`hybrid.symbolic`), not from samples, so
that :func:`hybrid.spaceex_import.import_spaceex` reads back the same
expressions.  What SpaceEx's language can say (docs/spaceex.md):

* arithmetic ``+ - * /`` (division by a constant), integer powers ``^``,
  ``sin cos exp sqrt log``; named parameters (:func:`hybrid.symbolic.param`)
  are written as their values;
* invariants and guards as conjunctions of comparisons: a level form
  ``min(g1, g2)`` is ``g1 >= 0 & g2 >= 0``, ``-abs(a - b)`` is ``a == b``; a
  guard that is a disjunction (``max`` at its top) becomes one transition per
  disjunct (same label), which SpaceEx reads as the same set of jumps;
* jump maps and memory resets as assignments ``x := e`` (a state the jump map
  keeps is not assigned); memory variables become SpaceEx variables with flow
  ``m' == 0``.

A transition whose guard, jump or reset holds ``ite``, ``select``, ``min``,
``max`` or ``abs`` is split into one SpaceEx transition per case
(:mod:`hybrid.spaceex_split`).  Not expressible, and refused with the
function and the place named: ``atan2``; ``abs``, ``min``/``max``, ``ite``,
``select`` in a flow or an invariant; time ``t``; a disjunction inside an
invariant; plain Python callables.  A crossing-triggered transition (``direction = ±1``) is written as
its level guard and priorities are dropped; a comment in the XML says so
(SpaceEx has neither).  Names that are not SpaceEx identifiers (``a.b``,
``m|n``) are written with ``_`` for the other characters, listed in a comment.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from typing import Any

from .model import Conjunction, HybridAutomaton
from .spaceex_inputs import SpaceExInput
from .spaceex_split import MAX_CASES, Split, case_of, negate, replace, static_truth
from .spaceex_syntax import SpaceExError
from .symbolic import (
    Apply,
    Compare,
    Condition,
    Const,
    Coordinate,
    Expr,
    Ite,
    Logic,
    MemoryRef,
    Param,
    Select,
    SymbolicReset,
    SymbolicVector,
    substitute,
)
from .system import HybridSystem

__all__ = ["to_spaceex", "spaceex_cfg", "spaceex_names", "SPACEEX_NS", "model_to_spaceex"]

SPACEEX_NS = "http://www-verimag.imag.fr/xml-namespaces/sspaceex"
"""XML namespace of SpaceEx model files."""

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_OPS = {"add": "+", "sub": "-", "mul": "*", "div": "/"}
_FUNCS = ("sin", "cos", "exp", "sqrt", "log")
_CMP = {">=", ">", "<=", "<", "=="}


def _identifiers(names: Sequence[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    used: set[str] = set(n for n in names if _IDENT.match(n))
    for n in names:
        if _IDENT.match(n):
            out[n] = n
            continue
        base = re.sub(r"[^A-Za-z0-9_]", "_", n)
        base = base if _IDENT.match(base) else f"_{base}"
        candidate, k = base, 1
        while candidate in used:
            k += 1
            candidate = f"{base}_{k}"
        used.add(candidate)
        out[n] = candidate
    return out


class _Writer:
    def __init__(self, system: HybridSystem, names: dict[str, str], inputs: Mapping[str, str] | None = None) -> None:
        self.system = system
        self.names = names
        self.inputs = dict(inputs or {})  # placeholder Param name -> the input's SpaceEx name
        self.split = False  # inside a transition: a piecewise node raises Split (the transition is split by cases)

    def number(self, value: float, where: str) -> str:
        if not math.isfinite(value):
            raise SpaceExError(where, value, "a finite number", "SpaceEx has no infinities")
        text = repr(float(value))
        return f"({text})" if value < 0 else text

    def expr(self, node: Any, where: str) -> str:
        if isinstance(node, Const):
            return self.number(node.value, where)
        if isinstance(node, (Coordinate, MemoryRef)):
            return self.names[node.name]
        if isinstance(node, Param):
            return self.inputs[node.name] if node.name in self.inputs else self.number(node.value, where)
        if isinstance(node, Apply):
            if node.op in _OPS:
                a, b = node.args
                return f"({self.expr(a, where)} {_OPS[node.op]} {self.expr(b, where)})"
            if node.op == "neg":
                return f"(-{self.expr(node.args[0], where)})"
            if node.op == "pow":
                return f"({self.expr(node.args[0], where)}^{int(node.args[1].value)})"
            if node.op in _FUNCS:
                return f"{node.op}({self.expr(node.args[0], where)})"
            if self.split and node.op in ("min", "max", "abs"):
                raise Split(node)
            raise SpaceExError(where, node.op, f"a function SpaceEx expresses (+ - * / ^ {' '.join(_FUNCS)})",
                               f"{node.op}() has no SpaceEx form: split the mode where it switches, or keep the "
                               "model in visnav")
        if self.split and isinstance(node, (Ite, Select)):
            raise Split(node)
        raise SpaceExError(where, type(node).__name__, "an arithmetic expression of states, numbers and parameters",
                           "time t, ite() and select() have no SpaceEx form in a flat component")

    def constraints(self, node: Any, where: str) -> list[str]:
        """A level form (``>= 0``) or condition as a list of conjuncts (no disjunction)."""
        if isinstance(node, Conjunction):
            return [c for term in node.terms for c in self.constraints(term, where)]
        if isinstance(node, Compare):
            if node.op not in _CMP:
                raise SpaceExError(where, node.op, "a comparison <, <=, >, >=, ==", "write != as two transitions")
            return [f"{self.expr(node.left, where)} {node.op} {self.expr(node.right, where)}"]
        if isinstance(node, Logic):
            if node.op == "and":
                return [c for a in node.args for c in self.constraints(a, where)]
            raise SpaceExError(where, node.op, "a conjunction", "SpaceEx invariants and guards are conjunctions")
        if isinstance(node, Apply) and node.op == "min":
            return [c for a in node.args for c in self.constraints(a, where)]
        if isinstance(node, Apply) and node.op == "max":
            raise SpaceExError(where, "a disjunction (max)", "a conjunction", "split the mode or the transition")
        if (isinstance(node, Apply) and node.op == "neg" and isinstance(node.args[0], Apply)
                and node.args[0].op == "abs"):  # the level form -|a - b| of a == b
            inner = node.args[0].args[0]
            if isinstance(inner, Apply) and inner.op == "sub":
                return [f"{self.expr(inner.args[0], where)} == {self.expr(inner.args[1], where)}"]
            return [f"{self.expr(inner, where)} == 0"]
        if isinstance(node, Apply) and node.op == "sub":
            a, b = node.args
            return [f"{self.expr(a, where)} >= {self.expr(b, where)}"]
        if isinstance(node, Expr):
            return [f"{self.expr(node, where)} >= 0"]
        raise SpaceExError(where, type(node).__name__, "a symbolic guard or invariant (hybrid.symbolic)",
                           "write the function with hybrid.symbolic so that it can be exported")

    def guards(self, node: Any, where: str) -> list[list[str]]:
        """Disjuncts of a guard (a ``max`` or ``or`` at the top), each a list of conjuncts."""
        if isinstance(node, Apply) and node.op == "max":
            return [self.constraints(a, where) for a in node.args]
        if isinstance(node, Logic) and node.op == "or":
            return [self.constraints(a, where) for a in node.args]
        return [self.constraints(node, where)]


def _signals(system: HybridSystem) -> dict[str, Expr]:
    """Automaton variable -> its expression of the state (the output map; the identity when absent)."""
    a = system.automaton
    states = {s: Coordinate(s, i) for i, s in enumerate(system.state_names)}
    if system.output is None:
        return states
    if not isinstance(system.output, SymbolicVector):
        raise SpaceExError(f"system {a.name!r}: output", "a Python function", "a symbolic output_map(...)",
                           "write the output with hybrid.symbolic.output_map")
    return {v: substitute(e, coordinates=states) for v, e in zip(a.variables, system.output.components)}


def _check_names(system: HybridSystem) -> None:
    a = system.automaton
    labels = {t.name for t in a.transitions}
    clash = sorted(labels & (set(system.state_names) | {m.name for m in a.memory}))
    if clash:
        raise SpaceExError(f"system {a.name!r}", f"name(s) {clash} used for a transition and a variable",
                           "distinct names (SpaceEx labels and variables share one namespace)",
                           "rename the transitions")


def spaceex_names(system: HybridSystem) -> dict[str, str]:
    """The SpaceEx identifier :func:`to_spaceex` writes for each state, memory variable, mode and transition.

    A name that is already an identifier is kept; other characters become ``_`` (with a suffix ``_k`` when
    that name is taken).
    """
    a = system.automaton
    return _identifiers([*system.state_names, *(m.name for m in a.memory), *a.mode_names,
                         *(t.name for t in a.transitions)])


def to_spaceex(system: HybridSystem, *, component: str | None = None, inputs: Sequence[SpaceExInput] = ()) -> str:
    """The SpaceEx XML of a symbolic system: one component, a location per mode, a transition per jump.

    Parameters
    ----------
    system : HybridSystem
        Flows, jump maps, invariants, guards and resets written with :mod:`hybrid.symbolic`.
    component : str or None
        The component id (default: the automaton's name, made an identifier).
    inputs : sequence of SpaceExInput
        Non-deterministic inputs, read by the flows through their placeholders ``Param(input.symbol)``: each is
        written as an uncontrolled variable without a flow, bounded in every location's invariant
        (:func:`model_to_spaceex` writes an imported model so).

    Returns
    -------
    str
        The XML document (UTF-8 declaration, ending with a newline).

    Raises
    ------
    SpaceExError
        Naming the mode or transition and the function SpaceEx cannot express (see the module docstring).
    """
    if not isinstance(system, HybridSystem):
        raise SpaceExError("to_spaceex: system", system, "a hybrid.HybridSystem", "pass the system")
    _check_names(system)
    a: HybridAutomaton = system.automaton
    memory = [m.name for m in a.memory]
    names = _identifiers([*system.state_names, *(m.name for m in a.memory), *a.mode_names,
                          *(t.name for t in a.transitions), *(i.name for i in inputs)])
    w = _Writer(system, names, {i.symbol: names[i.name] for i in inputs})
    signals = _signals(system)
    root = ET.Element("sspaceex", {"xmlns": SPACEEX_NS, "version": "0.2", "math": "SpaceEx"})
    renamed = {n: v for n, v in names.items() if n != v}
    note = f"exported by visnav (hybrid.spaceex_export) from system {a.name!r}"
    if renamed:
        note += "; renamed to SpaceEx identifiers: " + ", ".join(f"{k} -> {v}" for k, v in renamed.items())
    root.append(ET.Comment(" " + note.replace("--", "- -") + " "))
    comp = ET.SubElement(root, "component", {"id": component or _identifiers([a.name])[a.name]})
    for s in (*system.state_names, *memory):
        ET.SubElement(comp, "param", {"name": names[s], "type": "real", "local": "false", "d1": "1", "d2": "1",
                                      "dynamics": "any"})
    for i in inputs:
        ET.SubElement(comp, "param", {"name": names[i.name], "type": "real", "local": "false", "d1": "1", "d2": "1",
                                      "dynamics": "any", "controlled": "false"})
    for t in a.transitions:
        ET.SubElement(comp, "param", {"name": names[t.name], "type": "label", "local": "false"})
    ids = {m: str(i + 1) for i, m in enumerate(a.mode_names)}
    bounds = [f"{w.number(i.low, 'input')} <= {names[i.name]} & {names[i.name]} <= {w.number(i.high, 'input')}"
              for i in inputs]
    for mode in a.modes:
        _location(comp, w, system, mode, ids[mode.name], signals, memory, bounds)
    for t in a.transitions:
        _transition(comp, w, system, t, ids, signals)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def model_to_spaceex(model: Any, *, component: str | None = None) -> str:
    """The SpaceEx XML of an imported :class:`~hybrid.spaceex_import.SpaceExModel`, its inputs written as inputs.

    Without inputs this is ``to_spaceex(model.system)``; with inputs the flows read them by name (from
    ``model.input_flows``) and every location bounds them, as the imported file did.
    """
    system = model.system
    if model.inputs:
        system = HybridSystem(automaton=system.automaton, state_names=system.state_names, flows=model.input_flows,
                              jumps=system.jumps, output=system.output)
    return to_spaceex(system, component=component, inputs=model.inputs)


def _on_state(node: Any, signals: Mapping[str, Expr]) -> Any:
    if isinstance(node, Conjunction):
        return Conjunction(tuple(_on_state(t, signals) for t in node.terms))
    if isinstance(node, (Expr, Condition)):
        return substitute(node, coordinates=dict(signals))
    return node


def _location(comp: ET.Element, w: _Writer, system: HybridSystem, mode: Any, lid: str,
              signals: Mapping[str, Expr], memory: Sequence[str], bounds: Sequence[str] = ()) -> None:
    where = f"system {system.automaton.name!r}: mode {mode.name!r}"
    loc = ET.SubElement(comp, "location", {"id": lid, "name": w.names[mode.name]})
    invariant = [] if mode.invariant is None else w.constraints(_on_state(mode.invariant, signals),
                                                                 f"{where}: invariant")
    if invariant or bounds:
        ET.SubElement(loc, "invariant").text = " & ".join([*invariant, *bounds])
    flow = system.flows[mode.name]
    if not isinstance(flow, SymbolicVector):
        raise SpaceExError(f"{where}: flow", "a Python function", "a symbolic flow_map(...)",
                           "write the flow with hybrid.symbolic.flow_map")
    parts = [f"{w.names[s]}' == {w.expr(e, f'{where}: flow of {s}')}"
             for s, e in zip(system.state_names, flow.components)]
    parts += [f"{w.names[m]}' == 0" for m in memory]
    ET.SubElement(loc, "flow").text = " & ".join(parts)


def _parts(system: HybridSystem, t: Any, signals: Mapping[str, Expr],
           where: str) -> tuple[Any, dict[str, Expr], dict[str, Expr]]:
    """The guard, the jump's assignments (states it changes) and the reset's, all over the state."""
    jumps: dict[str, Expr] = {}
    jump = system.jumps.get(t.name)
    if jump is not None:
        if not isinstance(jump, SymbolicVector):
            raise SpaceExError(f"{where}: jump map", "a Python function", "a symbolic jump_map(...)",
                               "write the jump map with hybrid.symbolic.jump_map")
        jumps = {s: e for s, e in zip(system.state_names, jump.components)
                 if not (isinstance(e, Coordinate) and e.name == s)}
    resets: dict[str, Expr] = {}
    if t.reset is not None:
        if not isinstance(t.reset, SymbolicReset):
            raise SpaceExError(f"{where}: reset", "a Python function", "a symbolic reset(...)",
                               "write the reset with hybrid.symbolic.reset")
        resets = {m: _on_state(e, signals) for m, e in t.reset.assignments.items()}
    return _on_state(t.guard, signals), jumps, resets


def _alternatives(c: Condition) -> list[list[Compare]]:
    """``c`` in disjunctive normal form over comparisons without ``!=``."""
    if isinstance(c, Compare):
        if c.op == "!=":
            return [[Compare("<", c.left, c.right)], [Compare(">", c.left, c.right)]]
        return [[c]]
    if c.op == "not":
        return _alternatives(negate(c.args[0]))
    if c.op == "or":
        return [alt for a in c.args for alt in _alternatives(a)]
    out: list[list[Compare]] = [[]]
    for a in c.args:
        out = [x + y for x in out for y in _alternatives(a)]
    return out


def _rows(w: _Writer, extra: tuple[Condition, ...], guard: Any, jumps: Mapping[str, Expr],
          resets: Mapping[str, Expr], where: str) -> list[tuple[list[str], list[str]]]:
    """``(guard conjuncts, assignments)`` of each SpaceEx transition (raises :class:`Split` at a piecewise node)."""
    assignments = [f"{w.names[s]} := {w.expr(e, f'{where}: jump of {s}')}" for s, e in jumps.items()]
    assignments += [f"{w.names[m]} := {w.expr(e, f'{where}: reset of {m}')}" for m, e in resets.items()]
    cases: list[list[Compare]] = [[]]
    for c in extra:
        cases = [x + y for x in cases for y in _alternatives(c)]
    rows = []
    for disjunct in w.guards(guard, f"{where}: guard"):
        for case in cases:
            conjuncts = disjunct + [text for c in case for text in w.constraints(c, f"{where}: case")]
            rows.append(([c for c in conjuncts if c != "1.0 >= 0"], assignments))
    return rows


def _transition(comp: ET.Element, w: _Writer, system: HybridSystem, t: Any, ids: Mapping[str, str],
                signals: Mapping[str, Expr]) -> None:
    where = f"system {system.automaton.name!r}: transition {t.name!r}"
    guard, jumps, resets = _parts(system, t, signals, where)
    notes = []
    if t.direction != 0:
        notes.append(f"crossing-triggered (direction {t.direction:+d}) in visnav; SpaceEx has level guards only")
    if t.priority != 0 or len(system.automaton.outgoing(t.source)) > 1:
        notes.append(f"priority {t.priority} dropped: SpaceEx transitions are unprioritised")
    work: list[tuple[tuple[Condition, ...], Any, dict[str, Expr], dict[str, Expr]]] = [((), guard, jumps, resets)]
    rows: list[tuple[list[str], list[str]]] = []
    w.split = True
    try:
        while work:
            extra, g, js, rs = work.pop(0)
            try:
                rows += _rows(w, extra, g, js, rs, where)
            except Split as split:
                cond, then, otherwise = case_of(split.node)
                truth = static_truth(cond)
                cases = [(cond, then), (negate(cond), otherwise)]
                if truth is not None:  # x < inf: one branch only, no condition to write
                    cases = [(None, then if truth else otherwise)]
                for c, branch in cases:
                    conditions = tuple(replace(e, split.node, branch) for e in extra)
                    if c is not None:
                        conditions += (replace(c, split.node, branch),)
                    work.append((conditions, replace(g, split.node, branch),
                                 {k: replace(v, split.node, branch) for k, v in js.items()},
                                 {k: replace(v, split.node, branch) for k, v in rs.items()}))
                if len(work) + len(rows) > MAX_CASES:
                    raise SpaceExError(where, f"more than {MAX_CASES} cases", f"at most {MAX_CASES} case splits",
                                       "simplify the piecewise functions of the transition") from None
    finally:
        w.split = False
    if len(rows) > 1:
        notes.append(f"split into {len(rows)} SpaceEx transitions (disjunctions and piecewise functions by cases)")
    for conjuncts, assignments in rows:
        if notes:
            comp.append(ET.Comment(f" transition {t.name}: " + "; ".join(notes) + " "))
        edge = ET.SubElement(comp, "transition", {"source": ids[t.source], "target": ids[t.target]})
        ET.SubElement(edge, "label").text = w.names[t.name]
        if conjuncts:
            ET.SubElement(edge, "guard").text = " & ".join(conjuncts)
        if assignments:
            ET.SubElement(edge, "assignment").text = " & ".join(assignments)


def spaceex_cfg(system: HybridSystem, initial: Mapping[str, tuple[float, float]], *, horizon: float,
                initial_mode: str | None = None, forbidden: str | None = None, component: str | None = None) -> str:
    """The ``.cfg`` of an exported system: system, initial box and location, forbidden set, horizon.

    Parameters
    ----------
    initial : Mapping[str, tuple[float, float]]
        ``state -> (low, high)`` for every state (``low == high`` writes ``x == value``).
    horizon : float
        ``time-horizon`` [s], finite and > 0, or ``math.inf`` (unbounded: written as SpaceEx's ``time-horizon = -1``,
        without a ``sampling-time``).
    initial_mode : str or None
        The initial location (default: the automaton's).
    forbidden : str or None
        The forbidden set in SpaceEx syntax (``"x >= 10"``), or none.

    Raises
    ------
    SpaceExError
        A missing or unknown state, an empty range, a bad horizon or mode.
    """
    a = system.automaton
    names = _identifiers([*system.state_names, *a.mode_names])
    unknown = sorted(set(initial) - set(system.state_names))
    missing = [s for s in system.state_names if s not in initial]
    if unknown or missing:
        raise SpaceExError("spaceex_cfg: initial", dict(initial), f"one range per state {list(system.state_names)}",
                           f"unknown: {unknown}, missing: {missing}")
    if not (isinstance(horizon, (int, float)) and not isinstance(horizon, bool) and horizon > 0
            and (math.isfinite(horizon) or horizon == math.inf)):
        raise SpaceExError("spaceex_cfg: horizon", horizon, "a finite time > 0 [s], or math.inf (unbounded)",
                           "give horizon=10.0, or horizon=math.inf for time-horizon = -1")
    mode = initial_mode or a.initial_mode or a.mode_names[0]
    if mode not in a.mode_names:
        raise SpaceExError("spaceex_cfg: initial_mode", mode, f"a mode of {list(a.mode_names)}", "name a mode")
    parts = []
    for s in system.state_names:
        lo, hi = (float(v) for v in initial[s])
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise SpaceExError(f"spaceex_cfg: initial[{s!r}]", (lo, hi), "a finite range low <= high", "fix it")
        parts.append(f"{names[s]} == {lo!r}" if lo == hi else f"{lo!r} <= {names[s]} & {names[s]} <= {hi!r}")
    parts.append(f"loc({component or _identifiers([a.name])[a.name]}) == {names[mode]}")
    lines = [f"# exported by visnav (hybrid.spaceex_export) for system {a.name!r}",
             f'system = "{component or _identifiers([a.name])[a.name]}"',
             f'initially = "{" & ".join(parts)}"']
    if forbidden:
        lines.append(f'forbidden = "{forbidden}"')
    bounded = math.isfinite(horizon)
    lines += [f"time-horizon = {float(horizon)!r}" if bounded else "time-horizon = -1", 'scenario = "supp"',
              'directions = "oct"', *(["sampling-time = " + repr(float(horizon) / 100.0)] if bounded else []),
              f'output-variables = "{", ".join(names[s] for s in system.state_names)}"', "iter-max = -1"]
    return "\n".join(lines) + "\n"
