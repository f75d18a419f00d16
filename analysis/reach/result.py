"""The result of a reachability run: the flowpipe, the jumps, why it stopped, distances to unsafe sets.

Every set of the result is an over-approximation for the *mathematical* semantics of the model
(see docs/reachability.md): a segment ``(mode, [t_lo, t_hi], Z, [lo, hi])`` contains every state
that an execution in ``mode`` can have at a time in ``[t_lo, t_hi]`` and that the segment covers
(the union of the segments covers every execution up to the time horizon and the jump bound, when
:attr:`ReachResult.complete`).  The set of a segment is ``Z ∩ [lo, hi]``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .sets import UnsafeSet, separation
from .zonotope import Zonotope

__all__ = ["ReachSegment", "ReachJump", "Termination", "ReachResult", "INCONCLUSIVE", "zonotope_contains"]

INCONCLUSIVE = ("blow_up", "segment_limit", "flowpipe_limit", "not_finite")
"""Termination reasons after which the flowpipe does not cover the horizon: the run decided nothing."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachSegment:
    """States of ``mode`` at times ``[t_lo, t_hi]`` [s]: ``zonotope ∩ [lo, hi]`` (each shape ``(n,)``).

    ``entry`` marks the set a flowpipe starts from (the initial set or the image of a jump), which
    is not clipped to the invariant (a jump may land outside it and jump again at once).  ``step`` [s] is
    the length of the segment's own step when it is an adaptive one (``reach(..., adaptive_step=...)``),
    else ``None``.
    """

    mode: str
    t_lo: float
    t_hi: float
    jumps: int
    zonotope: Zonotope
    lo: np.ndarray
    hi: np.ndarray
    entry: bool = False
    step: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (``"step"`` only for a segment of an adaptive step)."""
        out = {"mode": self.mode, "t": [self.t_lo, self.t_hi], "jumps": self.jumps, "entry": self.entry,
               "box": [self.lo.tolist(), self.hi.tolist()], "center": self.zonotope.center.tolist(),
               "generators": self.zonotope.generators.tolist()}
        if self.step is not None:
            out["step"] = self.step
        return out


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachJump:
    """A transition that may fire: from the box ``before`` (states in its guard) at times ``[t_lo, t_hi]``.

    ``zonotope``: a jump set kept as a zonotope (:mod:`analysis.reach.jumpsets`), ``None`` for a box jump set.
    Then ``before`` still holds the guard part, the target's flowpipe starts from ``zonotope.start()`` (which
    ``after`` holds), and the JSON carries ``zonotope`` as ``{"before": {"center", "generators"}, "after":
    {"center", "generators", "box"}}`` (the columns of ``after`` are the images of those of ``before``).
    """

    transition: str
    source: str
    target: str
    jumps: int
    t_lo: float
    t_hi: float
    before_lo: np.ndarray
    before_hi: np.ndarray
    after_lo: np.ndarray
    after_hi: np.ndarray
    zonotope: Any = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (``"zonotope"`` only for a zonotope jump set: the JSON of box jumps is unchanged)."""
        out = {"transition": self.transition, "source": self.source, "target": self.target, "jumps": self.jumps,
               "t": [self.t_lo, self.t_hi], "before": [self.before_lo.tolist(), self.before_hi.tolist()],
               "after": [self.after_lo.tolist(), self.after_hi.tolist()]}
        z = self.zonotope
        if z is not None:
            out["zonotope"] = {"before": {"center": z.before.center.tolist(), "generators": z.before.generators.tolist()},
                               "after": {"center": z.center.tolist(), "generators": z.generators.tolist(),
                                         "box": z.box.tolist()}}
        return out


@dataclass(frozen=True, kw_only=True, slots=True)
class Termination:
    """Why one flowpipe stopped: ``reason`` (``"horizon"``, ``"left_invariant"``, ``"max_jumps"`` or one of
    :data:`INCONCLUSIVE`), where and when, in words."""

    reason: str
    mode: str
    time: float
    jumps: int
    detail: str

    @property
    def conclusive(self) -> bool:
        """Whether the flowpipe covers what it had to (the horizon, the jump bound)."""
        return self.reason not in INCONCLUSIVE

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"reason": self.reason, "mode": self.mode, "time": self.time, "jumps": self.jumps,
                "detail": self.detail, "conclusive": self.conclusive}


