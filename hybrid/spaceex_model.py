"""SpaceEx input, second layer: the components of a SpaceEx XML document (no interpretation yet).

A *base component* has parameters, locations (invariant, flow) and
transitions (label, guard, assignment); a *network component* has parameters
and ``bind`` elements instantiating other components with a map from their
parameters to the network's variables, labels or constants.  Layout elements
and attributes (``note``, ``labelposition``, ``middlepoint``, ``waypoints``,
``x``/``y``/``width``/``height``) are skipped; any other element or attribute is
refused with its line, so that nothing of a model's meaning is silently lost.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

from .spaceex_syntax import SpaceExError, XmlElement, parse_constraints, parse_expression, read_xml

__all__ = [
    "SpaceExParam",
    "SpaceExLocation",
    "SpaceExTransition",
    "SpaceExBind",
    "SpaceExComponent",
    "parse_components",
    "MAX_LOCATIONS",
]

MAX_LOCATIONS = 20_000
"""Most locations a component, or the flattened product, may have: beyond it the import is refused (bounded work)."""

_LAYOUT = {"x", "y", "width", "height", "placement", "bezier"}
_SKIPPED = {"note", "labelposition", "middlepoint", "waypoints", "beforemiddle", "aftermiddle"}


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExParam:
    """A ``<param>``: a real variable (``dynamics`` ``any`` or ``const``) or a synchronisation label."""

    name: str
    kind: str  # "real" or "label"
    local: bool
    constant: bool
    controlled: bool
    line: int


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExLocation:
    """A ``<location>``: id, name, invariant and flow as constraint trees (:mod:`hybrid.spaceex_syntax`)."""

    id: str
    name: str
    invariant: Any
    flow: Any
    line: int


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExTransition:
    """A ``<transition>``: source and target location ids, label (``""`` when none), guard, assignment."""

    source: str
    target: str
    label: str
    guard: Any
    assignment: Any
    urgent: bool
    line: int


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExBind:
    """A ``<bind>``: the instantiated component, its instance name and ``key -> tree`` maps."""

    component: str
    instance: str
    maps: dict[str, Any]
    line: int


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExComponent:
    """A base component (locations, transitions) or a network component (binds)."""

    id: str
    params: dict[str, SpaceExParam]
    locations: tuple[SpaceExLocation, ...]
    transitions: tuple[SpaceExTransition, ...]
    binds: tuple[SpaceExBind, ...]
    line: int

    @property
    def is_network(self) -> bool:
        """Whether this component is a network (binds other components)."""
        return bool(self.binds)


def _where(source: str, node: XmlElement, what: str = "") -> str:
    return f"{source}:{node.line}: <{node.tag}>{' ' + what if what else ''}"


def _attrs(node: XmlElement, source: str, allowed: set[str], required: tuple[str, ...]) -> None:
    unknown = sorted(set(node.attrs) - allowed - _LAYOUT)
    if unknown:
        raise SpaceExError(_where(source, node), f"attribute(s) {unknown}",
                           f"only the attributes {sorted(allowed)} (and layout)",
                           "remove them, or convert the model with SpaceEx's own tools first")
    for name in required:
        if not node.attrs.get(name, "").strip():
            raise SpaceExError(_where(source, node), f"missing attribute {name!r}", f"<{node.tag} {name}=\"...\">",
                               f"add the {name} attribute")


def _unknown(node: XmlElement, source: str, parent: str, allowed: set[str]) -> None:
    raise SpaceExError(_where(source, node), f"element <{node.tag}> in <{parent}>",
                       f"one of {sorted(allowed | _SKIPPED)}",
                       "remove the element (this importer does not guess the meaning of unknown elements)")


def _flag(node: XmlElement, source: str, name: str, default: str) -> bool:
    value = node.attrs.get(name, default).strip().lower()
    if value not in ("true", "false"):
        raise SpaceExError(_where(source, node, name), value, "true or false", f"write {name}=\"true\" or \"false\"")
    return value == "true"


def _param(node: XmlElement, source: str) -> SpaceExParam:
    _attrs(node, source, {"name", "type", "local", "d1", "d2", "dynamics", "controlled"}, ("name", "type"))
    kind = node.attrs["type"].strip()
    if kind not in ("real", "label"):
        raise SpaceExError(_where(source, node, f"param {node.attrs['name']!r}: type"), kind, "real or label",
                           "only real variables/constants and labels are supported (no int, no clock types)")
    for dim in ("d1", "d2"):
        if node.attrs.get(dim, "1").strip() not in ("1", ""):
            raise SpaceExError(_where(source, node, f"param {node.attrs['name']!r}: {dim}"), node.attrs[dim],
                               "1 (scalars)", "SpaceEx matrices/vectors are not supported: write one param per entry")
    dynamics = node.attrs.get("dynamics", "any").strip()
    if dynamics not in ("any", "const"):
        raise SpaceExError(_where(source, node, f"param {node.attrs['name']!r}: dynamics"), dynamics,
                           "any or const", "write dynamics=\"any\" (a variable) or \"const\" (a constant)")
    return SpaceExParam(name=node.attrs["name"].strip(), kind=kind, local=_flag(node, source, "local", "false"),
                        constant=dynamics == "const", controlled=_flag(node, source, "controlled", "true"),
                        line=node.line)


def _child_texts(node: XmlElement, source: str, allowed: set[str]) -> dict[str, XmlElement]:
    out: dict[str, XmlElement] = {}
    for child in node.children:
        if child.tag in _SKIPPED:
            continue
        if child.tag not in allowed:
            _unknown(child, source, node.tag, allowed)
        if child.tag in out:
            raise SpaceExError(_where(source, child), f"a second <{child.tag}>", f"at most one <{child.tag}>",
                               f"join the two with &")
        out[child.tag] = child
    return out


def _location(node: XmlElement, source: str) -> SpaceExLocation:
    _attrs(node, source, {"id", "name"}, ("id",))
    parts = _child_texts(node, source, {"invariant", "flow"})
    name = node.attrs.get("name", "").strip() or f"loc{node.attrs['id'].strip()}"

    def tree(tag: str) -> Any:
        child = parts.get(tag)
        return ("true",) if child is None else parse_constraints(child.text, _where(source, child, f"of {name!r}"))

    return SpaceExLocation(id=node.attrs["id"].strip(), name=name, invariant=tree("invariant"), flow=tree("flow"),
                           line=node.line)


def _transition(node: XmlElement, source: str) -> SpaceExTransition:
    _attrs(node, source, {"source", "target", "asap", "timedriven"}, ("source", "target"))
    parts = _child_texts(node, source, {"label", "guard", "assignment"})
    where = f"{node.attrs['source']}->{node.attrs['target']}"
    guard = parts.get("guard")
    assignment = parts.get("assignment")
    return SpaceExTransition(
        source=node.attrs["source"].strip(), target=node.attrs["target"].strip(),
        label=parts["label"].text.strip() if "label" in parts else "",
        guard=("true",) if guard is None else parse_constraints(guard.text, _where(source, guard, where)),
        assignment=("true",) if assignment is None
        else parse_constraints(assignment.text, _where(source, assignment, where)),
        urgent=_flag(node, source, "asap", "false") or _flag(node, source, "timedriven", "false"),
        line=node.line,
    )


def _bind(node: XmlElement, source: str) -> SpaceExBind:
    _attrs(node, source, {"component", "as"}, ("component",))
    maps: dict[str, Any] = {}
    for child in node.children:
        if child.tag in _SKIPPED:
            continue
        if child.tag != "map":
            _unknown(child, source, "bind", {"map"})
        _attrs(child, source, {"key"}, ("key",))
        key = child.attrs["key"].strip()
        if key in maps:
            raise SpaceExError(_where(source, child, f"key {key!r}"), "a second map of the same key",
                               "one <map> per key", "remove the duplicate")
        maps[key] = parse_expression(child.text, _where(source, child, f"key {key!r}"))
    component = node.attrs["component"].strip()
    return SpaceExBind(component=component, instance=node.attrs.get("as", "").strip() or component, maps=maps,
                       line=node.line)


def _component(node: XmlElement, source: str) -> SpaceExComponent:
    _attrs(node, source, {"id"}, ("id",))
    params: dict[str, SpaceExParam] = {}
    locations: list[SpaceExLocation] = []
    transitions: list[SpaceExTransition] = []
    binds: list[SpaceExBind] = []
    allowed = {"param", "location", "transition", "bind"}
    for child in node.children:
        if child.tag in _SKIPPED:
            continue
        if child.tag == "param":
            p = _param(child, source)
            if p.name in params:
                raise SpaceExError(_where(source, child, f"param {p.name!r}"), "declared twice",
                                   "one <param> per name", "remove the duplicate")
            params[p.name] = p
        elif child.tag == "location":
            locations.append(_location(child, source))
            if len(locations) > MAX_LOCATIONS:
                raise SpaceExError(_where(source, node, f"component {node.attrs['id']!r}"),
                                   f"more than {MAX_LOCATIONS} locations", f"at most {MAX_LOCATIONS} locations",
                                   "reduce the model (the limit bounds the import's work)")
        elif child.tag == "transition":
            transitions.append(_transition(child, source))
        elif child.tag == "bind":
            binds.append(_bind(child, source))
        else:
            _unknown(child, source, "component", allowed)
    cid = node.attrs["id"].strip()
    if binds and (locations or transitions):
        raise SpaceExError(_where(source, node, f"component {cid!r}"), "locations and binds together",
                           "a base component (locations) or a network component (binds)", "split the component")
    ids = [loc.id for loc in locations]
    idset = set(ids)
    dup = sorted(i for i, n in Counter(ids).items() if n > 1)
    if dup:
        raise SpaceExError(_where(source, node, f"component {cid!r}"), f"location id(s) {dup[:5]} repeated",
                           "unique location ids", "renumber the locations")
    for t in transitions:
        for end in (t.source, t.target):
            if end not in idset:
                raise SpaceExError(f"{source}:{t.line}: <transition>", f"location id {end!r}",
                                   f"a location of component {cid!r} ({sorted(ids)[:10]})", "fix source/target")
    return SpaceExComponent(id=cid, params=params, locations=tuple(locations), transitions=tuple(transitions),
                            binds=tuple(binds), line=node.line)


def parse_components(data: bytes, source: str) -> dict[str, SpaceExComponent]:
    """Every component of a SpaceEx XML document, by id.

    Parameters
    ----------
    data : bytes
        The XML document.
    source : str
        Its name (a path) for the messages.

    Raises
    ------
    SpaceExError
        An unsafe or malformed document, an unknown element or attribute, an
        expression outside the supported language, a duplicate id or name.
    """
    root = read_xml(data, source)
    if root.tag != "sspaceex":
        raise SpaceExError(_where(source, root), f"root element <{root.tag}>", "<sspaceex>",
                           "give a SpaceEx model file (root element sspaceex)")
    _attrs(root, source, {"xmlns", "version", "math"}, ())
    if root.attrs.get("math", "SpaceEx") != "SpaceEx":
        raise SpaceExError(_where(source, root, "math"), root.attrs["math"], "SpaceEx", "write math=\"SpaceEx\"")
    components: dict[str, SpaceExComponent] = {}
    for child in root.children:
        if child.tag in _SKIPPED:
            continue
        if child.tag != "component":
            _unknown(child, source, "sspaceex", {"component"})
        c = _component(child, source)
        if c.id in components:
            raise SpaceExError(_where(source, child, f"component {c.id!r}"), "defined twice", "unique component ids",
                               "rename one of them")
        components[c.id] = c
    if not components:
        raise SpaceExError(source, "no <component>", "at least one component", "give a SpaceEx model")
    return components
