"""Problem parameters as constant states, and the initial modes of a box (exact readings).

A verification problem whose system is built by a function of its parameters
(``hybrid_problem(system=build, parameters=...)``) gets a reachability proof when the builder
accepts *symbolic* parameters: :func:`reach_setup` calls ``build`` once with every coordinate of
the problem's box replaced by :func:`hybrid.symbolic.param` (its nominal value), and reads the
returned system's expression trees.  A parameter symbol ``p`` becomes a coordinate with ``ṗ = 0``
and ``p⁺ = p`` whose initial set is the parameter's interval, so one flowpipe covers every
parameter value at once (exact: nothing is sampled).  Two shapes are read:

* **Affine in states and parameters.**  Every flow, jump map, guard and invariant is affine in
  ``(x, p)``: ``p`` is an extra state and the model is affine as it stands.
* **A common time scale.**  Every flow component of every mode is ``m(p)·g(x, p')`` with one
  monomial ``m(p) = Π p_k^{e_k}`` of parameters (``-rate·(T − 10)``), ``m > 0`` over the box and
  ``g`` affine.  For a fixed ``p`` the run of ``ẋ = m(p) g(x)`` is the run of ``ẏ = g(y)`` at
  time ``τ = m(p)·t``, with the same jumps (guards, invariants and resets do not read time), so
  ``always[0, b] φ`` (``φ`` over states and modes, as the fragment requires) holds for every
  ``p`` when it holds for ``ẏ = g(y)`` over ``τ ∈ [0, b·max m]``.  The parameters left in ``g``
  are constant states as above.

Anything else — a parameter multiplying a state in only some terms (bilinear dynamics: polynomial
reachability), a parameter inside a guard in a product with a state, a builder that does not take
symbolic values (it converts, compares or branches on a parameter, so it builds a *different
system per value*) — gets no proof, and :class:`ParameterRoute` says why.

The initial mode (:func:`initial_modes`): a mode name is used as it is; when the invariants decide
it per point, every mode whose invariant may meet the initial box is a start (the box is not
clipped: each start's entry must lie in its invariant or a guard, else the verdict declines); a
function of the point may return any mode, so every mode is a start.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from hybrid.model import Conjunction
from hybrid.symbolic import (
    Apply,
    Condition,
    Const,
    Coordinate,
    Expr,
    MemoryRef,
    Param,
    SymbolicVector,
    Time,
    param,
    render,
    walk_nodes,
)
from hybrid.system import HybridSystem

from .affine import AffineError, AffineForm, Halfspace, Polyhedron, affine_form, affine_vector, condition_polyhedra
from .model import AffineHybridModel, AffineMode, AffineTransition, affine_model

__all__ = ["ParameterRoute", "ReachSetup", "reach_setup", "initial_modes", "MAX_DEGREE"]

MAX_DEGREE = 8
"""Largest total degree a flow term may expand to while the time scale is read (``(p·x)**k``)."""


class ParameterRoute(Exception):
    """Reachability cannot read the parameters of this problem; ``str(exc)`` says why and what to write."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachSetup:
    """What a reachability proof of a problem runs on.

    Attributes
    ----------
    model : AffineHybridModel
        The exact affine model; its ``state_names`` are the states then the parameters kept as states.
    box : tuple of (name, lo, hi)
        The initial box over ``model.state_names`` (states, then parameter intervals).
    parameters : tuple of str
        The parameters that are constant states.
    scale : Fraction
        ``max m(p)`` over the box (1 without a time scale): the window end is multiplied by it.
    scale_text : str
        The time scale ``m(p)`` in words (empty without one).
    """

    model: AffineHybridModel
    box: tuple[tuple[str, float, float], ...]
    parameters: tuple[str, ...] = ()
    scale: Fraction = Fraction(1)
    scale_text: str = ""


Poly = dict[tuple[int, ...], Fraction]


