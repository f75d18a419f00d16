"""Exports of hybrid automata and systems: Graphviz DOT, JSON and SpaceEx XML.

* :func:`to_dot` draws the mode graph (invariants on the nodes; priority,
  guard, crossing direction and resets on the edges).
* :func:`to_json` gives a deterministic, JSON-ready description of a model
  and, for a :class:`~hybrid.system.HybridSystem` with a declared
  :class:`~hybrid.region.Box`, the affine coefficients of every flow,
  invariant term, guard term, jump map and memory reset (or why there are none).
* :func:`to_spacex` and :func:`spacex_config` write a SpaceEx model and its
  configuration.  A system written entirely with :mod:`hybrid.symbolic` is
  exported from its expressions by :func:`hybrid.spaceex_export.to_spaceex`
  (the box is then not needed; non-expressible functions are named in the
  error); a system with plain Python functions is exported when it is affine
  on the box, from sampled affine forms.

Which functions are affine, and their coefficients, is decided by
:mod:`hybrid.affine` (:func:`~hybrid.affine.system_affinity`); this module
only writes the results.  Memory variables become SpaceEx variables with
flow ``m' == 0.0`` and the identity assignment unless a transition writes
them; a memory variable written by a reset must have an interval in
``Box.memory``.

Examples
--------
>>> from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition, all_of
>>> ball = HybridAutomaton(
...     name="ball", variables=("h", "v"),
...     modes=(Mode(name="fall", invariant=lambda v, m: v[0], invariant_text="h >= 0"),),
...     transitions=(Transition(name="bounce", source="fall", target="fall",
...                             guard=all_of(lambda v, m: -v[0], lambda v, m: -v[1]),
...                             guard_text="h <= 0 and v <= 0"),))
>>> system = HybridSystem(automaton=ball, state_names=("h", "v"),
...     flows={"fall": lambda t, x, m: (x[1], -9.81)},
...     jumps={"bounce": lambda x, m: (x[0], -0.8 * x[1])})
>>> box = Box(bounds={"h": (0.0, 10.0), "v": (-20.0, 20.0)})
>>> to_json(system, box)["modes"][0]["affine"]["flow"]["matrix"]
[[0.0, 1.0], [0.0, 0.0]]
>>> xml = to_spacex(system, box)
>>> "h' == v &amp; v' == -9.81" in xml
True
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from decimal import Decimal
from typing import Any

from .affine import (
    AffineForm,
    AffineResult,
    ModeAffinity,
    NotAffine,
    NotAffineError,
    SystemAffinity,
    TransitionAffinity,
    system_affinity,
)
from .errors import ModelDefinitionError
from .graph import mode_graph
from .jsonable import to_jsonable
from .model import HybridAutomaton, Mode, Transition
from .region import Box
from .system import HybridSystem

__all__ = [
    "SPACEEX_NAMESPACE",
    "to_dot",
    "to_json",
    "to_spacex",
    "spacex_config",
]

SPACEEX_NAMESPACE = "http://www-verimag.imag.fr/xml-namespaces/sspaceex"
"""XML namespace of SpaceEx model files."""

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


# ---------------------------------------------------------------------------- DOT


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


_ARROWS = {1: " ↑", -1: " ↓", 0: ""}


def to_dot(model: HybridAutomaton | HybridSystem) -> str:
    """Graphviz DOT text of the mode graph.

    Nodes carry the mode name and invariant text (description as tooltip);
    edges carry ``[priority] guard`` followed by ``↑`` / ``↓`` for a rising /
    falling crossing, then ``/`` and the reset text (the written memory when
    the reset has no text) and, for a system, ``x⁺ = jump map`` when the
    transition has one.  A point node ``__start__`` points at the initial mode.
    Every identifier is quoted; output order is declaration order.

    Parameters
    ----------
    model : HybridAutomaton or HybridSystem

    Returns
    -------
    str
        DOT text ending with a newline.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, Mode, Transition
    >>> a = HybridAutomaton(name="a", modes=(Mode(name="x"), Mode(name="y")), variables=("s",),
    ...     transitions=(Transition(name="go", source="x", target="y", guard=lambda v, m: v[0],
    ...                             guard_text="s >= 0", direction=+1),))
    >>> print(to_dot(a).splitlines()[-2])
      "x" -> "y" [label="[0] s >= 0 ↑"];
    """
    automaton, jumps = _automaton(model, "to_dot")
    graph = mode_graph(automaton)
    start = "__start__"
    while start in automaton.mode_names:
        start += "_"
    lines = [f"digraph {_quote(automaton.name)} {{", "  rankdir=LR;", "  node [shape=box, style=rounded];"]
    lines.append(f'  {_quote(start)} [shape=point, label=""];')
    lines.append(f"  {_quote(start)} -> {_quote(automaton.initial_mode)};")
    for name, data in graph.nodes(data=True):
        label = name if not data["invariant"] else f"{name}\ninv: {data['invariant']}"
        attributes = f"label={_quote(label)}"
        if data["description"]:
            attributes += f", tooltip={_quote(data['description'])}"
        lines.append(f"  {_quote(name)} [{attributes}];")
    by_name = {t.name: t for t in automaton.transitions}
    for source, target, key, data in graph.edges(keys=True, data=True):
        label = f"[{data['priority']}] {data['guard'] or key}{_ARROWS[data['direction']]}"
        parts = []
        if data["reset"]:
            parts.append(data["reset"])
        elif by_name[key].reset is not None:
            parts.append(f"reset {', '.join(by_name[key].writes) or 'memory'}")
        if key in jumps:
            parts.append("x⁺ = jump map")
        if parts:
            label += " / " + "; ".join(parts)
        lines.append(f"  {_quote(source)} -> {_quote(target)} [label={_quote(label)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _automaton(model: object, what: str) -> tuple[HybridAutomaton, Mapping[str, Any]]:
    if isinstance(model, HybridSystem):
        return model.automaton, model.jumps
    if isinstance(model, HybridAutomaton):
        return model, {}
    raise ModelDefinitionError(f"{what}: model = {model!r}; expected a HybridAutomaton or a HybridSystem")


# ---------------------------------------------------------------------------- JSON


def _labels_json(labels: Mapping[str, Any]) -> dict[str, Any]:
    """Labels are arbitrary user data: sorted keys, non-finite floats as strings, other objects by ``repr``."""
    return to_jsonable(dict(labels), nonfinite="string", sort_mappings=True, fallback="repr")


def _form_json(result: AffineResult | None) -> dict[str, Any] | None:
    return result.as_dict() if isinstance(result, AffineForm) else None


def _reasons_json(results: Sequence[tuple[str, AffineResult | None]]) -> dict[str, Any]:
    """``{key: NotAffine.as_dict()}`` of the results that are not affine."""
    return {key: r.as_dict() for key, r in results if isinstance(r, NotAffine)}


def _mode_affine_json(result: ModeAffinity) -> dict[str, Any]:
    reasons = [("flow", result.flow)] + [(f"invariant[{k}]", r) for k, r in enumerate(result.invariant)]
    return {
        "flow": _form_json(result.flow),
        "invariant": [_form_json(r) for r in result.invariant],
        "not_affine": _reasons_json(reasons),
    }


def _transition_affine_json(result: TransitionAffinity) -> dict[str, Any]:
    reasons = [(f"guard[{k}]", r) for k, r in enumerate(result.guard)]
    reasons += [("jump_map", result.jump_map), ("memory_reset", result.memory_reset)]
    return {
        "guard": [_form_json(r) for r in result.guard],
        "jump_map": _form_json(result.jump_map),
        "memory_reset": _form_json(result.memory_reset),
        "not_affine": _reasons_json(reasons),
    }


def _mode_json(mode: Mode, affinity: SystemAffinity | None) -> dict[str, Any]:
    return {
        "name": mode.name,
        "description": mode.description,
        "invariant_text": mode.invariant_text,
        "has_invariant": mode.invariant is not None,
        "labels": _labels_json(mode.labels),
        "affine": None if affinity is None else _mode_affine_json(affinity.modes[mode.name]),
    }


def _transition_json(t: Transition, jumps: Mapping[str, Any], affinity: SystemAffinity | None) -> dict[str, Any]:
    return {
        "name": t.name,
        "source": t.source,
        "target": t.target,
        "guard_text": t.guard_text,
        "reset_text": t.reset_text,
        "direction": t.direction,
        "priority": t.priority,
        "writes": list(t.writes),
        "reads": list(t.reads),
        "has_reset": t.reset is not None,
        "has_jump_map": t.name in jumps,
        "affine": None if affinity is None else _transition_affine_json(affinity.transitions[t.name]),
    }


def _affinity_json(affinity: SystemAffinity, box: Box, tol: float, seed: int) -> dict[str, Any]:
    return {
        "box": box.as_dict(),
        "coordinates": list(affinity.coordinates.names),
        "fixed_memory": dict(affinity.coordinates.fixed_memory),
        "tol": float(tol),
        "seed": seed,
    }


def to_json(
    model: HybridAutomaton | HybridSystem, box: Box | None = None, *, tol: float = 1e-9, seed: int = 0
) -> dict[str, Any]:
    """A JSON-ready, deterministic description of an automaton or a system.

    Parameters
    ----------
    model : HybridAutomaton or HybridSystem
    box : Box or None
        With a system, the region on which to test affinity; every mode and
        transition then gets an ``"affine"`` entry (see below).  ``None``
        leaves the entries ``null``.
    tol, seed
        Passed to :func:`~hybrid.affine.affine_form`.

    Returns
    -------
    dict
        Keys ``kind``, ``name``, ``description``, ``variables``,
        ``state_names`` (``null`` for an automaton), ``memory``,
        ``initial_mode``, ``modes``, ``transitions`` and ``affinity``
        (``null`` without a box, else the box, the coordinates of the
        coefficient columns, the fixed memory values and the tolerance).
        A mode's ``"affine"`` is ``{"flow": form, "invariant": [form, ...],
        "not_affine": {...}}`` and a transition's is ``{"guard": [form, ...],
        "jump_map": form, "memory_reset": form, "not_affine": {...}}``; a form
        is ``{"names", "matrix", "offset", "max_residual", "points_checked"}``
        or ``null`` when the function is not affine, and then ``not_affine``
        holds the reason and the witness under the same key (``"flow"``,
        ``"invariant[k]"``, ``"guard[k]"``, ``"jump_map"``, ``"memory_reset"``).
        Rows of a flow or jump map follow ``state_names``, rows of a memory
        reset follow the transition's ``writes``.  ``memory_reset`` is
        ``null`` without an entry in ``not_affine`` when nothing is written.

    Raises
    ------
    ModelDefinitionError
        A box with an automaton, a box that does not declare the states, or a
        written memory variable without a ``Box.memory`` interval.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, Mode
    >>> to_json(HybridAutomaton(name="a", modes=(Mode(name="x"),), transitions=(), variables=()))["modes"]
    [{'name': 'x', 'description': '', 'invariant_text': '', 'has_invariant': False, 'labels': {}, 'affine': None}]
    """
    automaton, jumps = _automaton(model, "to_json")
    system = model if isinstance(model, HybridSystem) else None
    affinity = None
    if box is not None:
        if system is None:
            raise ModelDefinitionError(
                f"to_json: a box was given for automaton {automaton.name!r}, which has no flows; "
                "pass the HybridSystem to get affine coefficients"
            )
        affinity = system_affinity(system, box, tol=tol, seed=seed, what=f"JSON export of system {system.name!r}")
    return {
        "kind": "hybrid_system" if system is not None else "hybrid_automaton",
        "name": automaton.name,
        "description": automaton.description,
        "variables": list(automaton.variables),
        "state_names": list(system.state_names) if system is not None else None,
        "memory": [
            {"name": m.name, "initial": float(m.initial), "description": m.description} for m in automaton.memory
        ],
        "initial_mode": automaton.initial_mode,
        "modes": [_mode_json(mode, affinity) for mode in automaton.modes],
        "transitions": [_transition_json(t, jumps, affinity) for t in automaton.transitions],
        "affinity": None if affinity is None or box is None else _affinity_json(affinity, box, tol, seed),
    }


# ---------------------------------------------------------------------------- SpaceEx


def _num(x: float) -> str:
    """Shortest round-trip decimal of ``x`` (its ``repr``) written without exponent."""
    x = float(x)
    text = repr(0.0 if x == 0.0 else x)
    if "e" in text or "E" in text:
        text = format(Decimal(text), "f")
    return text


def _linear(names: Sequence[str], coefficients: Sequence[float], constant: float) -> str:
    parts: list[tuple[bool, str]] = []
    for name, a in zip(names, coefficients):
        if a == 0.0:
            continue
        magnitude = abs(a)
        parts.append((a < 0, name if magnitude == 1.0 else f"{_num(magnitude)}*{name}"))
    if constant != 0.0 or not parts:
        parts.append((constant < 0, _num(abs(constant))))
    text = ("-" if parts[0][0] else "") + parts[0][1]
    for negative, body in parts[1:]:
        text += (" - " if negative else " + ") + body
    return text


def _inequality(names: Sequence[str], coefficients: Sequence[float], constant: float) -> str | None:
    """``a·z + b >= 0`` as text; ``None`` when it always holds."""
    nonzero = [a for a in coefficients if a != 0.0]
    if not nonzero:
        return None if constant >= 0.0 else f"{_num(constant)} >= 0"
    if nonzero[0] < 0:
        return f"{_linear(names, [-a for a in coefficients], 0.0)} <= {_num(constant)}"
    return f"{_linear(names, coefficients, 0.0)} >= {_num(-constant)}"


def _ascii_box(box: Box) -> str:
    parts = [f"{n} in [{_num(lo)}, {_num(hi)}]" for n, (lo, hi) in box.bounds.items()]
    parts += [f"{n} in {{{', '.join(_num(c) for c in values)}}}" for n, values in box.choices.items()]
    parts += [f"memory {n} in [{_num(lo)}, {_num(hi)}]" for n, (lo, hi) in box.memory.items()]
    return ", ".join(parts)


def _comment(text: str) -> ET.Element:
    return ET.Comment(" " + text.replace("--", "- -") + " ")


def _require_identifiers(system: HybridSystem, what: str) -> None:
    a = system.automaton
    for kind, names in (
        ("system name", (a.name,)),
        ("state", system.state_names),
        ("memory variable", tuple(m.name for m in a.memory)),
        ("mode", a.mode_names),
        ("transition", tuple(t.name for t in a.transitions)),
    ):
        bad = [n for n in names if not _IDENTIFIER.match(n)]
        if bad:
            raise ModelDefinitionError(
                f"{what}: {kind} name(s) {bad} are not SpaceEx identifiers; "
                "use letters, digits and underscores, not starting with a digit"
            )


def to_spacex(system: HybridSystem, box: Box, *, tol: float = 1e-9, seed: int = 0) -> str:
    """SpaceEx XML model of a system that is affine on ``box``.

    One ``<component>`` named after the system holds a ``real`` parameter per
    state and per memory variable, a ``label`` parameter per transition, a
    ``<location>`` per mode (invariant terms joined by ``&``, flows
    ``x' == a·z + b``, memory flows ``m' == 0.0``) and a ``<transition>`` per
    transition (guard terms as linear inequalities, an assignment for every
    variable: jump map, memory reset, else identity).

    SpaceEx transitions are non-urgent and unprioritised, so the export
    over-approximates the executions of the model: a crossing-triggered
    transition (``direction = ±1``) is exported as its level guard ``g >= 0``
    and the XML says so in a comment, and priorities are dropped (a comment
    says so when a mode has several outgoing transitions).  Time is fixed at
    ``t = 0`` in flows and the output map after checking that they do not
    change at ``t`` in :data:`hybrid.affine.TIME_PROBES`.

    Parameters
    ----------
    system : HybridSystem
    box : Box
        Declares exactly the states (bounds or choices) and, in
        ``Box.memory``, an interval for every memory variable a reset writes.
    tol, seed
        Passed to :func:`~hybrid.affine.affine_form`.

    Returns
    -------
    str
        The XML document, ending with a newline.

    Raises
    ------
    NotAffineError
        Naming the first function (model order) that is not affine, with the
        witness point, direction and second-difference size.
    ModelDefinitionError
        Names that are not SpaceEx identifiers, or a box that does not
        declare what is needed.
    """
    if not isinstance(system, HybridSystem):
        raise ModelDefinitionError(f"to_spacex: system = {system!r}; expected a HybridSystem")
    if _all_symbolic(system):  # written from the expressions themselves (hybrid.spaceex_export), not sampled
        from .spaceex_export import to_spaceex

        return to_spaceex(system)
    what = f"SpaceEx export of system {system.name!r}"
    _require_identifiers(system, what)
    affinity = system_affinity(system, box, tol=tol, seed=seed, what=what)
    defect = affinity.first_defect()
    if defect is not None:
        raise NotAffineError(system.name, *defect)
    a = system.automaton
    root = ET.Element("sspaceex", {"xmlns": SPACEEX_NAMESPACE, "version": "0.2", "math": "SpaceEx"})
    root.append(_comment(
        f"generated by hybrid.export from system {system.name!r}; affine on {_ascii_box(box)} "
        f"(relative tolerance {tol:g})"
    ))
    component = ET.SubElement(root, "component", {"id": a.name})
    _spacex_header(component, system, affinity)
    ids = {mode: str(i + 1) for i, mode in enumerate(a.mode_names)}
    for mode in a.modes:
        _spacex_location(component, system, mode, ids[mode.name], affinity)
    for t in a.transitions:
        _spacex_transition(component, system, t, ids, affinity)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _all_symbolic(system: HybridSystem) -> bool:
    """Whether every function of ``system`` is a :mod:`hybrid.symbolic` tree (the export then needs no sampling)."""
    from .model import Conjunction
    from .symbolic import is_symbolic

    def sym(f: Any) -> bool:
        if isinstance(f, Conjunction):
            return all(sym(t) for t in f.terms)
        return f is None or is_symbolic(f)

    a = system.automaton
    return (all(sym(m.invariant) for m in a.modes) and all(sym(t.guard) and sym(t.reset) for t in a.transitions)
            and all(sym(f) for f in system.flows.values()) and all(sym(j) for j in system.jumps.values())
            and sym(system.output))


def _memory_names(system: HybridSystem) -> tuple[str, ...]:
    return tuple(m.name for m in system.automaton.memory)


def _spacex_header(component: ET.Element, system: HybridSystem, affinity: SystemAffinity) -> None:
    """Comments on memory and priorities, then the ``param`` declarations."""
    a = system.automaton
    memory_names = _memory_names(system)
    if memory_names:
        fixed = affinity.coordinates.fixed_memory
        note = f"memory variable(s) {', '.join(memory_names)} have flow 0 and change only by resets"
        if fixed:
            note += "; held fixed for the affinity test: " + ", ".join(f"{k} = {_num(v)}" for k, v in fixed.items())
        component.append(_comment(note))
    if any(len(a.outgoing(m)) > 1 for m in a.mode_names):
        component.append(_comment(
            "SpaceEx transitions are non-urgent and unprioritised: the priorities of the model are not exported"
        ))
    for name in system.state_names + memory_names:
        ET.SubElement(component, "param", {"name": name, "type": "real", "local": "false", "d1": "1",
                                           "d2": "1", "dynamics": "any"})
    for t in a.transitions:
        ET.SubElement(component, "param", {"name": t.name, "type": "label", "local": "false"})


def _conditions(names: Sequence[str], forms: Sequence[AffineResult]) -> str | None:
    """Affine condition terms ``g >= 0`` joined by ``&``; ``None`` when every term always holds."""
    terms = [_inequality(names, f.matrix[0], f.offset[0]) for f in forms]  # type: ignore[union-attr]
    terms = [term for term in terms if term is not None]
    return " & ".join(terms) if terms else None


def _equations(names: Sequence[str], states: Sequence[str], form: AffineResult) -> list[str]:
    """``x' == a·z + b`` for every state (rows of ``form``)."""
    assert isinstance(form, AffineForm)
    return [f"{s}' == {_linear(names, row, b)}" for s, row, b in zip(states, form.matrix, form.offset)]


