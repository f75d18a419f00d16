"""Where a watched function switches on along a flow, and when: the event search of the continuous executor.

:func:`hybrid.continuous.simulate_continuous` watches, in each mode, the
guards of the outgoing transitions, the invariant and the user's stop
functions (one :class:`Watch` each, value ``phi``).  This module decides,
from their samples along a solver step, whether and where one *switches on*
(:func:`find_switch`, with the :class:`Refiner` for windows hidden between
samples), and locates the first such time (:func:`locate_event`, a bracketing
search by :func:`locate_crossing`).  What then happens at that instant is
:func:`hybrid.instant.settle_instant`'s business.

Switching on (the kinds of :class:`Watch`)
------------------------------------------
* ``"level"`` (a level-triggered guard ``phi = g``, a stop function): on where
  ``phi >= 0``; switches on when ``phi`` goes from strictly below zero to
  zero or above.
* ``"strict"`` (the invariant, ``phi = -inv``): on where ``phi > 0``.
* ``"crossing"`` (a crossing-triggered guard, ``phi = ±g`` so that its
  direction is upwards): switches on when ``phi`` goes from *strictly below*
  zero to zero or above — one event per real crossing.  A crossing guard that
  starts a flow on zero or above (in particular one left on its zero by its
  own jump, :func:`arm_watches`) is therefore *disarmed*: it fires again only
  after ``phi`` has been strictly below zero.  Between samples that are both
  strictly above zero the refiner searches a dip below zero and back (a
  crossing).
* ``"from_zero"``: a crossing guard that starts a flow exactly on zero
  *armed* — at the initial time of a run, or entered on zero by another
  transition's jump: it leaves zero in its direction, so it switches on as soon
  as ``phi > 0`` (the rule of :func:`hybrid.model.crossed`).

The located time is the right end of the final bracket, where the switched
watch is on; its left end, where none is, is the kernel's "previous"
evaluation for crossing guards.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, replace
from typing import Any

from .errors import ExecutionError, format_time
from .model import Transition

__all__ = [
    "REFINE_SUBDIVISIONS",
    "REFINE_BUDGET",
    "RATE_SAFETY",
    "COHERENCE",
    "SWITCH_SLACK",
    "UNRESOLVED_KEPT",
    "EXTREMUM_ITERATIONS",
    "CROSSING_KINDS",
    "Watch",
    "Bracket",
    "LocatedEvent",
    "UnresolvedWindow",
    "UnresolvedLog",
    "Refiner",
    "locate_crossing",
    "is_on",
    "switches_on",
    "switched_on",
    "arm_watches",
    "still_disarmed",
    "find_switch",
    "locate_event",
    "unresolved_message",
]

CROSSING_KINDS = ("crossing", "from_zero")
"""The kinds of a crossing-triggered guard's watch."""


