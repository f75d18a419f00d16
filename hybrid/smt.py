"""Symbolic expressions (:mod:`hybrid.symbolic`) as z3 terms, and the solver calls of the checker.

The translation is exact for the piecewise polynomial part: numbers become
exact rationals (every float is one), ``min``/``max``/``abs``/``ite``/``select``
become ``If`` terms, powers become products.  A transcendental term
(``sin``, ``cos``, ``exp``, ``log``, ``sqrt``, ``atan2``, and ``1/x`` from a
derivative) becomes a fresh real bounded by its interval enclosure over the
declared region (:func:`hybrid.symbolic.enclose`): an over-approximation, so
an *unsat* answer stays a proof while a *sat* answer must be confirmed by
evaluating the model's own functions at the witness (the checker always does).

``select`` and the transcendental terms contribute *domain conditions*
(``-1 < index < n``, ``x > 0`` under ``log``): a query only considers points
where the model's functions are defined.

Every query runs with a timeout; ``unknown`` is returned as it is, and the
checker reports it as "undecided within N s", never as clean.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from .symbolic import (
    TRANSCENDENTAL,
    Apply,
    Compare,
    Const,
    Coordinate,
    Ite,
    Logic,
    MemoryRef,
    Param,
    Select,
    SymbolicError,
    Time,
    enclose,
    render,
)

__all__ = ["z3_available", "Translation", "rational", "to_float", "check_sat", "Answer", "solver_version",
           "context", "fresh_context", "all_of", "any_of", "compare", "combine"]


def z3_available() -> bool:
    """Whether the z3 solver can be imported."""
    try:
        import z3  # noqa: F401
    except ImportError:
        return False
    return True


def solver_version() -> str:
    """``"z3 <version>"``."""
    import z3

    return f"z3 {z3.get_version_string()}"


_STATE: dict[str, Any] = {"ctx": None, "numbers": {}, "solver": None}


def context() -> Any:
    """The z3 context of the current decision (:func:`fresh_context`), else z3's main context."""
    return _STATE["ctx"]


@contextlib.contextmanager
def fresh_context() -> Iterator[Any]:
    """A private z3 context for one decision: the same questions give the same answers (and witnesses)
    however many decisions ran before in the process (z3's shared context keeps state between them)."""
    import z3

    saved = dict(_STATE)
    _STATE["ctx"], _STATE["numbers"], _STATE["solver"] = z3.Context(), {}, None
    try:
        yield _STATE["ctx"]
    finally:
        _STATE.update(saved)


def rational(value: float) -> Any:
    """The exact z3 rational of a finite float (cached per context: the same numbers recur in every query)."""
    numbers = _STATE["numbers"]
    hit = numbers.get(value)
    if hit is not None:
        return hit
    import z3

    if not math.isfinite(value):
        raise SymbolicError(f"the constant {value!r} is not finite; an SMT solver cannot represent it")
    f = Fraction(value)
    ctx = _STATE["ctx"]
    out = z3.Q(f.numerator, f.denominator, ctx) if f.denominator != 1 else z3.RealVal(f.numerator, ctx)
    if len(numbers) < 100_000:
        numbers[value] = out
    return out


def _connective(terms: list[Any], conjunction: bool) -> Any:
    import z3

    ctx = _STATE["ctx"] if _STATE["ctx"] is not None else z3.main_ctx()
    if not terms:
        return z3.BoolVal(conjunction, ctx)
    if len(terms) == 1 and isinstance(terms[0], z3.BoolRef):
        return terms[0]
    if not all(isinstance(t, z3.BoolRef) and t.ctx is ctx for t in terms):
        return z3.And(*terms) if conjunction else z3.Or(*terms)  # z3 coerces (and reports what it cannot)
    array = (z3.Ast * len(terms))(*(t.as_ast() for t in terms))
    make = z3.Z3_mk_and if conjunction else z3.Z3_mk_or
    return z3.BoolRef(make(ctx.ref(), len(terms), array), ctx)


_COMPARE = {">=": "Z3_mk_ge", ">": "Z3_mk_gt", "<=": "Z3_mk_le", "<": "Z3_mk_lt", "==": "Z3_mk_eq"}
_COMBINE = {"add": "Z3_mk_add", "sub": "Z3_mk_sub", "mul": "Z3_mk_mul"}


def _both_terms(a: Any, b: Any) -> bool:
    import z3

    return isinstance(a, z3.ArithRef) and isinstance(b, z3.ArithRef) and a.ctx is b.ctx


def compare(op: str, a: Any, b: Any) -> Any:
    """``a op b`` for two real z3 terms of one context, built in one call (z3's operators check sorts
    and coerce first: the cost of most of a translation); other operands go through those operators."""
    import z3

    if op in _COMPARE and _both_terms(a, b):
        return z3.BoolRef(getattr(z3, _COMPARE[op])(a.ctx.ref(), a.as_ast(), b.as_ast()), a.ctx)
    return {">=": lambda: a >= b, ">": lambda: a > b, "<=": lambda: a <= b, "<": lambda: a < b,
            "==": lambda: a == b, "!=": lambda: a != b}[op]()


