"""Zeno and chatter diagnostics on the jumps of an execution.

Both executors produce events with a ``time``, a ``transition``, a ``source``
and a ``target``; these pure functions read them.

* **Zeno** (:func:`estimate_zeno`): jumps accumulate when the intervals between
  them shrink geometrically, ``Δ_{k+1} ≈ r Δ_k`` with ``r < 1``; the jumps then
  converge to ``t_Z = t_n + Δ_n r / (1 − r)`` (sum of the geometric tail).  The
  ratio is fitted by least squares on ``log Δ_k`` over a window of recent
  intervals, and the fit's scatter says how much to trust it.
* **Chatter** (:func:`find_chatter`): a pair of transitions ``q1 → q2`` and
  ``q2 → q1`` firing back and forth with dwell times shorter than a window.

Examples
--------
>>> times = [1.0 - 0.5 ** k for k in range(1, 30)]          # Zeno at t = 1
>>> z = estimate_zeno(times, window=8)
>>> round(z.zeno_time, 12), round(z.ratio, 12)
(1.0, 0.5)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .jsonable import to_jsonable

__all__ = [
    "JumpLike",
    "ZenoEstimate",
    "ZenoReport",
    "ChatterEpisode",
    "estimate_zeno",
    "find_chatter",
]


class JumpLike(Protocol):
    """What the diagnostics read from an event."""

    time: float
    transition: str
    source: str
    target: str


@dataclass(frozen=True, kw_only=True, slots=True)
class ZenoEstimate:
    """Geometric fit of the last inter-jump intervals.

    Attributes
    ----------
    zeno_time : float
        Estimated accumulation time ``t_Z`` [s] (``inf`` when ``ratio >= 1``).
    ratio : float
        Fitted ratio ``r`` of successive intervals.
    scatter : float
        Largest relative deviation of an interval from the fitted geometric law.
    intervals : int
        Number of intervals fitted.
    last_interval : float
        ``Δ_n`` [s].
    """

    zeno_time: float
    ratio: float
    scatter: float
    intervals: int
    last_interval: float

    @property
    def accumulating(self) -> bool:
        """Whether the fit describes converging jump times (``r < 1``, tight fit)."""
        return self.ratio < 1.0 and self.scatter < 1e-2 and math.isfinite(self.zeno_time)


@dataclass(frozen=True, kw_only=True, slots=True)
class ZenoReport:
    """Zeno behaviour found by an executor.

    Attributes
    ----------
    kind : str
        ``"accumulation"`` (jump times converge) or ``"instantaneous"``
        (more jumps at one instant than allowed).
    zeno_time : float
        Estimated (accumulation) or actual (instantaneous) time [s].
    ratio : float
        Fitted interval ratio (``nan`` for instantaneous Zeno).
    jumps : int
        Jumps taken when it was detected.
    modes : tuple of str
        Modes visited by the accumulating jumps (first visit order).
    transitions : tuple of str
        Transitions involved (first firing order).
    last_times : tuple of float
        The most recent jump times (at most 12).
    message : str
        One line for humans.
    """

    kind: str
    zeno_time: float
    ratio: float
    jumps: int
    modes: tuple[str, ...]
    transitions: tuple[str, ...]
    last_times: tuple[float, ...]
    message: str

    def as_dict(self) -> dict[str, object]:
        """JSON-ready view: every field, non-finite times and ratio as ``None``."""
        return to_jsonable(self)


@dataclass(frozen=True, kw_only=True, slots=True)
class ChatterEpisode:
    """A pair of transitions firing back and forth faster than a window.

    Attributes
    ----------
    transitions : tuple of str
        ``(q1 → q2, q2 → q1)`` transition names, in first-firing order.
    modes : tuple of str
        ``(q1, q2)``.
    start, end : float
        Times of the first and last switch of the episode [s].
    switches : int
        Number of jumps in the episode.
    shortest_dwell : float
        Shortest time spent in either mode during the episode [s].
    """

    transitions: tuple[str, str]
    modes: tuple[str, str]
    start: float
    end: float
    switches: int
    shortest_dwell: float

    @property
    def rate(self) -> float:
        """Switches per second over the episode (``inf`` if instantaneous)."""
        span = self.end - self.start
        return math.inf if span <= 0.0 else (self.switches - 1) / span

    def as_dict(self) -> dict[str, object]:
        """JSON-ready view: every field and ``rate_per_s`` (:attr:`rate`, ``None`` when instantaneous)."""
        return {**to_jsonable(self), "rate_per_s": to_jsonable(self.rate)}


def estimate_zeno(times: Sequence[float], *, window: int = 10) -> ZenoEstimate | None:
    """Fit ``Δ_{k+1} = r Δ_k`` to the last ``window`` intervals of ``times``.

    Parameters
    ----------
    times : sequence of float
        Jump times in non-decreasing order [s].
    window : int
        Number of most recent intervals used (>= 2).

    Returns
    -------
    ZenoEstimate or None
        ``None`` when there are fewer than ``window`` positive intervals.
    """
    if window < 2:
        raise ValueError(f"estimate_zeno: window = {window}; expected at least 2 intervals")
    t = np.asarray(times, dtype=float)
    if t.size < window + 1:
        return None
    deltas = np.diff(t[-(window + 1):])
    if np.any(deltas <= 0.0):
        return None
    k = np.arange(window, dtype=float)
    slope, intercept = np.polyfit(k, np.log(deltas), 1)
    ratio = float(math.exp(slope))
    fitted = np.exp(intercept + slope * k)
    scatter = float(np.max(np.abs(deltas / fitted - 1.0)))
    last = float(deltas[-1])
    if ratio < 1.0:
        # tail after the last jump, anchored on the fitted value of the last interval
        zeno_time = float(t[-1] + float(fitted[-1]) * ratio / (1.0 - ratio))
    else:
        zeno_time = math.inf
    return ZenoEstimate(zeno_time=zeno_time, ratio=ratio, scatter=scatter, intervals=window, last_interval=last)


def find_chatter(events: Sequence[JumpLike], *, window: float, min_switches: int = 4) -> tuple[ChatterEpisode, ...]:
    """Episodes where two modes alternate with every dwell shorter than ``window``.

    Parameters
    ----------
    events : sequence of events
        Jumps in time order (``time``, ``transition``, ``source``, ``target``).
    window : float
        Longest dwell [s] that still counts as chatter (> 0).
    min_switches : int
        Fewest back-and-forth jumps that make an episode (>= 2).

    Returns
    -------
    tuple of ChatterEpisode
        In time order; empty when nothing chatters.
    """
    if not (window > 0.0):
        raise ValueError(f"find_chatter: window = {window!r}; expected a positive time [s]")
    if min_switches < 2:
        raise ValueError(f"find_chatter: min_switches = {min_switches}; expected at least 2")
    episodes: list[ChatterEpisode] = []
    run: list[JumpLike] = []

    def close() -> None:
        if len(run) >= min_switches:
            dwell = min(b.time - a.time for a, b in zip(run, run[1:]))
            first, second = run[0], run[1]
            episodes.append(
                ChatterEpisode(
                    transitions=(first.transition, second.transition),
                    modes=(first.source, first.target),
                    start=float(first.time),
                    end=float(run[-1].time),
                    switches=len(run),
                    shortest_dwell=float(dwell),
                )
            )

    for event in events:
        if run:
            last = run[-1]
            alternates = (
                event.source == last.target
                and event.target == last.source
                and event.source != event.target
                and event.time - last.time <= window
                and (len(run) < 2 or event.transition == run[-2].transition)
            )
            if alternates:
                run.append(event)
                continue
            close()
        run = [event] if event.source != event.target else []
    close()
    return tuple(episodes)