@dataclass(frozen=True, kw_only=True, slots=True)
class ReachResult:
    """A flowpipe of a hybrid system.

    Attributes
    ----------
    system : str
    state_names : tuple of str
    horizon : float
        Time horizon [s].
    max_jumps : int
        Jump bound.
    time_step : float
        ``δ`` [s].
    segments : tuple of ReachSegment
    jumps : tuple of ReachJump
    terminations : tuple of Termination
        One per flowpipe (a mode entered with a set), in the order computed.
    distances : tuple of (str, float)
        For each unsafe set given to the run, :meth:`distance_to` of it.
    inputs : tuple of (str, list, list, list)
        The run's bounded inputs ``(mode, B (n×p rows), lo (p,), hi (p,))``: ``ẋ = A x + c + B u``,
        ``u(t) ∈ [lo, hi]`` (a zonotope ``U`` as its interval hull, rounded outward); saved in the JSON
        (key ``"inputs"``, only when there are inputs) for the re-check.
    """

    system: str
    state_names: tuple[str, ...]
    horizon: float
    max_jumps: int
    time_step: float
    segments: tuple[ReachSegment, ...]
    jumps: tuple[ReachJump, ...]
    terminations: tuple[Termination, ...]
    distances: tuple[tuple[str, float], ...] = ()
    inputs: tuple[tuple[str, list[list[float]], list[float], list[float]], ...] = ()
    schedule: tuple[tuple[str, Any], ...] = ()
    _index: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        index: dict[str, tuple[list[float], list[float], list[int]]] = {}
        for i, s in enumerate(self.segments):
            lows, highs, rows = index.setdefault(s.mode, ([], [], []))
            lows.append(s.t_lo)
            highs.append(s.t_hi)
            rows.append(i)
        object.__setattr__(self, "_index", {m: (np.array(a), np.array(b), np.array(c, dtype=int))
                                             for m, (a, b, c) in index.items()})

    @property
    def complete(self) -> bool:
        """Whether every flowpipe ended conclusively (horizon, invariant left, jump bound)."""
        return all(t.conclusive for t in self.terminations)

    @property
    def status(self) -> str:
        """``"complete"`` or ``"inconclusive"`` (a blow-up or a limit: the sets decide nothing)."""
        return "complete" if self.complete else "inconclusive"

    def distance_to(self, unsafe: UnsafeSet) -> float:
        """The smallest separation between the flowpipe and ``unsafe`` (positive: separated, proven).

        A positive value is a lower bound of the Euclidean distance between every segment (of the
        modes where the set is unsafe) and the set (:func:`analysis.reach.sets.separation`); it
        proves the set unreachable up to the horizon and the jump bound only if :attr:`complete`.
        ``inf`` when no segment is in those modes.
        """
        best = math.inf
        for s in self.segments:
            if unsafe.modes is not None and s.mode not in unsafe.modes:
                continue
            for poly in unsafe.polyhedra:
                best = min(best, separation(s.zonotope, s.lo, s.hi, poly))
        return best

    def contains(self, mode: str, t: float, x: Sequence[float], tol: float = 0.0) -> bool:
        """Whether some segment of ``mode`` whose time interval holds ``t`` contains ``x`` (within ``tol``).

        ``tol`` widens the time interval, the box and the zonotope (by ``tol`` in every coordinate).
        """
        if mode not in self._index:
            return False
        point = np.asarray(x, dtype=float)
        lows, highs, rows = self._index[mode]
        for i in rows[(lows - tol <= t) & (t <= highs + tol)]:
            s = self.segments[int(i)]
            if np.all(point >= s.lo - tol) and np.all(point <= s.hi + tol) and zonotope_contains(
                    s.zonotope, point, tol):
                return True
        return False

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (deterministic: the same run gives the same dict)."""
        out = {
            "system": self.system, "state_names": list(self.state_names), "status": self.status,
            "horizon": self.horizon, "max_jumps": self.max_jumps, "time_step": self.time_step,
            "terminations": [t.as_dict() for t in self.terminations],
            "distances": [{"unsafe": name, "distance": _json_float(d)} for name, d in self.distances],
            "jumps": [j.as_dict() for j in self.jumps],
            "segments": [s.as_dict() for s in self.segments],
        }
        if self.schedule:  # the options the re-check takes as its schedule; absent with the defaults
            out["schedule"] = dict(self.schedule)
        if self.inputs:  # absent without inputs: the JSON of an input-free run is unchanged
            out["inputs"] = {mode: {"matrix": [list(r) for r in b], "low": list(lo), "high": list(hi)}
                             for mode, b, lo, hi in self.inputs}
        return out

    def to_json(self) -> str:
        """:meth:`as_dict` as JSON text (keys sorted; infinite distances as strings)."""
        return json.dumps(self.as_dict(), sort_keys=True, allow_nan=False)


def _json_float(value: float) -> float | str:
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def zonotope_contains(z: Zonotope, point: np.ndarray, tol: float = 0.0) -> bool:
    """Whether ``point`` lies in ``z ⊕ [-tol, tol]^n`` (decided by a linear program; exact in 1-D and 2-D).

    1-D: an interval.  2-D: the facets of the zonotope (one normal per generator direction).
    Higher dimensions: feasibility of ``G ξ = p − c``, ``|ξ| <= 1`` with scipy's HiGHS.
    """
    d = np.asarray(point, dtype=float) - z.center
    g = z.generators
    n = z.dimension
    if g.shape[1] == 0:
        return bool(np.all(np.abs(d) <= tol))
    if n == 1:
        return bool(abs(d[0]) <= np.abs(g).sum() + tol)
    if n == 2:
        # a normal per generator (the facets) and the generators' own directions (a flat zonotope)
        normals = np.vstack([np.vstack([-g[1], g[0]]).T, g.T])
        lengths = np.hypot(normals[:, 0], normals[:, 1])
        keep = lengths > 0
        normals = normals[keep] / lengths[keep, None]
        reach = np.abs(normals @ g).sum(axis=1) + tol * np.abs(normals).sum(axis=1)
        return bool(np.all(np.abs(normals @ d) <= reach * (1 + 1e-12) + 1e-300))
    from scipy.optimize import linprog

    m = g.shape[1]
    a_ub = np.vstack([np.hstack([g, -np.eye(n)]), np.hstack([-g, -np.eye(n)])])
    b_ub = np.concatenate([d, -d])
    bounds = [(-1.0, 1.0)] * m + [(0.0, tol)] * n
    res = linprog(np.zeros(m + n), A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    return bool(res.status == 0)