def combine(op: str, a: Any, b: Any) -> Any:
    """``a + b``, ``a - b`` or ``a * b`` for two real z3 terms of one context, built in one call."""
    import z3

    if _both_terms(a, b):
        array = (z3.Ast * 2)(a.as_ast(), b.as_ast())
        return z3.ArithRef(getattr(z3, _COMBINE[op])(a.ctx.ref(), 2, array), a.ctx)
    return a + b if op == "add" else (a - b if op == "sub" else a * b)


def all_of(terms: list[Any]) -> Any:
    """The conjunction of z3 formulas of the current context (``True`` when empty), built in one call."""
    return _connective(list(terms), True)


def any_of(terms: list[Any]) -> Any:
    """The disjunction of z3 formulas of the current context (``False`` when empty), built in one call."""
    return _connective(list(terms), False)


def to_float(value: Any) -> float:
    """A z3 numeral (rational or algebraic) as the nearest float."""
    import z3

    if z3.is_rational_value(value):  # the numeral's exact text "p" or "p/q", in one call
        return float(Fraction(z3.Z3_get_numeral_string(value.ctx_ref(), value.as_ast())))
    if z3.is_algebraic_value(value):
        return float(Fraction(value.approx(20).as_fraction()))
    return float(Fraction(str(z3.simplify(value))))


@dataclass
class Translation:
    """Translates expressions into z3 terms over given symbols, collecting domain conditions.

    Attributes
    ----------
    coordinates : Mapping[str, z3 term]
        The term of every coordinate name.
    memory : Mapping[str, z3 term]
        The term of every memory variable.
    params : Mapping[str, z3 term]
        Parameters left free (the others are their values).
    bounds, memory_bounds : Mapping[str, (lo, hi)]
        The region the transcendental terms are enclosed over.
    prefix : str
        Prefix of the fresh variables of this translation.
    """

    coordinates: Mapping[str, Any]
    memory: Mapping[str, Any]
    params: Mapping[str, Any] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    memory_bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    param_bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    prefix: str = "aux"
    side: list[Any] = field(default_factory=list)
    approximated: list[str] = field(default_factory=list)
    _memo: dict[int, Any] = field(default_factory=dict)
    _keep: list[Any] = field(default_factory=list)
    _side_ids: set[int] = field(default_factory=set)
    _collect: Any = None

    def term(self, node: Any) -> Any:
        """The z3 term (arithmetic) or formula (condition) of ``node``; its domain conditions join :attr:`side`."""
        out, sides = self._term(node)
        for c in sides:
            if id(c) not in self._side_ids:
                self._side_ids.add(id(c))
                self.side.append(c)
        return out

    def begin(self) -> None:
        """Start a new query: forget the domain conditions collected so far (the translated terms are kept)."""
        self.side = []
        self._side_ids = set()

    def _term(self, node: Any) -> tuple[Any, tuple[Any, ...]]:
        key = id(node)
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        outer = self._collect
        self._collect = []
        try:
            out = self._translate(node)
            result = (out, tuple(self._collect))
        finally:
            inner = self._collect
            self._collect = outer
        if outer is not None:
            outer.extend(inner)
        self._memo[key] = result
        self._keep.append(node)
        return result

    def _sub(self, node: Any) -> Any:
        out, sides = self._term(node)
        self._collect.extend(sides)
        return out

    def _translate(self, node: Any) -> Any:
        import z3

        if isinstance(node, Const):
            return rational(node.value)
        if isinstance(node, Param):
            return self.params[node.name] if node.name in self.params else rational(node.value)
        if isinstance(node, Coordinate):
            return self._lookup(self.coordinates, node.name, "coordinate")
        if isinstance(node, MemoryRef):
            return self._lookup(self.memory, node.name, "memory variable")
        if isinstance(node, Time):
            raise SymbolicError("time t appears in a guard, invariant or reset; the checker cannot decide it")
        if isinstance(node, Apply):
            return self._apply(node)
        if isinstance(node, Ite):
            return z3.If(self._sub(node.condition), self._sub(node.then), self._sub(node.otherwise))
        if isinstance(node, Select):
            index = self._sub(node.index)
            n = len(node.options)
            self._collect.append(all_of([index > -1, index < n]))
            out = self._sub(node.options[-1])
            for i in range(n - 2, -1, -1):
                out = z3.If(index < i + 1, self._sub(node.options[i]), out)
            return out
        if isinstance(node, Compare) and (_infinite(node.left) or _infinite(node.right)):
            return z3.BoolVal(_infinite_compare(node), context())
        if isinstance(node, Compare):
            return compare(node.op, self._sub(node.left), self._sub(node.right))
        if isinstance(node, Logic):
            args = [self._sub(c) for c in node.args]
            return z3.Not(args[0]) if node.op == "not" else (all_of(args) if node.op == "and" else any_of(args))
        raise SymbolicError(f"cannot translate {node!r} for the SMT solver")

    def _lookup(self, table: Mapping[str, Any], name: str, what: str) -> Any:
        try:
            return table[name]
        except KeyError:
            raise SymbolicError(f"the {what} {name!r} is not declared here; known: {sorted(table)}") from None

    def _apply(self, node: Apply) -> Any:
        import z3

        op = node.op
        if op in TRANSCENDENTAL or op == "inv":
            return self._enclosed(node)
        args = [self._sub(a) for a in node.args]
        if op in ("add", "sub", "mul"):
            return combine(op, args[0], args[1])
        if op == "div":
            return args[0] / args[1]
        if op == "neg":
            return -args[0]
        if op == "abs":
            return z3.If(compare(">=", args[0], rational(0.0)), args[0], -args[0])
        if op == "pow":
            k = int(node.args[1].value)  # type: ignore[attr-defined]
            if k == 0:
                return z3.RealVal(1, context())
            out = args[0]
            for _ in range(k - 1):
                out = combine("mul", out, args[0])
            return out
        if op in ("min", "max"):
            out = args[0]
            for a in args[1:]:
                out = z3.If(compare("<=" if op == "min" else ">=", out, a), out, a)
            return out
        raise SymbolicError(f"unsupported operation {op!r} for the SMT solver")

    def _enclosed(self, node: Apply) -> Any:
        """A fresh real within the interval enclosure of a transcendental term (an over-approximation)."""
        import z3

        lo, hi = enclose(node, self.bounds, self.memory_bounds, param_bounds=self.param_bounds)
        fresh = z3.Real(f"{self.prefix}!{len(self.approximated)}", context())
        self.approximated.append(render(node))
        if math.isfinite(lo):
            self._collect.append(compare(">=", fresh, rational(lo)))
        if math.isfinite(hi):
            self._collect.append(compare("<=", fresh, rational(hi)))
        if node.op == "inv":
            self._collect.append(self._sub(node.args[0]) != 0)
        if node.op == "log":
            self._collect.append(self._sub(node.args[0]) > 0)
        if node.op == "sqrt":
            self._collect.append(self._sub(node.args[0]) >= 0)
        return fresh


