"""The re-check's interval evaluation of many expressions at once, vectorised over the expression DAG.

:class:`IntervalTape` compiles a list of symbolic roots (``hybrid.symbolic`` trees built from
coordinates, numbers, ``+ − ×``, ``/``, integer powers, ``sin``, ``cos``) once into levels of a
DAG — nodes with the same structure merged (``sin(α)`` written twice by differentiation is one
node), every node after its arguments — and evaluates it over a box with numpy arrays, one
vector operation per (level, operation).

The arithmetic is :class:`analysis.interval.Interval`'s, bit for bit: the same error-free
transformations (TwoSum, Dekker's TwoProduct and the division residual) decide the sign of each
operation's rounding error and the bound moves one ulp outward only when the error is non-zero, and
an interval product or quotient is the minimum and maximum over the four corner bounds (equal to
``Interval``'s short cut for non-negative factors: directed rounding is monotone).  ``pow``,
``sin`` and ``cos`` are evaluated by :class:`~analysis.interval.Interval` itself, node by node.
Wherever the vector kernels' exactness conditions fail — a bound not finite, a factor outside
``[2⁻⁴⁰⁰, 2⁴⁰⁰]``, a divisor interval holding 0 — :meth:`IntervalTape.evaluate` raises
:class:`TapeFallback` and the caller evaluates with :class:`~analysis.interval.Interval` node by
node (same numbers, same errors).  So the tape changes the re-check's speed, not its results.

This module holds no code of the producer (:mod:`analysis.reach.nonlinear` encloses with
:func:`hybrid.symbolic.enclose`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from analysis.interval import Interval
from hybrid.symbolic import Apply, Const, Coordinate

__all__ = ["IntervalTape", "TapeFallback", "compile_tape"]

_VECTOR_OPS = ("add", "sub", "neg", "mul", "div")
_SCALAR_OPS = ("pow", "sin", "cos")
_SPLITTER = 134217729.0  # 2**27 + 1 (Veltkamp's split)
_SAFE_LOW = 2.0 ** -400  # Dekker's TwoProduct and the division residual are exact for such factors
_SAFE_HIGH = 2.0 ** 400


class TapeFallback(Exception):
    """The vector kernels cannot guarantee ``Interval``'s exact result here: evaluate node by node."""