def _spacex_location(
    component: ET.Element, system: HybridSystem, mode: Mode, location_id: str, affinity: SystemAffinity
) -> None:
    names = affinity.coordinates.names
    result = affinity.modes[mode.name]
    location = ET.SubElement(component, "location", {"id": location_id, "name": mode.name})
    invariant = _conditions(names, result.invariant)
    if invariant is not None:
        ET.SubElement(location, "invariant").text = invariant
    equations = _equations(names, system.state_names, result.flow)
    equations += [f"{m}' == 0.0" for m in _memory_names(system)]
    ET.SubElement(location, "flow").text = " & ".join(equations)


def _spacex_transition(
    component: ET.Element, system: HybridSystem, t: Transition, ids: Mapping[str, str], affinity: SystemAffinity
) -> None:
    names = affinity.coordinates.names
    result = affinity.transitions[t.name]
    element = ET.SubElement(component, "transition", {"source": ids[t.source], "target": ids[t.target]})
    if t.direction:
        sense = "rising" if t.direction > 0 else "falling"
        element.append(_comment(
            f"transition {t.name!r} fires on a {sense} zero crossing of its guard "
            f"(direction {t.direction:+d}); exported as the level guard g >= 0"
        ))
    ET.SubElement(element, "label").text = t.name
    guard = _conditions(names, result.guard)
    if guard is not None:
        ET.SubElement(element, "guard").text = guard
    equations = _equations(names, system.state_names, result.jump_map)
    written = {w: k for k, w in enumerate(t.writes)}
    memory = result.memory_reset
    for m in _memory_names(system):
        if m in written:
            assert isinstance(memory, AffineForm)
            k = written[m]
            equations.append(f"{m}' == {_linear(names, memory.matrix[k], memory.offset[k])}")
        else:
            equations.append(f"{m}' == {m}")
    ET.SubElement(element, "assignment").text = " & ".join(equations)