# ---------------------------------------------------------------------- root finding
def locate_crossing(
    phi: Callable[[float], float],
    lo: float,
    hi: float,
    phi_lo: float,
    phi_hi: float,
    *,
    strict: bool = False,
    tol: float = 1e-12,
    max_iterations: int = 200,
    holds: Callable[[float], bool] | None = None,
) -> tuple[float, float, float, float, int]:
    """Shrink a bracket ``[lo, hi]`` around the first time the condition becomes true.

    The condition is ``phi >= 0`` (``phi > 0`` when ``strict``); it is false at
    ``lo`` and true at ``hi``; ``holds(t)``, when given, decides it instead
    (several watched functions searched at once: ``phi`` is then their
    maximum, used only for the secant steps).  Anderson–Björck regula falsi steps are tried first;
    bisection takes over when a step is not finite (``phi`` may be ``±inf``,
    e.g. a distance to an obstacle that is not in view) or the bracket shrinks
    too slowly (the bracket must halve every four evaluations); trial points
    keep ``tol / 2`` away from the ends, so a secant point on the root pins it.

    Returns
    -------
    lo, hi, phi_lo, phi_hi, iterations
        ``hi - lo <= tol`` (or ``lo`` and ``hi`` adjacent doubles), condition
        false at ``lo`` and true at ``hi``.
    """
    tol = max(tol, 4.0 * math.ulp(max(abs(lo), abs(hi))))
    iterations = 0
    side = 0
    f_lo, f_hi = phi_lo, phi_hi  # Anderson-Bjorck-weighted copies
    widths = [hi - lo]
    while hi - lo > tol and iterations < max_iterations:
        width = hi - lo
        t = math.nan
        slow = len(widths) >= 4 and width > 0.5 * widths[-4]
        if not slow and math.isfinite(f_lo) and math.isfinite(f_hi) and f_hi != f_lo:
            t = hi - f_hi * width / (f_hi - f_lo)
        if not math.isfinite(t):
            t = lo + 0.5 * width
        # never closer than tol/2 to an end: a secant point on the root then pins it
        t = min(max(t, lo + 0.5 * tol), hi - 0.5 * tol)
        value = phi(t)
        iterations += 1
        if value != value:
            raise ExecutionError(f"event function is NaN at t = {t:.17g} s during event location")
        if holds(t) if holds is not None else ((value > 0.0) if strict else (value >= 0.0)):
            if side == 1 and math.isfinite(f_hi) and f_hi != 0.0:
                m = 1.0 - value / f_hi
                f_lo *= m if m > 0.0 else 0.5
            hi, phi_hi, f_hi = t, value, value
            side = 1
        else:
            if side == -1 and math.isfinite(f_lo) and f_lo != 0.0:
                m = 1.0 - value / f_lo
                f_hi *= m if m > 0.0 else 0.5
            lo, phi_lo, f_lo = t, value, value
            side = -1
        widths.append(hi - lo)
    return lo, hi, phi_lo, phi_hi, iterations


@dataclass(frozen=True, slots=True)
class Watch:
    """One watched function of the current mode: a guard, the invariant, or a stop.

    Its value ``phi`` switches the watch on by ``phi >= 0`` (``kind="level"``:
    level guards and stops), ``phi > 0`` (``kind="strict"``: the invariant's
    ``-inv``) or by a rising crossing of ``phi`` (``kind="crossing"`` or
    ``"from_zero"``: a crossing guard, ``phi = ±g``); see the module docstring.

    Attributes
    ----------
    role : {"guard", "invariant", "stop"}
    name : str
        Transition, mode or stop-function name.
    kind : {"level", "strict", "crossing", "from_zero"}
    transition : Transition or None
        The guard's transition (``role="guard"``).
    """

    role: str
    name: str
    kind: str
    transition: Transition | None = None


def arm_watches(watches: Sequence[Watch], phi: Sequence[float], disarmed: Collection[str]) -> tuple[Watch, ...]:
    """The watches of a flow that starts with values ``phi``: crossing guards armed or not on zero.

    A crossing guard whose ``phi`` is exactly zero at the start fires as soon
    as it leaves zero in its direction (kind ``"from_zero"``) unless its name
    is in ``disarmed`` (it sits on zero because of its own crossing at the
    instant just settled, :func:`still_disarmed`): then, like one that starts
    above zero, it must first be strictly below zero (kind ``"crossing"``).

    Parameters
    ----------
    watches : sequence of Watch
    phi : sequence of float, shape (len(watches),)
        Watch values at the start of the flow.
    disarmed : collection of str
        Transition names disarmed by the instant before the flow.
    """
    out = None
    for k, w in enumerate(watches):
        if w.kind in CROSSING_KINDS:
            kind = "from_zero" if phi[k] == 0.0 and w.name not in disarmed else "crossing"
            if kind != w.kind:
                out = list(watches) if out is None else out
                out[k] = replace(w, kind=kind)
    return tuple(watches) if out is None else tuple(out)