def _symbolic_system(build: Callable[[Mapping[str, Any]], Any], box: Sequence[Any]) -> HybridSystem:
    names = [p.name for p in box]
    bad = [n for n in names if not n.isidentifier()]
    if bad:
        raise ParameterRoute(f"the parameter name(s) {bad} are not identifiers, so they cannot be symbols "
                             "(rename them, e.g. 'rate')")
    point = {p.name: param(p.name, float(p.at(0.0))) for p in box}
    try:
        system = build(point)
    except Exception as exc:  # the user's builder: any failure means it needs numbers
        raise ParameterRoute(
            f"the system is built by a function of the parameters that does not take symbolic values "
            f"(build(point) with hybrid.symbolic.param(...) values raised {type(exc).__name__}: {exc}); it builds "
            "a different system per parameter value, so one flowpipe cannot cover them. Fix: use the parameters "
            "only inside the symbolic expressions (flow_map(-point['k'] * v.x), guards v.x >= point['c']), not "
            "in float(), comparisons or if-branches; or pass the HybridSystem itself") from None
    if not isinstance(system, HybridSystem):
        raise ParameterRoute(f"build(point) with symbolic parameters returned {type(system).__name__}, "
                             "not a HybridSystem")
    return system


def _rewrite(node: Any, coords: Mapping[str, Coordinate]) -> Any:
    """``node`` with each parameter symbol named in ``coords`` replaced by its coordinate (same tree otherwise)."""
    if isinstance(node, Param):
        return coords.get(node.name, node)
    if isinstance(node, tuple):
        return tuple(_rewrite(a, coords) for a in node)
    if isinstance(node, (Expr, Condition, Conjunction, SymbolicVector)) and dataclasses.is_dataclass(node):
        changes = {f.name: _rewrite(getattr(node, f.name), coords) for f in dataclasses.fields(node) if f.init}
        return dataclasses.replace(node, **changes)
    return node


def _parts(system: HybridSystem) -> list[Any]:
    a = system.automaton
    out: list[Any] = [system.flows[m.name] for m in a.modes]
    out += [m.invariant for m in a.modes if m.invariant is not None]
    out += [t.guard for t in a.transitions] + list(system.jumps.values())
    if system.output is not None:
        out.append(system.output)
    return out


def _roots(part: Any) -> list[Any]:
    if isinstance(part, SymbolicVector):
        return list(part.components)
    if isinstance(part, Conjunction):
        return [r for t in part.terms for r in _roots(t)]
    return [part]


def _used(system: HybridSystem, names: set[str]) -> list[str]:
    found: list[str] = []
    for part in _parts(system):
        for root in _roots(part):
            if not isinstance(root, (Expr, Condition)):
                continue
            for node in walk_nodes(root):
                if isinstance(node, Param) and node.name in names and node.name not in found:
                    found.append(node.name)
    return found


def _poly(expr: Any, names: Sequence[str], memory: Mapping[str, float], written: frozenset[str],
          role: str) -> Poly:
    """The exact polynomial of ``expr`` over the coordinates ``names`` (parameters already coordinates)."""
    n = len(names)
    memo: dict[int, Poly] = {}

    def const(q: Fraction) -> Poly:
        return {(0,) * n: q} if q else {}

    def walk(node: Any) -> Poly:
        if id(node) in memo:
            return memo[id(node)]
        if isinstance(node, (Const, Param)):
            if not math.isfinite(node.value):
                raise AffineError(f"{role}: the constant {node.value!r} is not finite", "use finite constants")
            out = const(Fraction(node.value))
        elif isinstance(node, Coordinate):
            out = {tuple(int(i == node.index) for i in range(n)): Fraction(1)}
        elif isinstance(node, (MemoryRef, Time)):
            out = const(affine_form(node, names, memory=memory, written=written, role=role).constant)
        elif isinstance(node, Apply) and node.op in ("add", "sub", "neg", "mul", "div", "pow"):
            out = _apply(node, [walk(a) for a in node.args], n, role)
        else:
            form = affine_form(node, names, memory=memory, written=written, role=role)  # raises with the reason
            out = {tuple(int(i == j) for i in range(n)): c for j, c in enumerate(form.coefficients) if c}
            out.update(const(form.constant))
        memo[id(node)] = out
        return out

    return walk(expr)


