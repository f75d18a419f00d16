"""Signal Temporal Logic: robustness, boolean semantics and explanations over a :class:`SignalTrace`.

Discrete-time semantics over the samples, with windows measured in *time*.
At sample ``i`` (``t_i``; index order breaks ties between the two sides of a jump):

* ``always[a,b] phi``       min of ``rho_phi(k)`` over ``k >= i`` with ``t_k - t_i`` in ``[a, b]``;
* ``eventually[a,b] phi``   the max over the same window;
* ``historically[a,b] phi`` min over ``k <= i`` with ``t_i - t_k`` in ``[a, b]`` (no interval: the whole past);
* ``once[a,b] phi``         the max over the same window;
* ``phi until[a,b] psi``    max over the future window of ``min(rho_psi(k), min of rho_phi on [i, k))``;
* ``phi since[a,b] psi``    max over the past window of ``min(rho_psi(k), min of rho_phi on (k, i])``;
* ``rise(phi)``             ``min(rho(i), -rho(i-1))``, ``fall(phi)`` ``min(-rho(i), rho(i-1))``; at ``i = 0``
  ``rise = rho(0)`` and ``fall = -rho(0)`` (as if ``phi`` were false, resp. true, before the trace);
* ``prev(e)``               ``e`` at sample ``i - 1``; ``e`` at sample 0 itself at ``i = 0``.

A window is truncated to the samples present; an empty window gives ``+inf``
for always/historically and ``-inf`` for eventually/once/until/since.  Window
bounds are compared with the slack of :func:`time_slack`, relative to the
window and the sample period (never to the absolute times: a trace stamped
around 1.7e9 s gets the same windows as one starting at 0), so that sampled
times with rounding drift (``k * 0.05`` accumulated) land in the windows their
bounds mean.  This matches rtamt's
discrete-time offline monitor sample for sample on uniformly sampled traces
(``tests/analysis/stl/test_rtamt_oracle.py``); ``docs/stl.md`` has the full
statement.

Windowed min/max over non-uniform windows: the bounds come from
:func:`numpy.searchsorted`, the reduction decomposes every window into
``O(log w)`` power-of-two blocks, one level at a time (``O(n log w)`` time,
``O(n)`` memory); ``until``/``since`` use the same decomposition with the
monoid ``(min phi over the block, until-value of the block)``.

The boolean semantics (:meth:`Formula.satisfied`) is a separate evaluation on
booleans (strict comparisons, all/any over windows), not a threshold of the
robustness.

Examples
--------
>>> trace = SignalTrace(times=[0.0, 0.5, 1.0, 1.5], signals={"x": [3.0, 1.0, 2.0, -1.0]})
>>> f = parse_formula("always[0, 1] x > 0")
>>> f.robustness_signal(trace).tolist()
[1.0, -1.0, -1.0, -1.0]
>>> f.satisfied(trace), f.explain(trace).index, f.explain(trace).atom
(True, 1, '(x > 0)')
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from analysis.stl.syntax import (
    And,
    BinOp,
    Compare,
    Const,
    Edge,
    Func,
    Implies,
    LabelIs,
    Neg,
    Node,
    Not,
    Num,
    Or,
    Temporal,
    Until,
    Var,
    canonical,
    future_horizon,
    label_pattern,
    labels_of,
    parse_tree,
    past_horizon,
    signals_of,
)
from analysis.stl.trace import SignalTrace, TraceError

__all__ = [
    "TIME_RESOLUTION",
    "STAMP_ULPS",
    "FormulaValueError",
    "Explanation",
    "Formula",
    "parse_formula",
    "time_slack",
    "window_bounds",
    "window_reduce",
    "until_values",
]

TIME_RESOLUTION = 1e-9
"""Relative slack of window bounds, per second of the window's extent (``max(1 s, a, b)``; :func:`time_slack`)."""
STAMP_ULPS = 4
"""Rounding units of the largest time stamp allowed per sample step a window spans (:func:`time_slack`)."""

