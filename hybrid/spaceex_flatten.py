"""SpaceEx input, third layer: instantiate a network of components and flatten it into one automaton.

Semantics implemented (SpaceEx's parallel composition, docs/spaceex.md):

* **binds**: each ``<map key="p">value</map>`` binds the child's parameter ``p``
  to a variable or label of the parent (by name) or to a constant expression of
  the parent's constants.  An unmapped non-local parameter is bound to the
  parent's parameter of the same name when there is one and is otherwise local
  to the instance.  Local variables and labels of an instance are named
  ``instance.name`` (``instance.sub.name`` when nested), as SpaceEx's ``.cfg``
  files write them (``break_pattern.t``).  Constants are substituted.
* **locations**: the Cartesian product of the instances' locations; the
  invariant and the flow are the conjunctions of the instances' ones.
* **transitions**: a transition whose label is shared by several instances
  fires only together with one transition of the same label in *every*
  instance whose alphabet holds the label (synchronisation); its guard is the
  conjunction and its assignment the union of theirs (two instances assigning
  one variable is refused).  An unlabelled transition, or a label only one
  instance knows, interleaves.  A variable that no participant assigns keeps
  its value.

Work is bounded: the product is refused when it would exceed
:data:`~hybrid.spaceex_model.MAX_LOCATIONS` locations or
:data:`MAX_TRANSITIONS` transitions, and nesting deeper than :data:`MAX_NESTING`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .spaceex_model import MAX_LOCATIONS, SpaceExComponent
from .spaceex_syntax import SpaceExError

__all__ = ["FlatLocation", "FlatTransition", "FlatAutomaton", "flatten", "rename", "constant_value",
           "MAX_TRANSITIONS", "MAX_NESTING"]

MAX_TRANSITIONS = 200_000
"""Most transitions of the flattened product (bounded work)."""

MAX_NESTING = 32
"""Deepest nesting of network components."""


@dataclass(frozen=True, kw_only=True, slots=True)
class FlatLocation:
    """A location of the product: its name, the instance locations it stands for, invariant and flow trees."""

    name: str
    parts: tuple[tuple[str, str], ...]  # (instance path, location name)
    invariant: tuple[Any, ...]  # constraint trees, conjoined
    flow: tuple[Any, ...]
    where: str


@dataclass(frozen=True, kw_only=True, slots=True)
class FlatTransition:
    """A transition of the product."""

    label: str
    source: str
    target: str
    guard: tuple[Any, ...]
    assignment: tuple[Any, ...]
    urgent: bool
    where: str


@dataclass(frozen=True, kw_only=True, slots=True)
class FlatAutomaton:
    """The flattened automaton: real variables (declaration order), which are controlled, locations, transitions."""

    name: str
    variables: tuple[str, ...]
    uncontrolled: tuple[str, ...]
    locations: tuple[FlatLocation, ...]
    transitions: tuple[FlatTransition, ...]
    instances: tuple[str, ...]  # instance paths of the base components, in product order


@dataclass(kw_only=True, slots=True)
class _Instance:
    path: str
    component: SpaceExComponent
    names: dict[str, Any]  # param -> ("name", flat var) | ("num", value) | ("label", flat label)


def constant_value(tree: Any, where: str) -> float:
    """The value of an arithmetic tree with numbers only.

    Raises
    ------
    SpaceExError
        A name in the tree, or a non-finite value.
    """
    kind = tree[0]
    if kind == "num":
        return float(tree[1])
    if kind == "neg":
        return -constant_value(tree[1], where)
    if kind == "call":
        return float(getattr(math, tree[1])(constant_value(tree[2][0], where)))
    if kind in ("+", "-", "*", "/", "^"):
        a, b = constant_value(tree[1], where), constant_value(tree[2], where)
        try:
            value = {"+": a + b, "-": a - b, "*": a * b}.get(kind) if kind in "+-*" else (a / b if kind == "/" else a ** b)
        except (ZeroDivisionError, OverflowError, ValueError) as error:
            raise SpaceExError(where, f"{a!r} {kind} {b!r}", "a finite constant", f"fix the constant ({error})") from None
        if not isinstance(value, float) or not math.isfinite(value):
            raise SpaceExError(where, f"{a!r} {kind} {b!r}", "a finite real constant", "fix the constant")
        return value
    raise SpaceExError(where, tree, "a constant expression (numbers and the parent's constants)",
                       "map the key to a variable name or a number")


def rename(tree: Any, names: dict[str, Any], where: str, component: str) -> Any:
    """``tree`` with every parameter name replaced by its flat variable (``("name", ...)``) or constant.

    Raises
    ------
    SpaceExError
        An undefined name (not a parameter of ``component``), or a label used as a number.
    """
    kind = tree[0]
    if kind in ("name", "deriv"):
        target = names.get(tree[1])
        if target is None:
            raise SpaceExError(where, tree[1], f"a parameter declared in component {component!r} "
                               f"({sorted(n for n, v in names.items() if v[0] != 'label')[:12]})",
                               f"declare <param name=\"{tree[1]}\" .../> or correct the name")
        if target[0] == "label":
            raise SpaceExError(where, tree[1], "a real variable or constant", "labels are not numbers")
        if target[0] == "unbound":
            raise SpaceExError(where, tree[1], f"a value for the constant {target[1]!r}",
                               f"map it to a number in the <bind> of its instance: <map key=\"{tree[1]}\">...</map>"
                               " (a constant of the top component: load_spaceex(..., "
                               f"constants={{{target[1]!r}: ...}}))")
        if kind == "deriv":
            if target[0] != "name":
                raise SpaceExError(where, f"{tree[1]}'", "the derivative of a variable",
                                   f"{tree[1]} is a constant: drop its flow")
            return ("deriv", target[1])
        return target
    if kind == "assign":
        target = rename(("name", tree[1]), names, where, component)
        if target[0] != "name":
            raise SpaceExError(where, tree[1], "an assignment to a variable", f"{tree[1]} is a constant")
        return ("assign", target[1], rename(tree[2], names, where, component))
    if kind in ("num", "true", "false", "loc"):
        return tree
    if kind == "call":
        return ("call", tree[1], tuple(rename(a, names, where, component) for a in tree[2]))
    if kind == "cmp":
        return ("cmp", tree[1], rename(tree[2], names, where, component), rename(tree[3], names, where, component))
    if kind in ("and", "or"):
        return (kind, tuple(rename(a, names, where, component) for a in tree[1]))
    if kind == "neg":
        return ("neg", rename(tree[1], names, where, component))
    return (kind, rename(tree[1], names, where, component), rename(tree[2], names, where, component))


def _bind_value(tree: Any, parent: dict[str, Any], where: str) -> Any:
    if tree[0] == "name":
        if tree[1] not in parent:
            raise SpaceExError(where, tree[1], f"a parameter of the network ({sorted(parent)[:12]}) or a number",
                               f"declare <param name=\"{tree[1]}\" .../> in the network or map the key to a number")
        return parent[tree[1]]
    renamed = rename(tree, parent, where, "the network")
    return ("num", constant_value(renamed, where))


def _instantiate(components: dict[str, SpaceExComponent], cid: str, path: str, names: dict[str, Any],
                 out: list[_Instance], variables: dict[str, bool], source: str, depth: int) -> None:
    comp = components[cid]
    if depth > MAX_NESTING:
        raise SpaceExError(f"{source}:{comp.line}: <component id={cid!r}>", f"nesting deeper than {MAX_NESTING}",
                           "a network without cycles", "a component binds itself (directly or not): break the cycle")
    if not comp.is_network:
        if not comp.locations:
            raise SpaceExError(f"{source}:{comp.line}: <component id={cid!r}>", "no location",
                               "a base component with at least one location", "add a <location>")
        out.append(_Instance(path=path, component=comp, names=names))
        return
    for bind in comp.binds:
        where = f"{source}:{bind.line}: <bind component={bind.component!r} as={bind.instance!r}>"
        child = components.get(bind.component)
        if child is None:
            raise SpaceExError(where, bind.component, f"a component of the file ({sorted(components)[:12]})",
                               "define the component or correct the bind's component attribute")
        unknown = sorted(set(bind.maps) - set(child.params))
        if unknown:
            raise SpaceExError(where, f"map key(s) {unknown}", f"parameters of {bind.component!r} "
                               f"({sorted(child.params)[:12]})", "remove the maps or declare the parameters")
        sub = f"{path}.{bind.instance}" if path else bind.instance
        child_names: dict[str, Any] = {}
        for p in child.params.values():
            if p.name in bind.maps:
                value = _bind_value(bind.maps[p.name], names, f"{where}: <map key={p.name!r}>")
                if (p.kind == "label") != (value[0] == "label"):
                    raise SpaceExError(f"{where}: <map key={p.name!r}>", value[1],
                                       "a label" if p.kind == "label" else "a variable or constant",
                                       "map labels to labels and reals to variables or constants")
                if p.kind == "real" and not p.constant and value[0] == "num":
                    raise SpaceExError(f"{where}: <map key={p.name!r}>", value[1], "a variable",
                                       f"{p.name} is a variable (dynamics any): map it to a variable")
                child_names[p.name] = value
            elif not p.local and p.name in names:
                child_names[p.name] = names[p.name]
            else:
                local = f"{sub}.{p.name}"
                if p.kind == "label":
                    child_names[p.name] = ("label", local)
                elif p.constant:
                    child_names[p.name] = ("unbound", local)
                else:
                    child_names[p.name] = ("name", local)
                    variables.setdefault(local, p.controlled)
        _instantiate(components, bind.component, sub, child_names, out, variables, source, depth + 1)


def _top_names(comp: SpaceExComponent, variables: dict[str, bool], constants: Mapping[str, float],
               source: str) -> dict[str, Any]:
    known = {p.name for p in comp.params.values() if p.kind != "label" and p.constant}
    unknown = sorted(set(constants) - known)
    if unknown:
        raise SpaceExError(f"{source}: constants", unknown, f"constants of component {comp.id!r} ({sorted(known)})",
                           "give values to the top component's constants only")
    names: dict[str, Any] = {}
    for p in comp.params.values():
        if p.kind == "label":
            names[p.name] = ("label", p.name)
        elif p.constant and p.name in constants:
            value = constants[p.name]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise SpaceExError(f"{source}: constants[{p.name!r}]", value, "a finite number", "give a number")
            names[p.name] = ("num", float(value))
        elif p.constant:
            names[p.name] = ("unbound", p.name)
        else:
            names[p.name] = ("name", p.name)
            variables.setdefault(p.name, p.controlled)
    return names


def _renamed(inst: _Instance, tree: Any, where: str) -> Any:
    return rename(tree, inst.names, where, inst.component.id)


def _conjuncts(tree: Any) -> tuple[Any, ...]:
    if tree[0] == "true":
        return ()
    return tree[1] if tree[0] == "and" else (tree,)


def flatten(components: dict[str, SpaceExComponent], system: str, source: str,
            constants: Mapping[str, float] | None = None) -> FlatAutomaton:
    """The product automaton of component ``system`` (see the module docstring).

    ``constants`` gives values to constants of ``system`` itself that no bind maps (SpaceEx's symbolic
    parameters, e.g. the platoon's ``tc``); any other unbound constant is an error naming it.

    Raises
    ------
    SpaceExError
        An unknown system or bound component, an undefined name, an unbound
        constant, a product beyond the limits, two instances assigning one variable.
    """
    if system not in components:
        raise SpaceExError(f"{source}: system", system, f"a component of the file ({sorted(components)[:12]})",
                           "name an existing component (FILE.xml:COMPONENT or the .cfg's system = ...)")
    variables: dict[str, bool] = {}
    top = components[system]
    names = _top_names(top, variables, dict(constants or {}), source)
    instances: list[_Instance] = []
    _instantiate(components, system, "", names, instances, variables, source, 0)
    size = 1
    for inst in instances:
        size *= len(inst.component.locations)
        if size > MAX_LOCATIONS:
            raise SpaceExError(f"{source}: system {system!r}", f"a product of more than {MAX_LOCATIONS} locations",
                               f"at most {MAX_LOCATIONS} locations after flattening",
                               "reduce the model (the limit bounds the import's work)")
    locs, alph = _instance_tables(instances, source)
    locations = _product_locations(instances, locs, source)
    transitions = _product_transitions(instances, locs, alph, locations, source)
    return FlatAutomaton(name=system, variables=tuple(variables),
                         uncontrolled=tuple(v for v, c in variables.items() if not c),
                         locations=tuple(locations.values()), transitions=tuple(transitions),
                         instances=tuple(inst.path for inst in instances))


def _instance_tables(instances: list[_Instance], source: str) -> tuple[list[dict[str, Any]], list[set[str]]]:
    """Per instance: location id -> (name, invariant, flow, outgoing [(label, guard, assign, target, urgent, where)])."""
    tables, alphabets = [], []
    for inst in instances:
        comp = inst.component
        table: dict[str, Any] = {}
        names_seen: dict[str, int] = {}
        for loc in comp.locations:
            where = f"{source}:{loc.line}: <location {loc.name!r}> of {inst.path or comp.id!r}"
            names_seen[loc.name] = names_seen.get(loc.name, 0) + 1
            table[loc.id] = [loc.name, _renamed(inst, loc.invariant, where), _renamed(inst, loc.flow, where), [], where]
        dup = sorted(n for n, k in names_seen.items() if k > 1)
        if dup:
            raise SpaceExError(f"{source}: component {comp.id!r}", f"location name(s) {dup[:5]} repeated",
                               "unique location names", "rename the locations")
        alphabet = {v[1] for v in inst.names.values() if v[0] == "label"}
        for t in comp.transitions:
            where = f"{source}:{t.line}: <transition> of {inst.path or comp.id!r}"
            label = ""
            if t.label:
                mapped = inst.names.get(t.label)
                if mapped is None or mapped[0] != "label":
                    raise SpaceExError(where, t.label, f"a label declared in component {comp.id!r}",
                                       f"declare <param name=\"{t.label}\" type=\"label\" .../>")
                label = mapped[1]
            table[t.source][3].append((label, _renamed(inst, t.guard, where), _renamed(inst, t.assignment, where),
                                       t.target, t.urgent, where))
        tables.append(table)
        alphabets.append(alphabet)
    return tables, alphabets


def _product_locations(instances: list[_Instance], tables: list[dict[str, Any]],
                       source: str) -> dict[tuple[str, ...], FlatLocation]:
    single = len(instances) == 1
    out: dict[tuple[str, ...], FlatLocation] = {}
    for key in itertools.product(*(list(t) for t in tables)):
        parts = tuple((inst.path or inst.component.id, tables[i][lid][0]) for i, (inst, lid) in
                      enumerate(zip(instances, key)))
        name = parts[0][1] if single else "|".join(f"{p}.{n}" for p, n in parts)
        invariant = tuple(c for i, lid in enumerate(key) for c in _conjuncts(tables[i][lid][1]))
        flow = tuple(c for i, lid in enumerate(key) for c in _conjuncts(tables[i][lid][2]))
        out[key] = FlatLocation(name=name, parts=parts, invariant=invariant, flow=flow,
                                where="; ".join(tables[i][lid][4] for i, lid in enumerate(key)))
    return out


def _product_transitions(instances: list[_Instance], tables: list[dict[str, Any]], alphabets: list[set[str]],
                         locations: dict[tuple[str, ...], FlatLocation], source: str) -> list[FlatTransition]:
    out: list[FlatTransition] = []
    for key, loc in locations.items():
        moves: dict[str, list[list[tuple[int, Any]]]] = {}
        for i, lid in enumerate(key):
            for edge in tables[i][lid][3]:
                label = edge[0]
                shared = label and sum(label in a for a in alphabets) > 1
                if not shared:
                    _emit(out, key, loc, [(i, edge)], locations, tables, source)
                else:
                    moves.setdefault(label, [[] for _ in instances])[i].append((i, edge))
        for label, per in moves.items():
            takers = [per[i] for i in range(len(instances)) if label in alphabets[i]]
            if any(not t for t in takers):
                continue  # an instance that knows the label cannot take it here: blocked
            for combo in itertools.product(*takers):
                _emit(out, key, loc, list(combo), locations, tables, source)
                if len(out) > MAX_TRANSITIONS:
                    raise SpaceExError(f"{source}", f"more than {MAX_TRANSITIONS} transitions after flattening",
                                       f"at most {MAX_TRANSITIONS}", "reduce the model")
    return out


def _emit(out: list[FlatTransition], key: tuple[str, ...], loc: FlatLocation, combo: list[tuple[int, Any]],
          locations: dict[tuple[str, ...], FlatLocation], tables: list[dict[str, Any]], source: str) -> None:
    target = list(key)
    guard: list[Any] = []
    assignment: list[Any] = []
    assigned: dict[str, str] = {}
    for i, edge in combo:
        target[i] = edge[3]
        guard.extend(_conjuncts(edge[1]))
        for a in _conjuncts(edge[2]):
            var = a[1] if a[0] == "assign" else (a[2][1] if a[0] == "cmp" and a[2][0] == "deriv" else None)
            if var is not None and var in assigned:
                raise SpaceExError(edge[5], f"{var} assigned by two synchronised transitions",
                                   "each variable assigned by at most one instance", f"see also {assigned[var]}")
            if var is not None:
                assigned[var] = edge[5]
            assignment.append(a)
        if len(out) > MAX_TRANSITIONS:
            raise SpaceExError(source, f"more than {MAX_TRANSITIONS} transitions after flattening",
                               f"at most {MAX_TRANSITIONS}", "reduce the model")
    out.append(FlatTransition(label=combo[0][1][0], source=loc.name, target=locations[tuple(target)].name,
                              guard=tuple(guard), assignment=tuple(assignment),
                              urgent=any(e[4] for _, e in combo), where="; ".join(e[5] for _, e in combo)))