def _apply(node: Apply, args: list[Poly], n: int, role: str) -> Poly:
    op = node.op
    if op in ("add", "sub"):
        out = dict(args[0])
        for k, v in args[1].items():
            out[k] = out.get(k, Fraction(0)) + (v if op == "add" else -v)
        return {k: v for k, v in out.items() if v}
    if op == "neg":
        return {k: -v for k, v in args[0].items()}
    if op == "mul":
        return _times(args[0], args[1], node, role)
    if op == "div":
        if any(any(k) for k in args[1]) or not args[1]:
            raise AffineError(f"{role}: the term {render(node)} divides by a state or parameter",
                              "multiply through, or make the divisor a number")
        q = next(iter(args[1].values()))
        return {k: v / q for k, v in args[0].items()}
    power = int(node.args[1].value) if isinstance(node.args[1], Const) else -1
    if power < 0:
        raise AffineError(f"{role}: the term {render(node)} has a non-constant exponent", "use a whole number")
    out: Poly = {(0,) * n: Fraction(1)}
    for _ in range(power):
        out = _times(out, args[0], node, role)
    return out


def _times(a: Poly, b: Poly, node: Any, role: str) -> Poly:
    out: Poly = {}
    for ka, va in a.items():
        for kb, vb in b.items():
            k = tuple(x + y for x, y in zip(ka, kb))
            if sum(k) > MAX_DEGREE:
                raise AffineError(f"{role}: the term {render(node)} has degree above {MAX_DEGREE}",
                                  "reachability reads affine dynamics")
            out[k] = out.get(k, Fraction(0)) + va * vb
    return {k: v for k, v in out.items() if v}


def _monomial_text(exps: Sequence[int], names: Sequence[str]) -> str:
    return "·".join(n if e == 1 else f"{n}^{e}" for n, e in zip(names, exps) if e) or "1"


def _time_scale(flows: Mapping[str, list[Poly]], n: int, names: Sequence[str],
                bounds: Mapping[str, tuple[Fraction, Fraction]]) -> tuple[tuple[int, ...], Fraction, str]:
    """The common parameter monomial of every flow term (its exponents over the parameters), ``max m``, text."""
    terms = [k for comps in flows.values() for poly in comps for k in poly]
    k = len(names) - n
    if not terms:
        return (0,) * k, Fraction(1), ""
    common = tuple(min(t[n + i] for t in terms) for i in range(k))
    if not any(common):
        return common, Fraction(1), ""
    lo, hi = Fraction(1), Fraction(1)
    for name, e in zip(names[n:], common):
        a, b = bounds[name]
        corners = [a ** e, b ** e] + ([Fraction(0)] if a < 0 < b else [])
        lo, hi = min(x * y for x in (lo, hi) for y in corners), max(x * y for x in (lo, hi) for y in corners)
    text = _monomial_text(common, names[n:])
    if lo <= 0:
        raise ParameterRoute(f"every flow is a multiple of {text}, a time scale, but {text} is not positive over the "
                             f"parameter box (it ranges over [{float(lo):g}, {float(hi):g}]): the time would stop or "
                             "run backwards; give the parameter a range of one sign away from 0")
    return common, hi, text


def _flows(system: HybridSystem, used: Sequence[str], memory: Mapping[str, float],
           written: frozenset[str]) -> dict[str, list[Poly]]:
    n = len(system.state_names)
    names = (*system.state_names, *used)
    coords = {p: Coordinate(p, n + i) for i, p in enumerate(used)}
    out: dict[str, list[Poly]] = {}
    for mode in system.automaton.modes:
        vector = system.flows[mode.name]
        role = f"system {system.name!r}: flow of mode {mode.name!r}"
        if not isinstance(vector, SymbolicVector):  # a plain function: the symbolic-model message
            affine_vector(vector, system.state_names, memory=memory, written=written, role=role)
        out[mode.name] = [_poly(_rewrite(c, coords), names, memory, written, f"{role}, component {i}")
                          for i, c in enumerate(vector.components)]
    return out


