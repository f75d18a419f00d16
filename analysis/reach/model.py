"""A symbolic :class:`~hybrid.system.HybridSystem` read as an affine hybrid automaton (exactly).

Per mode: the flow ``ẋ = A x + c`` (:func:`~analysis.reach.affine.affine_vector` of its
``flow_map``) and the invariant as polyhedra; per transition: the guard as polyhedra, the jump
map ``x⁺ = R x + r`` (identity without one), the direction and the priority.  Guards and
invariants read the *signals* ``v``; with an output map ``v = C x + d`` (symbolic, affine, without
time) they are rewritten over the state exactly (``a·v <= b`` becomes ``(a C)·x <= b − a·d``).

Memory variables are constants here: one that a guard, invariant, flow or jump map reads must not
be written by any reset (reachability does not track memory yet); its value is the automaton's
initial memory.  Everything else is refused with :class:`~analysis.reach.affine.AffineError`
naming the part and the fix.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from hybrid.system import HybridSystem

from .affine import AffineError, AffineForm, Halfspace, Polyhedron, affine_vector, condition_polyhedra
from .smooth import SmoothFlow, smooth_flow

__all__ = ["AffineMode", "AffineTransition", "AffineHybridModel", "affine_model"]


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineMode:
    """``ẋ = A x + c`` with invariant ``∪ polyhedra`` (``((),)``, one empty conjunction: everywhere).

    A mode with a nonlinear (smooth) flow, read only by ``affine_model(..., nonlinear=True)``, has
    ``smooth`` set and ``a``, ``c`` empty.
    """

    name: str
    a: tuple[tuple[Fraction, ...], ...]
    c: tuple[Fraction, ...]
    invariant: tuple[Polyhedron, ...]
    smooth: SmoothFlow | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineTransition:
    """Guard ``∪ polyhedra``, jump ``x⁺ = R x + r``, crossing ``direction`` and ``priority`` (as in hybrid)."""

    name: str
    source: str
    target: str
    guard: tuple[Polyhedron, ...]
    r_matrix: tuple[tuple[Fraction, ...], ...]
    r_offset: tuple[Fraction, ...]
    direction: int
    priority: int


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineHybridModel:
    """The exact affine reading of a hybrid system."""

    name: str
    state_names: tuple[str, ...]
    modes: Mapping[str, AffineMode]
    transitions: tuple[AffineTransition, ...]
    initial_mode: str

    def outgoing(self, mode: str) -> tuple[AffineTransition, ...]:
        """Transitions leaving ``mode`` (priority order)."""
        return tuple(sorted((t for t in self.transitions if t.source == mode), key=lambda t: t.priority))


_NOT_SYMBOLIC = ("reachability needs a symbolic model: a HybridSystem whose flows, jump maps, guards and "
                 "invariants are hybrid.symbolic expressions")


def affine_model(system: Any, *, nonlinear: bool = False) -> AffineHybridModel:
    """The exact affine reading of ``system`` (see the module docstring).

    With ``nonlinear``, a mode whose flow is not affine but smooth (polynomials, sin, cos:
    :func:`analysis.reach.smooth.smooth_flow`) is read as a :class:`SmoothFlow` instead of refused;
    guards, invariants and jump maps must still be affine.

    Raises
    ------
    AffineError
        ``system`` is not a :class:`HybridSystem`, a part is a plain Python function, or a part
        is not affine (naming it and what to write instead).

    An :class:`AffineHybridModel` is returned as it is (a model read already, e.g. with parameters as
    constant states: :mod:`analysis.reach.parameters`).
    """
    if isinstance(system, AffineHybridModel):
        return system
    if not isinstance(system, HybridSystem):
        raise AffineError(f"system = {system!r}: {_NOT_SYMBOLIC}",
                          "build hybrid.system.HybridSystem(automaton=..., state_names=..., flows={mode: "
                          "flow_map(...)}, jumps={transition: jump_map(...)})")
    automaton = system.automaton
    names = system.state_names
    written = frozenset(w for t in automaton.transitions for w in t.writes)
    memory = automaton.initial_memory()
    output = _output_forms(system, memory, written)
    modes = {}
    for mode in automaton.modes:
        role = f"system {system.name!r}: flow of mode {mode.name!r}"
        try:
            forms = affine_vector(system.flows[mode.name], names, memory=memory, written=written, role=role)
        except AffineError:
            if not nonlinear:
                raise
            forms = None
            smooth = smooth_flow(system.flows[mode.name], names, memory=memory, written=written, role=role)
        invariant = (Polyhedron(halfspaces=()),) if mode.invariant is None else _over_state(
            condition_polyhedra(mode.invariant, automaton.variables, memory=memory, written=written,
                                role=f"system {system.name!r}: invariant of mode {mode.name!r}"), output)
        if forms is None:
            modes[mode.name] = AffineMode(name=mode.name, a=(), c=(), invariant=invariant, smooth=smooth)
        else:
            modes[mode.name] = AffineMode(name=mode.name, a=tuple(f.coefficients for f in forms),
                                          c=tuple(f.constant for f in forms), invariant=invariant)
    transitions = tuple(_transition(system, t, memory, written, output) for t in automaton.transitions)
    return AffineHybridModel(name=system.name, state_names=tuple(names), modes=modes, transitions=transitions,
                             initial_mode=automaton.initial_mode)


def _transition(system: HybridSystem, t: Any, memory: Mapping[str, float], written: frozenset[str],
                output: Sequence[AffineForm] | None) -> AffineTransition:
    names = system.state_names
    guard = _over_state(condition_polyhedra(t.guard, system.automaton.variables, memory=memory, written=written,
                                            role=f"system {system.name!r}: guard of transition {t.name!r}"), output)
    jump = system.jumps.get(t.name)
    n = len(names)
    if jump is None:
        r_matrix = tuple(tuple(Fraction(int(i == j)) for j in range(n)) for i in range(n))
        r_offset = (Fraction(0),) * n
    else:
        forms = affine_vector(jump, names, memory=memory, written=written,
                              role=f"system {system.name!r}: jump map of transition {t.name!r}")
        r_matrix = tuple(f.coefficients for f in forms)
        r_offset = tuple(f.constant for f in forms)
    return AffineTransition(name=t.name, source=t.source, target=t.target, guard=guard, r_matrix=r_matrix,
                            r_offset=r_offset, direction=t.direction, priority=t.priority)


def _output_forms(system: HybridSystem, memory: Mapping[str, float],
                  written: frozenset[str]) -> tuple[AffineForm, ...] | None:
    if system.output is None:
        return None
    return affine_vector(system.output, system.state_names, memory=memory, written=written,
                         role=f"system {system.name!r}: output map")


def _over_state(polyhedra: tuple[Polyhedron, ...], output: Sequence[AffineForm] | None) -> tuple[Polyhedron, ...]:
    """Halfspaces over the signals rewritten over the state through ``v = C x + d`` (exact)."""
    if output is None:
        return polyhedra
    out = []
    for p in polyhedra:
        rows = []
        for h in p.halfspaces:
            n = len(output[0].coefficients)
            normal = tuple(sum((h.normal[k] * output[k].coefficients[j] for k in range(len(output))), Fraction(0))
                           for j in range(n))
            offset = h.offset - sum((h.normal[k] * output[k].constant for k in range(len(output))), Fraction(0))
            rows.append(Halfspace(normal=normal, offset=offset, text=h.text))
        out.append(Polyhedron(halfspaces=tuple(rows)))
    return tuple(out)
