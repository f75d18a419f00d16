"""Case splits for the SpaceEx export: a transition whose guard, reset or jump map holds a piecewise function.

SpaceEx's expressions have no ``ite``, ``select``, ``min``, ``max`` or ``abs``,
but a *transition* can be split by cases: ``x := ite(c, a, b)`` is the two
transitions ``guard & c`` with ``x := a`` and ``guard & not c`` with ``x := b``
(the same jumps: every state satisfies exactly one of ``c`` and ``not c``).
``min(a, b)`` is ``ite(a <= b, a, b)``, ``max`` likewise, ``abs(a)`` is
``ite(a >= 0, a, -a)``, and ``select(i, (o_0, ..., o_{n-1}))`` is
``ite(i < 1/2, o_0, ite(i < 3/2, o_1, ...))``: exact for the integer indices
models write (an obstacle's number), and away from the guards' closure at the
integers (SpaceEx and hybrid read ``i < 1`` as the closed ``i <= 1``, which
would enable two cases at ``i = 1``); a fractional index in ``[k - 1/2, k)``
takes option ``k`` instead of ``k - 1``, and the domain ``-1 < i < n`` is not
enforced (an index outside it takes the first or last option).  The two cases
of a split share the boundary of its condition, where both may fire.  A flow or
an invariant cannot be split this way (that would split the location), so
there these functions stay refused.
"""

from __future__ import annotations

from typing import Any

from .symbolic import Apply, Compare, Condition, Const, Expr, Ite, Logic, Select

__all__ = ["Split", "case_of", "replace", "negate", "static_truth", "MAX_CASES"]

MAX_CASES = 256
"""Most transitions one transition may be split into (8 binary case distinctions)."""


class Split(Exception):
    """Raised by the expression writer at a piecewise node; carries the node."""

    def __init__(self, node: Expr) -> None:
        super().__init__(type(node).__name__)
        self.node = node


def case_of(node: Expr) -> tuple[Condition, Expr, Expr]:
    """``(condition, then, otherwise)`` with ``node == ite(condition, then, otherwise)``."""
    if isinstance(node, Ite):
        return node.condition, node.then, node.otherwise
    if isinstance(node, Select):
        first, rest = node.options[0], node.options[1:]
        if not rest:
            return Compare("<", node.index, Const(0.5)), first, first
        otherwise = rest[0] if len(rest) == 1 else Select(node.index - 1.0, rest)
        return Compare("<", node.index, Const(0.5)), first, otherwise
    assert isinstance(node, Apply)
    if node.op == "abs":
        a = node.args[0]
        return Compare(">=", a, Const(0.0)), a, Apply("neg", (a,))
    a, rest = node.args[0], node.args[1:]
    b = rest[0] if len(rest) == 1 else Apply(node.op, rest)
    return Compare("<=" if node.op == "min" else ">=", a, b), a, b


def replace(node: Any, target: Any, replacement: Any) -> Any:
    """``node`` with the subtree ``target`` (by identity) replaced."""
    if node is target:
        return replacement
    if isinstance(node, Apply):
        args = tuple(replace(a, target, replacement) for a in node.args)
        return node if all(x is y for x, y in zip(args, node.args)) else Apply(node.op, args)
    if isinstance(node, Ite):
        parts = (replace(node.condition, target, replacement), replace(node.then, target, replacement),
                 replace(node.otherwise, target, replacement))
        return Ite(*parts)
    if isinstance(node, Select):
        return Select(replace(node.index, target, replacement),
                      tuple(replace(o, target, replacement) for o in node.options))
    if isinstance(node, Compare):
        return Compare(node.op, replace(node.left, target, replacement), replace(node.right, target, replacement),
                       node.exact)
    if isinstance(node, Logic):
        return Logic(node.op, tuple(replace(a, target, replacement) for a in node.args))
    return node


_FLIP = {">=": "<", ">": "<=", "<=": ">", "<": ">=", "==": "!=", "!=": "=="}
_MIRROR = {">=": "<=", ">": "<", "<=": ">=", "<": ">", "==": "==", "!=": "!="}


def static_truth(c: Condition) -> bool | None:
    """The truth of a comparison of a (finite, real) expression with an infinite constant, else ``None``.

    ``x < inf`` holds for every real ``x`` (a guard against a missing measurement, say): the case split then
    keeps its one possible branch instead of writing an infinity SpaceEx cannot read.
    """
    if not isinstance(c, Compare):
        return None
    op, left, right = c.op, c.left, c.right
    if isinstance(left, Const) and not isinstance(right, Const):
        op, left, right = _MIRROR[op], right, left
    if not isinstance(right, Const) or isinstance(left, Const) or right.value not in (float("inf"), -float("inf")):
        return None
    big = right.value > 0  # x op +inf, or x op -inf
    return {"<": big, "<=": big, ">": not big, ">=": not big, "==": False, "!=": True}[op]


def negate(c: Condition) -> Condition:
    """``not c`` pushed onto the comparisons (``not (a >= b)`` is ``a < b``)."""
    if isinstance(c, Compare):
        return Compare(_FLIP[c.op], c.left, c.right)
    assert isinstance(c, Logic)
    if c.op == "not":
        return c.args[0]
    return Logic("or" if c.op == "and" else "and", tuple(negate(a) for a in c.args))
