"""The expressions of :mod:`hybrid.symbolic`: the node types (:class:`Expr` and its kinds, :class:`Condition`),
their constructors, rendering, float evaluation and the compiled evaluator, and the symbolic maps (resets,
jump, flow and output maps).

The compiled evaluator (:func:`compiled_function`) is the project's one code-generation site: it writes Python
source from the node types of this module only (floats by ``repr``, coordinate indices, memory names by
``repr``) and compiles it with an empty ``__builtins__`` (``_compile_lambda``); expressions too deep or too large
are interpreted instead.

:mod:`hybrid.symbolic` re-exports every public name (import them from there) and adds the calculus on
expressions (free symbols, substitution, derivatives, interval enclosures, CasADi, exact arithmetic).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from .errors import ExecutionError, ModelDefinitionError

# Helpers shared with hybrid.symbolic have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
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
    "Unsupported",
    "render",
    "depth",
    "SymbolicReset",
    "SymbolicVector",
    "reset",
    "jump_map",
    "flow_map",
    "output_map",
    "MAX_COMPILED_DEPTH",
]


TRANSCENDENTAL = ("sin", "cos", "exp", "log", "sqrt", "atan2")
"""Operations an SMT solver cannot decide exactly: the checker bounds them by interval enclosure."""

ARITY = {"add": 2, "sub": 2, "mul": 2, "div": 2, "neg": 1, "abs": 1, "pow": 2, "min": None, "max": None,
          "sin": 1, "cos": 1, "exp": 1, "log": 1, "sqrt": 1, "atan2": 2}

MAX_COMPILED_DEPTH = 60
"""Deeper trees are evaluated by the interpreter instead of a compiled lambda (Python's parser nests ~200)."""

MAX_COMPILED_SIZE = 5000
"""Trees whose written-out size exceeds this (shared subtrees repeated) are interpreted with a memo instead."""


class SymbolicError(ModelDefinitionError):
    """An expression uses an operation this module cannot represent, or is used where it cannot be."""


# ====================================================================== nodes
class Expr:
    """A real-valued symbolic term; build with :func:`coordinates`, :func:`memory` and the operators.

    Called as ``expr(v, m)`` it is a guard or invariant value (``v`` the
    coordinate vector, ``m`` the memory mapping), compiled on first use.
    """

    __slots__ = ()

    # --- arithmetic -------------------------------------------------------------------
    def __add__(self, other: Any) -> Expr:
        return _apply("add", self, other)

    def __radd__(self, other: Any) -> Expr:
        return _apply("add", other, self)

    def __sub__(self, other: Any) -> Expr:
        return _apply("sub", self, other)

    def __rsub__(self, other: Any) -> Expr:
        return _apply("sub", other, self)

    def __mul__(self, other: Any) -> Expr:
        return _apply("mul", self, other)

    def __rmul__(self, other: Any) -> Expr:
        return _apply("mul", other, self)

    def __truediv__(self, other: Any) -> Expr:
        divisor = as_expr(other)
        if not isinstance(divisor, (Const, Param)) or float_value(divisor) == 0.0:
            return Unsupported(
                "division by a non-constant" if not isinstance(divisor, (Const, Param)) else "division by zero",
                f"{render(self)} / {render(divisor)}",
                "a symbolic expression may only be divided by a non-zero constant: multiply both sides of the "
                "comparison through by the divisor (g = a - b * c for a / c >= b with c > 0), or use ite() on "
                "the divisor's sign")
        return _apply("div", self, divisor)

    def __rtruediv__(self, other: Any) -> Expr:
        return as_expr(other) / self

    def __neg__(self) -> Expr:
        return _apply("neg", self)

    def __pos__(self) -> Expr:
        return self

    def __abs__(self) -> Expr:
        return _apply("abs", self)

    def __pow__(self, exponent: Any) -> Expr:
        if isinstance(exponent, bool) or not isinstance(exponent, int) or exponent < 0:
            return Unsupported("a power that is not a non-negative integer", f"{render(self)} ** {exponent!r}",
                               "write sqrt(x) for x ** 0.5, multiply out x * x, or use exp(log(x) * p)")
        return Apply("pow", (self, Const(float(exponent))))

    def __rpow__(self, base: Any) -> Expr:
        return Unsupported("a variable exponent", f"{base!r} ** {render(self)}",
                           "write exp(log(base) * x) (transcendental: enclosed by intervals in the checker)")

    # --- comparisons -------------------------------------------------------------------
    def __ge__(self, other: Any) -> Compare:
        return Compare(">=", self, as_expr(other))

    def __gt__(self, other: Any) -> Compare:
        return Compare(">", self, as_expr(other))

    def __le__(self, other: Any) -> Compare:
        return Compare("<=", self, as_expr(other))

    def __lt__(self, other: Any) -> Compare:
        return Compare("<", self, as_expr(other))

    def __bool__(self) -> bool:
        """An expression object is always "given" (``inv or default`` keeps it); comparisons have no truth value."""
        return True

    def __float__(self) -> float:
        raise SymbolicError(
            f"the symbolic expression {render(self)} has no numeric value until evaluated; call it with "
            "(v, m) or use hybrid.symbolic.evaluate()"
        )

    def __round__(self, ndigits: int | None = None) -> Any:
        raise SymbolicError(f"unsupported operation: round() of {render(self)}; rounding is not piecewise polynomial")

    def __floor__(self) -> Any:
        raise SymbolicError(f"unsupported operation: math.floor() of {render(self)}; use select() on an index")

    def __index__(self) -> int:
        raise SymbolicError(
            f"unsupported operation: indexing with {render(self)}; use select(index, (option_0, option_1, ...))"
        )

    __hash__ = object.__hash__

    # --- use as a guard / invariant ----------------------------------------------------------
    def __call__(self, v: Sequence[float], m: Mapping[str, float]) -> float:
        return compiled_function(self, "condition")(v, m)

    def __repr__(self) -> str:
        return f"<expr {render(self)}>"


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Const(Expr):
    """A real constant (finite, or ±inf; NaN is refused)."""

    value: float

    def __post_init__(self) -> None:
        if isinstance(self.value, bool) or not isinstance(self.value, (int, float)) or math.isnan(self.value):
            raise SymbolicError(f"Const(value = {self.value!r}): expected a real number (not NaN, not a bool)")
        object.__setattr__(self, "value", float(self.value))


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Coordinate(Expr):
    """Component ``index`` (called ``name``) of the vector argument: a signal of a guard, a state of a flow."""

    name: str
    index: int


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class MemoryRef(Expr):
    """The memory variable ``name``."""

    name: str


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Time(Expr):
    """Time ``t`` [s] (flows and outputs only); the module's :data:`time` is one, used as it is (``time >= tb``).

    Calling it with no argument gives itself, so ``time()`` (the older spelling) still works.
    """

    def __call__(self, *args: Any) -> Any:
        if not args:
            return self
        return Expr.__call__(self, *args)


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Param(Expr):
    """A named constant: evaluated as ``value``, left free by a parametric question of the checker."""

    name: str
    value: float

    def __post_init__(self) -> None:
        if isinstance(self.value, bool) or not isinstance(self.value, (int, float)) or not math.isfinite(self.value):
            raise SymbolicError(f"param {self.name!r}: value = {self.value!r}; expected a finite real number")
        object.__setattr__(self, "value", float(self.value))


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Apply(Expr):
    """An arithmetic operation or function ``op`` applied to ``args``."""

    op: str
    args: tuple[Expr, ...]


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Unsupported(Expr):
    """An operation the module cannot represent; the model that uses it is refused, naming where.

    Built instead of raising at once, so that the transition or mode that uses
    it can be named (:func:`unsupported_terms`, checked by :mod:`hybrid.model`).
    """

    op: str
    text: str
    hint: str

    def message(self) -> str:
        """``unsupported operation: <op> in <text>; <how to rewrite>``."""
        return f"unsupported operation: {self.op} in {self.text}; {self.hint}"


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Ite(Expr):
    """``then`` where ``condition`` holds, ``otherwise`` elsewhere."""

    condition: Condition
    then: Expr
    otherwise: Expr


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Select(Expr):
    """``options[int(index)]`` (the module docstring gives the domain)."""

    index: Expr
    options: tuple[Expr, ...]


class Condition:
    """A comparison or a logical combination of comparisons (use ``&``, ``|``, ``~``)."""

    __slots__ = ()

    def __and__(self, other: Condition) -> Condition:
        return Logic("and", (self, _condition(other, "&")))

    def __or__(self, other: Condition) -> Condition:
        return Logic("or", (self, _condition(other, "|")))

    def __invert__(self) -> Condition:
        return Logic("not", (self,))

    def __bool__(self) -> bool:
        raise SymbolicError(
            f"the symbolic condition {render(self)} has no truth value until evaluated; combine conditions "
            "with &, | and ~ (not Python's and, or, not), choose values with ite(), and pass a condition as a "
            "guard or invariant directly (its level form is used)"
        )

    def level(self) -> Expr:
        """The level form: an expression that is ``>= 0`` exactly where the (closed) condition holds."""
        return level_form(self)

    def __call__(self, v: Sequence[float], m: Mapping[str, float]) -> float:
        return compiled_function(self, "level")(v, m)

    __hash__ = object.__hash__

    def __repr__(self) -> str:
        return f"<condition {render(self)}>"


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Compare(Condition):
    """``left op right`` with ``op`` one of ``>=, >, <=, <, ==, !=``.

    ``exact=True`` makes the level form the subtraction as written, without the light simplification of a
    zero side (``0 - x`` stays ``0 - x``, not ``-x``): it then evaluates bit for bit like the float
    difference, ``+0.0`` on the face where a threshold that happens to be ``0.0`` is met (see
    :func:`exactly`).  Everything else (text, SMT form, enclosure) is the same comparison.
    """

    op: str
    left: Expr
    right: Expr
    exact: bool = False


@dataclass(frozen=True, eq=False, slots=True, repr=False)
class Logic(Condition):
    """``and`` / ``or`` of several conditions, or ``not`` of one."""

    op: str
    args: tuple[Condition, ...]


def _condition(value: Any, where: str) -> Condition:
    if not isinstance(value, Condition):
        raise SymbolicError(f"{where}: {value!r} is not a symbolic condition; compare expressions (x >= 1) first")
    return value


# ====================================================================== builders
def const(value: float) -> Const:
    """A constant node."""
    return Const(value)


def as_expr(value: Any) -> Expr:
    """``value`` as an expression (numbers become :class:`Const`)."""
    if isinstance(value, Expr):
        return value
    if isinstance(value, Condition):
        raise SymbolicError(
            f"the condition {render(value)} is used as a number; use ite(condition, a, b) or its .level()"
        )
    if isinstance(value, bool):
        raise SymbolicError(f"the bool {value!r} is used as a number in a symbolic expression; write 1.0 or 0.0")
    try:
        import numpy as np

        if isinstance(value, np.generic):
            value = value.item()
    except ImportError:  # pragma: no cover - numpy is a dependency
        pass
    if isinstance(value, (int, float)):
        return Const(float(value))
    raise SymbolicError(
        f"unsupported operand {value!r} ({type(value).__name__}) in a symbolic expression; expected a number or "
        "an expression of hybrid.symbolic"
    )


def float_value(node: Expr) -> float:
    """The value of a constant node."""
    return node.value  # type: ignore[attr-defined]


def _apply(op: str, *args: Any) -> Expr:
    nodes = tuple(as_expr(a) for a in args)
    return _fold(Apply(op, nodes))


def _fold(node: Apply) -> Expr:
    """Light simplification: constants folded, ``0 +``, ``1 *``, ``0 *`` removed (keeps trees small)."""
    op, args = node.op, node.args
    if all(isinstance(a, Const) for a in args) and op not in TRANSCENDENTAL:
        return Const(FLOAT_OPS[op](*(a.value for a in args)))  # type: ignore[attr-defined]
    if op == "add":
        if _is(args[0], 0.0):
            return args[1]
        if _is(args[1], 0.0):
            return args[0]
    elif op == "sub":
        if _is(args[1], 0.0):
            return args[0]
        if _is(args[0], 0.0):
            return _fold(Apply("neg", (args[1],)))
    elif op == "mul":
        if _is(args[0], 0.0) or _is(args[1], 0.0):
            return Const(0.0)
        if _is(args[0], 1.0):
            return args[1]
        if _is(args[1], 1.0):
            return args[0]
    elif op == "neg" and isinstance(args[0], Apply) and args[0].op == "neg":
        return args[0].args[0]
    return node


def _is(node: Expr, value: float) -> bool:
    return isinstance(node, Const) and node.value == value


class Coordinates:
    """Named coordinates of a vector argument: ``v.T`` or ``v["T"]`` is a :class:`Coordinate`."""

    def __init__(self, names: Sequence[str]) -> None:
        names = tuple(names)
        for n in names:
            if not isinstance(n, str) or not n:
                raise SymbolicError(f"coordinates(): name {n!r}; expected non-empty strings")
        if len(set(names)) != len(names):
            raise SymbolicError(f"coordinates(): duplicate names in {list(names)}")
        object.__setattr__(self, "_nodes", {n: Coordinate(n, i) for i, n in enumerate(names)})
        object.__setattr__(self, "names", names)

    def __getattr__(self, name: str) -> Coordinate:
        nodes = object.__getattribute__(self, "_nodes")
        try:
            return nodes[name]
        except KeyError:
            raise SymbolicError(f"no coordinate {name!r}; the coordinates are {list(nodes)}") from None

    __getitem__ = __getattr__

    def __iter__(self):
        return iter(object.__getattribute__(self, "_nodes").values())

    def __len__(self) -> int:
        return len(self.names)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("Coordinates are read-only")


class MemoryRefs(Coordinates):
    """Named memory variables: ``m.dL`` is a :class:`MemoryRef`."""

    def __init__(self, names: Sequence[str]) -> None:
        super().__init__(names)
        object.__setattr__(self, "_nodes", {n: MemoryRef(n) for n in self.names})

    def __getattr__(self, name: str) -> MemoryRef:  # type: ignore[override]
        nodes = object.__getattribute__(self, "_nodes")
        try:
            return nodes[name]
        except KeyError:
            raise SymbolicError(f"no memory variable {name!r}; declared: {list(nodes)}") from None

    __getitem__ = __getattr__


def coordinates(*names: str) -> Coordinates:
    """Coordinates named ``names`` in vector order (the automaton's variables, or a system's state names)."""
    if len(names) == 1 and not isinstance(names[0], str):
        names = tuple(names[0])
    return Coordinates(names)


def memory(*names: str) -> MemoryRefs:
    """Memory variables named ``names``."""
    if len(names) == 1 and not isinstance(names[0], str):
        names = tuple(names[0])
    return MemoryRefs(names)


def param(name: str, value: float) -> Param:
    """A named constant (see :class:`Param`)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise SymbolicError(f"param(): name {name!r}; expected an identifier")
    return Param(name, value)

time = Time()
"""The time symbol of flows and outputs: ``flow_map(-k * (v.T - 20 - sin(time)))``, ``time >= tb``."""


def minimum(*args: Any) -> Expr:
    """``min`` of one or more terms."""
    return nary_apply("min", args)


def maximum(*args: Any) -> Expr:
    """``max`` of one or more terms."""
    return nary_apply("max", args)


def nary_apply(op: str, args: tuple[Any, ...]) -> Expr:
    """``op`` (``"min"`` or ``"max"``) of ``args`` (or of the one list or tuple given), as an :class:`Apply` node."""
    if len(args) == 1 and isinstance(args[0], (list, tuple)):
        args = tuple(args[0])
    if not args:
        raise SymbolicError(f"{'minimum' if op == 'min' else 'maximum'}(): give at least one term")
    nodes: list[Expr] = []
    for a in args:
        e = as_expr(a)
        nodes.extend(e.args if isinstance(e, Apply) and e.op == op else (e,))
    if len(nodes) == 1:
        return nodes[0]
    return Apply(op, tuple(nodes))


def ite(condition: Condition, then: Any, otherwise: Any) -> Expr:
    """``then`` where ``condition`` holds, else ``otherwise``."""
    return Ite(_condition(condition, "ite()"), as_expr(then), as_expr(otherwise))


def select(index: Any, options: Sequence[Any]) -> Expr:
    """``options[int(index)]``: a latched index choosing among terms (e.g. the distance to obstacle ``i``)."""
    opts = tuple(as_expr(o) for o in options)
    if not opts:
        raise SymbolicError("select(): no options; give at least one term to choose from")
    return Select(as_expr(index), opts)


def sin(x: Any) -> Expr:
    """Sine (transcendental: enclosed by intervals in the checker)."""
    return _apply("sin", x)


def cos(x: Any) -> Expr:
    """Cosine (transcendental)."""
    return _apply("cos", x)


def exp(x: Any) -> Expr:
    """Exponential (transcendental)."""
    return _apply("exp", x)


def log(x: Any) -> Expr:
    """Natural logarithm, ``x > 0`` (transcendental)."""
    return _apply("log", x)


def sqrt(x: Any) -> Expr:
    """Square root, ``x >= 0`` (enclosed by intervals in the checker)."""
    return _apply("sqrt", x)


def atan2(y: Any, x: Any) -> Expr:
    """Four-quadrant arctangent (transcendental)."""
    return _apply("atan2", y, x)


def all_true(*conditions: Condition) -> Condition:
    """Conjunction of conditions."""
    if not conditions:
        raise SymbolicError("all_true(): give at least one condition")
    return Logic("and", tuple(_condition(c, "all_true()") for c in conditions))


def any_true(*conditions: Condition) -> Condition:
    """Disjunction of conditions."""
    if not conditions:
        raise SymbolicError("any_true(): give at least one condition")
    return Logic("or", tuple(_condition(c, "any_true()") for c in conditions))


def level_form(condition: Condition | Expr) -> Expr:
    """An expression ``>= 0`` exactly on the closure of ``condition`` (an expression is returned as it is)."""
    if isinstance(condition, Expr):
        return condition
    if isinstance(condition, Compare):
        a, b = condition.left, condition.right
        if condition.exact and condition.op in (">=", ">", "<=", "<"):
            return Apply("sub", (a, b) if condition.op in (">=", ">") else (b, a))
        if condition.op in (">=", ">"):
            return a - b
        if condition.op in ("<=", "<"):
            return b - a
        if condition.op == "==":
            return -abs(a - b)
        raise SymbolicError(
            f"the condition {render(condition)} (!=) has no closed level form: its closure is everything; "
            "write the two sides as (a > b) | (a < b) with a margin"
        )
    if isinstance(condition, Logic):
        if condition.op == "and":
            return minimum(*(level_form(c) for c in condition.args))
        if condition.op == "or":
            return maximum(*(level_form(c) for c in condition.args))
        return level_form(_negate(condition.args[0]))
    raise SymbolicError(f"level_form(): {condition!r} is not a condition")


def exactly(condition: Condition) -> Condition:
    """``condition`` whose comparisons take their level form exactly as written (``Compare.exact``).

    For a threshold given as a number that may be ``0.0``: ``exactly(x <= r)`` has the level ``r - x``,
    ``+0.0`` at ``x = r = 0`` as in float arithmetic, where the simplified ``-x`` gives ``-0.0``.

    Examples
    --------
    >>> from hybrid.symbolic import coordinates, exactly
    >>> v = coordinates("x")
    >>> (v.x <= 0.0)((0.0,), {}), exactly(v.x <= 0.0)((0.0,), {})
    (-0.0, 0.0)
    """
    if isinstance(condition, Compare):
        return Compare(condition.op, condition.left, condition.right, True)
    if isinstance(condition, Logic):
        return Logic(condition.op, tuple(exactly(c) for c in condition.args))
    raise SymbolicError(f"exactly(): {condition!r} is not a condition; compare expressions (x >= 1) first")


def _negate(c: Condition) -> Condition:
    """``not c`` pushed inside (``not (a >= b)`` is ``a < b``), so its level form is defined."""
    if isinstance(c, Compare):
        flipped = {">=": "<", ">": "<=", "<=": ">", "<": ">=", "==": "!=", "!=": "=="}[c.op]
        return Compare(flipped, c.left, c.right, c.exact)
    assert isinstance(c, Logic)
    if c.op == "not":
        return c.args[0]
    return Logic("or" if c.op == "and" else "and", tuple(_negate(a) for a in c.args))

# ====================================================================== rendering
_INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/"}

RENDER_LIMIT = 400
"""Written-out size above which :func:`render` abbreviates an expression (shared subtrees repeat when written)."""


def render(node: Expr | Condition) -> str:
    """Human-readable text of an expression or condition (abbreviated beyond :data:`RENDER_LIMIT` nodes)."""
    if isinstance(node, (Apply, Ite, Select, Logic)):
        size = expanded_size(node)
        if size > RENDER_LIMIT:
            return f"<expression of {size} nodes, depth {depth(node)}>"
    return _render(node)


def _render(node: Expr | Condition) -> str:
    if isinstance(node, Const):
        return f"{node.value:g}"
    if isinstance(node, Coordinate):
        return node.name
    if isinstance(node, MemoryRef):
        return node.name
    if isinstance(node, Param):
        return node.name
    if isinstance(node, Time):
        return "t"
    if isinstance(node, Apply):
        if node.op in _INFIX:
            return f"({render(node.args[0])} {_INFIX[node.op]} {render(node.args[1])})"
        if node.op == "neg":
            return f"-{render(node.args[0])}"
        if node.op == "pow":
            return f"{render(node.args[0])}^{int(float_value(node.args[1]))}"
        return f"{node.op}({', '.join(render(a) for a in node.args)})"
    if isinstance(node, Unsupported):
        return f"<unsupported: {node.text}>"
    if isinstance(node, Ite):
        return f"ite({render(node.condition)}, {render(node.then)}, {render(node.otherwise)})"
    if isinstance(node, Select):
        return f"select({render(node.index)}, [{', '.join(render(o) for o in node.options)}])"
    if isinstance(node, Compare):
        return f"{render(node.left)} {node.op} {render(node.right)}"
    if isinstance(node, Logic):
        if node.op == "not":
            return f"not ({render(node.args[0])})"
        return "(" + f" {node.op} ".join(render(a) for a in node.args) + ")"
    return repr(node)

# ====================================================================== float evaluation
FLOAT_OPS: dict[str, Callable[..., float]] = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "neg": lambda a: -a,
    "abs": abs,
    "pow": lambda a, n: a ** int(n),
    "min": min,
    "max": max,
    "sin": math.sin,
    "cos": math.cos,
    "exp": math.exp,
    "log": math.log,
    "sqrt": math.sqrt,
    "atan2": math.atan2,
}

_COMPARE = {">=": lambda a, b: a >= b, ">": lambda a, b: a > b, "<=": lambda a, b: a <= b,
            "<": lambda a, b: a < b, "==": lambda a, b: a == b, "!=": lambda a, b: a != b}


def _pick(index: float, options: Sequence[float]) -> float:
    n = len(options)
    if not (-1.0 < index < n):
        raise ExecutionError(
            f"select(): index {index!r} is outside -1 < index < {n}; it chooses among {n} option(s)"
        )
    return options[int(index)]


def evaluate(node: Expr | Condition, v: Sequence[float] = (), m: Mapping[str, float] | None = None,
             t: float = 0.0) -> Any:
    """Interpret ``node`` with floats (the reference of the compiled form; a condition gives a bool).

    Each distinct node is evaluated at most once (a memo), and ``ite`` evaluates only its taken branch.
    """
    m = {} if m is None else m
    memo: dict[int, Any] = {}

    def ev(n: Any) -> Any:
        key = id(n)
        if key in memo:
            return memo[key]
        out = _evaluate_node(n, ev, v, m, t)
        memo[key] = out
        return out

    return ev(node)


def _evaluate_node(node: Any, ev: Callable[[Any], Any], v: Sequence[float], m: Mapping[str, float],
                   t: float) -> Any:
    if isinstance(node, Const):
        return node.value
    if isinstance(node, Coordinate):
        return v[node.index]
    if isinstance(node, MemoryRef):
        return m[node.name]
    if isinstance(node, Param):
        return node.value
    if isinstance(node, Time):
        return t
    if isinstance(node, Apply):
        return FLOAT_OPS[node.op](*(ev(a) for a in node.args))
    if isinstance(node, Unsupported):
        raise SymbolicError(node.message())
    if isinstance(node, Ite):
        return ev(node.then if ev(node.condition) else node.otherwise)
    if isinstance(node, Select):
        return _pick(ev(node.index), [ev(o) for o in node.options])
    if isinstance(node, Compare):
        return _COMPARE[node.op](ev(node.left), ev(node.right))
    if isinstance(node, Logic):
        if node.op == "and":
            return all(ev(c) for c in node.args)
        if node.op == "or":
            return any(ev(c) for c in node.args)
        return not ev(node.args[0])
    raise SymbolicError(f"evaluate(): {node!r} is not an expression")

_NAMESPACE = {"min": min, "max": max, "abs": abs, "inf": math.inf, "_pick": _pick,
              "sin": math.sin, "cos": math.cos, "exp": math.exp, "log": math.log, "sqrt": math.sqrt,
              "atan2": math.atan2, "__builtins__": {}}


def _source(node: Expr | Condition, vec: str) -> str:
    """Python source of ``node`` reading coordinates from ``vec``, memory from ``m`` and time from ``t``."""
    if isinstance(node, (Const, Param)):
        value = node.value
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "(-inf)")
    if isinstance(node, Coordinate):
        return f"{vec}[{node.index}]"
    if isinstance(node, MemoryRef):
        return f"m[{node.name!r}]"
    if isinstance(node, Time):
        return "t"
    if isinstance(node, Apply):
        args = [_source(a, vec) for a in node.args]
        if node.op in _INFIX:
            return f"({args[0]} {_INFIX[node.op]} {args[1]})"
        if node.op == "neg":
            return f"(-{args[0]})"
        if node.op == "pow":
            base = f"({args[0]})" if args[0].startswith("-") else args[0]  # -2.0 ** 2 would be -(2.0 ** 2)
            return f"({base} ** {int(float_value(node.args[1]))})"
        if node.op == "inv":
            return f"(1.0 / {args[0]})"
        return f"{node.op}({', '.join(args)})"
    if isinstance(node, Unsupported):
        raise SymbolicError(node.message())
    if isinstance(node, Ite):
        return f"({_source(node.then, vec)} if {_source(node.condition, vec)} else {_source(node.otherwise, vec)})"
    if isinstance(node, Select):
        return f"_pick({_source(node.index, vec)}, ({', '.join(_source(o, vec) for o in node.options)},))"
    if isinstance(node, Compare):
        return f"({_source(node.left, vec)} {node.op} {_source(node.right, vec)})"
    if isinstance(node, Logic):
        if node.op == "not":
            return f"(not {_source(node.args[0], vec)})"
        return "(" + f" {node.op} ".join(_source(a, vec) for a in node.args) + ")"
    raise SymbolicError(f"{node!r} is not an expression")


def depth(node: Expr | Condition) -> int:
    """Height of the tree (shared subtrees counted once: linear in the number of distinct nodes)."""
    memo: dict[int, int] = {}
    order = _postorder(node)
    for n in order:
        memo[id(n)] = 1 + max((memo[id(c)] for c in _children(n)), default=0)
    return memo[id(node)]


def expanded_size(node: Any) -> int:
    """Number of nodes of the tree written out (shared subtrees counted every time they appear)."""
    memo: dict[int, int] = {}
    for n in _postorder(node):
        memo[id(n)] = 1 + sum(memo[id(c)] for c in _children(n))
    return memo[id(node)]


def _postorder(node: Any) -> list[Any]:
    """Distinct nodes, children before parents (iterative: deep trees do not hit the recursion limit)."""
    out: list[Any] = []
    seen: set[int] = set()
    stack: list[tuple[Any, bool]] = [(node, False)]
    while stack:
        n, done = stack.pop()
        if done:
            out.append(n)
            continue
        if id(n) in seen:
            continue
        seen.add(id(n))
        stack.append((n, True))
        stack.extend((c, False) for c in _children(n) if id(c) not in seen)
    return out


def _children(node: Expr | Condition) -> tuple[Any, ...]:
    if isinstance(node, Apply):
        return node.args
    if isinstance(node, Ite):
        return (node.condition, node.then, node.otherwise)
    if isinstance(node, Select):
        return (node.index, *node.options)
    if isinstance(node, Compare):
        return (node.left, node.right)
    if isinstance(node, Logic):
        return node.args
    return ()

_SIGNATURES = {"condition": ("v, m", "v"), "reset": ("v, m", "v"), "jump": ("x, m", "x"),
               "flow": ("t, x, m", "x"), "output": ("t, x", "x")}

_CACHE: dict[tuple[int, str], tuple[Any, Callable[..., Any]]] = {}
_BY_SOURCE: dict[str, Callable[..., Any]] = {}

_ROLE = {"condition": "the guard or invariant", "reset": "the reset term", "jump": "the jump map term"}

_CACHE_LIMIT = 50_000


def compiled_function(node: Any, kind: str) -> Callable[..., Any]:
    """The compiled float function of ``node`` (an expression, a reset mapping or a vector) for a signature."""
    key = (id(node), kind)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit[1]
    if kind == "level":
        fn = compiled_function(level_form(node), "condition")
        _CACHE[key] = (node, fn)
        return fn
    params, vec = _SIGNATURES[kind]
    parts = _parts(node)
    if kind in ("condition", "reset", "jump"):
        for _, p in parts:
            if any(isinstance(n, Time) for n in walk_nodes(p)):
                raise SymbolicError(
                    f"{_ROLE[kind]} {render(p)} reads time t; "
                    "time is available in flows and outputs only"
                )
    if (max((depth(p) for _, p in parts), default=0) > MAX_COMPILED_DEPTH
            or sum(expanded_size(p) for _, p in parts) > MAX_COMPILED_SIZE):
        fn = _interpreted(node, kind)
    else:
        if kind == "condition":
            body = _source(node, vec)
        elif kind == "reset":
            body = "{" + ", ".join(f"{name!r}: {_source(p, vec)}" for name, p in parts) + "}"
        else:
            body = "(" + "".join(f"{_source(p, vec)}, " for _, p in parts) + ")"
        source = f"lambda {params}: {body}"
        fn = _BY_SOURCE.get(source) or _compile_lambda(source, kind)  # a rebuilt system's same guard: compiled once
        _BY_SOURCE[source] = fn
    if len(_CACHE) >= _CACHE_LIMIT:
        _CACHE.clear()
        _BY_SOURCE.clear()
    _CACHE[key] = (node, fn)  # the node is kept alive with its function, so its id stays unique
    return fn

_COMPILED = itertools.count()


def _compile_lambda(source: str, kind: str) -> Callable[..., Any]:
    """The float function of a generated lambda, its source registered with :mod:`linecache`.

    The source is built by :func:`_source` from the node types of this module only (floats by
    ``repr``, coordinate indices, memory names by ``repr``), evaluated with an empty ``__builtins__``;
    registering it makes a traceback through a compiled guard show the expression, not a blank line.
    """
    import linecache

    filename = f"<symbolic {kind} {next(_COMPILED)}>"
    linecache.cache[filename] = (len(source), None, [source + "\n"], filename)
    return eval(compile(source, filename, "eval"), dict(_NAMESPACE))  # noqa: S307 - generated, see above


def _parts(node: Any) -> list[tuple[str, Expr]]:
    if isinstance(node, SymbolicReset):
        return list(node.assignments.items())
    if isinstance(node, SymbolicVector):
        return [(str(i), e) for i, e in enumerate(node.components)]
    return [("", node)]


def _interpreted(node: Any, kind: str) -> Callable[..., Any]:
    if kind == "condition":
        return lambda v, m: evaluate(node, v, m)
    if kind == "reset":
        return lambda v, m: {k: evaluate(e, v, m) for k, e in node.assignments.items()}
    if kind == "jump":
        return lambda x, m: tuple(evaluate(e, x, m) for e in node.components)
    if kind == "flow":
        return lambda t, x, m: tuple(evaluate(e, x, m, t) for e in node.components)
    return lambda t, x: tuple(evaluate(e, x, {}, t) for e in node.components)


# ====================================================================== maps
@dataclass(frozen=True, eq=False, slots=True)
class SymbolicReset:
    """A memory reset ``{name: expression}``, callable as ``r(v, m) -> dict``."""

    assignments: Mapping[str, Expr]

    def __post_init__(self) -> None:
        items = {}
        for name, e in dict(self.assignments).items():
            if not isinstance(name, str) or not name:
                raise SymbolicError(f"reset(): memory name {name!r}; expected a non-empty string")
            items[name] = as_expr(e)
        object.__setattr__(self, "assignments", MappingProxyType(items))

    @property
    def writes(self) -> tuple[str, ...]:
        """The memory variables assigned, in order."""
        return tuple(self.assignments)

    def __call__(self, v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return compiled_function(self, "reset")(v, m)


@dataclass(frozen=True, eq=False, slots=True)
class SymbolicVector:
    """A vector of expressions used as a jump map ``(x, m)``, flow ``(t, x, m)`` or output ``(t, x)``."""

    components: tuple[Expr, ...]
    kind: str

    def __post_init__(self) -> None:
        if self.kind not in ("jump", "flow", "output"):
            raise SymbolicError(f"SymbolicVector.kind = {self.kind!r}; expected 'jump', 'flow' or 'output'")
        comps = tuple(as_expr(c) for c in self.components)
        if not comps:
            raise SymbolicError(f"{self.kind} map: no components; give one expression per coordinate")
        if self.kind == "output" and any(isinstance(n, MemoryRef) for c in comps for n in walk_nodes(c)):
            raise SymbolicError("output map: an output reads the state and time only, not memory")
        object.__setattr__(self, "components", comps)

    def __call__(self, *args: Any) -> tuple[float, ...]:
        return compiled_function(self, self.kind)(*args)

    def __len__(self) -> int:
        return len(self.components)


def reset(assignments: Mapping[str, Any] | None = None, **named: Any) -> SymbolicReset:
    """A symbolic memory reset: ``reset(dL=v.d, d_end=...)``."""
    return SymbolicReset({**dict(assignments or {}), **named})


def jump_map(*components: Any) -> SymbolicVector:
    """A symbolic continuous-state reset ``x⁺ = r(x, m)``, one expression per state."""
    return SymbolicVector(_flatten(components), "jump")


def flow_map(*components: Any) -> SymbolicVector:
    """A symbolic flow ``ẋ = f(t, x, m)``, one expression per state."""
    return SymbolicVector(_flatten(components), "flow")


def output_map(*components: Any) -> SymbolicVector:
    """A symbolic output ``v = h(t, x)``, one expression per automaton variable."""
    return SymbolicVector(_flatten(components), "output")


def _flatten(components: tuple[Any, ...]) -> tuple[Any, ...]:
    if len(components) == 1 and isinstance(components[0], (list, tuple)):
        return tuple(components[0])
    return components


# ====================================================================== structure
def walk_nodes(node: Any) -> Iterable[Any]:
    """Every node under ``node`` (itself included), each once, depth first."""
    stack = [node]
    seen: set[int] = set()
    while stack:
        n = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        yield n
        stack.extend(_children(n))
