"""The gradient of a formula's robustness with respect to a model's parameters, from the sensitivities of its trace.

A simulator that differentiates its run gives, for each numeric signal ``s``, the sensitivities
``S_s[i, j] = d s(t_i) / d p_j`` at the trace's samples (shape ``(n, k)``).  The robustness
(:mod:`analysis.stl.semantics`) is a composition of ``min`` and ``max`` over samples and subformulas of the
atoms' values: where the arg-min/arg-max is unique it equals ``sign * mu(i*)``, one atom ``mu`` read at one
sample ``i*`` (:meth:`analysis.stl.Formula.explain` follows the arg-min/arg-max from the root to it, and the
negations on the way give ``sign``), so its gradient is ``sign * grad mu(i*)`` by the chain rule through the
atom's arithmetic.  At a tie the first candidate is taken (as ``explain`` does): a subgradient, one of the
one-sided gradients.  An atom that reads no numeric signal (a label, ``true``) and an empty window (robustness
``+-inf``) have a zero gradient; ``time`` and ``jumps`` do not depend on the parameters.

Examples
--------
>>> import numpy as np
>>> from analysis.stl import SignalTrace, parse_formula
>>> t = np.array([0.0, 0.5, 1.0])
>>> a, b = 1.0, 2.0                                    # x(t) = a + b t, parameters (a, b)
>>> trace = SignalTrace(times=t, signals={"x": a + b * t})
>>> rho, grad = robustness_gradient(parse_formula("always[0, 1] (x < 5)"), trace,
...                                 {"x": np.stack([np.ones(3), t], axis=1)})
>>> rho, grad.tolist()                                 # 5 - (a + b), at t = 1
(2.0, [-1.0, -1.0])
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from analysis.stl.semantics import Formula
from analysis.stl.syntax import BinOp, Compare, Func, Neg, Num, Var
from analysis.stl.trace import SignalTrace, TraceError

__all__ = ["robustness_gradient", "expression_gradient", "CONSTANT_SIGNALS"]

CONSTANT_SIGNALS = ("time", "jumps")
"""Signals of a trace that never depend on the parameters (zero sensitivity when not given)."""


def _sensitivity(name: str, i: int, trace: SignalTrace, sensitivities: Mapping[str, np.ndarray], k: int) -> np.ndarray:
    found = sensitivities.get(name)
    if found is None:
        if name in CONSTANT_SIGNALS:
            return np.zeros(k)
        raise TraceError("sensitivities", sorted(sensitivities), f"the sensitivities of signal {name!r}, which the "
                         "formula reads", f"give d {name}/d parameters (shape ({trace.n}, {k})) or use finite "
                         "differences")
    row = np.asarray(found, dtype=float)
    if row.shape != (trace.n, k):
        raise TraceError(f"sensitivities[{name!r}]", row.shape, f"shape ({trace.n}, {k}): one row per sample, one "
                         "column per parameter", "return d signal(t_i) / d p_j for every sample i and parameter j")
    return row[i]


def expression_gradient(expr: object, i: int, trace: SignalTrace, sensitivities: Mapping[str, np.ndarray],
                        k: int) -> tuple[float, np.ndarray]:
    """Value and gradient (shape ``(k,)``) of an arithmetic expression of the formula's syntax at sample ``i``.

    ``abs``, ``min`` and ``max`` take the branch of the value (``abs`` at 0 and a tie of ``min``/``max``: the
    left one, a one-sided derivative); ``prev(e)`` reads ``e`` at ``i - 1`` (at ``i = 0``: at 0)."""
    match expr:
        case Num(value):
            return float(value), np.zeros(k)
        case Var(name):
            return float(trace.signal(name)[i]), _sensitivity(name, i, trace, sensitivities, k)
        case Neg(arg):
            v, g = expression_gradient(arg, i, trace, sensitivities, k)
            return -v, -g
        case BinOp(op, left, right):
            a, ga = expression_gradient(left, i, trace, sensitivities, k)
            b, gb = expression_gradient(right, i, trace, sensitivities, k)
            if op == "+":
                return a + b, ga + gb
            if op == "-":
                return a - b, ga - gb
            if op == "*":
                return a * b, b * ga + a * gb
            return a / b, (ga - (a / b) * gb) / b
        case Func("abs", (arg,)):
            v, g = expression_gradient(arg, i, trace, sensitivities, k)
            return abs(v), (g if v >= 0 else -g)
        case Func("prev", (arg,)):
            return expression_gradient(arg, max(i - 1, 0), trace, sensitivities, k)
        case Func(name, (left, right)):
            a, ga = expression_gradient(left, i, trace, sensitivities, k)
            b, gb = expression_gradient(right, i, trace, sensitivities, k)
            first = a <= b if name == "min" else a >= b
            return (a, ga) if first else (b, gb)
    raise TypeError(f"not an expression node: {expr!r}")


def robustness_gradient(formula: Formula, trace: SignalTrace, sensitivities: Mapping[str, np.ndarray],
                        k: int | None = None) -> tuple[float, np.ndarray]:
    """The robustness at the first sample and its gradient with respect to the ``k`` parameters.

    Parameters
    ----------
    formula : Formula
    trace : SignalTrace
        The run, ``n`` samples.
    sensitivities : mapping of str to numpy.ndarray
        Signal name -> ``d signal(t_i) / d p_j``, shape ``(n, k)``, for every numeric signal the deciding atom
        reads (``time`` and ``jumps`` may be left out).
    k : int or None
        The number of parameters (default: the columns of the first sensitivity).

    Returns
    -------
    rho : float
        :meth:`Formula.robustness` (may be ``+-inf``).
    grad : numpy.ndarray, shape (k,)
        ``d rho / d p`` (the subgradient of the first arg-min/arg-max on ties; zeros where ``rho`` is infinite or
        decided by a label atom).

    Raises
    ------
    TraceError
        A sensitivity missing for a signal the deciding atom reads, or of the wrong shape.
    """
    if k is None:
        shapes = [np.shape(v) for v in sensitivities.values()]
        k = int(shapes[0][1]) if shapes and len(shapes[0]) == 2 else 0
    why = formula.explain(trace)
    rho = why.sign * why.value
    if not math.isfinite(rho) or not isinstance(why.node, Compare):
        return rho, np.zeros(k)
    op, left, right = why.node.op, why.node.left, why.node.right
    a, ga = expression_gradient(left, why.index, trace, sensitivities, k)
    b, gb = expression_gradient(right, why.index, trace, sensitivities, k)
    if op in (">", ">="):
        g = ga - gb
    elif op in ("<", "<="):
        g = gb - ga
    else:
        g = (ga - gb) if a - b >= 0 else (gb - ga)  # d|a - b|
        g = -g if op == "==" else g
    return rho, why.sign * g
