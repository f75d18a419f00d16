"""Smooth (polynomial and sin/cos) flows read from the symbolic tree for nonlinear reachability.

A flow component of a mode that is not affine is accepted by :func:`smooth_flow` when it is built
from the state coordinates, numbers, memory variables that no reset writes (constants at their
initial values), parameters (constants at their values), ``+ − ×``, division by a constant,
integer powers, ``sin`` and ``cos``: every function the producer (:mod:`hybrid.symbolic`'s
``enclose``) and the re-checker (:mod:`analysis.interval`) enclose soundly, and smooth, so the
Lagrange remainder of the linearisation exists.  Anything else — ``atan2``, ``exp``, ``log``,
``sqrt``, ``abs``/``min``/``max``, ``ite``/``select``, the time ``t``, a memory variable a reset
writes — is refused with :class:`~analysis.reach.affine.AffineError`, naming the term, the mode and
the fix.  The derivatives are the exact symbolic ones (:func:`hybrid.symbolic.diff`).

This module holds no set code: the producer (:mod:`analysis.reach.nonlinear`) and the independent
re-check (:mod:`analysis.reach.recheck_smooth`) both read the model through it.

Examples
--------
>>> from hybrid.symbolic import coordinates, flow_map
>>> x = coordinates("x", "y")
>>> f = smooth_flow(flow_map(x.y, (1.0 - x.x ** 2) * x.y - x.x), ("x", "y"))
>>> len(f.components), len(f.hessian[1][0])
(2, 2)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from hybrid.symbolic import (
    Apply,
    Const,
    Coordinate,
    Expr,
    Ite,
    MemoryRef,
    Param,
    Select,
    SymbolicVector,
    Time,
    Unsupported,
    diff,
    render,
)

from .affine import AffineError

__all__ = ["SMOOTH_OPERATIONS", "SmoothFlow", "smooth_flow"]

SMOOTH_OPERATIONS = ("add", "sub", "neg", "mul", "div", "pow", "sin", "cos")
"""Operations a nonlinear flow may use (enclosed soundly by both interval arithmetics, and smooth)."""

_FIX = ("write the flow with + - *, division by constants, integer powers, sin and cos of the state; split a "
        "piecewise term (ite, select, abs, min, max) into modes with the branch condition as invariant")


@dataclass(frozen=True, kw_only=True, slots=True)
class SmoothFlow:
    """``ẋ = f(x)`` with its exact first and second derivatives (symbolic, constants folded in).

    Attributes
    ----------
    components : tuple of Expr, length n
        ``f_i`` (memory variables and parameters replaced by their constant values).
    jacobian : tuple of tuple of Expr, shape (n, n)
        ``∂f_i/∂x_j``.
    hessian : tuple of tuple of tuple of Expr, shape (n, n, n)
        ``∂²f_i/∂x_j∂x_k`` (symmetric in ``j, k``).
    names : tuple of str
        The state coordinates, in vector order.
    """

    components: tuple[Expr, ...]
    jacobian: tuple[tuple[Expr, ...], ...]
    hessian: tuple[tuple[tuple[Expr, ...], ...], ...]
    names: tuple[str, ...]


def smooth_flow(vector: Any, names: Sequence[str], *, memory: Mapping[str, float] | None = None,
                written: frozenset[str] = frozenset(), role: str = "flow") -> SmoothFlow:
    """The :class:`SmoothFlow` of a symbolic flow map (see the module docstring).

    Raises
    ------
    AffineError
        A plain Python function, or a term outside :data:`SMOOTH_OPERATIONS` (named, with the fix).
    """
    if not isinstance(vector, SymbolicVector):
        raise AffineError(f"{role} is {vector!r}, a plain Python function: reachability needs a symbolic model",
                          "write it with hybrid.symbolic, e.g. x = coordinates('x', 'y'); flow_map(x.y, -x.x)")
    names = tuple(names)
    if len(vector.components) != len(names):
        raise AffineError(f"{role} has {len(vector.components)} components for the {len(names)} states {list(names)}",
                          "give one component per state")
    mem = dict(memory or {})
    components = tuple(_constants(e, names, mem, written, f"{role}, component {names[i]!r}")
                       for i, e in enumerate(vector.components))
    jacobian = tuple(tuple(diff(f, x) for x in names) for f in components)
    hessian = tuple(tuple(tuple(diff(d, x) for x in names) for d in row) for row in jacobian)
    return SmoothFlow(components=components, jacobian=jacobian, hessian=hessian, names=names)


def _constants(expr: Any, names: tuple[str, ...], mem: Mapping[str, float], written: frozenset[str],
               role: str) -> Expr:
    """``expr`` with memory and parameters as constants; refuses what is not smooth and enclosable."""
    memo: dict[int, Expr] = {}

    def walk(node: Any) -> Expr:
        key = id(node)
        if key not in memo:
            memo[key] = _node(node, walk, names, mem, written, role)
        return memo[key]

    if not isinstance(expr, Expr):
        raise AffineError(f"{role} is {expr!r}, not a symbolic expression", _FIX)
    return walk(expr)


def _node(node: Any, walk: Any, names: tuple[str, ...], mem: Mapping[str, float], written: frozenset[str],
          role: str) -> Expr:
    if isinstance(node, Const):
        if node.value != node.value or node.value in (float("inf"), float("-inf")):
            raise AffineError(f"{role}: the constant {node.value!r} is not finite", "use finite constants")
        return node
    if isinstance(node, Param):
        return Const(float(node.value))
    if isinstance(node, Coordinate):
        if node.index >= len(names) or names[node.index] != node.name:
            raise AffineError(f"{role}: coordinate {node.name!r} (index {node.index}) is not coordinate "
                              f"{node.index} of {list(names)}", f"build it with coordinates{names!r}")
        return node
    if isinstance(node, MemoryRef):
        if node.name in written or node.name not in mem:
            raise AffineError(f"{role} reads the memory variable {node.name!r}, which a reset writes or nobody "
                              "declares: reachability does not track memory",
                              f"model {node.name!r} as a state with flow 0 and a jump map")
        return Const(float(mem[node.name]))
    if isinstance(node, Time):
        raise AffineError(f"{role} reads the time t: reachability handles time-invariant dynamics",
                          "add a clock state c with flow c' = 1 and write c instead of t")
    if isinstance(node, Unsupported):
        raise AffineError(f"{role}: {node.message()}", "rewrite the term as the message says")
    if isinstance(node, (Ite, Select)):
        raise AffineError(f"{role}: the term {render(node)} is piecewise (ite/select): nonlinear reachability "
                          "needs a smooth flow (its Lagrange remainder)", _FIX)
    if isinstance(node, Apply):
        if node.op not in SMOOTH_OPERATIONS:
            raise AffineError(f"{role}: the term {render(node)} uses {node.op}(), which nonlinear reachability does "
                              f"not enclose (supported: polynomials, sin, cos)", _FIX)
        return Apply(node.op, tuple(walk(a) for a in node.args))
    raise AffineError(f"{role}: {node!r} is not a symbolic expression", _FIX)