def _affine_flows(flows: Mapping[str, list[Poly]], common: Sequence[int], system: HybridSystem,
                  used: Sequence[str], kept: Sequence[str]) -> dict[str, tuple[AffineForm, ...]]:
    """Every flow divided by the time scale, as affine forms over ``states + kept`` (or ParameterRoute)."""
    n = len(system.state_names)
    names = (*system.state_names, *used)
    where = {p: n + i for i, p in enumerate(kept)}
    out: dict[str, tuple[AffineForm, ...]] = {}
    for mode, comps in flows.items():
        forms = []
        for i, poly in enumerate(comps):
            coefficients = [Fraction(0)] * (n + len(kept))
            constant = Fraction(0)
            for exps, value in poly.items():
                e = (*exps[:n], *(x - c for x, c in zip(exps[n:], common)))
                if sum(e) > 1:
                    raise ParameterRoute(
                        f"the flow of mode {mode!r}, component {system.state_names[i]!r}, has the term "
                        f"{float(value):g}·{_monomial_text(e, names)}: a parameter multiplies a state (or another "
                        "parameter) and the parameters are not a common time scale of every flow, so the dynamics "
                        "over the parameter box are not affine (nonlinear reachability does not read parameters "
                        "as states in this version). "
                        "Fix: fix that parameter (give low == high), or make it scale every flow of every mode")
                j = next((k for k, x in enumerate(e) if x), None)
                if j is None:
                    constant += value
                else:
                    coefficients[j if j < n else where[names[j]]] += value
            forms.append(AffineForm(coefficients=tuple(coefficients), constant=constant))
        out[mode] = tuple(forms)
    return out


def _over_state(polyhedra: tuple[Polyhedron, ...], output: Sequence[AffineForm] | None, k: int
                ) -> tuple[Polyhedron, ...]:
    """Halfspaces over ``signals + parameters`` rewritten over ``states + parameters`` (exact)."""
    if output is None:
        return polyhedra
    m = len(output)
    out = []
    for p in polyhedra:
        rows = []
        for h in p.halfspaces:
            width = len(output[0].coefficients)
            normal = [sum((h.normal[r] * output[r].coefficients[j] for r in range(m)), Fraction(0))
                      for j in range(width)]
            for i in range(k):
                normal[width - k + i] += h.normal[m + i]
            offset = h.offset - sum((h.normal[r] * output[r].constant for r in range(m)), Fraction(0))
            rows.append(Halfspace(normal=tuple(normal), offset=offset, text=h.text))
        out.append(Polyhedron(halfspaces=tuple(rows)))
    return tuple(out)