def still_disarmed(watches: Sequence[Watch], left: Sequence[float], disarmed: Collection[str]) -> frozenset[str]:
    """The guards of ``disarmed`` that are still disarmed at a located event (not yet strictly below zero).

    A ``"crossing"`` watch whose value at the final bracket's left end
    ``left`` is zero or above has not been strictly below zero since the flow
    began (else it would have switched on, and been located, before), so a
    guard disarmed at the flow's start (:func:`arm_watches`) is still disarmed.
    """
    if not disarmed:
        return frozenset()
    return frozenset(w.name for k, w in enumerate(watches)
                     if w.kind == "crossing" and w.name in disarmed and left[k] >= 0.0)


# ---------------------------------------------------------------------- finding, locating, resolving events
def is_on(kind: str, phi: float) -> bool:
    """Whether a watch of ``kind`` is on at the value ``phi`` (``> 0`` strict kinds, ``>= 0`` the others)."""
    return phi > 0.0 if (kind == "strict" or kind == "from_zero") else phi >= 0.0


def switched_on(watches: Sequence[Watch], before: Sequence[float], after: Sequence[float]) -> list[int]:
    """Indices of the watches that switch on between two evaluations (:func:`switches_on`)."""
    out = []
    for k, w in enumerate(watches):
        b, a = before[k], after[k]
        kind = w.kind
        if kind == "strict" or kind == "from_zero":
            if a > 0.0 >= b:
                out.append(k)
        elif a >= 0.0 > b:  # level, and crossing: from strictly below zero
            out.append(k)
    return out


@dataclass(frozen=True, slots=True)
class Bracket:
    """An interval of one step where watches ``candidates`` switch on (found by :func:`find_switch`)."""

    lo: float
    hi: float
    phi_lo: list[float]
    phi_hi: list[float]
    candidates: list[int]


REFINE_SUBDIVISIONS = 4
"""A refined sample interval is split into this many (three new evaluations)."""

REFINE_BUDGET = 256
"""Evaluations of the watches spent on refinement per solver step, at most."""

RATE_SAFETY = 1.5
"""The rate bound of a watched function is this times the largest rate seen between its samples."""

COHERENCE = 0.5
"""Samples resolve a function when their second differences are at most this times their first ones."""

SWITCH_SLACK = 2.0
"""An interval that switches on is refined (levels 0 and 1) when rate bound × spacing exceeds this × its rise."""

EXTREMUM_ITERATIONS = 80
"""Golden-section steps of :meth:`Refiner.extremum` at most (the interval shrinks by 0.618 a step)."""