def spacex_config(
    system: HybridSystem,
    x0: Mapping[str, float | tuple[float, float]] | Sequence[float],
    initial_mode: str | None = None,
    *,
    time_horizon: float,
    sampling_time: float | None = None,
    scenario: str = "supp",
    directions: str = "oct",
    set_aggregation: str = "chull",
    flowpipe_tolerance: float = 0.01,
    iter_max: int = -1,
    output_variables: Sequence[str] | None = None,
    output_format: str = "TXT",
    forbidden: str = "",
    rel_err: float = 1.0e-12,
    abs_err: float = 1.0e-15,
) -> str:
    """SpaceEx configuration (``.cfg``) text for the model written by :func:`to_spacex`.

    Parameters
    ----------
    system : HybridSystem
    x0 : mapping or sequence
        Initial set: one value per state (in ``state_names`` order), or a
        mapping ``name -> value`` or ``name -> (lower, upper)`` over states
        and memory variables.  Every state must be given; memory variables
        not given start at their initial value.
    initial_mode : str or None
        Initial location; ``None`` means the automaton's initial mode.
    time_horizon : float
        Analysis horizon (positive).
    sampling_time : float or None
        Time step of the flowpipe; ``None`` means ``time_horizon / 100``.
    scenario, directions, set_aggregation, flowpipe_tolerance, iter_max, output_format, rel_err, abs_err
        SpaceEx options written as given.
    output_variables : sequence of str or None
        Variables to output; ``None`` means every state.
    forbidden : str
        SpaceEx expression of the forbidden set (empty for none).

    Returns
    -------
    str
        The configuration, one ``key = value`` per line.

    Raises
    ------
    ModelDefinitionError
        Unknown or missing variables, an empty or reversed interval, an
        unknown mode, a non-positive horizon or an option that would break
        the quoting.

    Examples
    --------
    >>> from hybrid import HybridAutomaton, HybridSystem, Mode
    >>> a = HybridAutomaton(name="decay", modes=(Mode(name="run"),), transitions=(), variables=("x",))
    >>> s = HybridSystem(automaton=a, state_names=("x",), flows={"run": lambda t, x, m: (-x[0],)})
    >>> print(spacex_config(s, {"x": (0.9, 1.1)}, time_horizon=2.0).splitlines()[2])
    initially = "loc(decay)==run & x >= 0.9 & x <= 1.1"
    """
    if not isinstance(system, HybridSystem):
        raise ModelDefinitionError(f"spacex_config: system = {system!r}; expected a HybridSystem")
    what = f"SpaceEx configuration of system {system.name!r}"
    _require_identifiers(system, what)
    a = system.automaton
    mode = a.initial_mode if initial_mode is None else initial_mode
    a.mode(mode)
    for option, value in (("time_horizon", time_horizon), ("sampling_time", sampling_time)):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ModelDefinitionError(f"{what}: {option} = {value!r}; expected a finite positive time in seconds")
    if isinstance(x0, Mapping):
        given = dict(x0)
    else:
        values = list(x0)
        if len(values) != system.dimension:
            raise ModelDefinitionError(
                f"{what}: x0 has {len(values)} values, expected {system.dimension} ({', '.join(system.state_names)})"
            )
        given = dict(zip(system.state_names, values))
    memory_names = tuple(m.name for m in a.memory)
    known = system.state_names + memory_names
    unknown = [n for n in given if n not in known]
    missing = [n for n in system.state_names if n not in given]
    if unknown or missing:
        raise ModelDefinitionError(
            f"{what}: x0 misses state(s) {missing} and names unknown variable(s) {unknown}; "
            f"give every state of {list(system.state_names)} (memory {list(memory_names)} optional)"
        )
    for m in a.memory:
        given.setdefault(m.name, float(m.initial))
    constraints = [f"loc({a.name})=={mode}"]
    for name in known:
        value = given[name]
        if isinstance(value, (tuple, list)):
            if len(value) != 2:
                raise ModelDefinitionError(f"{what}: x0[{name!r}] = {value!r}; expected a value or (lower, upper)")
            lo, hi = (float(c) for c in value)
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise ModelDefinitionError(
                    f"{what}: x0[{name!r}] = ({lo!r}, {hi!r}); expected finite bounds with lower <= upper"
                )
            constraints.append(f"{name} == {_num(lo)}" if lo == hi else f"{name} >= {_num(lo)} & {name} <= {_num(hi)}")
        else:
            v = float(value)
            if not math.isfinite(v):
                raise ModelDefinitionError(f"{what}: x0[{name!r}] = {v!r}; expected a finite value")
            constraints.append(f"{name} == {_num(v)}")
    for option, text in (("forbidden", forbidden), ("scenario", scenario), ("directions", directions),
                         ("set_aggregation", set_aggregation), ("output_format", output_format)):
        if not isinstance(text, str) or '"' in text or "\n" in text:
            raise ModelDefinitionError(f"{what}: {option} = {text!r}; expected one line of text without '\"'")
    outputs = tuple(system.state_names if output_variables is None else output_variables)
    bad = [n for n in outputs if n not in known]
    if bad:
        raise ModelDefinitionError(f"{what}: output_variables {bad} are not variables of {list(known)}")
    step = time_horizon / 100.0 if sampling_time is None else sampling_time
    lines = [
        f"# SpaceEx configuration of system {a.name!r}, generated by hybrid.export",
        f'system = "{a.name}"',
        f'initially = "{" & ".join(constraints)}"',
        f'forbidden = "{forbidden}"',
        f'scenario = "{scenario}"',
        f'directions = "{directions}"',
        f'set-aggregation = "{set_aggregation}"',
        f"sampling-time = {_num(step)}",
        f"time-horizon = {_num(time_horizon)}",
        f"flowpipe-tolerance = {_num(flowpipe_tolerance)}",
        f"iter-max = {int(iter_max)}",
        f'output-variables = "{",".join(outputs)}"',
        f'output-format = "{output_format}"',
        f"rel-err = {rel_err!r}",
        f"abs-err = {abs_err!r}",
    ]
    return "\n".join(lines) + "\n"