def _infinite(node: Any) -> bool:
    return isinstance(node, Const) and math.isinf(node.value)


def _infinite_compare(node: Compare) -> bool:
    """A comparison with an infinite constant, for finite reals (the solver's values are all finite)."""
    left = node.left.value if isinstance(node.left, Const) else 0.0
    right = node.right.value if isinstance(node.right, Const) else 0.0
    if _infinite(node.left) and _infinite(node.right):
        raise SymbolicError(f"the comparison {render(node)} compares two infinite constants")
    ops = {">=": lambda a, b: a >= b, ">": lambda a, b: a > b, "<=": lambda a, b: a <= b,
           "<": lambda a, b: a < b, "==": lambda a, b: a == b, "!=": lambda a, b: a != b}
    return ops[node.op](left, right)


@dataclass(frozen=True)
class Answer:
    """One solver answer: ``"sat"`` with a model, ``"unsat"``, or ``"unknown"`` with the reason."""

    status: str
    model: Any = None
    reason: str = ""
    seconds: float = 0.0


def _session() -> Any:
    """The incremental solver of the current context (created on first use; one per :func:`fresh_context`)."""
    import z3

    if _STATE["solver"] is None:
        _STATE["solver"] = z3.SimpleSolver(ctx=_STATE["ctx"])
    return _STATE["solver"]


def check_sat(constraints: list[Any], timeout_s: float) -> Answer:
    """Decide the conjunction of ``constraints`` within ``timeout_s`` seconds.

    The question goes first to the context's incremental SMT core
    (``z3.SimpleSolver``, one per :func:`fresh_context`, the constraints asserted
    inside ``push``/``pop``: no solver is built per question and no
    preprocessing tactic runs, the cheapest on the small linear queries of a
    supervisor).  When it answers "unknown" (non-linear arithmetic it cannot
    settle, or its timeout) the question is put to a fresh default solver (which
    picks a tactic for the logic, e.g. ``nlsat`` for polynomial real arithmetic)
    with the same timeout.  Both are decision procedures: "unsat" from either is
    a proof, a model from either is re-checked by the caller.  ``seconds``
    counts both calls.
    """
    import time as _time

    import z3

    ms = max(1, int(round(timeout_s * 1000)))
    session = _session()
    session.set("timeout", ms)
    session.push()
    try:
        session.add(*constraints)
        start = _time.perf_counter()
        result = session.check()
        elapsed = _time.perf_counter() - start
        if result == z3.sat:
            return Answer("sat", session.model(), seconds=elapsed)
        if result == z3.unsat:
            return Answer("unsat", seconds=elapsed)
    finally:
        session.pop()
    solver = z3.Solver(ctx=context())
    solver.set("timeout", ms)
    solver.add(*constraints)
    start = _time.perf_counter()
    result = solver.check()
    elapsed += _time.perf_counter() - start
    if result == z3.sat:
        return Answer("sat", solver.model(), seconds=elapsed)
    if result == z3.unsat:
        return Answer("unsat", seconds=elapsed)
    return Answer("unknown", reason=solver.reason_unknown(), seconds=elapsed)
