"""The producer's interval enclosures of a list of expressions, compiled once into straight-line Python.

:mod:`analysis.reach.nonlinear` encloses ``f``, ``Df`` and the Hessian entries of a smooth flow at every
step, over a new box each time.  :func:`hybrid.symbolic.enclose` walks the expression tree for that
(dispatch by type, a memo dictionary, a tuple per node): most of a step's time for a small flow.
:func:`compile_enclosure` turns the list once into the source of one Python function — the expression
DAG in topological order (nodes with the same structure merged: the numbers of a node depend only on
its structure and the box), two float locals per node — and ``exec``s it.

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

import math
from collections.abc import Callable, Sequence
from typing import Any

from hybrid.symbolic import Apply, Const, Coordinate

__all__ = ["CompiledEnclosure", "compile_enclosure"]

_MAX = 1.7976931348623157e308
_INF = math.inf
_OPS = ("add", "sub", "neg", "mul", "div", "pow", "sin", "cos")


def _dn(x: float) -> float:
    return math.nextafter(x, -_INF) if math.isfinite(x) else x


def _un(x: float) -> float:
    return math.nextafter(x, _INF) if math.isfinite(x) else x


def _corner(x: float, y: float) -> float:
    if (x == 0.0 and math.isinf(y)) or (y == 0.0 and math.isinf(x)):
        return 0.0
    return x * y


def _mul(al: float, ah: float, bl: float, bh: float) -> tuple[float, float]:
    p = (_corner(al, bl), _corner(al, bh), _corner(ah, bl), _corner(ah, bh))
    return _dn(min(p)), _un(max(p))


def _div(al: float, ah: float, c: float) -> tuple[float, float]:
    return _mul(al, ah, _dn(1.0 / c), _un(1.0 / c))


def _power(x: float, k: int) -> float:
    try:
        return x ** k
    except OverflowError:
        return -_INF if (x < 0.0 and k % 2 == 1) else _INF


def _pow(lo: float, hi: float, k: int) -> tuple[float, float]:
    if k == 0:
        return 1.0, 1.0
    ends = (_power(lo, k), _power(hi, k))
    low = 0.0 if (k % 2 == 0 and lo <= 0.0 <= hi) else min(ends)
    return _dn(_dn(low)), _un(_un(max(ends)))


def _trig(op: str, lo: float, hi: float) -> tuple[float, float]:
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= 2.0 * math.pi:
        return -1.0, 1.0
    f = math.sin if op == "sin" else math.cos
    shift = 0.5 * math.pi if op == "sin" else 0.0
    values = [f(lo), f(hi)]
    k = math.ceil((lo - shift) / math.pi - 1e-12)
    while shift + k * math.pi <= hi + 1e-12:
        values.append(f(shift + k * math.pi))
        k += 1
    return max(-1.0, _dn(min(values)) - 1e-15), min(1.0, _un(max(values)) + 1e-15)


class _Unsupported(Exception):
    pass


class CompiledEnclosure:
    """Enclosures of ``roots`` over a box, as :func:`hybrid.symbolic.enclose` gives them (the same floats).

    Call it with the box's lower and upper bounds (sequences of floats, in the order of ``names``); it returns
    ``(lows, highs)``, two lists of floats, one entry per root.
    """

    __slots__ = ("source", "_function", "size")

    def __init__(self, source: str, function: Callable[..., tuple[float, ...]], size: int) -> None:
        self.source = source
        self._function = function
        self.size = size

    def __call__(self, lo: Sequence[float], hi: Sequence[float]) -> tuple[list[float], list[float]]:
        out = self._function(lo, hi)
        return list(out[0::2]), list(out[1::2])


class _Builder:
    """The straight-line source of a DAG, one node at a time (structurally equal nodes share their locals)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.index = {name: i for i, name in enumerate(names)}
        self.lines: list[str] = []
        self.keys: dict[Any, int] = {}
        self.by_id: dict[int, tuple[Any, int]] = {}

    def node(self, expr: Any) -> int:
        seen = self.by_id.get(id(expr))
        if seen is not None and seen[0] is expr:
            return seen[1]
        key, body = self._body(expr)
        slot = self.keys.get(key)
        if slot is None:
            slot = len(self.keys)
            self.keys[key] = slot
            self.lines.append(f"    l{slot}, h{slot} = {body}")
            self.lines.append(f"    if l{slot} == INF: l{slot}, h{slot} = MAX, INF")
            self.lines.append(f"    elif h{slot} == -INF: l{slot}, h{slot} = -INF, -MAX")
        self.by_id[id(expr)] = (expr, slot)
        return slot

    def _body(self, expr: Any) -> tuple[Any, str]:
        if isinstance(expr, Const):
            return ("const", repr(expr.value)), f"{float(expr.value)!r}, {float(expr.value)!r}"
        if isinstance(expr, Coordinate):
            if expr.name not in self.index:
                raise _Unsupported
            i = self.index[expr.name]
            return ("x", i), f"lo[{i}], hi[{i}]"
        if not isinstance(expr, Apply) or expr.op not in _OPS:
            raise _Unsupported
        op = expr.op
        if op == "pow":
            power = expr.args[1]
            if not isinstance(power, Const) or power.value != int(power.value):
                raise _Unsupported
            a = self.node(expr.args[0])
            return ("pow", a, int(power.value)), f"POW(l{a}, h{a}, {int(power.value)})"
        args = tuple(self.node(arg) for arg in expr.args)
        if len(args) != (1 if op in ("neg", "sin", "cos") else 2):
            raise _Unsupported
        a = args[0]
        b = args[-1]
        body = {
            "add": f"DN(l{a} + l{b}), UP(h{a} + h{b})",
            "sub": f"DN(l{a} - h{b}), UP(h{a} - l{b})",
            "neg": f"-h{a}, -l{a}",
            "mul": f"MUL(l{a}, h{a}, l{b}, h{b})",
            "div": f"DIV(l{a}, h{a}, l{b})",
            "sin": f"TRIG('sin', l{a}, h{a})",
            "cos": f"TRIG('cos', l{a}, h{a})",
        }[op]
        return (op, *args), body


def compile_enclosure(roots: Sequence[Any], names: Sequence[str]) -> CompiledEnclosure | None:
    """The compiled enclosure of ``roots`` (symbolic expressions of the coordinates ``names``), or ``None``.

    ``None`` when a root uses an operation outside ``+ − × /`` (by a constant), integer powers, ``sin``, ``cos``,
    or a coordinate not in ``names``: the caller then encloses with :func:`hybrid.symbolic.enclose`.
    """
    builder = _Builder(names)
    try:
        slots = [builder.node(root) for root in roots]
    except _Unsupported:
        return None
    lines = ["def enclosure(lo, hi):", *builder.lines]
    outs = []
    for k, slot in enumerate(slots):  # a NaN bound (inf - inf) makes the root unbounded, as enclose does
        lines.append(f"    r{k}l, r{k}h = (l{slot}, h{slot}) if l{slot} == l{slot} and h{slot} == h{slot} "
                     "else (-INF, INF)")
        outs.append(f"r{k}l, r{k}h")
    lines.append(f"    return ({', '.join(outs)}{',' if outs else ''})")
    source = "\n".join(lines) + "\n"
    namespace: dict[str, Any] = {"INF": _INF, "MAX": _MAX, "DN": _dn, "UP": _un, "MUL": _mul, "DIV": _div,
                                 "POW": _pow, "TRIG": _trig}
    exec(compile(source, "<analysis.reach.enclose_compiled>", "exec"), namespace)  # noqa: S102 - our own source
    return CompiledEnclosure(source, namespace["enclosure"], len(slots))