class FormulaValueError(TraceError):
    """A formula's arithmetic is not finite at a sample (a division by zero, an overflow): the formula's fault.

    A :class:`TraceError` (the trace's values are finite: :class:`SignalTrace` refuses others), so code
    catching trace errors still catches it; catch this one first to blame the formula, not the simulator.

    Attributes
    ----------
    formula : str
        The formula's text (as written).
    expression : str
        Canonical text of the expression that is not finite.
    index : int
        First sample where it is not finite.
    time : float
        That sample's time [s].
    value : float
        The value there (``inf``, ``-inf`` or ``nan``).
    count : int
        Samples where it is not finite.
    """

    def __init__(self, formula: str, expression: str, index: int, time: float, value: float, count: int,
                 samples: int) -> None:
        self.formula, self.expression, self.index, self.time = formula, expression, index, time
        self.count, self.samples = count, samples
        super().__init__(
            f"formula {' '.join(formula.split())!r}: expression {expression} at sample {index} "
            f"(t = {time:.9g} s)", value, "a finite number",
            "avoid divisions by zero and overflows in the formula, e.g. guard a denominator with max(abs(d), 1e-9) "
            f"({count} of {samples} samples are not finite)")

    def __reduce__(self):
        return (type(self), (self.formula, self.expression, self.index, self.time, self.value, self.count,
                             self.samples))


_FORMULA_NODES = (Const, Compare, LabelIs, Not, And, Or, Implies, Temporal, Until, Edge)
_MIN_OPS = ("always", "historically")
_PAST_OPS = ("historically", "once", "since")


# --------------------------------------------------------------------------- windows


def time_slack(times: np.ndarray, interval: tuple[float, float] | None) -> float:
    """Slack [s] with which the bounds of the window ``interval`` are compared on ``times``.

    ``min(TIME_RESOLUTION * max(1, a, b) + STAMP_ULPS * ulp(T) * (1 + m), h / 4)``: the rounding of the
    window's decimal bounds (``0.1 + 0.2`` vs ``0.3``), plus the rounding of the time stamps themselves
    (``T = max(|t_0|, |t_n-1|)``, accumulated over the ``m = min(n, b / h)`` sample steps the window spans),
    but never more than a quarter of the smallest positive sample step ``h``, so a bound never reaches a
    neighbouring sample.  It depends on the window and the sampling, not on where the times start.

    Parameters
    ----------
    times : ndarray, shape (n,)
        Non-decreasing sample times [s].
    interval : (a, b) or None
        The window [s]; ``None`` is ``[0, inf)``.

    Returns
    -------
    float
        The slack [s], >= 0.
    """
    a, b = (0.0, math.inf) if interval is None else interval
    extent = b if math.isfinite(b) else a
    steps = np.diff(times)
    steps = steps[steps > 0]
    h = float(steps.min()) if steps.size else math.inf
    spanned = min(float(times.size), extent / h)
    magnitude = max(abs(float(times[0])), abs(float(times[-1])))
    slack = TIME_RESOLUTION * max(1.0, a, extent) + STAMP_ULPS * math.ulp(magnitude) * (1.0 + spanned)
    return min(slack, h / 4)


def window_bounds(times: np.ndarray, interval: tuple[float, float] | None, *, past: bool) -> tuple[np.ndarray,
                                                                                                    np.ndarray]:
    """First and last sample index of the window of every sample.

    Parameters
    ----------
    times : ndarray, shape (n,)
        Non-decreasing sample times [s].
    interval : (a, b) or None
        Window [s]; ``None`` is ``[0, inf)`` (the whole past). Bounds compared with :func:`time_slack`.
    past : bool
        ``False``: samples ``k >= i`` with ``t_k - t_i`` in ``[a, b]``; ``True``: ``k <= i`` with
        ``t_i - t_k`` in ``[a, b]``.

    Returns
    -------
    lo, hi : ndarray of int, shape (n,)
        The window of sample ``i`` is ``lo[i] .. hi[i]`` (inclusive), empty when ``lo[i] > hi[i]``.
    """
    a, b = (0.0, math.inf) if interval is None else interval
    eps = time_slack(times, interval)
    index = np.arange(times.size)
    if past:
        lo = np.searchsorted(times, times - b - eps, side="left")
        hi = np.minimum(index, np.searchsorted(times, times - a + eps, side="right") - 1)
    else:
        lo = np.maximum(index, np.searchsorted(times, times + a - eps, side="left"))
        hi = np.searchsorted(times, times + b + eps, side="right") - 1
    return lo, hi


