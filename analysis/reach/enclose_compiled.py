"""The producer's interval enclosures of a list of expressions, compiled once into straight-line Python.

:mod:`analysis.reach.nonlinear` encloses ``f``, ``Df`` and the Hessian entries of a smooth flow at every
step, over a new box each time.  :func:`hybrid.symbolic.enclose` walks the expression tree for that
(dispatch by type, a memo dictionary, a tuple per node): most of a step's time for a small flow.
:func:`compile_enclosure` turns the list once into a program: the expression DAG in topological order
(nodes with the same structure merged: the numbers of a node depend only on its structure and the box),
one instruction per operation node, each a kernel on the float bounds of its arguments' slots.  No dispatch
by type, no memo and no tuple of the tree walk per step; no generated code either (the project runs
generated code in one place only, ``hybrid.symbolic_core``).

The arithmetic is :func:`hybrid.symbolic.enclose`'s, operation by operation, so the bounds are
the same floats (``tests/analysis/reach/test_enclose_compiled.py`` compares them on random boxes and
checks the exact value at random points, in rationals, lies inside):

* ``+``, ``−``: the float sum or difference of the bounds moved one ulp outward (``math.nextafter``),
  infinite bounds kept; ``neg`` exact;
* ``×``: the minimum and maximum of the four corner products (``0·∞`` taken as 0) one ulp outward;
* ``/`` by a constant: the product with ``[1/c]`` one ulp outward on each side (``c`` the divisor's
  lower bound, as ``enclose`` does: a smooth flow divides by constants only);
* integer powers: the end points' powers (``0`` the minimum of an even power of an interval holding
  0), two ulps outward; ``sin``, ``cos``: ``enclose``'s own kernel (end points and interior extremes,
  ``±10⁻¹⁵`` more, clipped to ``[−1, 1]``);
* every node's interval is cleaned as in ``enclose`` (a lower bound ``+∞`` or an upper bound ``−∞``
  becomes the largest float), a root with a NaN bound becomes ``(−∞, ∞)``.

An expression outside these operations (or a coordinate not among the names) is not compiled:
:func:`compile_enclosure` returns ``None`` and the caller walks the tree.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

from hybrid.interval_kernels import mul_bounds as _mul
from hybrid.interval_kernels import pow_bounds as _pow
from hybrid.interval_kernels import round_down as _dn
from hybrid.interval_kernels import round_up as _un
from hybrid.interval_kernels import trig_bounds as _trig
from hybrid.symbolic import Apply, Const, Coordinate

__all__ = ["CompiledEnclosure", "compile_enclosure"]

_MAX = 1.7976931348623157e308
_INF = math.inf
_OPS = ("add", "sub", "neg", "mul", "div", "pow", "sin", "cos")


def _div(al: float, ah: float, c: float) -> tuple[float, float]:
    return _mul(al, ah, _dn(1.0 / c), _un(1.0 / c))


class _Unsupported(Exception):
    pass


def _add(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _dn(al + bl), _un(ah + bh)


def _sub(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _dn(al - bh), _un(ah - bl)


def _neg(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return -ah, -al


def _quotient(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _div(al, ah, bl)


def _sin(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _trig("sin", al, ah)


def _cos(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _trig("cos", al, ah)


_KERNELS = {"add": _add, "sub": _sub, "neg": _neg, "mul": _mul, "div": _quotient, "sin": _sin, "cos": _cos}


class _Unsupported(Exception):
    pass


class CompiledEnclosure:
    """Enclosures of ``roots`` over a box, as :func:`hybrid.symbolic.enclose` gives them (the same floats).

    Call it with the box's lower and upper bounds (sequences of floats, in the order of ``names``); it returns
    ``(lows, highs)``, two lists of floats, one entry per root.  The program is a list of instructions
    ``(kernel, a, b)`` over slots (the coordinates first, then the constants, then one slot per operation node,
    every node after its arguments); ``kernel(lo_a, hi_a, lo_b, hi_b)`` gives the node's interval.
    """

    __slots__ = ("_inputs", "_constants", "_program", "_roots", "size")

    def __init__(self, inputs: int, constants: list[float], program: list[tuple[Any, int, int]],
                 roots: list[int]) -> None:
        self._inputs = inputs
        # enclose's cleaning of a constant's interval ([inf, inf] becomes [MAX, inf])
        self._constants = ([_MAX if c == _INF else -_INF if c == -_INF else c for c in constants],
                           [_INF if c == _INF else -_MAX if c == -_INF else c for c in constants])
        self._program = program
        self._roots = roots
        self.size = len(roots)

    def __call__(self, lo: Sequence[float], hi: Sequence[float]) -> tuple[list[float], list[float]]:
        low, high = list(lo[: self._inputs]), list(hi[: self._inputs])
        for i in range(self._inputs):  # enclose's cleaning of a coordinate's interval
            if low[i] == _INF:
                low[i], high[i] = _MAX, _INF
            elif high[i] == -_INF:
                low[i], high[i] = -_INF, -_MAX
        low.extend(self._constants[0])
        high.extend(self._constants[1])
        for kernel, a, b in self._program:
            x, y = kernel(low[a], high[a], low[b], high[b])
            if x == _INF:
                x, y = _MAX, _INF
            elif y == -_INF:
                x, y = -_INF, -_MAX
            low.append(x)
            high.append(y)
        lows, highs = [], []
        for slot in self._roots:  # a NaN bound (inf − inf) makes the root unbounded, as enclose does
            x, y = low[slot], high[slot]
            if x != x or y != y:
                x, y = -_INF, _INF
            lows.append(x)
            highs.append(y)
        return lows, highs


class _Builder:
    """The program of a DAG, one node at a time (structurally equal nodes share their slot)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.index = {name: i for i, name in enumerate(names)}
        self.constants: list[float] = []
        self.program: list[tuple[Any, int, int]] = []
        self.keys: dict[Any, tuple[str, int]] = {}
        self.by_id: dict[int, tuple[Any, tuple[str, int]]] = {}

    def node(self, expr: Any) -> tuple[str, int]:
        """``(kind, index)``: ``"x"`` a coordinate, ``"c"`` a constant, ``"op"`` an instruction."""
        seen = self.by_id.get(id(expr))
        if seen is not None and seen[0] is expr:
            return seen[1]
        key, make = self._key(expr)
        ref = self.keys.get(key)
        if ref is None:
            ref = make()
            self.keys[key] = ref
        self.by_id[id(expr)] = (expr, ref)
        return ref

    def _constant(self, value: float) -> tuple[str, int]:
        self.constants.append(value)
        return "c", len(self.constants) - 1

    def _instruction(self, kernel: Any, a: tuple[str, int], b: tuple[str, int]) -> tuple[str, int]:
        self.program.append((kernel, a, b))
        return "op", len(self.program) - 1

    def _key(self, expr: Any) -> tuple[Any, Any]:
        if isinstance(expr, Const):
            value = float(expr.value)
            return ("const", repr(value)), lambda: self._constant(value)
        if isinstance(expr, Coordinate):
            if expr.name not in self.index:
                raise _Unsupported
            i = self.index[expr.name]
            return ("x", i), lambda: ("x", i)
        if not isinstance(expr, Apply) or expr.op not in _OPS:
            raise _Unsupported
        op = expr.op
        if op == "pow":
            power = expr.args[1]
            if not isinstance(power, Const) or power.value != int(power.value):
                raise _Unsupported
            a = self.node(expr.args[0])
            k = int(power.value)
            return ("pow", a, k), lambda: self._instruction(functools.partial(_pow_kernel, k), a, a)
        args = tuple(self.node(arg) for arg in expr.args)
        if len(args) != (1 if op in ("neg", "sin", "cos") else 2):
            raise _Unsupported
        return (op, *args), lambda: self._instruction(_KERNELS[op], args[0], args[-1])

    def slots(self, ref: tuple[str, int], inputs: int) -> int:
        kind, i = ref
        return i if kind == "x" else inputs + i if kind == "c" else inputs + len(self.constants) + i


def _pow_kernel(k: int, al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    return _pow(al, ah, k)


def compile_enclosure(roots: Sequence[Any], names: Sequence[str]) -> CompiledEnclosure | None:
    """The compiled enclosure of ``roots`` (symbolic expressions of the coordinates ``names``), or ``None``.

    ``None`` when a root uses an operation outside ``+ − × /`` (by a constant), integer powers, ``sin``, ``cos``,
    or a coordinate not in ``names``: the caller then encloses with :func:`hybrid.symbolic.enclose`.
    """
    builder = _Builder(names)
    try:
        refs = [builder.node(root) for root in roots]
    except _Unsupported:
        return None
    inputs = len(names)
    program = [(kernel, builder.slots(a, inputs), builder.slots(b, inputs)) for kernel, a, b in builder.program]
    return CompiledEnclosure(inputs, builder.constants, program, [builder.slots(r, inputs) for r in refs])
