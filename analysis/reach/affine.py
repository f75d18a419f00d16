"""Exact affine forms read from the expression tree of :mod:`hybrid.symbolic` (never sampled).

A flow component, a jump map component, an output component or one term of a
guard or invariant is walked node by node and written as ``a·x + b`` with
``a`` and ``b`` exact rationals (:class:`fractions.Fraction`: every float
constant of the tree *is* a dyadic rational, and ``+ − ×`` and division by a
constant stay exact).  A node that is not affine in the state (a product of two
state-dependent terms, a power ``x**2``, ``min``/``max``/``abs``/``ite`` of the
state, a transcendental function, the time ``t``, a memory variable that a
reset writes) is refused with :class:`AffineError`, naming the term and what
to write instead.  Nothing here is numerical: :mod:`hybrid.affine` decides
affinity by sampling, this module by reading the tree.

Conditions (guards and invariants, in their level form ``g >= 0``) become a
*disjunction of conjunctions* of halfspaces ``a·x <= b`` (:class:`Polyhedron`
lists): ``min`` is a conjunction, ``max`` a disjunction, ``-abs(e)`` (the
level form of ``==``) the pair ``e <= 0, -e <= 0``.  A
:class:`hybrid.model.Conjunction` (``all_of``) is the conjunction of its terms.

Examples
--------
>>> from hybrid.symbolic import coordinates
>>> x = coordinates("p", "q")
>>> form = affine_form(3.0 * (x.p - 2.0 * x.q) + 1.5, ("p", "q"))
>>> [str(c) for c in form.coefficients], str(form.constant)
(['3', '-6'], '3/2')
>>> affine_form(x.p * x.q, ("p", "q"))
Traceback (most recent call last):
...
analysis.reach.affine.AffineError: the term (p * q) is a product of two state-dependent factors, p and q: reachability reads affine dynamics x' = A x + B u + c only; fix: linearise it, or split the mode so that one factor is constant in each
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from hybrid.errors import ModelDefinitionError
from hybrid.model import Conjunction
from hybrid.symbolic import (
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
    SymbolicVector,
    Time,
    Unsupported,
    level_form,
    render,
)

__all__ = [
    "AffineError",
    "AffineForm",
    "Halfspace",
    "Polyhedron",
    "affine_form",
    "affine_vector",
    "condition_polyhedra",
    "MAX_DISJUNCTS",
]

MAX_DISJUNCTS = 64
"""Largest number of conjunctions a guard or invariant may expand to (``max`` of ``min`` multiplies them)."""


class AffineError(ModelDefinitionError):
    """A model part is not affine where reachability needs it (or is not symbolic at all)."""

    def __init__(self, message: str, fix: str) -> None:
        self.fix = fix
        super().__init__(f"{message}; fix: {fix}")


@dataclass(frozen=True, kw_only=True, slots=True)
class AffineForm:
    """``coefficients · x + constant``, exactly.

    Attributes
    ----------
    coefficients : tuple of Fraction, shape (n,)
    constant : Fraction
    """

    coefficients: tuple[Fraction, ...]
    constant: Fraction

    @property
    def is_constant(self) -> bool:
        """Whether every coefficient is zero."""
        return not any(self.coefficients)

    def scaled(self, k: Fraction) -> AffineForm:
        """``k`` times the form."""
        return AffineForm(coefficients=tuple(k * a for a in self.coefficients), constant=k * self.constant)

    def plus(self, other: AffineForm, sign: int = 1) -> AffineForm:
        """The form plus ``sign`` times ``other``."""
        return AffineForm(coefficients=tuple(a + sign * b for a, b in zip(self.coefficients, other.coefficients)),
                          constant=self.constant + sign * other.constant)


@dataclass(frozen=True, kw_only=True, slots=True)
class Halfspace:
    """``normal · x <= offset`` exactly (rationals)."""

    normal: tuple[Fraction, ...]
    offset: Fraction
    text: str = ""


@dataclass(frozen=True, kw_only=True, slots=True)
class Polyhedron:
    """A conjunction of halfspaces (empty tuple: the whole space)."""

    halfspaces: tuple[Halfspace, ...]


def _constant(value: Fraction, n: int) -> AffineForm:
    return AffineForm(coefficients=(Fraction(0),) * n, constant=value)


def affine_form(expr: Any, names: Sequence[str], *, memory: Mapping[str, float] | None = None,
                written: frozenset[str] = frozenset(), role: str = "expression") -> AffineForm:
    """The exact affine form of a symbolic expression in the coordinates ``names``.

    Parameters
    ----------
    expr : hybrid.symbolic.Expr
    names : sequence of str, length n
        The coordinates, in vector order (a coordinate's index must match its name).
    memory : mapping or None
        Values of memory variables the expression may read as constants.
    written : frozenset of str
        Memory variables some reset writes: reading one is refused (not a constant).
    role : str
        What the expression is (``"flow of mode 'on', component 'T'"``), for the messages.

    Raises
    ------
    AffineError
        Naming the first non-affine term and ``role``.
    """
    n, mem = len(names), dict(memory or {})
    memo: dict[int, AffineForm] = {}

    def walk(node: Any) -> AffineForm:
        key = id(node)
        if key not in memo:
            memo[key] = _node_form(node, walk, names, mem, written, role)
        return memo[key]

    if not isinstance(expr, Expr):
        raise AffineError(f"{role} is {expr!r}, not a symbolic expression",
                          "write it with hybrid.symbolic (coordinates(), flow_map(), jump_map())")
    out = walk(expr)
    assert len(out.coefficients) == n
    return out


def _node_form(node: Any, walk: Any, names: Sequence[str], mem: Mapping[str, float], written: frozenset[str],
               role: str) -> AffineForm:
    n = len(names)
    if isinstance(node, (Const, Param)):
        if node.value != node.value or node.value in (float("inf"), float("-inf")):
            raise AffineError(f"{role}: the constant {node.value!r} is not finite", "use finite constants")
        return _constant(Fraction(node.value), n)
    if isinstance(node, Coordinate):
        if node.index >= n or names[node.index] != node.name:
            raise AffineError(f"{role}: coordinate {node.name!r} (index {node.index}) is not coordinate "
                              f"{node.index} of {list(names)}", f"build it with coordinates{tuple(names)!r}")
        coefficients = [Fraction(0)] * n
        coefficients[node.index] = Fraction(1)
        return AffineForm(coefficients=tuple(coefficients), constant=Fraction(0))
    if isinstance(node, MemoryRef):
        return _memory_form(node, mem, written, role, n)
    if isinstance(node, Time):
        raise AffineError(f"{role} reads the time t: reachability handles time-invariant affine dynamics",
                          "add a clock state c with flow c' = 1 and write c instead of t")
    if isinstance(node, Unsupported):
        raise AffineError(f"{role}: {node.message()}", "rewrite the term as the message says")
    if isinstance(node, Apply):
        return _apply_form(node, [walk(a) for a in node.args], role)
    if isinstance(node, (Ite, Select)):
        raise AffineError(f"{role}: the term {render(node)} is piecewise (ite/select), not affine",
                          "split the mode into one mode per branch, with the branch condition as invariant")
    raise AffineError(f"{role}: {node!r} is not a symbolic expression", "write it with hybrid.symbolic")


def _memory_form(node: MemoryRef, mem: Mapping[str, float], written: frozenset[str], role: str,
                 n: int) -> AffineForm:
    if node.name in written:
        raise AffineError(f"{role} reads the memory variable {node.name!r}, which a reset writes: reachability "
                          "does not track memory", f"model {node.name!r} as a state with flow 0 and a jump map")
    if node.name not in mem:
        raise AffineError(f"{role} reads the memory variable {node.name!r}, which is not declared",
                          "declare it as a MemoryVariable of the automaton")
    return _constant(Fraction(float(mem[node.name])), n)


_NON_AFFINE = {"abs": "abs()", "min": "min()", "max": "max()", "sin": "sin()", "cos": "cos()", "exp": "exp()",
               "log": "log()", "sqrt": "sqrt()", "atan2": "atan2()", "inv": "a reciprocal"}


def _apply_form(node: Apply, args: list[AffineForm], role: str) -> AffineForm:
    op = node.op
    if op == "add":
        return args[0].plus(args[1])
    if op == "sub":
        return args[0].plus(args[1], -1)
    if op == "neg":
        return args[0].scaled(Fraction(-1))
    if op == "mul":
        if args[0].is_constant:
            return args[1].scaled(args[0].constant)
        if args[1].is_constant:
            return args[0].scaled(args[1].constant)
        raise AffineError(
            f"the term {render(node)} is a product of two state-dependent factors, {render(node.args[0])} and "
            f"{render(node.args[1])}: reachability reads affine dynamics x' = A x + B u + c only",
            "linearise it, or split the mode so that one factor is constant in each")
    if op == "div":
        if not args[1].is_constant or args[1].constant == 0:
            raise AffineError(f"{role}: the term {render(node)} divides by a non-constant", "multiply through")
        return args[0].scaled(1 / args[1].constant)
    if op == "pow":
        k = int(args[1].constant)
        if k == 0:
            return _constant(Fraction(1), len(args[0].coefficients))
        if k == 1 or args[0].is_constant:
            return args[0] if k == 1 else _constant(args[0].constant ** k, len(args[0].coefficients))
        raise AffineError(f"{role}: the term {render(node)} is a power {k} of a state-dependent term, not affine",
                          "reachability of polynomial dynamics is not available yet; linearise the flow")
    if all(a.is_constant for a in args) and op in ("abs", "min", "max"):
        values = [a.constant for a in args]
        value = abs(values[0]) if op == "abs" else (min(values) if op == "min" else max(values))
        return _constant(value, len(args[0].coefficients))
    what = _NON_AFFINE.get(op, op)
    raise AffineError(f"{role}: the term {render(node)} uses {what}, which is not affine in the state",
                      "precompute constants as floats, and split piecewise terms into modes")


def affine_vector(vector: Any, names: Sequence[str], *, memory: Mapping[str, float] | None = None,
                  written: frozenset[str] = frozenset(), role: str = "map") -> tuple[AffineForm, ...]:
    """The affine forms of every component of a :class:`~hybrid.symbolic.SymbolicVector`.

    Raises
    ------
    AffineError
        ``vector`` is not symbolic (a plain Python function: reachability cannot read it), or a
        component is not affine.
    """
    if not isinstance(vector, SymbolicVector):
        raise AffineError(
            f"{role} is {vector!r}, a plain Python function: reachability needs a symbolic model to read "
            "its affine form exactly",
            "write it with hybrid.symbolic, e.g. x = coordinates('h', 'v'); flow_map(x.v, -9.81) for a flow, "
            "jump_map(x.h, -0.8 * x.v) for a jump map")
    return tuple(affine_form(e, names, memory=memory, written=written, role=f"{role}, component {i}")
                 for i, e in enumerate(vector.components))


def condition_polyhedra(condition: Any, names: Sequence[str], *, memory: Mapping[str, float] | None = None,
                        written: frozenset[str] = frozenset(), role: str = "condition") -> tuple[Polyhedron, ...]:
    """A guard or invariant (level form ``g >= 0``) as a disjunction of conjunctions of halfspaces.

    Returns
    -------
    tuple of Polyhedron
        The condition holds exactly on their union.

    Raises
    ------
    AffineError
        A term that is not affine, a plain Python function, or more than :data:`MAX_DISJUNCTS` disjuncts.
    """
    if isinstance(condition, Conjunction):
        parts = [condition_polyhedra(t, names, memory=memory, written=written, role=role) for t in condition.terms]
        return _conjoin(parts, role)
    if isinstance(condition, Condition):
        condition = level_form(condition)
    if not isinstance(condition, Expr):
        raise AffineError(
            f"{role} is {condition!r}, a plain Python function: reachability needs a symbolic model",
            "write it as a symbolic comparison, e.g. v = coordinates('h', 'v'); (v.h <= 0.0) & (v.v <= 0.0)")
    return _level_polyhedra(condition, names, memory or {}, written, role)


def _level_polyhedra(expr: Expr, names: Sequence[str], memory: Mapping[str, float], written: frozenset[str],
                     role: str) -> tuple[Polyhedron, ...]:
    if isinstance(expr, Apply) and expr.op == "min":
        return _conjoin([_level_polyhedra(a, names, memory, written, role) for a in expr.args], role)
    if isinstance(expr, Apply) and expr.op == "max":
        out = tuple(p for a in expr.args for p in _level_polyhedra(a, names, memory, written, role))
        if len(out) > MAX_DISJUNCTS:
            raise AffineError(f"{role} expands to {len(out)} conjunctions", f"keep it under {MAX_DISJUNCTS}")
        return out
    if isinstance(expr, Apply) and expr.op == "neg" and isinstance(expr.args[0], Apply) and expr.args[0].op == "abs":
        form = affine_form(expr.args[0].args[0], names, memory=memory, written=written, role=role)
        text = f"{render(expr.args[0].args[0])} == 0"
        return (Polyhedron(halfspaces=(_halfspace(form, text), _halfspace(form.scaled(Fraction(-1)), text))),)
    form = affine_form(expr, names, memory=memory, written=written, role=role)
    # g >= 0  <=>  -g <= 0  <=>  (-a)·x <= b
    return (Polyhedron(halfspaces=(_halfspace(form.scaled(Fraction(-1)), f"{render(expr)} >= 0"),)),)


def _halfspace(form: AffineForm, text: str) -> Halfspace:
    """``form <= 0`` as ``a·x <= -constant``."""
    return Halfspace(normal=form.coefficients, offset=-form.constant, text=text)


def _conjoin(parts: Sequence[tuple[Polyhedron, ...]], role: str) -> tuple[Polyhedron, ...]:
    count = 1
    for p in parts:
        count *= len(p)
    if count > MAX_DISJUNCTS:
        raise AffineError(f"{role} expands to {count} conjunctions of halfspaces", f"keep it under {MAX_DISJUNCTS}")
    return tuple(Polyhedron(halfspaces=tuple(h for poly in combo for h in poly.halfspaces))
                 for combo in itertools.product(*parts))