def window_reduce(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, op: Callable, identity: object) -> np.ndarray:
    """``op``-reduction (``np.minimum`` or ``np.maximum``) of ``values[lo[i] : hi[i] + 1]`` for every ``i``.

    Each window is split into power-of-two blocks, smallest first; level ``b``
    holds the reduction of every block of length ``2**b``.  ``O(n log w)``
    time for windows of at most ``w`` samples, ``O(n)`` memory.  An empty
    window gives ``identity``.  Works on floats and on booleans.
    """
    length = np.maximum(hi - lo + 1, 0)
    out = np.full(values.shape, identity, dtype=values.dtype)
    pos = lo.copy()
    level, width = values, 1
    longest = int(length.max(initial=0))
    while width <= longest:
        if width > 1:
            half = width // 2
            level = op(level[:-half], level[half:])
        take = np.flatnonzero(length & width)
        if take.size:
            out[take] = op(out[take], level[pos[take]])
            pos[take] += width
        width *= 2
    return out


def until_values(phi: np.ndarray, psi: np.ndarray, lo: np.ndarray, hi: np.ndarray, top: object,
                 bottom: object) -> np.ndarray:
    """``max over k in [lo[i], hi[i]] of min(psi[k], min of phi over [i, k))`` for every ``i`` (``lo >= i``).

    ``top``/``bottom`` are the identities of min and max (``+inf``/``-inf``, or ``True``/``False``).  The
    block of ``[p, p + 2**b)`` carries ``m`` (min of ``phi``) and ``u`` (the value above restricted to the
    block, counted from ``p``); blocks combine as ``m = min(m1, m2)``, ``u = max(u1, min(m1, u2))``.
    """
    index = np.arange(phi.size)
    before = window_reduce(phi, index, lo - 1, np.minimum, top)  # phi on [i, lo): must hold before the window
    length = np.maximum(hi - lo + 1, 0)
    held = np.full(phi.shape, top, dtype=phi.dtype)
    reached = np.full(phi.shape, bottom, dtype=phi.dtype)
    pos = lo.copy()
    m_level, u_level, width = phi, psi, 1
    longest = int(length.max(initial=0))
    while width <= longest:
        if width > 1:
            half = width // 2
            u_level = np.maximum(u_level[:-half], np.minimum(m_level[:-half], u_level[half:]))
            m_level = np.minimum(m_level[:-half], m_level[half:])
        take = np.flatnonzero(length & width)
        if take.size:
            p = pos[take]
            reached[take] = np.maximum(reached[take], np.minimum(held[take], u_level[p]))
            held[take] = np.minimum(held[take], m_level[p])
            pos[take] += width
        width *= 2
    out = np.minimum(before, reached)
    out[length == 0] = bottom
    return out


def _since_values(phi: np.ndarray, psi: np.ndarray, lo: np.ndarray, hi: np.ndarray, top: object,
                  bottom: object) -> np.ndarray:
    """Past mirror of :func:`until_values`: ``phi`` on ``(k, i]``; computed on the reversed samples."""
    last = phi.size - 1
    out = until_values(phi[::-1], psi[::-1], last - hi[::-1], last - lo[::-1], top, bottom)
    return out[::-1].copy()


# --------------------------------------------------------------------------- evaluators


