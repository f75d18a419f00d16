"""SpaceEx import: a SpaceEx XML model (one component, or a flattened network) as a symbolic HybridSystem.

>>> from hybrid.spaceex_import import load_spaceex
>>> model = load_spaceex("tests/data/spaceex/spaceexparser/bball/bball.xml", "system")  # doctest: +SKIP
>>> model.system.state_names                                                              # doctest: +SKIP
('x', 'v')

Mapping onto :mod:`hybrid` (docs/spaceex.md):

* every real variable with a flow ``x' == e`` in every location is a state
  (in declaration order); a location whose flow is ``false`` (time may not
  pass) gets the zero flow: the state is held, which reaches exactly the states
  SpaceEx reaches (noted in :attr:`SpaceExModel.notes`);
* a variable without any flow that an invariant defines by ``y == e`` in every
  location is an *output* (algebraic): it is substituted by ``e`` wherever it is
  read; any other variable without a flow is an *input* (SpaceEx lets it take any
  value in the invariant at every instant): :mod:`hybrid.spaceex_inputs` (bounded by
  constants in the invariants, read by flows only; a placeholder in
  :attr:`SpaceExModel.input_flows`, held at the middle of its bounds in ``system``);
* invariants and guards are symbolic conditions; assignments ``x := e`` become
  the jump map (a variable not assigned keeps its value);
* a transition is named by its label (``tau`` when unlabelled), with ``_k``
  suffixes when a label occurs on several transitions.  hybrid fires a
  transition as soon as its guard holds; SpaceEx may also fire it later, while
  the source invariant holds (noted whenever a guard is not implied by the end
  of the invariant, see the docs);
* a constant of the analysed component that no bind maps takes the value the
  configuration's initial set pins it to (``Tmax == 50``), as SpaceEx reads it
  (:attr:`SpaceExModel.constants`); a range (an uncertain constant) is refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from .errors import HybridError
from .model import HybridAutomaton, Mode, Transition
from .spaceex_flatten import FlatAutomaton, constant_value, flatten
from .spaceex_inputs import SpaceExInput, find_inputs, input_signal, is_input_bound, with_inputs
from .spaceex_model import parse_components
from .spaceex_syntax import MAX_FILE_BYTES, SpaceExError
from .symbolic import Compare, Const, Expr, Param, all_true, any_true, coordinates, cos, exp, flow_map, jump_map
from .symbolic import log, sin, sqrt
from .system import HybridSystem

__all__ = ["SpaceExModel", "load_spaceex", "import_spaceex", "build_system", "to_symbolic", "symbolic_node",
           "substitute_tree", "read_bytes"]


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExModel:
    """An imported SpaceEx model.

    Attributes
    ----------
    system : HybridSystem
        The flattened automaton with symbolic flows, invariants, guards and jump maps.
    flat : FlatAutomaton
        The flattened SpaceEx automaton (trees, for the configuration's sets).
    outputs : dict
        Algebraic variables ``name -> tree`` (substituted in the model).
    source : str
        The file read.
    notes : tuple of str
        Every place where hybrid's reading differs in form from SpaceEx's (held state, must-fire guards).
    inputs : tuple of SpaceExInput
        The non-deterministic inputs (variables without a flow bounded by the invariants), in declaration order.
    input_flows : dict
        ``mode -> flow_map`` reading each input through its placeholder ``Param(input.symbol)`` (empty without
        inputs); :func:`hybrid.spaceex_inputs.with_inputs` puts a signal in.  ``system`` holds every input at the
        middle of its bounds (a one-piece signal of time, which reachability refuses).
    constants : dict
        ``name -> value`` of the analysed component's own constants that no bind maps, given by ``constants`` or
        pinned by the configuration's initial set (``Tmax == 50``); substituted in the model.
    """

    system: HybridSystem
    flat: FlatAutomaton
    outputs: dict[str, Any]
    source: str
    notes: tuple[str, ...]
    inputs: tuple[SpaceExInput, ...] = ()
    input_flows: dict[str, Any] = field(default_factory=dict)
    constants: dict[str, float] = field(default_factory=dict)


def read_bytes(path: str | Path, what: str) -> bytes:
    """The bytes of ``path`` (bounded), or a :class:`SpaceExError` naming the path."""
    p = Path(path)
    if not p.is_file():
        raise SpaceExError(what, str(path), "an existing file", "check the path (relative to the current folder)")
    if p.stat().st_size > MAX_FILE_BYTES:
        raise SpaceExError(what, str(path), f"a file of at most {MAX_FILE_BYTES} bytes", "check the file")
    return p.read_bytes()


def load_spaceex(path: str | Path, component: str | None = None, *,
                 constants: dict[str, float] | None = None, initially: Any = None) -> SpaceExModel:
    """Import the SpaceEx model in file ``path`` (component ``component``; default: the last one of the file).

    ``constants``: values of the component's own constants that no bind maps (else they are an error).
    ``initially``: the configuration's initial set (a parsed tree, :attr:`hybrid.spaceex_config.SpaceExConfig.
    initially`); a constant it pins to one value (``Tmax == 50``) takes that value, as in SpaceEx.

    Raises
    ------
    SpaceExError
        Naming the file, line and element of anything not supported (docs/spaceex.md).
    """
    return import_spaceex(read_bytes(path, "SpaceEx model"), component, source=str(path), constants=constants,
                          initially=initially)


def import_spaceex(data: bytes, component: str | None = None, *, source: str = "<spaceex>",
                   constants: dict[str, float] | None = None, initially: Any = None) -> SpaceExModel:
    """Import a SpaceEx model from its XML bytes (see :func:`load_spaceex`)."""
    try:
        components = parse_components(data, source)
        name = component if component is not None else list(components)[-1]
        given = {**pinned_constants(components.get(name), initially, source, set(constants or {})),
                 **(constants or {})}
        flat = flatten(components, name, source, given)
        return replace(build_system(flat, source), constants=given)
    except SpaceExError:
        raise
    except (HybridError, ArithmeticError, ValueError, RecursionError) as error:  # e.g. 10^1000 in a flow
        raise SpaceExError(source, f"{type(error).__name__}: {error}", "a model hybrid can represent (finite "
                           "constants, integer powers, division by constants)", "fix the expression named") from None


_SWAP = {"<=": ">=", "<": ">", ">=": "<=", ">": "<", "==": "=="}


def pinned_constants(top: Any, initially: Any, source: str, given: set[str]) -> dict[str, float]:
    """``{constant: value}`` the initial set pins for component ``top``'s own constants (not in ``given``).

    Raises
    ------
    SpaceExError
        A constant the set bounds by a range rather than one value (an uncertain constant), naming it.
    """
    if top is None or initially is None or initially[0] == "true":
        return {}
    names = {p.name for p in top.params.values() if p.kind != "label" and p.constant} - given
    low: dict[str, float] = {}
    high: dict[str, float] = {}
    for c in initially[1] if initially[0] == "and" else (initially,):
        if c[0] != "cmp":
            continue
        a, op, b = c[2], c[1], c[3]
        if a[0] != "name" and b[0] == "name":
            a, b, op = b, a, _SWAP[op]
        if a[0] != "name" or a[1] not in names:
            continue
        value = constant_value(b, f"{source}: initially")
        if op in (">=", ">", "=="):
            low[a[1]] = max(low.get(a[1], -math.inf), value)
        if op in ("<=", "<", "=="):
            high[a[1]] = min(high.get(a[1], math.inf), value)
    out = {}
    for n in sorted(set(low) | set(high)):
        lo, hi = low.get(n, -math.inf), high.get(n, math.inf)
        if not lo == hi:
            raise SpaceExError(f"{source}: initially", f"{lo!r} <= {n} <= {hi!r}", f"one value for the constant {n!r} "
                               f"of component {top.id!r} ({n} == value)", f"write {n} == <value> in the initial set, "
                               "or map the constant to a number in a <bind>; an uncertain constant is not supported")
        out[n] = lo
    return out


_FUNCS = {"sin": sin, "cos": cos, "exp": exp, "sqrt": sqrt, "log": log}
_BIN = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b}


def to_symbolic(tree: Any, env: dict[str, Expr], where: str) -> Any:
    """See :func:`symbolic_node`; a constant that folds to an infinity is refused."""
    node = symbolic_node(tree, env, where)
    if isinstance(node, Const) and not math.isfinite(node.value):
        raise SpaceExError(where, tree, "a finite constant", "the constant overflows double precision: rescale it")
    return node


def symbolic_node(tree: Any, env: dict[str, Expr], where: str) -> Any:
    """A :mod:`hybrid.symbolic` expression or condition for a renamed tree (``env``: variable -> expression).

    Raises
    ------
    SpaceExError
        A name not in ``env``, a division by a non-constant, a non-integer power of a variable.
    """
    kind = tree[0]
    if kind == "num":
        return Const(float(tree[1]))
    if kind == "name":
        if tree[1] not in env:
            raise SpaceExError(where, tree[1], f"a state variable ({sorted(env)[:12]})",
                               "an input or undefined variable cannot be read here")
        return env[tree[1]]
    if kind == "neg":
        return -to_symbolic(tree[1], env, where)
    if kind == "call":
        return _FUNCS[tree[1]](to_symbolic(tree[2][0], env, where))
    if kind in _BIN:
        return _BIN[kind](to_symbolic(tree[1], env, where), to_symbolic(tree[2], env, where))
    if kind in ("/", "^"):
        a, b = to_symbolic(tree[1], env, where), to_symbolic(tree[2], env, where)
        if not isinstance(b, Const):
            raise SpaceExError(where, tree, "a constant divisor or exponent",
                               "hybrid.symbolic divides by constants and raises to integer powers only")
        if kind == "/":
            if b.value == 0.0:
                raise SpaceExError(where, tree, "a non-zero divisor", "fix the expression")
            return Const(a.value / b.value) if isinstance(a, Const) else a / b
        if isinstance(a, Const):
            return Const(a.value ** b.value)
        if b.value != int(b.value) or b.value < 0:
            raise SpaceExError(where, tree, "an integer power >= 0 of a variable", "rewrite the power")
        return a ** int(b.value)
    if kind == "cmp":
        return Compare(tree[1], to_symbolic(tree[2], env, where), to_symbolic(tree[3], env, where))
    if kind == "and":
        return all_true(*(to_symbolic(c, env, where) for c in tree[1]))
    if kind == "or":
        return any_true(*(to_symbolic(c, env, where) for c in tree[1]))
    raise SpaceExError(where, tree, "an arithmetic expression or a comparison", "rewrite the expression")


def substitute_tree(tree: Any, values: dict[str, Any]) -> Any:
    """``tree`` with ``("name", n)`` replaced by ``values[n]`` (the outputs' definitions)."""
    if not isinstance(tree, tuple) or not tree:
        return tree
    if tree[0] == "name":
        return values.get(tree[1], tree)
    return tuple(substitute_tree(t, values) if isinstance(t, tuple) else t for t in tree)


def _names_in(tree: Any) -> set[str]:
    if not isinstance(tree, tuple) or not tree:
        return set()
    if tree[0] in ("name", "deriv") and isinstance(tree[1], str):
        return {tree[1]}
    out: set[str] = set()
    for t in tree[1:]:
        out |= _names_in(t)
    return out


def _derivatives(flat: FlatAutomaton) -> tuple[dict[str, dict[str, Any]], set[str]]:
    flows: dict[str, dict[str, Any]] = {}
    frozen: set[str] = set()
    for loc in flat.locations:
        eqs: dict[str, Any] = {}
        for c in loc.flow:
            if c[0] == "false":
                frozen.add(loc.name)
                continue
            if c[0] == "cmp" and c[1] == "==" and c[2][0] == "deriv" and "deriv" not in str(c[3]):
                var = c[2][1]
                if var in eqs and eqs[var] != c[3]:
                    raise SpaceExError(loc.where, f"two flows for {var}'", "one x' == e per variable and location",
                                       "two instances define the same derivative: keep one")
                eqs[var] = c[3]
            else:
                raise SpaceExError(loc.where, c, "flow constraints of the form x' == expression",
                                   "differential inclusions and constraints on inputs in flows are not supported")
        flows[loc.name] = eqs
    return flows, frozen


def _outputs(flat: FlatAutomaton, flows: dict[str, dict[str, Any]]) -> tuple[list[str], dict[str, Any], list[str]]:
    """The states, the outputs (``name -> tree``) and the other variables without a flow (inputs)."""
    with_flow = {v for eqs in flows.values() for v in eqs}
    states, outputs, inputs = [], {}, []
    for var in flat.variables:
        if var in with_flow:
            states.append(var)
            continue
        defs = []
        for loc in flat.locations:
            found = [c[3] if c[2] == ("name", var) else c[2] for c in loc.invariant
                     if c[0] == "cmp" and c[1] == "==" and ("name", var) in (c[2], c[3])]
            found = [d for d in found if var not in _names_in(d)]
            defs.append(found[0] if found else None)
        if defs and all(d is not None and d == defs[0] for d in defs):
            outputs[var] = defs[0]
            continue
        inputs.append(var)
    return states, outputs, inputs


def build_system(flat: FlatAutomaton, source: str) -> SpaceExModel:
    """The :class:`SpaceExModel` of a flattened automaton (see the module docstring)."""
    flows, frozen = _derivatives(flat)
    states, outputs, candidates = _outputs(flat, flows)
    inputs = find_inputs(flat, candidates)
    bound_names = {i.name for i in inputs}
    if not states:
        raise SpaceExError(f"{source}: system {flat.name!r}", "no state variable", "at least one x' == e",
                           "give the component a flow")
    for _ in range(len(outputs) + 1):  # an output may read another one
        outputs = {k: substitute_tree(v, outputs) for k, v in outputs.items()}
    x = coordinates(*states)
    env = {s: getattr(x, s) if s.isidentifier() else x[s] for s in states}
    flow_env = {**env, **{i.name: Param(i.symbol, i.middle) for i in inputs}}
    notes: list[str] = [f"input {i.name} in [{i.low!r}, {i.high!r}] (no flow: any value at every instant); held at "
                        f"{i.middle!r} in the imported system" for i in inputs]
    modes, flow_maps = [], {}
    for loc in flat.locations:
        eqs = flows[loc.name]
        if loc.name in frozen:
            notes.append(f"location {loc.name!r}: flow false (time may not pass); every derivative is 0 "
                         "(the state is held: the reached states are SpaceEx's)")
            comps = [Const(0.0)] * len(states)
        else:
            missing = [s for s in states if s not in eqs]
            if missing:
                raise SpaceExError(loc.where, f"no flow for {missing}", "x' == e for every state variable",
                                   "SpaceEx leaves them unconstrained (an input): give their flow")
            comps = [to_symbolic(substitute_tree(eqs[s], outputs), flow_env, f"{loc.where}: flow of {s}")
                     for s in states]
        kept = [c for c in loc.invariant if not (c[0] == "cmp" and c[1] == "==" and
                                                 {("name", o) for o in outputs} & {c[2], c[3]})
                and is_input_bound(c, bound_names) is None]
        inv = [to_symbolic(substitute_tree(c, outputs), env, f"{loc.where}: invariant") for c in kept]
        modes.append(Mode(name=loc.name, invariant=all_true(*inv) if inv else None))
        flow_maps[loc.name] = flow_map(*comps)
    transitions, jumps = _transitions(flat, outputs, env, states, notes, bound_names)
    automaton = HybridAutomaton(name=flat.name, modes=tuple(modes), transitions=tuple(transitions),
                                variables=tuple(states), initial_mode=flat.locations[0].name,
                                description=f"imported from SpaceEx {source} (component {flat.name!r})")
    system = HybridSystem(automaton=automaton, state_names=tuple(states), flows=flow_maps, jumps=jumps)
    if not inputs:
        return SpaceExModel(system=system, flat=flat, outputs=outputs, source=source, notes=tuple(notes))
    held = with_inputs(system, flow_maps, inputs, {i.name: input_signal((i.middle,), 1.0) for i in inputs})
    return SpaceExModel(system=held, flat=flat, outputs=outputs, source=source, notes=tuple(notes), inputs=inputs,
                        input_flows=flow_maps)


def _names(flat: FlatAutomaton) -> list[str]:
    labels = [t.label or "tau" for t in flat.transitions]
    counts = {lab: labels.count(lab) for lab in set(labels)} if len(labels) < 5000 else None
    if counts is None:
        from collections import Counter
        counts = dict(Counter(labels))
    used: set[str] = set()
    seen: dict[str, int] = {}
    out = []
    for lab in labels:
        if counts[lab] == 1 and lab not in used:
            name = lab
        else:
            seen[lab] = seen.get(lab, 0) + 1
            name = f"{lab}_{seen[lab]}"
            while name in used or (name in counts and name != lab):
                seen[lab] += 1
                name = f"{lab}_{seen[lab]}"
        used.add(name)
        out.append(name)
    return out


_OPPOSITE = {">=": "<=", ">": "<=", "<=": ">=", "<": ">="}
_MIRROR = {">=": "<=", ">": "<", "<=": ">=", "<": ">"}


def _equality(c: Any, invariant: tuple[Any, ...], name: str, notes: list[str]) -> Any:
    """A guard ``a == b`` whose source invariant bounds ``a - b`` on one side, as the other side's inequality.

    Within the invariant ``a >= b`` the guard ``a == b`` and ``a <= b`` hold on the same states, and the
    inequality is crossed by a trajectory where the equality is only touched (hybrid locates sign changes).
    """
    if c[0] != "cmp" or c[1] != "==":
        return c
    a, b = c[2], c[3]
    for d in invariant:
        if d[0] != "cmp" or d[1] not in _OPPOSITE:
            continue
        op = d[1] if (d[2], d[3]) == (a, b) else (_MIRROR[d[1]] if (d[2], d[3]) == (b, a) else None)
        if op is not None:
            notes.append(f"transition {name!r}: guard equality read as {_OPPOSITE[op]} (the same states within "
                         f"the source invariant {op})")
            return ("cmp", _OPPOSITE[op], a, b)
    notes.append(f"transition {name!r}: guard equality kept as an equality: a trajectory touches it without "
                 "crossing, and hybrid's event location may miss it (GuardResolutionWarning)")
    return c


def _assignments(t: Any, env: dict[str, Expr]) -> dict[str, Any]:
    """``variable -> right-hand side tree`` of a transition's assignment."""
    values: dict[str, Any] = {}
    for a in t.assignment:
        if a[0] == "assign":
            var, rhs = a[1], a[2]
        elif a[0] == "cmp" and a[1] == "==" and a[2][0] == "deriv":
            var, rhs = a[2][1], a[3]
        elif a[0] == "true":
            continue
        else:
            raise SpaceExError(f"{t.where}: assignment", a, "x := e (or x' == e) per assigned variable",
                               "nondeterministic assignments (x' <= e) are not supported")
        if var not in env:
            raise SpaceExError(f"{t.where}: assignment", var, f"a state variable ({sorted(env)[:12]})",
                               "assign state variables only")
        if rhs != ("name", var):
            values[var] = rhs
    return values


def _guard_trees(t: Any, values: dict[str, Any], invariants: dict[str, tuple[Any, ...]], outputs: dict[str, Any],
                 name: str, notes: list[str]) -> list[Any]:
    """The guard, conjoined with the target invariant after the assignment (SpaceEx lets a jump happen only
    into its target's invariant); conjuncts the source invariant or the guard already give are left out."""
    source = [substitute_tree(c, outputs) for c in invariants[t.source]]
    trees = [substitute_tree(c, outputs) for c in t.guard if c[0] != "true"]
    for c in invariants[t.target]:
        c = substitute_tree(c, outputs)
        if c[0] == "cmp" and c[2] == c[3]:
            continue  # an output's definition y == e, substituted
        after = substitute_tree(c, values)
        if after in trees or (after == c and c in source):
            continue
        trees.append(after)
    return [_equality(c, tuple(source), name, notes) for c in trees]


def _transitions(flat: FlatAutomaton, outputs: dict[str, Any], env: dict[str, Expr], states: list[str],
                 notes: list[str], inputs: set[str]) -> tuple[list[Transition], dict[str, Any]]:
    transitions, jumps = [], {}
    invariants = {loc.name: tuple(c for c in loc.invariant if is_input_bound(c, inputs) is None)
                  for loc in flat.locations}
    for name, t in zip(_names(flat), flat.transitions):
        if any(c[0] == "false" for c in t.guard):
            notes.append(f"transition {name!r}: guard false (never enabled); dropped")
            continue
        values = _assignments(t, env)
        trees = _guard_trees(t, values, invariants, outputs, name, notes)
        guard = [to_symbolic(c, env, f"{t.where}: guard") for c in trees]
        jump = {v: to_symbolic(substitute_tree(rhs, outputs), env, f"{t.where}: assignment of {v}")
                for v, rhs in values.items()}
        if t.urgent:
            notes.append(f"transition {name!r}: urgent (asap) in SpaceEx; hybrid fires every transition as soon "
                         "as its guard holds")
        transitions.append(Transition(name=name, source=t.source, target=t.target,
                                      guard=all_true(*guard) if guard else Const(1.0)))
        if jump:
            jumps[name] = jump_map(*(jump.get(s, env[s]) for s in states))
    return transitions, jumps

