"""Symbolic guards, invariants, resets, jump maps, flows and outputs: one definition, four readings.

An expression of this module is a small tree of piecewise polynomial terms
(``+ - *``, division by a constant, integer powers, ``min``, ``max``, ``abs``,
``ite`` and ``select``) over named coordinates, memory variables, time and
named parameters, plus a few transcendental functions (``sin``, ``cos``,
``exp``, ``log``, ``sqrt``, ``atan2``).  The same tree is

* **evaluated with floats** by the executors: it is compiled once to a Python
  function (``lambda v, m: ...``) as fast as a hand-written lambda;
* **differentiated**: exactly, by :func:`diff` (an expression again, used by
  the checker for the rate of an invariant along a flow), and through CasADi by
  :func:`to_casadi` (an ``SX`` expression, for Jacobians);
* **enclosed** by interval arithmetic with outward rounding (:func:`enclose`):
  a sound range over a box;
* **decided** by an SMT solver: :mod:`hybrid.smt` translates it to z3.

Writing a model
---------------
>>> from hybrid.symbolic import coordinates, memory, minimum, ite
>>> v = coordinates("T", "T_out")
>>> m = memory("T_set")
>>> guard = minimum(m.T_set - v.T, v.T_out - 5.0)     # T <= T_set and T_out >= 5
>>> guard((18.0, 10.0), {"T_set": 19.0})
1.0
>>> (v.T >= 21.0).level()((22.0, 0.0), {})            # a comparison becomes its level form T - 21
1.0

A comparison is a :class:`Condition`, not a number: used as a guard or an
invariant it is turned into its *level form* (``a >= b`` into ``a - b``,
``a <= b`` into ``b - a``, ``&`` into ``min``, ``|`` into ``max``).  Guards
are closed sets, so ``a > b`` and ``a >= b`` have the same level form; the
strict comparison keeps its strictness inside :func:`ite` conditions, where it
decides a branch.  Python's ``if``, ``and``, ``or`` and the built-in ``min``
cannot be applied to a condition (its truth is unknown until evaluated): that
raises :class:`SymbolicError` with the function to use instead.

Semantics of the pieces that Python does not define
---------------------------------------------------
``select(i, (o_0, ..., o_{n-1}))`` is ``o_k`` with ``k = int(i)`` (truncation,
as Python's ``int``), for ``-1 < i < n``; outside that range evaluation raises
and the checker treats the point as outside the model's domain.
``x ** n`` needs an integer ``n >= 0``; division needs a non-zero constant
divisor (multiply through, or write ``ite``, otherwise).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from fractions import Fraction
from typing import Any

from .interval_kernels import mul_bounds, pow_bounds, trig_bounds
from .interval_kernels import round_down as _down
from .interval_kernels import round_up as _up
from .symbolic_core import (
    ARITY,
    Apply,
    Compare,
    Condition,
    Const,
    Coordinate,
    Coordinates,
    Expr,
    FLOAT_OPS,
    Ite,
    Logic,
    MAX_COMPILED_DEPTH,
    MAX_COMPILED_SIZE,
    MemoryRef,
    MemoryRefs,
    Param,
    RENDER_LIMIT,
    Select,
    SymbolicError,
    SymbolicReset,
    SymbolicVector,
    TRANSCENDENTAL,
    Time,
    Unsupported,
    all_true,
    any_true,
    as_expr,
    atan2,
    const,
    coordinates,
    cos,
    depth,
    evaluate,
    exactly,
    exp,
    expanded_size,
    float_value,
    flow_map,
    ite,
    jump_map,
    level_form,
    log,
    maximum,
    memory,
    minimum,
    nary_apply,
    output_map,
    param,
    render,
    reset,
    select,
    sin,
    sqrt,
    time,
    walk_nodes,
)

__all__ = [
    "SymbolicError",
    "Expr",
    "Const",
    "Coordinate",
    "MemoryRef",
    "Time",
    "Param",
    "Apply",
    "Ite",
    "Select",
    "Condition",
    "Compare",
    "Logic",
    "Coordinates",
    "MemoryRefs",
    "coordinates",
    "memory",
    "param",
    "time",
    "const",
    "as_expr",
    "minimum",
    "maximum",
    "ite",
    "select",
    "sin",
    "cos",
    "exp",
    "log",
    "sqrt",
    "atan2",
    "all_true",
    "any_true",
    "level_form",
    "exactly",
    "evaluate",
    "diff",
    "enclose",
    "free_symbols",
    "transcendental_terms",
    "unsupported_terms",
    "misplaced_coordinates",
    "Unsupported",
    "substitute",
    "to_casadi",
    "render",
    "depth",
    "exact",
    "SymbolicReset",
    "SymbolicVector",
    "reset",
    "jump_map",
    "flow_map",
    "output_map",
    "is_symbolic",
    "MAX_COMPILED_DEPTH",
]


def is_symbolic(function: Any) -> bool:
    """Whether a guard, invariant, reset or map is symbolic (decidable by the checker)."""
    return isinstance(function, (Expr, Condition, SymbolicReset, SymbolicVector))


def free_symbols(node: Expr | Condition) -> dict[str, set[str]]:
    """``{"coordinates": ..., "memory": ..., "params": ..., "time": {"t"} or empty}`` used by ``node``."""
    out: dict[str, set[str]] = {"coordinates": set(), "memory": set(), "params": set(), "time": set()}
    for n in walk_nodes(node):
        if isinstance(n, Coordinate):
            out["coordinates"].add(n.name)
        elif isinstance(n, MemoryRef):
            out["memory"].add(n.name)
        elif isinstance(n, Param):
            out["params"].add(n.name)
        elif isinstance(n, Time):
            out["time"].add("t")
    return out


def unsupported_terms(node: Any) -> list[Unsupported]:
    """The :class:`Unsupported` operations inside an expression, condition, reset or vector."""
    if isinstance(node, SymbolicReset):
        return [u for e in node.assignments.values() for u in unsupported_terms(e)]
    if isinstance(node, SymbolicVector):
        return [u for e in node.components for u in unsupported_terms(e)]
    if not isinstance(node, (Expr, Condition)):
        return []
    return [n for n in walk_nodes(node) if isinstance(n, Unsupported)]


def misplaced_coordinates(node: Any, names: Sequence[str]) -> list[str]:
    """Coordinates of ``node`` whose name is not the ``names`` entry at their index (text for each).

    A coordinate built by :func:`coordinates` over other names than the vector it is evaluated on would
    read the wrong component silently: the model refuses it (:mod:`hybrid.model`, :mod:`hybrid.system`).
    """
    if isinstance(node, SymbolicReset):
        parts: list[Any] = list(node.assignments.values())
    elif isinstance(node, SymbolicVector):
        parts = list(node.components)
    elif isinstance(node, (Expr, Condition)):
        parts = [node]
    else:
        return []
    bad = set()
    for p in parts:
        for n in walk_nodes(p):
            if isinstance(n, Coordinate) and (n.index >= len(names) or names[n.index] != n.name):
                actual = names[n.index] if n.index < len(names) else "nothing"
                bad.add(f"{n.name!r} (index {n.index}, where the vector has {actual!r})")
    return sorted(bad)


def transcendental_terms(node: Expr | Condition) -> list[str]:
    """Names of the transcendental operations in ``node`` (sorted, unique)."""
    return sorted({n.op for n in walk_nodes(node) if isinstance(n, Apply) and n.op in TRANSCENDENTAL})


def substitute(node: Any, coordinates: Mapping[str, Expr] | None = None,
               memory: Mapping[str, Expr] | None = None, params: Mapping[str, Expr] | None = None) -> Any:
    """``node`` with coordinates, memory variables or parameters (by name) replaced by expressions."""
    cmap, mmap, pmap = dict(coordinates or {}), dict(memory or {}), dict(params or {})
    memo: dict[int, Any] = {}

    def sub(n: Any) -> Any:
        key = id(n)
        if key in memo:
            return memo[key]
        if isinstance(n, Coordinate):
            out = cmap.get(n.name, n)
        elif isinstance(n, MemoryRef):
            out = mmap.get(n.name, n)
        elif isinstance(n, Param):
            out = pmap.get(n.name, n)
        elif isinstance(n, Apply):
            out = Apply(n.op, tuple(sub(a) for a in n.args))
        elif isinstance(n, Ite):
            out = Ite(sub(n.condition), sub(n.then), sub(n.otherwise))
        elif isinstance(n, Select):
            out = Select(sub(n.index), tuple(sub(o) for o in n.options))
        elif isinstance(n, Compare):
            out = Compare(n.op, sub(n.left), sub(n.right), n.exact)
        elif isinstance(n, Logic):
            out = Logic(n.op, tuple(sub(a) for a in n.args))
        else:
            out = n
        memo[key] = out
        return out

    return sub(node)


# ====================================================================== exact derivative
def diff(node: Expr, wrt: Coordinate | MemoryRef | Time | str) -> Expr:
    """The derivative of ``node`` with respect to a coordinate (by node or name), memory variable or time.

    Piecewise terms differentiate branch by branch (``d min(a, b) = ite(a <= b, da, db)``,
    ``d |a| = ite(a >= 0, da, -da)``), which is the derivative wherever it exists.
    """
    def same(n: Expr) -> bool:
        if isinstance(wrt, str):
            return isinstance(n, Coordinate) and n.name == wrt
        if isinstance(wrt, Coordinate):
            return isinstance(n, Coordinate) and n.name == wrt.name
        if isinstance(wrt, MemoryRef):
            return isinstance(n, MemoryRef) and n.name == wrt.name
        return isinstance(n, Time)

    memo: dict[int, Expr] = {}

    def d(n: Expr) -> Expr:
        if id(n) in memo:
            return memo[id(n)]
        if isinstance(n, Unsupported):
            raise SymbolicError(n.message())
        if isinstance(n, (Coordinate, MemoryRef, Time)):
            out: Expr = Const(1.0 if same(n) else 0.0)
        elif isinstance(n, (Const, Param)):
            out = Const(0.0)
        elif isinstance(n, Ite):
            out = _ite_or_same(n.condition, d(n.then), d(n.otherwise))
        elif isinstance(n, Select):
            out = Select(n.index, tuple(d(o) for o in n.options))
        else:
            out = _diff_apply(n, d)  # type: ignore[arg-type]
        memo[id(n)] = out
        return out

    return d(as_expr(node))


def _ite_or_same(c: Condition, a: Expr, b: Expr) -> Expr:
    if isinstance(a, Const) and isinstance(b, Const) and a.value == b.value:
        return a
    return Ite(c, a, b)


def _diff_apply(n: Apply, d: Callable[[Expr], Expr]) -> Expr:
    op, args = n.op, n.args
    a = args[0]
    if op == "add":
        return d(a) + d(args[1])
    if op == "sub":
        return d(a) - d(args[1])
    if op == "mul":
        return d(a) * args[1] + a * d(args[1])
    if op == "div":
        return d(a) / args[1]
    if op == "neg":
        return -d(a)
    if op == "abs":
        return _ite_or_same(a >= 0.0, d(a), -d(a))
    if op == "pow":
        k = int(float_value(args[1]))
        return Const(0.0) if k == 0 else Const(float(k)) * a ** (k - 1) * d(a)
    if op in ("min", "max"):
        first, rest = args[0], (args[1:] if len(args) > 2 else args[1])
        other = nary_apply(op, rest) if isinstance(rest, tuple) else rest
        cond = first <= other if op == "min" else first >= other
        return _ite_or_same(cond, d(first), d(other))
    if op == "sin":
        return cos(a) * d(a)
    if op == "cos":
        return -sin(a) * d(a)
    if op == "exp":
        return n * d(a)
    if op == "log":
        return d(a) * _reciprocal(a)
    if op == "sqrt":
        return d(a) * _reciprocal(Const(2.0) * n)
    if op == "atan2":
        y, x = args
        return (x * d(y) - y * d(x)) * _reciprocal(x * x + y * y)
    if op == "inv":
        return -(d(a) * _reciprocal(a * a))
    raise SymbolicError(f"diff(): no derivative for operation {op!r}")


def _reciprocal(e: Expr) -> Expr:
    """``1 / e`` as a node (internal: derivatives of transcendental terms only)."""
    return Apply("inv", (e,))


FLOAT_OPS["inv"] = lambda a: 1.0 / a
ARITY["inv"] = 1


# ====================================================================== interval enclosure
Interval = tuple[float, float]
_MAX = 1.7976931348623157e308  # the largest finite float


def _mul_iv(a: Interval, b: Interval) -> Interval:
    return mul_bounds(a[0], a[1], b[0], b[1])


def enclose(node: Expr, bounds: Mapping[str, Interval], memory_bounds: Mapping[str, Interval] | None = None,
            time_bounds: Interval = (0.0, 0.0), param_bounds: Mapping[str, Interval] | None = None,
            shared: dict[int, tuple[Expr, Interval]] | None = None) -> Interval:
    """A sound interval containing ``node`` over a box (coordinates by name, memory, time).

    Rounding is outward (one ulp per operation); a function outside its domain
    (``log`` of an interval reaching 0, ``sqrt`` below 0, ``select`` out of range)
    gives ``(-inf, inf)``.  A coordinate or memory variable missing from the
    bounds is unbounded; a parameter named in ``param_bounds`` ranges over its interval (else its value).
    ``shared``: a dictionary kept by the caller across calls with the same bounds, so that a subtree common
    to several expressions is enclosed once (the same numbers as without it; entries hold their node).
    """
    mb = memory_bounds or {}
    pb = param_bounds or {}
    memo: dict[int, Interval] = {}
    held: dict[int, tuple[Expr, Interval]] = {} if shared is None else shared  # holding the node keeps its id

    def iv(n: Expr) -> Interval:
        if id(n) in memo:
            return memo[id(n)]
        if id(n) in held and held[id(n)][0] is n:
            return held[id(n)][1]
        if isinstance(n, Unsupported):
            raise SymbolicError(n.message())
        if isinstance(n, Param) and n.name in pb:
            out = tuple(pb[n.name])  # type: ignore[assignment]
        elif isinstance(n, (Const, Param)):
            out = (n.value, n.value)
        elif isinstance(n, Coordinate):
            out = tuple(bounds.get(n.name, (-math.inf, math.inf)))  # type: ignore[assignment]
        elif isinstance(n, MemoryRef):
            out = tuple(mb.get(n.name, (-math.inf, math.inf)))  # type: ignore[assignment]
        elif isinstance(n, Time):
            out = time_bounds
        elif isinstance(n, Ite):
            a, b = iv(n.then), iv(n.otherwise)
            out = (min(a[0], b[0]), max(a[1], b[1]))
        elif isinstance(n, Select):
            k = iv(n.index)
            # option i is chosen on [i, i + 1), option 0 on (-1, 1) (int() truncates towards zero)
            options = [iv(o) for i, o in enumerate(n.options)
                       if k[0] < i + 1 and (k[1] > -1.0 if i == 0 else i <= k[1])]
            if k[0] <= -1.0 or k[1] >= len(n.options) or not options:
                out = (-math.inf, math.inf)
            else:
                out = (min(o[0] for o in options), max(o[1] for o in options))
        else:
            out = _apply_iv(n, [iv(a) for a in n.args])  # type: ignore[attr-defined]
        if out[0] == math.inf:  # a real value is finite: never [inf, inf] (inf - inf would give NaN bounds)
            out = (_MAX, math.inf)
        elif out[1] == -math.inf:
            out = (-math.inf, -_MAX)
        memo[id(n)] = out
        if shared is not None:
            shared[id(n)] = (n, out)
        return out

    lo, hi = iv(as_expr(node))
    if lo != lo or hi != hi:
        return -math.inf, math.inf
    return lo, hi


def _apply_iv(n: Apply, a: list[Interval]) -> Interval:
    op = n.op
    if op == "add":
        return _down(a[0][0] + a[1][0]), _up(a[0][1] + a[1][1])
    if op == "sub":
        return _down(a[0][0] - a[1][1]), _up(a[0][1] - a[1][0])
    if op == "neg":
        return -a[0][1], -a[0][0]
    if op == "mul":
        return _mul_iv(a[0], a[1])
    if op == "div":
        c = a[1][0]
        return _mul_iv(a[0], (_down(1.0 / c), _up(1.0 / c)) if c > 0 else (_down(1.0 / c), _up(1.0 / c)))
    if op == "inv":
        lo, hi = a[0]
        if lo <= 0.0 <= hi:
            return -math.inf, math.inf
        return _down(1.0 / hi), _up(1.0 / lo)
    if op == "abs":
        lo, hi = a[0]
        if lo >= 0.0:
            return lo, hi
        if hi <= 0.0:
            return -hi, -lo
        return 0.0, max(-lo, hi)
    if op == "pow":
        return pow_bounds(a[0][0], a[0][1], int(n.args[1].value))  # type: ignore[attr-defined]
    if op == "min":
        return min(x[0] for x in a), min(x[1] for x in a)
    if op == "max":
        return max(x[0] for x in a), max(x[1] for x in a)
    if op in ("sin", "cos"):
        return trig_bounds(op, a[0][0], a[0][1])
    if op == "exp":
        lo, hi = a[0]  # math.exp overflows (OverflowError) above ~709.78
        low = 0.0 if lo <= -745.0 else max(0.0, _down(_down(math.exp(min(lo, 709.0)))))
        return low, (_up(_up(math.exp(hi))) if hi < 709.0 else math.inf)
    if op == "log":
        lo, hi = a[0]
        if lo <= 0.0:
            return -math.inf, math.inf
        return _down(_down(math.log(lo))), _up(_up(math.log(hi))) if math.isfinite(hi) else math.inf
    if op == "sqrt":
        lo, hi = a[0]
        if lo < 0.0:
            return -math.inf, math.inf
        return max(0.0, _down(_down(math.sqrt(lo)))), _up(_up(math.sqrt(hi))) if math.isfinite(hi) else math.inf
    if op == "atan2":
        return -math.pi - 1e-15, math.pi + 1e-15
    raise SymbolicError(f"enclose(): no interval rule for operation {op!r}")


# ====================================================================== CasADi
def to_casadi(node: Expr | Condition, coords: Mapping[str, Any], memory: Mapping[str, Any] | None = None,
              t: Any = 0.0) -> Any:
    """``node`` as a CasADi expression in the given symbols (``coords[name]``, ``memory[name]``, ``t``).

    Example: the gradient of an invariant is ``casadi.gradient(to_casadi(inv, {...}), x)``.
    """
    import casadi as ca

    mem = memory or {}
    memo: dict[int, Any] = {}
    ops = {"add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b,
           "div": lambda a, b: a / b, "neg": lambda a: -a, "abs": ca.fabs, "inv": lambda a: 1 / a,
           "sin": ca.sin, "cos": ca.cos, "exp": ca.exp, "log": ca.log, "sqrt": ca.sqrt, "atan2": ca.atan2}

    def cs(n: Any) -> Any:
        if id(n) in memo:
            return memo[id(n)]
        if isinstance(n, (Const, Param)):
            out = n.value
        elif isinstance(n, Coordinate):
            out = coords[n.name]
        elif isinstance(n, MemoryRef):
            out = mem[n.name]
        elif isinstance(n, Time):
            out = t
        elif isinstance(n, Apply):
            args = [cs(a) for a in n.args]
            if n.op == "pow":
                out = args[0] ** int(n.args[1].value)
            elif n.op in ("min", "max"):
                f = ca.fmin if n.op == "min" else ca.fmax
                out = args[0]
                for a in args[1:]:
                    out = f(out, a)
            else:
                out = ops[n.op](*args)
        elif isinstance(n, Ite):
            out = ca.if_else(cs(n.condition), cs(n.then), cs(n.otherwise))
        elif isinstance(n, Select):
            idx = cs(n.index)
            out = cs(n.options[-1])
            for i in range(len(n.options) - 2, -1, -1):
                out = ca.if_else(idx < i + 1, cs(n.options[i]), out)
        elif isinstance(n, Compare):
            a, b = cs(n.left), cs(n.right)
            out = {">=": a >= b, ">": a > b, "<=": a <= b, "<": a < b, "==": a == b, "!=": a != b}[n.op]
        elif isinstance(n, Logic):
            args = [cs(c) for c in n.args]
            if n.op == "not":
                out = ca.logic_not(args[0])
            else:
                f = ca.logic_and if n.op == "and" else ca.logic_or
                out = args[0]
                for a in args[1:]:
                    out = f(out, a)
        else:
            raise SymbolicError(f"to_casadi(): {n!r} is not an expression")
        memo[id(n)] = out
        return out

    return cs(node)


def exact(value: float) -> Fraction:
    """The exact rational value of a finite float."""
    return Fraction(value)