def _augmented_model(system: HybridSystem, flows: Mapping[str, tuple[AffineForm, ...]], kept: Sequence[str],
                     memory: Mapping[str, float], written: frozenset[str]) -> AffineHybridModel:
    """The affine model over ``states + kept``: parameters with flow 0 and identity resets."""
    a = system.automaton
    n, k = len(system.state_names), len(kept)
    names = (*system.state_names, *kept)
    signals = (*a.variables, *kept)
    to_state = {p: Coordinate(p, n + i) for i, p in enumerate(kept)}
    to_signal = {p: Coordinate(p, len(a.variables) + i) for i, p in enumerate(kept)}
    output = None if system.output is None else affine_vector(
        _rewrite(system.output, to_state), names, memory=memory, written=written,
        role=f"system {system.name!r}: output map")

    def region(cond: Any, role: str) -> tuple[Polyhedron, ...]:
        return _over_state(condition_polyhedra(_rewrite(cond, to_signal), signals, memory=memory, written=written,
                                               role=role), output, k)

    zero = AffineForm(coefficients=(Fraction(0),) * (n + k), constant=Fraction(0))
    modes = {}
    for mode in a.modes:
        forms = (*flows[mode.name], *([zero] * k))
        inv = (Polyhedron(halfspaces=()),) if mode.invariant is None else region(
            mode.invariant, f"system {system.name!r}: invariant of mode {mode.name!r}")
        modes[mode.name] = AffineMode(name=mode.name, a=tuple(f.coefficients for f in forms),
                                      c=tuple(f.constant for f in forms), invariant=inv)
    identity = tuple(tuple(Fraction(int(i == j)) for j in range(n + k)) for i in range(n + k))
    transitions = []
    for t in a.transitions:
        guard = region(t.guard, f"system {system.name!r}: guard of transition {t.name!r}")
        jump = system.jumps.get(t.name)
        r_matrix, r_offset = identity, (Fraction(0),) * (n + k)
        if jump is not None:
            forms = affine_vector(_rewrite(jump, to_state), names, memory=memory, written=written,
                                  role=f"system {system.name!r}: jump map of transition {t.name!r}")
            r_matrix = (*(f.coefficients for f in forms), *identity[n:])
            r_offset = (*(f.constant for f in forms), *(Fraction(0),) * k)
        transitions.append(AffineTransition(name=t.name, source=t.source, target=t.target, guard=guard,
                                            r_matrix=r_matrix, r_offset=r_offset, direction=t.direction,
                                            priority=t.priority))
    return AffineHybridModel(name=system.name, state_names=names, modes=modes, transitions=tuple(transitions),
                             initial_mode=a.initial_mode)


def _bounds(box: Sequence[Any]) -> dict[str, tuple[Fraction, Fraction]]:
    return {p.name: (Fraction(float(p.low)), Fraction(float(p.high))) for p in box}


def reach_setup(system: Any, initial: Mapping[str, Any], box: Sequence[Any], *, builder: bool,
                nonlinear: bool = False) -> ReachSetup:
    """The affine model and initial box a reachability proof of a problem runs on.

    Parameters
    ----------
    system : HybridSystem or callable
        The problem's system, or (``builder``) ``build(point) -> HybridSystem``.
    initial : mapping {state: Parameter or float}
        The problem's initial states.
    box : sequence of analysis.verify.verification.Parameter
        Every coordinate of the problem's box (initial-state parameters, then model parameters).
    builder : bool
        ``system`` is a function of the point.
    nonlinear : bool
        Read smooth nonlinear flows too (``affine_model(..., nonlinear=True)``), for a system that is not built
        from the parameters; a builder's flows must still be affine (or a time scale of affine flows).

    Raises
    ------
    ParameterRoute
        The parameters cannot be read as constant states (why, and what to write).
    analysis.reach.affine.AffineError
        The system is not symbolic or not affine.
    """
    states = {k: (float(getattr(v, "low", v)), float(getattr(v, "high", v))) for k, v in initial.items()}
    if not builder:
        model = affine_model(system, nonlinear=nonlinear)
        return ReachSetup(model=model, box=tuple((s, *states[s]) for s in model.state_names))
    sym = _symbolic_system(system, box)
    used = _used(sym, {p.name for p in box})
    clash = sorted(set(used) & (set(sym.state_names) | set(sym.automaton.variables)))
    if clash:
        raise ParameterRoute(f"the parameter(s) {clash} have the name of a state or signal; rename them")
    a = sym.automaton
    written = frozenset(w for t in a.transitions for w in t.writes)
    memory = a.initial_memory()
    n = len(sym.state_names)
    bounds = _bounds(box)
    try:
        polys = _flows(sym, used, memory, written)
    except AffineError as exc:
        if not nonlinear:
            raise
        # reach=True reads smooth flows, but not with parameters as constant states: decline, never guess
        raise ParameterRoute(f"{exc}; nonlinear (smooth) flows are read only for a system not built from the "
                             "parameters in this version. Fix: fix the parameters (low == high) and pass the "
                             "HybridSystem itself") from None
    common, scale, text = _time_scale(polys, n, (*sym.state_names, *used), bounds)
    in_flows = {used[i] for comps in polys.values() for poly in comps for e in poly
                for i in range(len(used)) if e[n + i] > common[i]}
    others = [part for part in _parts(sym) if not (isinstance(part, SymbolicVector) and part.kind == "flow")]
    in_rest = {node.name for part in others for root in _roots(part) if isinstance(root, (Expr, Condition))
               for node in walk_nodes(root) if isinstance(node, Param)}
    kept = tuple(p for p in used if p in in_flows or p in in_rest)
    flows = _affine_flows(polys, common, sym, used, kept)
    model = _augmented_model(sym, flows, kept, memory, written)
    full = {**states, **{p: (float(bounds[p][0]), float(bounds[p][1])) for p in kept}}
    return ReachSetup(model=model, box=tuple((s, *full[s]) for s in model.state_names), parameters=kept,
                      scale=scale, scale_text=text)