def _two_product_error(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``a·b − p`` exactly (Dekker) for ``p = fl(a·b)``, elementwise, for factors in the safe range."""
    c = _SPLITTER * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLITTER * b
    bh = c - (c - b)
    bl = b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _rounded(r: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(down, up)`` bounds of ``r + e`` from the sign of ``e`` (``_round_pair`` of :mod:`analysis.interval`)."""
    return (np.where(error < 0.0, np.nextafter(r, -np.inf), r), np.where(error > 0.0, np.nextafter(r, np.inf), r))


def _safe(x: np.ndarray) -> np.ndarray:
    ax = np.abs(x)
    return (ax == 0.0) | ((ax >= _SAFE_LOW) & (ax <= _SAFE_HIGH))


def _add(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tightest ``(down, up)`` of ``a + b`` (TwoSum; finite operands and sums)."""
    s = a + b
    if not np.all(np.isfinite(s)):
        raise TapeFallback
    bb = s - a
    err = (a - (s - bb)) + (b - bb)
    return _rounded(s + 0.0, err)


def _mul(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tightest ``(down, up)`` of ``a · b``; a zero factor gives ``+0`` exactly."""
    zero = (a == 0.0) | (b == 0.0)
    p = a * b
    if not np.all(zero | (np.isfinite(p) & _safe(a) & _safe(b))):
        raise TapeFallback
    down, up = _rounded(p, _two_product_error(a, b, p))
    return np.where(zero, 0.0, down), np.where(zero, 0.0, up)


def _div(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tightest ``(down, up)`` of ``a / b`` (``b`` finite and non-zero); ``a = 0`` gives ``+0`` exactly."""
    zero = a == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        q = a / b
    ok = zero | (np.isfinite(q) & (q != 0.0) & _safe(a) & _safe(b) & _safe(q))
    if not np.all(ok):
        raise TapeFallback
    p = q * b
    residual = (a - p) - _two_product_error(q, b, p)
    down, up = _rounded(q + 0.0, residual * np.sign(b))
    return np.where(zero, 0.0, down), np.where(zero, 0.0, up)


def _corners(kernel: Any, a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """The interval product or quotient: min of the four corners' lower bounds, max of their upper bounds."""
    down, up = kernel(np.concatenate([a_lo, a_lo, a_hi, a_hi]), np.concatenate([b_lo, b_hi, b_lo, b_hi]))
    return down.reshape(4, -1).min(axis=0), up.reshape(4, -1).max(axis=0)


class IntervalTape:
    """Compiled roots (see the module docstring); build with :func:`compile_tape`."""

    def __init__(self, size: int, roots: list[int], leaves: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                 levels: list[list[tuple[str, Any]]]) -> None:
        self.size = size
        self.roots = np.array(roots, dtype=np.intp)
        self.const_index, self.const_value, self.coord_index, self.coord_of = leaves
        self.levels = levels

    def evaluate(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Enclosures ``(lo, hi)`` of every root over the box ``[lo, hi]`` (coordinates by index), each shape (roots,).

        Raises
        ------
        TapeFallback
            Where the vector kernels' exactness conditions fail (evaluate with ``Interval`` instead).
        """
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
            raise TapeFallback
        low, high = np.empty(self.size), np.empty(self.size)
        low[self.const_index] = self.const_value
        high[self.const_index] = self.const_value
        low[self.coord_index] = lo[self.coord_of]
        high[self.coord_index] = hi[self.coord_of]
        for level in self.levels:
            for op, plan in level:
                if op in _SCALAR_OPS:
                    for out, arg, exponent in plan:
                        x = Interval(float(low[arg]), float(high[arg]))
                        y = x ** exponent if op == "pow" else (x.sin() if op == "sin" else x.cos())
                        low[out], high[out] = y.lo, y.hi
                    continue
                out, a, b = plan
                if op == "neg":
                    low[out], high[out] = -high[a], -low[a]
                    continue
                a_lo, a_hi, b_lo, b_hi = low[a], high[a], low[b], high[b]
                if op == "add":
                    low[out], high[out] = _add(a_lo, b_lo)[0], _add(a_hi, b_hi)[1]
                elif op == "sub":
                    low[out], high[out] = _add(a_lo, -b_hi)[0], _add(a_hi, -b_lo)[1]
                elif op == "mul":
                    low[out], high[out] = _corners(_mul, a_lo, a_hi, b_lo, b_hi)
                else:  # div: a divisor interval holding 0 is an error of Interval's
                    if np.any((b_lo <= 0.0) & (b_hi >= 0.0)):
                        raise TapeFallback
                    low[out], high[out] = _corners(_div, a_lo, a_hi, b_lo, b_hi)
        return low[self.roots].copy(), high[self.roots].copy()


def compile_tape(roots: Sequence[Any]) -> IntervalTape | None:
    """The tape of ``roots``, or ``None`` when a node is not one it evaluates (evaluate node by node then)."""
    index: dict[Any, int] = {}
    seen: dict[int, int] = {}
    nodes: list[tuple[Any, ...]] = []  # (kind, payload, args, level)

    def visit(node: Any) -> int:
        if id(node) in seen:
            return seen[id(node)]
        if isinstance(node, Const):
            key: tuple[Any, ...] = ("const", float(node.value).hex())
            record: tuple[Any, ...] = ("const", float(node.value), (), 0)
        elif isinstance(node, Coordinate):
            key = ("coord", int(node.index))
            record = ("coord", int(node.index), (), 0)
        elif isinstance(node, Apply) and node.op in _VECTOR_OPS + _SCALAR_OPS:
            if node.op == "pow":
                if not isinstance(node.args[1], Const):
                    raise _NotCompiled
                args = (visit(node.args[0]),)
                exponent = int(node.args[1].value)
            else:
                args = tuple(visit(a) for a in node.args)
                exponent = 0
            key = (node.op, args, exponent)
            record = (node.op, exponent, args, 1 + max(nodes[a][3] for a in args))
        else:
            raise _NotCompiled
        if key not in index:
            index[key] = len(nodes)
            nodes.append(record)
        seen[id(node)] = index[key]
        return index[key]

    try:
        root_ids = [visit(r) for r in roots]
    except _NotCompiled:
        return None
    consts = [(i, r[1]) for i, r in enumerate(nodes) if r[0] == "const"]
    coords = [(i, r[1]) for i, r in enumerate(nodes) if r[0] == "coord"]
    leaves = (np.array([i for i, _ in consts], dtype=np.intp), np.array([v for _, v in consts], dtype=float),
              np.array([i for i, _ in coords], dtype=np.intp), np.array([c for _, c in coords], dtype=np.intp))
    depth = max((r[3] for r in nodes), default=0)
    levels: list[list[tuple[str, Any]]] = []
    for level in range(1, depth + 1):
        plans: list[tuple[str, Any]] = []
        for op in _VECTOR_OPS + _SCALAR_OPS:
            members = [i for i, r in enumerate(nodes) if r[3] == level and r[0] == op]
            if not members:
                continue
            if op in _SCALAR_OPS:
                plans.append((op, [(i, nodes[i][2][0], nodes[i][1]) for i in members]))
            else:
                first = np.array([nodes[i][2][0] for i in members], dtype=np.intp)
                second = np.array([nodes[i][2][-1] for i in members], dtype=np.intp)
                plans.append((op, (np.array(members, dtype=np.intp), first, second)))
        levels.append(plans)
    return IntervalTape(len(nodes), root_ids, leaves, levels)


class _NotCompiled(Exception):
    pass
