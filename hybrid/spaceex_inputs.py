"""SpaceEx inputs: uncontrolled variables without a flow, bounded by the invariant (non-deterministic inputs).

SpaceEx lets such a variable take any value within the invariant's bounds at every instant: the
building's ``model.u1 ∈ [0.8, 1]`` (BLDF01), the platoon's leader acceleration ``aL ∈ [-9, 1]``.
hybrid's flows are ODEs, so the import keeps each input as a named placeholder
(:class:`hybrid.symbolic.Param` ``input_<name>``) in :attr:`SpaceExModel.input_flows` and gives
the imported :attr:`SpaceExModel.system` a definite signal; the analyses choose the signal:

* simulation and falsification: a piecewise-constant signal of time (:func:`input_signal`, its
  values problem parameters: ``analysis.spaceex``);
* reachability: the input as a bounded non-deterministic input ``u(t) ∈ [low, high]``
  (``analysis.reach.ModeInput``), the flow's coefficients of the input its matrix ``B``.

The imported ``system`` holds each input at the middle of its bounds through a one-piece signal of
time: a concrete run, and a flow that reads time, which reachability refuses (so that nobody proves
the constant-input model by mistake: use the ``ModeInput`` route).

An input must be bounded by constants in the invariant of every location (``lo <= u <= hi``, the same
bounds everywhere) and read only by flows (not by guards, assignments or other invariant constraints).
Anything else is a :class:`~hybrid.spaceex_syntax.SpaceExError` naming the variable and the fix.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from .spaceex_flatten import FlatAutomaton
from .spaceex_syntax import SpaceExError
from .symbolic import Const, Expr, Param, Select, minimum, substitute, time
from .symbolic_core import SymbolicVector
from .system import HybridSystem

__all__ = ["SpaceExInput", "find_inputs", "is_input_bound", "input_symbol", "input_signal", "with_inputs",
           "inputs_in"]


@dataclass(frozen=True, kw_only=True, slots=True)
class SpaceExInput:
    """A non-deterministic input of a SpaceEx model.

    Attributes
    ----------
    name : str
        The flattened SpaceEx variable (``model.u1``, ``aL``).
    low, high : float
        Its bounds (from the invariant of every location), ``low <= high``.
    symbol : str
        The name of its placeholder :class:`~hybrid.symbolic.Param` in the flows (``input_model_u1``).
    """

    name: str
    low: float
    high: float
    symbol: str

    @property
    def middle(self) -> float:
        """``(low + high) / 2``."""
        return 0.5 * (self.low + self.high)


def input_symbol(name: str) -> str:
    """The placeholder's name: ``input_`` and the variable's name with non-identifier characters as ``_``."""
    return "input_" + re.sub(r"\W", "_", name)


def _constant(tree: Any) -> float | None:
    """The value of a tree without names (numbers, unary minus, + - * /), else ``None``."""
    kind = tree[0]
    if kind == "num":
        return float(tree[1])
    if kind == "neg":
        v = _constant(tree[1])
        return None if v is None else -v
    if kind in ("+", "-", "*", "/"):
        a, b = _constant(tree[1]), _constant(tree[2])
        if a is None or b is None or (kind == "/" and b == 0.0):
            return None
        return {"+": a + b, "-": a - b, "*": a * b, "/": a / b if b else math.nan}[kind]
    return None


_FLIP = {"<=": ">=", "<": ">", ">=": "<=", ">": "<", "==": "=="}


def is_input_bound(c: Any, names: Sequence[str] | set[str]) -> tuple[str, str, float] | None:
    """``(variable, op, value)`` when the constraint tree ``c`` bounds one of ``names`` by a constant, else ``None``."""
    if c[0] != "cmp" or c[1] not in _FLIP:
        return None
    left, right = c[2], c[3]
    if left[0] == "name" and left[1] in names:
        value = _constant(right)
        return None if value is None else (left[1], c[1], value)
    if right[0] == "name" and right[1] in names:
        value = _constant(left)
        return None if value is None else (right[1], _FLIP[c[1]], value)
    return None


def _names_in(tree: Any) -> set[str]:
    if not isinstance(tree, tuple) or not tree:
        return set()
    if tree[0] in ("name", "deriv") and isinstance(tree[1], str):
        return {tree[1]}
    out: set[str] = set()
    for t in tree[1:]:
        out |= _names_in(t)
    return out


def _bounds_in(flat: FlatAutomaton, var: str) -> tuple[float, float]:
    """The bounds of ``var`` (the same constants in the invariant of every location)."""
    found: set[tuple[float, float]] = set()
    for loc in flat.locations:
        lo, hi = -math.inf, math.inf
        for c in loc.invariant:
            b = is_input_bound(c, {var})
            if b is None:
                if var in _names_in(c):
                    raise SpaceExError(f"{loc.where}: invariant", c, f"bounds of the input {var!r} by constants "
                                       f"(lo <= {var} <= hi)", f"an input constrained with other variables is "
                                       "not supported: bound it by constants")
                continue
            _, op, value = b
            if op in (">=", ">", "=="):
                lo = max(lo, value)
            if op in ("<=", "<", "=="):
                hi = min(hi, value)
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
            raise SpaceExError(f"{loc.where}: variable {var!r}", f"{var} in [{lo}, {hi}] in location {loc.name!r}",
                               "an input bounded by constants in every location's invariant (a non-empty range)",
                               f"{var} has no flow, so it is an input of the SpaceEx model (any value at every "
                               f"instant): bound it in the invariant ({lo if math.isfinite(lo) else -1} <= {var} <= "
                               f"{hi if math.isfinite(hi) else 1}), give it a flow ({var}' == 0 for a constant input "
                               "chosen initially) or close the loop")
        found.add((lo, hi))
    if len(found) != 1:
        raise SpaceExError(f"{flat.locations[0].where}: variable {var!r}", sorted(found),
                           "the same bounds of the input in every location", "write one range for the input")
    return found.pop()


def find_inputs(flat: FlatAutomaton, candidates: Sequence[str]) -> tuple[SpaceExInput, ...]:
    """The inputs among ``candidates`` (variables without flow that are not outputs), each checked.

    Raises
    ------
    SpaceExError
        An input not bounded by constants in every location, with different bounds in different locations,
        or read by a guard or an assignment.
    """
    inputs = []
    for var in candidates:
        low, high = _bounds_in(flat, var)
        for t in flat.transitions:
            if var in set().union(*(_names_in(c) for c in (*t.guard, *t.assignment))):
                raise SpaceExError(f"{t.where}: transition {t.label or 'tau'!r}", var,
                                   "guards and assignments of states (an input acts on the flows only)",
                                   f"{var} is an input (no flow): give it a flow ({var}' == 0) to read it in a jump")
        inputs.append(SpaceExInput(name=var, low=low, high=high, symbol=input_symbol(var)))
    symbols = [i.symbol for i in inputs]
    if len(set(symbols)) != len(symbols):
        raise SpaceExError(f"{flat.name}: inputs", [i.name for i in inputs], "input names distinct after "
                           "replacing non-identifier characters by _", "rename the inputs")
    return tuple(inputs)


def input_signal(values: Sequence[float | Expr], horizon: float) -> Expr:
    """The piecewise-constant signal of time taking ``values[k]`` on ``[k T/N, (k+1) T/N)`` (``T = horizon``).

    ``N = len(values)``; after ``T`` the last value is held.  The index is ``min(t N / T, N - 1/2)``,
    truncated by :func:`~hybrid.symbolic.select`.
    """
    n = len(values)
    if n < 1 or not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and horizon > 0):
        raise SpaceExError("input_signal", (n, horizon), "at least one value and a finite horizon > 0 [s]",
                           "give the signal's values and the horizon")
    options = tuple(v if isinstance(v, Expr) else Const(float(v)) for v in values)
    return Select(minimum(time * (n / float(horizon)), n - 0.5), options)


def with_inputs(system: HybridSystem, input_flows: Mapping[str, SymbolicVector], inputs: Sequence[SpaceExInput],
                signals: Mapping[str, Expr | float]) -> HybridSystem:
    """``system`` with its flows ``input_flows`` (placeholders) and each input replaced by ``signals[name]``.

    Parameters
    ----------
    signals : mapping {input name: expression or number}
        A number is a constant input (``Const``: the affine flow without the input when 0, for reachability).
    """
    missing = sorted({i.name for i in inputs} - set(signals))
    if missing:
        raise SpaceExError("with_inputs: signals", sorted(signals), f"a signal for every input ({missing} missing)",
                           "give each input an expression of time or a number")
    by_symbol = {i.symbol: (signals[i.name] if isinstance(signals[i.name], Expr) else Const(float(signals[i.name])))
                 for i in inputs}
    flows = {mode: SymbolicVector(tuple(substitute(c, params=by_symbol) for c in f.components), "flow")
             for mode, f in input_flows.items()}
    return replace(system, flows=flows)


def inputs_in(node: Any, inputs: Sequence[SpaceExInput]) -> list[str]:
    """The inputs whose placeholders ``node`` reads (by :class:`Param` name)."""
    from .symbolic_core import walk_nodes

    symbols = {i.symbol: i.name for i in inputs}
    return sorted({symbols[n.name] for n in walk_nodes(node) if isinstance(n, Param) and n.name in symbols})