def _float_down(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) <= q else math.nextafter(f, -math.inf)


def _float_up(q: Fraction) -> float:
    f = float(q)
    return f if Fraction(f) >= q else math.nextafter(f, math.inf)


def _clipped(poly: Polyhedron, box: Sequence[tuple[float, float]]) -> list[tuple[float, float]] | None:
    """A box holding ``box ∩ poly`` (rows on one coordinate tighten it, exactly; others are kept out), or
    None when a row is proven beyond the box."""
    out = [(Fraction(lo), Fraction(hi)) for lo, hi in box]
    for h in poly.halfspaces:
        low = sum((a * (lo if a > 0 else hi) for a, (lo, hi) in zip(h.normal, out)), Fraction(0))
        if low > h.offset:
            return None
        used = [j for j, a in enumerate(h.normal) if a]
        if len(used) == 1:
            j = used[0]
            bound = h.offset / h.normal[j]
            lo, hi = out[j]
            out[j] = (lo, min(hi, bound)) if h.normal[j] > 0 else (max(lo, bound), hi)
    return [(_float_down(lo), _float_up(hi)) for lo, hi in out]


Start = tuple[str, tuple[tuple[str, float, float], ...]]


def initial_modes(setup: ReachSetup, initial_mode: Any, declared: bool) -> tuple[Start, ...]:
    """The modes a run may start in, each with its box of start states (see the module docstring).

    Parameters
    ----------
    initial_mode : str, callable or None
        The problem's.
    declared : bool
        The automaton declares its initial mode (used when ``initial_mode`` is None).

    Returns
    -------
    tuple of (mode, box)
        ``box`` over ``setup.model.state_names``: the whole initial box, or (when the invariants decide the
        mode) its part that may lie in the mode's invariant (rows on one coordinate clip it exactly).
    """
    model = setup.model
    if isinstance(initial_mode, str):
        return ((initial_mode, setup.box),)
    if callable(initial_mode):
        return tuple((m, setup.box) for m in model.modes)
    if declared or len(model.modes) == 1:
        return ((model.initial_mode, setup.box),)
    names = [n for n, _, _ in setup.box]
    box = [(lo, hi) for _, lo, hi in setup.box]
    found = []
    for m, mode in model.modes.items():
        parts = [c for c in (_clipped(p, box) for p in mode.invariant) if c is not None]
        if parts:
            hull = [(min(p[j][0] for p in parts), max(p[j][1] for p in parts)) for j in range(len(box))]
            found.append((m, tuple((n, lo, hi) for n, (lo, hi) in zip(names, hull))))
    if not found:
        raise ParameterRoute("no mode's invariant meets the initial box, so no run can start (give the initial "
                             "mode, or fix the box)")
    return tuple(found)