UNRESOLVED_KEPT = 1000
"""Places kept in :attr:`HybridTrajectory.unresolved` (the warning gives the total)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class UnresolvedWindow:
    """A place where a watched function may switch on and off again unseen (see :func:`simulate_continuous`).

    At the finest refinement the function's samples on ``[t_start, t_end]`` are
    still close enough to zero, for the rate at which it changes or for the
    way they bend, that a window narrower than ``t_end - t_start`` cannot be
    ruled out there (the tests of :class:`Refiner`).

    Attributes
    ----------
    mode : str
        Mode of the segment.
    role : str
        ``"guard"``, ``"invariant"`` or ``"stop"``.
    name : str
        Transition, mode or stop-function name.
    t_start, t_end : float
        The interval between the two samples [s].
    distance : float
        Distance from zero of the nearer sample (in the function's units).
    reach : float
        How far the function may move between the samples by the test that
        flagged them (rate bound × spacing, or the second difference of the
        samples), at least ``distance``.
    reason : str
        ``"depth"`` (the finest spacing was reached) or ``"budget"``
        (:data:`REFINE_BUDGET` evaluations were spent in the step).
    """

    mode: str
    role: str
    name: str
    t_start: float
    t_end: float
    distance: float
    reach: float
    reason: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"mode": self.mode, "role": self.role, "name": self.name, "t_start": self.t_start,
                "t_end": self.t_end, "distance": self.distance, "reach": self.reach, "reason": self.reason}


class Refiner:
    """Searches the sample intervals of a segment where a watch may switch on unseen (private).

    Between two samples ``a``, ``b`` of a watched function that are off and on
    the same side of zero (strictly below it; for a crossing watch also
    strictly above it, where a dip below zero and back is a rising crossing),
    the function can reach zero only if

    * its rate of change exceeds ``(|a| + |b|) / h`` somewhere (``h`` the
      spacing): the interval is flagged when that is at most the rate bound,
      :data:`RATE_SAFETY` times the largest rate seen between samples of this
      function so far in the segment (a mode's time scale is its own: the
      bouncing ball's flights shrink a thousandfold); or
    * the samples bend towards it: a second difference of the samples around
      the interval at least the distance of the nearer sample from zero (a
      parabola through three samples rises above their chord by an eighth of
      its second difference).

    Inside a refinement the rate bound is built on the rates of the
    sub-intervals themselves where their samples resolve the function
    (:meth:`bounds`), on the segment's largest otherwise.  Samples within
    ``rate bound × event_tol`` of zero count as on zero (the event resolution:
    the point a segment starts from after an event), and intervals with a
    sample on zero or non-finite values are decided by their end values.  An
    interval that switches on is refined too (at the step's level and the
    first below) when the function had time to go to zero and back before
    (:data:`SWITCH_SLACK`), so a window hidden before the visible crossing is
    not passed over.  A flagged interval is split into
    :data:`REFINE_SUBDIVISIONS` at points of the step's dense output and the
    flagged sub-intervals again, in time order, down to ``depth`` levels; the
    first switch-on found is the bracket.  What is still flagged at the finest
    level (or when the step's :data:`REFINE_BUDGET` is spent) is recorded as an
    :class:`UnresolvedWindow`, except the approach to a crossing found right
    after it (a window there would only move that event by less than the
    finest spacing).
    """

    __slots__ = ("values", "watches", "point", "depth", "mode", "budget", "evaluations", "unresolved", "rates",
                 "event_tol", "crossing", "kinds", "start", "pending")

    def __init__(self, values: Callable[[float, tuple[float, ...]], list[float]], watches: Sequence[Watch],
                 point: Callable[[float], tuple[float, ...]], depth: int, mode: str, unresolved: UnresolvedLog,
                 rates: list[float], event_tol: float, start: float = -math.inf) -> None:
        self.values, self.watches, self.point, self.depth, self.mode = values, watches, point, depth, mode
        self.start = start  # the flow's start time [s]: its first value may sit on zero at the event resolution
        self.pending: list[UnresolvedWindow] = []  # the step's records, until its search ends (flush)
        self.budget = REFINE_BUDGET
        self.evaluations = 0
        self.unresolved = unresolved
        self.rates = rates  # largest |d phi / dt| seen per watch in the segment
        self.event_tol = event_tol
        self.crossing = [w.kind in CROSSING_KINDS for w in watches]
        self.kinds = [w.kind for w in watches]

    def bounds(self, ts: Sequence[float], ps: Sequence[Sequence[float]]) -> list[float]:
        """Rates for the bound inside a refinement, per watch; the segment's maxima updated.

        A watch's samples resolve it when every second difference is at most
        :data:`COHERENCE` times the largest first difference (its curvature is
        seen); then its largest rate among these samples is used (a function
        that is slow here is slow here: the ball's guard near an impact).
        Otherwise (a kink, an extremum, samples that alias a faster variation)
        the segment's largest rate is kept.
        """
        rates = self.rates
        out = []
        for k in range(len(rates)):
            col = [row[k] for row in ps]
            local = first = second = 0.0
            for m in range(len(col) - 1):
                d = abs(col[m + 1] - col[m])
                h = ts[m + 1] - ts[m]
                if d > first:
                    first = d
                if h > 0.0 and local * h < d < math.inf:
                    local = d / h
                if m + 2 < len(col):
                    d2 = abs(col[m + 2] - 2.0 * col[m + 1] + col[m])
                    if d2 > second:
                        second = d2
            if local > rates[k]:
                rates[k] = local
            out.append(local if second <= COHERENCE * first < math.inf else rates[k])
        return out

    def scan(self, ts: Sequence[float], ps: Sequence[Sequence[float]]) -> list[int]:
        """The step's own samples: learn the rates; the watches some interval may need refining for.

        A watch whose samples all sit strictly on one side of zero, farther
        from it than the rate bound lets it move in a spacing and than they
        bend, is clear everywhere in the step (the tests of :meth:`flags`,
        all intervals at once); the others are returned.
        """
        n = len(ts) - 1
        h = (ts[-1] - ts[0]) / n  # the step's samples are evenly spaced
        if not h > 0.0:
            return list(range(len(self.rates)))
        rates = self.rates
        band = RATE_SAFETY * self.event_tol
        out = []
        for k, col in enumerate(zip(*ps)):
            move = max([abs(b - a) for a, b in zip(col, col[1:])])
            if rates[k] * h < move < math.inf:
                rates[k] = move / h
            high = max(col)
            if high < 0.0:
                distance = -high
            elif self.crossing[k] and min(col) > 0.0:
                distance = min(col)
            else:
                out.append(k)
                continue
            bound = RATE_SAFETY * rates[k]
            if not (2.0 * distance > bound * h and distance > band * rates[k]):
                out.append(k)
            elif n > 1 and not max([abs(a - 2.0 * b + c) for a, b, c in zip(col, col[1:], col[2:])]) < distance:
                out.append(k)
        return out

    def flags(self, ts: Sequence[float], ps: Sequence[Sequence[float]], i: int, level: int,
              rates: Sequence[float], only: Sequence[int] | None = None) -> list[tuple[int, float, float, str]]:
        """Watches whose samples ``i``, ``i + 1`` may hide a switch-on: ``(k, distance, reach, test)``.

        ``rates`` are the rates the bound is built on: the segment's largest
        at the step's own samples (``level = 0``), those of :meth:`bounds`
        below.  ``test`` is ``"rate"``,
        ``"bend"`` or ``"switch"`` (an interval that switches on, or where a
        crossing guard goes from above zero to below it, refined at
        ``level <= 1`` when the function had time to go to zero and back: rate
        bound × spacing > :data:`SWITCH_SLACK` × ``(|a| + |b|)``; such
        intervals are never recorded as unresolved).
        """
        a_row, b_row = ps[i], ps[i + 1]
        h = ts[i + 1] - ts[i]
        if not h > 0.0:
            return []
        left = ps[i - 1] if i >= 1 else None
        right = ps[i + 2] if i + 2 < len(ps) else None
        out = []
        for k in (range(len(a_row)) if only is None else only):
            a, b = a_row[k], b_row[k]
            bound = RATE_SAFETY * rates[k]
            if a < 0.0 and b < 0.0:
                a, b = -a, -b
            elif not (a > 0.0 and b > 0.0 and self.crossing[k]):
                # an interval that switches on, or where a crossing guard goes below zero: both may hide an
                # earlier switch-on (zero and back, or below, back up and below again)
                turns = switches_on(self.kinds[k], a, b) or (self.crossing[k] and a >= 0.0 > b)
                if level <= 1 and turns and math.isfinite(a) and math.isfinite(b):
                    reach = bound * h
                    if reach > SWITCH_SLACK * (abs(a) + abs(b)):
                        out.append((k, min(abs(a), abs(b)), reach, "switch"))
                continue
            reach = bound * h  # how far the function can move between the samples
            near = a if a < b else b
            band = bound * self.event_tol
            if not (a + b < math.inf) or (near <= band and a + b > 2.0 * band and ts[i] == self.start):
                continue  # no evidence, or on zero at the event resolution at a flow's start (after an event)
            if a + b <= reach and near > band:
                out.append((k, near, reach, "rate"))
                continue
            bend = 0.0
            if left is not None:
                d = abs(left[k] - 2.0 * a_row[k] + b_row[k])
                if d < math.inf:
                    bend = d
            if right is not None:
                d = abs(a_row[k] - 2.0 * b_row[k] + right[k])
                if bend < d < math.inf:
                    bend = d
            if bend >= near:  # both samples within the band too: a touch of zero is searched, not skipped
                out.append((k, near, bend, "bend"))
        return out

    def search(self, lo: float, hi: float, p_lo: list[float], p_hi: list[float],
               flagged: list[tuple[int, float, float, str]], level: int, approach: Sequence[int] = ()
               ) -> Bracket | None:
        """First switch-on inside ``[lo, hi]`` (sub-interval ``level`` of a step's sample interval), or ``None``.

        ``approach``: watches that switch on right after ``hi`` (an interval still
        flagged for them at the finest level is their approach to that
        crossing, not recorded).
        """
        n = REFINE_SUBDIVISIONS
        if level > self.depth or self.budget < n - 1 or hi - lo <= 8.0 * math.ulp(max(abs(lo), abs(hi))):
            if self.budget < n - 1:
                self._record(lo, hi, flagged, approach, "budget")
                return None
            for k, _, _, test in flagged:  # a touch of zero (or a dip) is found by the extremum
                found = None if test == "switch" or k in approach else self.extremum(lo, hi, p_lo, p_hi, k)
                if found is not None:
                    return found
            self._record(lo, hi, flagged, approach, "depth")
            return None
        self.budget -= n - 1
        self.evaluations += n - 1
        ts = [lo] + [lo + (hi - lo) * j / n for j in range(1, n)] + [hi]
        ps = [p_lo] + [self.values(tt, self.point(tt)) for tt in ts[1:-1]] + [p_hi]
        bounds = self.bounds(ts, ps)
        for m in range(n):
            inner = self.flags(ts, ps, m, level, bounds)
            if inner:
                after = approach if m == n - 1 else switched_on(self.watches, ps[m + 1], ps[m + 2])
                found = self.search(ts[m], ts[m + 1], ps[m], ps[m + 1], inner, level + 1, after)
                if found is not None:
                    return found
            candidates = switched_on(self.watches, ps[m], ps[m + 1])
            if candidates:
                return Bracket(ts[m], ts[m + 1], ps[m], ps[m + 1], candidates)
        return None

    def extremum(self, lo: float, hi: float, p_lo: list[float], p_hi: list[float], k: int) -> Bracket | None:
        """A switch-on of watch ``k`` in a finest-level interval, found by a golden-section search of its extremum.

        Both samples are off on one side of zero: below it, the search
        maximises ``phi`` (a window, or a touch of zero — on only where the
        computed guard is exactly zero, about ``sqrt(ulp)`` wide — is where the
        maximum is on); above it (a crossing guard), it minimises ``phi`` (a
        dip below zero and back is a crossing).  Returns the bracket of the
        switch-on found, or ``None`` (the interval stays undecided: a search
        of a local extremum cannot rule a window out).
        """
        below = p_lo[k] < 0.0
        sign = 1.0 if below else -1.0
        kind = self.kinds[k]
        cache: dict[float, list[float]] = {}

        def f(tt: float) -> float:
            if tt not in cache:
                cache[tt] = self.values(tt, self.point(tt))
                self.evaluations += 1
            return sign * cache[tt][k]

        ratio = 0.5 * (math.sqrt(5.0) - 1.0)
        a, b = lo, hi
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        fc, fd = f(c), f(d)
        for _ in range(EXTREMUM_ITERATIONS):
            for tt, value in ((c, fc), (d, fd)):
                if value != value or abs(value) == math.inf:
                    return None
                if is_on(kind, value) if below else value < 0.0:
                    lo_t, hi_t = (lo, tt) if below else (tt, hi)
                    p_a, p_b = (p_lo, cache[tt]) if below else (cache[tt], p_hi)
                    candidates = switched_on(self.watches, p_a, p_b)
                    return Bracket(lo_t, hi_t, p_a, p_b, candidates) if candidates else None
            if b - a <= max(self.event_tol, 8.0 * math.ulp(max(abs(a), abs(b)))):
                return None
            if fc >= fd:
                b, d, fd = d, c, fc
                c = b - ratio * (b - a)
                fc = f(c)
            else:
                a, c, fc = c, d, fd
                d = a + ratio * (b - a)
                fd = f(d)
        return None

    def flush(self, found: Bracket | None) -> None:
        """Keep the step's records, except the approach to the switch-on ``found`` (records ending where it begins).

        A window there would only move that event by less than the finest
        spacing (the same exemption as ``approach`` in :meth:`search`).
        """
        edge = None if found is None else found.lo
        names = () if found is None else {self.watches[k].name for k in found.candidates}
        dropped = set()
        for n in range(len(self.pending) - 1, -1, -1):
            record = self.pending[n]
            if record.t_end == edge and record.name in names:
                edge = record.t_start  # the chain of adjacent records before the switch-on
                dropped.add(n)
        for n, record in enumerate(self.pending):
            if n not in dropped:
                self.unresolved.add(record)
        self.pending = []

    def _record(self, lo: float, hi: float, flagged: list[tuple[int, float, float, str]], approach: Sequence[int],
                reason: str) -> None:
        for k, distance, reach, test in flagged:
            if test == "switch" or k in approach:
                continue
            w = self.watches[k]
            self.pending.append(UnresolvedWindow(mode=self.mode, role=w.role, name=w.name, t_start=lo, t_end=hi,
                                                 distance=distance, reach=reach, reason=reason))


def switches_on(kind: str, before: float, after: float) -> bool:
    """Whether a watch of ``kind`` switches on from ``before`` to ``after`` (see the module docstring)."""
    if kind == "strict" or kind == "from_zero":
        return after > 0.0 >= before
    return after >= 0.0 > before


class UnresolvedLog:
    """The run's :class:`UnresolvedWindow` records: adjacent ones of one watch merged, the first kept (private)."""

    __slots__ = ("items", "total")

    def __init__(self) -> None:
        self.items: list[UnresolvedWindow] = []
        self.total = 0

    def add(self, record: UnresolvedWindow) -> None:
        for n in range(len(self.items) - 1, max(len(self.items) - 4, -1), -1):  # the last few: one per watch
            last = self.items[n]
            if (last.t_end == record.t_start and last.name == record.name and last.role == record.role
                    and last.mode == record.mode):
                self.items[n] = UnresolvedWindow(
                    mode=last.mode, role=last.role, name=last.name, t_start=last.t_start, t_end=record.t_end,
                    distance=min(last.distance, record.distance), reach=max(last.reach, record.reach),
                    reason=last.reason)
                return
        self.total += 1
        if len(self.items) < UNRESOLVED_KEPT:
            self.items.append(record)


def find_switch(
    values: Callable[[float, tuple[float, ...]], list[float]],
    watches: Sequence[Watch],
    t_old: float,
    t_new: float,
    y_new: tuple[float, ...],
    phi_old: list[float],
    point: Callable[[float], tuple[float, ...]] | None,
    sign_checks: int,
    refiner: Refiner | None = None,
) -> tuple[Bracket | None, list[float]]:
    """Evaluate the watches at ``sign_checks`` interior points of a step and at its end; refine where they bend.

    The samples are evaluated in time order up to the first interval where a
    watch switches on.  The intervals up to that one are then examined by
    ``refiner`` (when given) in time order, so a window hidden between two
    samples before the first visible switch-on wins.

    Returns
    -------
    bracket, phi_end
        The first (sub-)interval where a watch switches on, or ``None``; the
        watch values at the step's end (when nothing switched on).
    """
    if point is None or sign_checks == 0:
        phi_new = values(t_new, y_new)
        candidates = switched_on(watches, phi_old, phi_new)
        return (Bracket(t_old, t_new, phi_old, phi_new, candidates) if candidates else None), phi_new
    n = sign_checks + 1
    ts, ps = [t_old], [phi_old]
    first_on: list[int] | None = None
    for i in range(1, n + 1):
        if i < n:
            hi = t_old + (t_new - t_old) * i / n
            phi = values(hi, point(hi))
        else:
            hi, phi = t_new, values(t_new, y_new)
        ts.append(hi)
        ps.append(phi)
        first_on = switched_on(watches, ps[-2], phi) or None
        if first_on is not None:
            break
    pairs = len(ts) - 1
    if refiner is not None and refiner.depth > 0:
        refiner.budget = REFINE_BUDGET
        refiner.pending = []
        found = None
        suspects = refiner.scan(ts, ps)
        for i in range(pairs if suspects else 0):
            flagged = refiner.flags(ts, ps, i, 0, refiner.rates, suspects)
            if flagged:
                approach = first_on if (first_on is not None and i == pairs - 2) else ()
                found = refiner.search(ts[i], ts[i + 1], ps[i], ps[i + 1], flagged, 1, approach or ())
                if found is not None:
                    break
        refiner.flush(found)
        if found is not None:
            return found, ps[-1]
    if first_on is not None:
        return Bracket(ts[-2], ts[-1], ps[-2], ps[-1], first_on), ps[-1]
    return None, ps[-1]


def locate_event(
    values: Callable[[float, tuple[float, ...]], list[float]],
    watches: Sequence[Watch],
    bracket: Bracket,
    point: Callable[[float], tuple[float, ...]],
    event_tol: float,
) -> tuple[LocatedEvent, int]:
    """First time in ``bracket`` where one of its candidates is on, to ``event_tol``.

    A candidate is on where :func:`is_on` (``phi >= 0``; ``> 0`` for the
    invariant and a crossing guard leaving zero), so the located time is the
    right end of the final bracket, where the condition holds.

    Returns
    -------
    event, iterations
        The event time, state and watch values, and the same at the final
        bracket's left end (where no candidate is on yet: the kernel's
        "previous" evaluation).
    """
    cands = bracket.candidates
    cache: dict[float, list[float]] = {bracket.lo: bracket.phi_lo}  # phi_lo was evaluated at point(lo)

    def values_at(tt: float) -> list[float]:
        if tt not in cache:
            cache[tt] = values(tt, point(tt))
        return cache[tt]

    stricts = [(k, watches[k].kind == "strict" or watches[k].kind == "from_zero") for k in cands]

    def any_on(tt: float) -> bool:
        vals = values_at(tt)
        for k, strict in stricts:
            if (vals[k] > 0.0) if strict else (vals[k] >= 0.0):
                return True
        return False

    t_left, t_star, _, _, iterations = locate_crossing(
        lambda tt: max(values_at(tt)[k] for k in cands),
        bracket.lo, bracket.hi, max(bracket.phi_lo[k] for k in cands), max(bracket.phi_hi[k] for k in cands),
        tol=event_tol, holds=any_on,
    )
    return LocatedEvent(time=float(t_star), state=point(t_star), values=values_at(t_star), left_time=t_left,
                  left_state=point(t_left), left_values=values_at(t_left)), iterations


@dataclass(frozen=True, slots=True)
class LocatedEvent:
    """A located event of one segment: time, state and watch values there and at the bracket's left end."""

    time: float
    state: tuple[float, ...]
    values: list[float]
    left_time: float
    left_state: tuple[float, ...]
    left_values: list[float]


def unresolved_message(name: str, log: UnresolvedLog) -> str:
    """The :class:`~hybrid.errors.GuardResolutionWarning` text of a run named ``name``."""
    first = log.items[0]
    return (
        f"simulate_continuous({name!r}): {log.total} place(s) where a watched function may switch on and off "
        f"between samples unseen; the first: the {first.role} {first.name!r} in mode {first.mode!r} on "
        f"[{format_time(first.t_start)}, {format_time(first.t_end)}] s, {first.distance:.3g} from zero where it "
        f"may move by {first.reach:.3g} ({first.reason} of the refinement reached); listed in "
        "HybridTrajectory.unresolved; fix: a smaller max_step, or a larger sign_checks or refine_depth"
    )