class _Evaluator:
    """Values of every subformula at every sample, memoised per node; subclasses give the atoms' meaning."""

    top: object
    bottom: object

    def __init__(self, trace: SignalTrace, text: str = "") -> None:
        self.trace = trace
        self.text = text
        self.values: dict[int, np.ndarray] = {}
        self.nodes: list[object] = []  # keeps the ids of self.values alive
        self.windows: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    def window(self, interval: tuple[float, float] | None, past: bool) -> tuple[np.ndarray, np.ndarray]:
        key = (interval, past)
        if key not in self.windows:
            self.windows[key] = window_bounds(self.trace.times, interval, past=past)
        return self.windows[key]

    def value(self, node: object) -> np.ndarray:
        """Values of ``node`` at every sample, shape (n,)."""
        found = self.values.get(id(node))
        if found is None:
            found = self.compute(node)
            self.values[id(node)] = found
            self.nodes.append(node)
        return found

    def compute(self, node: object) -> np.ndarray:
        n = self.trace.n
        match node:
            case Const(value):
                return np.full(n, self.top if value else self.bottom)
            case Compare(op, left, right):
                return self.compare(op, self.expression(left), self.expression(right), node)
            case LabelIs(label, op, pattern):
                return self.label(self.matches(label, pattern) if op == "==" else ~self.matches(label, pattern))
            case Not(arg):
                return self.negate(self.value(arg))
            case And(left, right):
                return np.minimum(self.value(left), self.value(right))
            case Or(left, right):
                return np.maximum(self.value(left), self.value(right))
            case Implies(left, right):
                return np.maximum(self.negate(self.value(left)), self.value(right))
            case Temporal(op, interval, arg):
                lo, hi = self.window(interval, op in _PAST_OPS)
                if op in _MIN_OPS:
                    return window_reduce(self.value(arg), lo, hi, np.minimum, self.top)
                return window_reduce(self.value(arg), lo, hi, np.maximum, self.bottom)
            case Until(op, interval, left, right):
                lo, hi = self.window(interval, op in _PAST_OPS)
                run = _since_values if op == "since" else until_values
                return run(self.value(left), self.value(right), lo, hi, self.top, self.bottom)
            case Edge(op, arg):
                x = self.value(arg)
                before = np.concatenate(([self.bottom if op == "rise" else self.top], x[:-1])).astype(x.dtype)
                if op == "rise":
                    return np.minimum(x, self.negate(before))
                return np.minimum(self.negate(x), before)
        raise TypeError(f"not a formula node: {node!r}")

    def expression(self, expr: object) -> np.ndarray:
        """Float values of an arithmetic expression, shape (n,); a non-finite value is a :class:`FormulaValueError`."""
        with np.errstate(all="ignore"):
            x = self._arithmetic(expr)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            k = int(bad[0])
            raise FormulaValueError(self.text or canonical(expr), canonical(expr), k, float(self.trace.times[k]),
                                    float(x[k]), int(bad.size), int(x.size))
        return x

    def _arithmetic(self, expr: object) -> np.ndarray:
        match expr:
            case Num(value):
                return np.full(self.trace.n, value)
            case Var(name):
                return self.trace.signal(name)
            case Neg(arg):
                return -self._arithmetic(arg)
            case BinOp(op, left, right):
                a, b = self._arithmetic(left), self._arithmetic(right)
                return {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide}[op](a, b)
            case Func("abs", (arg,)):
                return np.abs(self._arithmetic(arg))
            case Func("prev", (arg,)):
                x = self._arithmetic(arg)
                return np.concatenate((x[:1], x[:-1]))
            case Func(name, (left, right)):
                return (np.minimum if name == "min" else np.maximum)(self._arithmetic(left), self._arithmetic(right))
        raise TypeError(f"not an expression node: {expr!r}")

    def matches(self, label: str, pattern: str) -> np.ndarray:
        """Boolean mask, shape (n,): the label's value at each sample matches the wildcard pattern."""
        values = self.trace.label(label)
        distinct, inverse = np.unique(np.array(values, dtype=object).astype(str), return_inverse=True)
        regex = label_pattern(pattern)
        hit = np.array([regex.fullmatch(str(v)) for v in distinct], dtype=bool)
        return hit[inverse.reshape(-1)]

    def compare(self, op: str, left: np.ndarray, right: np.ndarray, node: object) -> np.ndarray:
        raise NotImplementedError

    def label(self, mask: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def negate(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class _Robustness(_Evaluator):
    """Space robustness: distances to the comparisons' thresholds, +-inf for label atoms and constants."""

    top, bottom = math.inf, -math.inf

    def compare(self, op: str, left: np.ndarray, right: np.ndarray, node: object) -> np.ndarray:
        if op in (">", ">="):
            return left - right
        if op in ("<", "<="):
            return right - left
        gap = np.abs(left - right)
        return -gap if op == "==" else gap

    def label(self, mask: np.ndarray) -> np.ndarray:
        return np.where(mask, math.inf, -math.inf)

    def negate(self, x: np.ndarray) -> np.ndarray:
        return -x


_STRICT = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal, "==": np.equal,
           "!=": np.not_equal}


class _Boolean(_Evaluator):
    """Boolean semantics: the comparisons as written (``>`` is false at equality), all/any over windows."""

    top, bottom = True, False

    def compare(self, op: str, left: np.ndarray, right: np.ndarray, node: object) -> np.ndarray:
        return _STRICT[op](left, right)

    def label(self, mask: np.ndarray) -> np.ndarray:
        return mask

    def negate(self, x: np.ndarray) -> np.ndarray:
        return ~x


# --------------------------------------------------------------------------- traces cut short


class _Prefix:
    """Bounds ``(lo, hi)`` of every subformula at every sample when the trace was cut short at its last sample.

    The run ended early (Zeno, a deadlock, a user-code error, ...): what would have come after the
    last sample is unknown.  A future window that reaches past the last sample takes any value on
    its unknown part, so ``always`` can only go down (``lo`` is ``bottom``) and ``eventually`` only
    up (``hi`` is ``top``); ``until`` can still be reached after the end while its left side held up
    to it.  Past operators, ``prev``, ``rise`` and ``fall`` read known samples only.  The bounds hold
    for *every* continuation of the trace: a formula is decided on the prefix when ``lo`` and ``hi``
    agree on its truth.  ``exact`` gives the atoms' meaning (robustness or booleans).
    """

    def __init__(self, exact: _Evaluator) -> None:
        self.exact = exact
        self.trace = exact.trace
        self.values: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.nodes: list[object] = []

    def value(self, node: object) -> tuple[np.ndarray, np.ndarray]:
        found = self.values.get(id(node))
        if found is None:
            found = self.compute(node)
            self.values[id(node)] = found
            self.nodes.append(node)
        return found

    def open(self, interval: tuple[float, float] | None) -> np.ndarray:
        """Samples whose future window reaches past the last sample, shape (n,) bool."""
        times = self.trace.times
        b = math.inf if interval is None else interval[1]
        end = float(times[-1])
        eps = TIME_RESOLUTION * max(1.0, abs(float(times[0])), abs(end))
        return times + b > end + eps

    def compute(self, node: object) -> tuple[np.ndarray, np.ndarray]:
        ex = self.exact
        match node:
            case Const() | Compare() | LabelIs():
                v = ex.value(node)
                return v, v
            case Not(arg):
                lo, hi = self.value(arg)
                return ex.negate(hi), ex.negate(lo)
            case And(left, right):
                (a, b), (c, d) = self.value(left), self.value(right)
                return np.minimum(a, c), np.minimum(b, d)
            case Or(left, right):
                (a, b), (c, d) = self.value(left), self.value(right)
                return np.maximum(a, c), np.maximum(b, d)
            case Implies(left, right):
                (a, b), (c, d) = self.value(left), self.value(right)
                return np.maximum(ex.negate(b), c), np.maximum(ex.negate(a), d)
            case Temporal(op, interval, arg):
                return self.temporal(op, interval, *self.value(arg))
            case Until(op, interval, left, right):
                return self.until(op, interval, self.value(left), self.value(right))
            case Edge(op, arg):
                lo, hi = self.value(arg)
                first = ex.bottom if op == "rise" else ex.top
                b_lo = np.concatenate(([first], lo[:-1])).astype(lo.dtype)
                b_hi = np.concatenate(([first], hi[:-1])).astype(hi.dtype)
                if op == "rise":
                    return np.minimum(lo, ex.negate(b_hi)), np.minimum(hi, ex.negate(b_lo))
                return np.minimum(ex.negate(hi), b_lo), np.minimum(ex.negate(lo), b_hi)
        raise TypeError(f"not a formula node: {node!r}")

    def temporal(self, op: str, interval: tuple[float, float] | None, lo: np.ndarray,
                 hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex = self.exact
        past = op in _PAST_OPS
        w_lo, w_hi = ex.window(interval, past)
        if op in _MIN_OPS:
            out_lo = window_reduce(lo, w_lo, w_hi, np.minimum, ex.top)
            out_hi = window_reduce(hi, w_lo, w_hi, np.minimum, ex.top)
            if not past:
                out_lo = np.where(self.open(interval), ex.bottom, out_lo).astype(lo.dtype)
            return out_lo, out_hi
        out_lo = window_reduce(lo, w_lo, w_hi, np.maximum, ex.bottom)
        out_hi = window_reduce(hi, w_lo, w_hi, np.maximum, ex.bottom)
        if not past:
            out_hi = np.where(self.open(interval), ex.top, out_hi).astype(hi.dtype)
        return out_lo, out_hi

    def until(self, op: str, interval: tuple[float, float] | None, left: tuple[np.ndarray, np.ndarray],
              right: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        ex = self.exact
        w_lo, w_hi = ex.window(interval, op in _PAST_OPS)
        run = _since_values if op == "since" else until_values
        lo = run(left[0], right[0], w_lo, w_hi, ex.top, ex.bottom)
        hi = run(left[1], right[1], w_lo, w_hi, ex.top, ex.bottom)
        if op != "since":
            index = np.arange(self.trace.n)
            held = window_reduce(left[1], index, np.full(self.trace.n, self.trace.n - 1), np.minimum, ex.top)
            hi = np.where(self.open(interval), np.maximum(hi, held), hi).astype(hi.dtype)
        return lo, hi


def _first_false(ev: _Boolean, node: object, i: int) -> int:
    """The earliest sample at which ``node``, false at ``i``, is seen false (see :meth:`Formula.first_violation`)."""
    match node:
        case Temporal("always", interval, arg):
            lo, hi = ev.window(interval, False)
            values = ev.value(arg)[lo[i]:hi[i] + 1]
            k = int(lo[i] + np.flatnonzero(~values)[0])
            return _first_false(ev, arg, k)
        case And(left, right):
            sides = [_first_false(ev, side, i) for side in (left, right) if not bool(ev.value(side)[i])]
            return min(sides)
        case Implies(_, right):
            return _first_false(ev, right, i)
    return i


# --------------------------------------------------------------------------- explanations


@dataclass(frozen=True)
class Explanation:
    """The atom whose value decides a formula's robustness at a sample.

    Attributes
    ----------
    index : int
        Sample where the deciding atom is read.
    time : float
        Its time [s].
    atom : str
        Canonical text of the deciding atom (a comparison, a label atom, ``true`` or ``false``), or of the
        temporal subformula whose window is empty (then ``value`` is ``+-inf``).
    value : float
        Robustness of ``atom`` at ``index``.
    signals : frozenset of str
        Numeric signals and labels ``atom`` reads.
    window : tuple of float or None
        ``(a, b)`` [s], the samples' times of the window of the first ``eventually`` (``once``; an ``always`` or
        ``historically`` under a negation) the explanation descends through: ``time`` is then that operator's
        *best* instant, where its operand came closest, not a violation instant; with a negative robustness the
        operand is reached nowhere in ``[a, b]``.  ``None``: no such operator on the way (``time`` is where the
        robustness is lowest).
    sign : int
        ``+1`` or ``-1``: the formula's robustness at the explained sample is ``sign * value`` (``not``, the
        antecedent of ``implies`` and ``rise``/``fall`` negate).
    node : Node or None
        The deciding atom's syntax node (not compared).
    """

    index: int
    time: float
    atom: str
    value: float
    signals: frozenset[str]
    window: tuple[float, float] | None = None
    sign: int = 1
    node: object = field(default=None, compare=False, repr=False)


def _step(ev: _Robustness, node: object, i: int) -> tuple[object, int] | None:
    """The child and the sample that decide ``node`` at ``i`` (first one on ties), ``None`` at a leaf."""
    v = ev.value
    match node:
        case Not(arg):
            return arg, i
        case And(left, right):
            return (left, i) if v(left)[i] <= v(right)[i] else (right, i)
        case Or(left, right):
            return (left, i) if v(left)[i] >= v(right)[i] else (right, i)
        case Implies(left, right):
            return (left, i) if -v(left)[i] >= v(right)[i] else (right, i)
        case Temporal(op, interval, arg):
            lo, hi = (int(w[i]) for w in ev.window(interval, op in _PAST_OPS))
            if lo > hi:
                return None
            segment = v(arg)[lo:hi + 1]
            return arg, lo + int(np.argmin(segment) if op in _MIN_OPS else np.argmax(segment))
        case Until(op, interval, left, right):
            lo, hi = (int(w[i]) for w in ev.window(interval, op in _PAST_OPS))
            return None if lo > hi else _until_step(v(left), v(right), op, i, lo, hi, left, right)
        case Edge(op, arg):
            x = v(arg)
            if i == 0:
                return arg, 0
            now = x[i] if op == "rise" else -x[i]
            before = -x[i - 1] if op == "rise" else x[i - 1]
            return (arg, i) if now <= before else (arg, i - 1)
    return None


def _step_sign(node: object, step: tuple[object, int], i: int) -> int:
    """-1 where :func:`_step` passes a negation (``not``, an antecedent, the negated side of ``rise``/``fall``)."""
    match node:
        case Not():
            return -1
        case Implies(left, _):
            return -1 if step[0] is left else 1
        case Edge(op, _):
            return -1 if (op == "rise") == (step[1] != i) else 1
    return 1


def _until_step(phi: np.ndarray, psi: np.ndarray, op: str, i: int, lo: int, hi: int, left: object,
                right: object) -> tuple[object, int]:
    ks = np.arange(lo, hi + 1)
    if op == "until":  # phi must hold on [i, k)
        run = np.concatenate(([math.inf], np.minimum.accumulate(phi[i:hi])))
        held = run[ks - i]
    else:  # since: phi must hold on (k, i]
        run = np.concatenate((np.minimum.accumulate(phi[lo + 1:i + 1][::-1])[::-1], [math.inf]))
        held = run[ks - lo]
    best = int(np.argmax(np.minimum(psi[ks], held)))
    k = int(ks[best])
    if psi[k] <= held[best]:
        return right, k
    if op == "until":
        return left, i + int(np.argmin(phi[i:k]))
    return left, k + 1 + int(np.argmin(phi[k + 1:i + 1]))


# --------------------------------------------------------------------------- formulas


@dataclass(frozen=True)
class Formula:
    """A parsed STL formula: immutable, hashable, picklable; equal when the syntax trees are equal.

    Build it with :func:`parse_formula`.

    Attributes
    ----------
    tree : Node
        The syntax tree (:mod:`analysis.stl.syntax`).
    text : str
        The source text (not compared); the canonical text when not given.
    """

    tree: Node
    text: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.tree, _FORMULA_NODES):
            raise TypeError(f"Formula(tree=...) takes a formula node of analysis.stl.syntax, not {self.tree!r}; "
                            f"build formulas with parse_formula(text)")
        if not self.text:
            object.__setattr__(self, "text", canonical(self.tree))

    @cached_property
    def canonical(self) -> str:
        """Fully parenthesised text; ``parse_formula(f.canonical) == f``."""
        return canonical(self.tree)

    @cached_property
    def signals(self) -> frozenset[str]:
        """Numeric signals read (``time``, ``jumps`` included when read)."""
        return signals_of(self.tree)

    @cached_property
    def labels(self) -> frozenset[str]:
        """Labels read."""
        return labels_of(self.tree)

    @cached_property
    def horizon(self) -> float:
        """How far ahead [s] the value at a sample looks (sum of nested future upper bounds; 0 for atoms)."""
        return future_horizon(self.tree)

    @cached_property
    def past_horizon(self) -> float:
        """How far back [s] past operators look (``inf`` for an untimed one); prev/rise/fall add one sample."""
        return past_horizon(self.tree)

    def check_trace(self, trace: SignalTrace) -> None:
        """Refuse a trace that lacks a signal or a label the formula reads.

        Raises
        ------
        TraceError
            Naming the missing names and the available ones.
        """
        if not isinstance(trace, SignalTrace):
            raise TraceError("trace", type(trace).__name__, "a SignalTrace", "build one with SignalTrace(times=...)")
        missing = sorted(self.signals - set(trace.names))
        if missing:
            raise TraceError("signals read by the formula", missing, f"signals of the trace: {', '.join(trace.names)}",
                             f"add them to the trace or fix the formula {self.text or self.canonical!r}")
        missing = sorted(self.labels - set(trace.label_names))
        if missing:
            raise TraceError("labels read by the formula", missing,
                             f"labels of the trace: {', '.join(trace.label_names) or '(none)'}",
                             f"add them to the trace (labels=...) or fix the formula {self.text or self.canonical!r}")

    def robustness_signal(self, trace: SignalTrace) -> np.ndarray:
        """Robustness at every sample, shape (n,), in the units of the atoms (``+-inf`` allowed)."""
        self.check_trace(trace)
        return _Robustness(trace, self.text).value(self.tree).astype(float, copy=True)

    def robustness(self, trace: SignalTrace) -> float:
        """Robustness at the first sample."""
        return float(self.robustness_signal(trace)[0])

    def satisfied_signal(self, trace: SignalTrace) -> np.ndarray:
        """Boolean semantics at every sample, shape (n,), bool."""
        self.check_trace(trace)
        return _Boolean(trace, self.text).value(self.tree).astype(bool, copy=True)

    def satisfied(self, trace: SignalTrace) -> bool:
        """Boolean semantics at the first sample (a separate evaluation, not ``robustness > 0``)."""
        return bool(self.satisfied_signal(trace)[0])

    def first_violation(self, trace: SignalTrace) -> float | None:
        """The first instant [s] at which the formula is seen violated on ``trace``; ``None`` when it holds.

        Descends the boolean semantics from the first sample: through ``always`` to the earliest sample of
        its window where the argument is false, through ``and`` to the earliest false side, through
        ``implies`` to its consequent and through ``not eventually`` like ``always not``; any other node is
        violated at the sample it is evaluated at.  (:meth:`explain` gives where the robustness is lowest,
        which can be later.)
        """
        self.check_trace(trace)
        ev = _Boolean(trace)
        if bool(ev.value(self.tree)[0]):
            return None
        return float(trace.times[_first_false(ev, self.tree, 0)])

    def prefix_satisfied(self, trace: SignalTrace) -> bool | None:
        """Boolean semantics at the first sample of a trace *cut short* at its last sample (a run that ended early).

        Returns ``True`` when every continuation of the trace satisfies the formula, ``False``
        when every continuation violates it, ``None`` when the prefix does not decide it (a window
        reaches past the end and the known samples do not settle it).  On a trace that covers the
        formula's whole horizon this is :meth:`satisfied`.
        """
        self.check_trace(trace)
        lo, hi = _Prefix(_Boolean(trace)).value(self.tree)
        if bool(lo[0]):
            return True
        if not bool(hi[0]):
            return False
        return None

    def prefix_robustness(self, trace: SignalTrace) -> tuple[float, float]:
        """Bounds ``(lo, hi)`` of the robustness at the first sample over every continuation of a cut-short trace."""
        self.check_trace(trace)
        lo, hi = _Prefix(_Robustness(trace)).value(self.tree)
        return float(lo[0]), float(hi[0])

    def explain(self, trace: SignalTrace, index: int = 0) -> Explanation:
        """Follow the arg-min/arg-max from the root at sample ``index`` down to the deciding atom."""
        self.check_trace(trace)
        if not 0 <= index < trace.n:
            raise TraceError("index", index, f"a sample index in [0, {trace.n - 1}]", "explain an existing sample")
        ev = _Robustness(trace, self.text)
        node, i, sign = self.tree, int(index), 1
        ev.value(node)
        negated, window = False, None
        while (step := _step(ev, node, i)) is not None:
            if window is None and isinstance(node, Temporal) and (node.op in _MIN_OPS) == negated:  # an argmax
                lo, hi = (int(w[i]) for w in ev.window(node.interval, node.op in _PAST_OPS))
                window = (float(trace.times[lo]), float(trace.times[hi]))
            if isinstance(node, Not) or (isinstance(node, Implies) and step[0] is node.left):
                negated = not negated
            sign *= _step_sign(node, step, i)
            node, i = step
        return Explanation(index=i, time=float(trace.times[i]), atom=canonical(node), value=float(ev.value(node)[i]),
                           signals=signals_of(node) | labels_of(node), window=window, sign=sign, node=node)


def parse_formula(text: str, *, signals: Collection[str] | None = None,
                  labels: Mapping[str, Collection[str]] | None = None, horizon: float | None = None) -> Formula:
    """Parse an STL formula.

    Parameters
    ----------
    text : str
        The formula (grammar in ``docs/stl.md``).
    signals : collection of str, optional
        Known numeric signals; an unknown one is refused (``time`` and ``jumps`` are always known).
    labels : mapping of str to collection of str, optional
        Known labels and their values; an unknown label, or a pattern matching no value, is refused.
    horizon : float, optional
        Largest future extent [s] accepted (see :attr:`Formula.horizon`).

    Returns
    -------
    Formula

    Raises
    ------
    FormulaError
        With line, column, caret and reason.
    """
    return Formula(parse_tree(text, signals=signals, labels=labels, horizon=horizon), text)
