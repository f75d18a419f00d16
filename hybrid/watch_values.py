"""All the watched functions of a mode as one compiled function (symbolic guards and invariants).

The continuous executor evaluates, many times per flow, the value ``phi`` of every watch of the mode
(:class:`hybrid.events.Watch`): ``±g`` for each outgoing transition's guard (``-g`` when it is crossed
downwards) and ``-inv`` for the invariant.  When all of them are symbolic (:mod:`hybrid.symbolic`
conditions or expressions, or :func:`hybrid.model.all_of` of such), :func:`watch_function` gives one
function ``phi(v, m) -> tuple`` of them all, compiled once by the project's one code-generation site
(:func:`hybrid.symbolic.compiled_function`) with the same source per term as each guard's own compiled
function, so its values are the same floats; one call replaces one Python call per watch.

Compiled functions are cached by the *structure* of the terms (the tree, constants by ``repr``), not by
object: a system rebuilt for every point of a search (new objects, same guards) compiles once.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from .model import Conjunction, Transition
from .symbolic_core import (
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
    SymbolicError,
    SymbolicVector,
    compiled_function,
    level_form,
    minimum,
)

__all__ = ["watch_function", "watch_terms", "evaluate_watches", "structure_key"]

_CACHE_LIMIT = 10_000
_CACHE: dict[Any, Callable[..., tuple[float, ...]] | None] = {}


def structure_key(node: Any) -> Any:
    """A hashable key equal for two trees that compile to the same source (``None``: not compilable here)."""
    memo: dict[int, Any] = {}

    def key(n: Any) -> Any:
        found = memo.get(id(n))
        if found is not None:
            return found
        if isinstance(n, (Const, Param)):
            out: Any = ("c", repr(n.value))
        elif isinstance(n, Coordinate):
            out = ("x", n.index)
        elif isinstance(n, MemoryRef):
            out = ("m", n.name)
        elif isinstance(n, Apply):
            out = (n.op, *(key(a) for a in n.args))
        elif isinstance(n, Ite):
            out = ("ite", key(n.condition), key(n.then), key(n.otherwise))
        elif isinstance(n, Select):
            out = ("select", key(n.index), *(key(o) for o in n.options))
        elif isinstance(n, (Compare, Logic)):
            out = (type(n).__name__, n.op, *(key(a) for a in ((n.left, n.right) if isinstance(n, Compare)
                                                                else n.args)))
        else:  # time (not in a guard), an unsupported operation: no fast path
            raise _NotCompilable
        memo[id(n)] = out
        return out

    try:
        return key(node)
    except _NotCompilable:
        return None


class _NotCompilable(Exception):
    pass


def _level(term: Any) -> Expr | None:
    """The level form of a symbolic guard or invariant (``all_of`` of symbolic terms: their minimum)."""
    if isinstance(term, Conjunction):
        levels = [_level(t) for t in term.terms]
        if any(level is None for level in levels):
            return None
        return levels[0] if len(levels) == 1 else minimum(*levels)  # type: ignore[arg-type]
    if isinstance(term, Condition):
        return level_form(term)
    if isinstance(term, Expr):
        return term
    return None


def watch_terms(outgoing: Sequence[Transition], invariant: Any) -> list[Expr] | None:
    """The symbolic ``phi`` of a mode's watches (guards in ``outgoing`` order, then ``-inv``), or ``None``.

    ``None`` when a guard or the invariant is not symbolic; an empty list when nothing is watched.
    """
    terms: list[Expr] = []
    for tr in outgoing:
        level = _level(tr.guard)
        if level is None:
            return None
        terms.append(-level if tr.direction < 0 else level)
    if invariant is not None:
        level = _level(invariant)
        if level is None:
            return None
        terms.append(-level)
    return terms


def watch_function(outgoing: Sequence[Transition], invariant: Any,
                   ) -> Callable[[Sequence[float], Mapping[str, float]], tuple[float, ...]] | None:
    """``phi(v, m)``: the values of a mode's watches, guards in ``outgoing`` order then the invariant's ``-inv``.

    Parameters
    ----------
    outgoing : sequence of Transition
        The mode's outgoing transitions (a crossing-downwards guard contributes ``-g``).
    invariant : callable or None
        The mode's invariant (``None``: no invariant watch).

    Returns
    -------
    callable or None
        ``None`` when a guard or the invariant is not symbolic (or cannot be compiled).
    """
    terms = watch_terms(outgoing, invariant)
    if not terms:
        return None
    key = tuple(structure_key(t) for t in terms)
    if any(k is None for k in key):
        return None
    if key in _CACHE:
        return _CACHE[key]
    try:
        fn: Callable[..., tuple[float, ...]] | None = compiled_function(SymbolicVector(tuple(terms), "jump"), "jump")
    except SymbolicError:
        fn = None
    if len(_CACHE) >= _CACHE_LIMIT:
        _CACHE.clear()
    _CACHE[key] = fn
    return fn


def evaluate_watches(compiled: Callable[..., tuple[float, ...]], output: Callable[..., Any] | None, t: float,
                     x: Sequence[float], memory: Mapping[str, float], n_signals: int, count: int) -> list[float]:
    """The ``count`` watch values of :func:`watch_function`'s ``compiled`` at ``(t, x)``, as floats.

    ``output``: the system's output map (``None``: the signals are the state).  Raises ``ValueError`` on any
    doubt (a wrong length, a NaN signal or value): the caller then evaluates the functions one by one and
    raises the error that names the culprit.
    """
    v = x if output is None else output(t, x)
    out = [float(c) for c in compiled(v, memory)]
    if len(v) != n_signals or len(out) != count:
        raise ValueError
    for value in out:
        if value != value:
            raise ValueError
    for value in v:
        if value != value:
            raise ValueError
    return out


def direct_function(fn: Any) -> Callable[..., Any]:
    """The function a guard or an invariant ``fn(v, m)`` calls: a symbolic one's compiled function, else ``fn``.

    ``Expr.__call__`` and ``Condition.__call__`` look their compiled function up at every call; an executor
    that calls the same guard thousands of times looks it up once (same function, same floats).
    """
    call = type(fn).__call__
    if call is Condition.__call__:
        return compiled_function(fn, "level")
    if call is Expr.__call__:
        return compiled_function(fn, "condition")
    return fn
