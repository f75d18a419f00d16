"""The sampled search of :func:`hybrid.check.check`: the search space of a mode (:class:`SearchSpace`: its box,
corners and faces), the points evaluated there, and :class:`ModeChecker`, which looks in each mode for
overlapping guards, deadlocks, resets outside the target invariant and re-triggering jumps (uniform samples,
then local optimisation), each finding with a witness; with the constants that tune it.

:mod:`hybrid.check` re-exports the public constants.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .findings import KIND_SEVERITY, Finding, Oracle, Witness, format_g
from .instant import MAX_JUMPS_PER_INSTANT, settle_instant
from .model import Transition
from .region import Box

# Helpers shared with hybrid.check have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["ModeSearch"]


BOUNDARY_PROBES = 200
"""Most segments (inside sample, outside sample) bisected per mode to reach the invariant's boundary."""

BOUNDARY_MAXITER = 200
"""Most iterations of one boundary search (alternating bisection and false position)."""

BOUNDARY_XTOL = 1e-13
"""Relative segment length (to the box width) at which a boundary search stops even if ``inv > tol``."""

FD_DISPLACEMENT = 1e-7
"""Step of the centred difference of ``inv`` along the flow, as a fraction of the box's largest width."""

NM_MAXFEV_BASE = 60
NM_MAXFEV_PER_DIM = 40
"""Nelder-Mead budget per start: ``NM_MAXFEV_BASE + NM_MAXFEV_PER_DIM * dimension`` merit evaluations."""

NM_SIMPLEX_STEP = 0.1
"""Initial simplex edge as a fraction of each coordinate's width."""

SNAP_DECIMALS = (12, 9, 6, 3)
"""Roundings tried on an optimiser's answer that misses a predicate by rounding error (e.g. ``x = 1e-11`` for 0)."""

CORNER_LIMIT = 256
"""Most box corners added to the samples."""

FACE_FRACTION = 0.5
"""Extra samples on the box's faces, as a fraction of ``samples`` (split evenly over the ``2 d`` faces).

Jump sets are often faces of the box (``h = 0``, ``T = low``): uniform samples of the interior never hit them.
"""

RETRIGGER_PROBE = 1e-3
"""Step (fraction of each coordinate's width) of the neighbours probed around a re-triggering guard state."""

_INFEASIBLE = 2.0  # merits are squashed into (-1, 1); an infeasible point scores 2 + violation


# ====================================================================== results
@dataclass(frozen=True, kw_only=True, slots=True)
class ModeSearch:
    """How hard the state space of one mode was searched.

    Attributes
    ----------
    mode : str
    box : str or None
        ``Box.describe()`` of the searched box; ``None`` when not searched.
    samples : int
        Uniform samples drawn.
    corners : int
        Box corners added to the samples.
    face_samples : int
        Samples drawn on the faces of the box (one continuous coordinate at a bound).
    boundary_points : int
        Points of the invariant's boundary located for the deadlock check.
    starts : int
        Local optimisations run.
    merit_evaluations : int
        Merit-function evaluations spent by the optimiser.
    function_calls : int
        Calls into the model (guards, invariants, resets, flows, jump maps, output).
    notes : tuple of str
        Why a check did not run, or ran partially, in this mode.
    """

    mode: str
    box: str | None
    samples: int = 0
    corners: int = 0
    face_samples: int = 0
    boundary_points: int = 0
    starts: int = 0
    merit_evaluations: int = 0
    function_calls: int = 0
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy."""
        return {
            "mode": self.mode,
            "box": self.box,
            "samples": self.samples,
            "corners": self.corners,
            "face_samples": self.face_samples,
            "boundary_points": self.boundary_points,
            "starts": self.starts,
            "merit_evaluations": self.merit_evaluations,
            "function_calls": self.function_calls,
            "notes": list(self.notes),
        }


def _squash(x: float) -> float:
    """Order-preserving map of the reals into (-1, 1) (Nelder-Mead only compares values)."""
    if math.isinf(x):
        return math.copysign(1.0, x)
    return x / (1.0 + abs(x))


def _crossing_note(transitions: Sequence[Transition]) -> str:
    crossing = [t.name for t in transitions if t.direction != 0]
    if not crossing:
        return ""
    return (
        f" (crossing-triggered {crossing} taken as enabled on the side their crossing ends on, "
        "g >= 0 for direction +1, g <= 0 for direction -1)"
    )


# ====================================================================== the search space of one mode
@dataclass(kw_only=True)
class SearchSpace:
    """Point layout of one mode's box: box coordinates, then the memory the box declares."""

    mode: str
    box: Box
    names: tuple[str, ...]
    order: tuple[int, ...]  # position in the point of each model coordinate
    memory_names: tuple[str, ...]
    base_memory: dict[str, float]
    free: np.ndarray  # indices the optimiser moves
    lower: np.ndarray
    upper: np.ndarray
    scale: float
    notes: list[str] = field(default_factory=list)

    @classmethod
    def build(cls, mode: str, box: Box, coords: tuple[str, ...], base_memory: dict[str, float]) -> SearchSpace:
        names = box.names + tuple(box.memory)
        index = {n: i for i, n in enumerate(names)}
        n_cont = len(box.bounds)
        lower = np.full(len(names), np.nan)
        upper = np.full(len(names), np.nan)
        lower[:n_cont], upper[:n_cont] = box.lower, box.upper
        offset = len(box.names)
        for k, (lo, hi) in enumerate(box.memory.values()):
            lower[offset + k], upper[offset + k] = lo, hi
        continuous = list(range(n_cont)) + list(range(offset, len(names)))
        free = np.array([i for i in continuous if upper[i] > lower[i]], dtype=int)
        widths = upper[free] - lower[free] if len(free) else np.zeros(0)
        return cls(
            mode=mode,
            box=box,
            names=names,
            order=tuple(index[n] for n in coords),
            memory_names=tuple(box.memory),
            base_memory=dict(base_memory),
            free=free,
            lower=lower,
            upper=upper,
            scale=float(widths.max()) if len(widths) else 1.0,
        )

    def split(self, p: np.ndarray) -> tuple[tuple[float, ...], dict[str, float]]:
        """State (model coordinate order) and memory of a point."""
        values = p.tolist()
        x = tuple(values[i] for i in self.order)
        m = dict(self.base_memory)
        if self.memory_names:
            m.update(zip(self.memory_names, values[len(values) - len(self.memory_names):]))
        return x, m

    def sample(self, rng: np.random.Generator, count: int) -> np.ndarray:
        points = self.box.sample(rng, count)
        if self.memory_names:
            lows = self.lower[len(self.box.names):]
            highs = self.upper[len(self.box.names):]
            points = np.hstack([points, rng.uniform(lows, highs, size=(count, len(lows)))])
        return points

    def faces(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """Samples with one continuous box coordinate pinned at a bound (``count`` in all, over the ``2 d`` faces)."""
        n_cont = len(self.box.bounds)
        sides = [(k, end) for k in range(n_cont) if self.upper[k] > self.lower[k] for end in (0, 1)]
        if n_cont < 2 or not sides:
            return np.empty((0, len(self.names)))  # in one dimension the faces are the corners
        per_face = max(1, count // len(sides))
        points = self.sample(rng, per_face * len(sides))
        for n, (k, end) in enumerate(sides):
            points[n * per_face:(n + 1) * per_face, k] = self.upper[k] if end else self.lower[k]
        return points

    def corners(self) -> np.ndarray:
        corners = self.box.corners(CORNER_LIMIT)
        if not self.memory_names:
            return corners
        lows = self.lower[len(self.box.names):]
        highs = self.upper[len(self.box.names):]
        ends = [np.hstack([corners, np.tile(lows, (len(corners), 1))])]
        if np.any(highs > lows):
            ends.append(np.hstack([corners, np.tile(highs, (len(corners), 1))]))
        return np.vstack(ends)

    def snapped(self, p: np.ndarray) -> list[np.ndarray]:
        """``p`` and copies with the free coordinates rounded (clipped back into the box)."""
        out = [p]
        for d in SNAP_DECIMALS:
            q = p.copy()
            q[self.free] = np.clip(np.round(p[self.free], d), self.lower[self.free], self.upper[self.free])
            if not any(np.array_equal(q, r) for r in out):
                out.append(q)
        return out


@dataclass(kw_only=True)
class _Point:
    """A point of a mode's space with everything evaluated there once."""

    p: np.ndarray
    x: tuple[float, ...]
    m: dict[str, float]
    v: tuple[float, ...]
    inv: float
    raw: tuple[float, ...]  # guards of the outgoing transitions, priority order
    enab: tuple[float, ...]  # the same, negated for direction = -1: >= 0 where the transition fires


# ====================================================================== the checker
class ModeChecker:
    """The state-space searches of one model; one instance per :func:`check` call."""

    def __init__(self, oracle: Oracle, *, samples: int, starts: int, tol: float) -> None:
        self.o = oracle
        self.a = oracle.automaton
        self.samples = samples
        self.starts = starts
        self.tol = tol
        # per-mode statistics, reset by search_mode
        self.n_starts = 0
        self.n_merit = 0
        self.n_boundary = 0

    # ---------------------------------------------------------------- evaluation helpers
    def point(self, space: SearchSpace, p: np.ndarray) -> _Point:
        x, m = space.split(p)
        v = self.o.signals(x, m)
        q = space.mode
        inv = self.o.invariant(q, x, v, m)
        outgoing = self.o.outgoing[q]
        raw = tuple([self.o.guard(t, x, v, m) for t in outgoing])
        # enabling value: the guard signed so that >= 0 is the side on which the transition fires
        enab = tuple([-g if t.direction < 0 else g for t, g in zip(outgoing, raw)])
        return _Point(p=p, x=x, m=m, v=v, inv=inv, raw=raw, enab=enab)

    def witness(self, pt: _Point, values: Mapping[str, float]) -> Witness:
        return Witness(
            state=dict(zip(self.o.coords, pt.x)),
            memory=pt.m,
            signals=dict(zip(self.a.variables, pt.v)),
            values=values,
        )

    def minimise(
        self, space: SearchSpace, merit: Callable[[np.ndarray], float], starts: Sequence[np.ndarray]
    ) -> list[np.ndarray]:
        """Bounded Nelder-Mead of ``merit`` (over the free coordinates) from each start."""
        from scipy.optimize import Bounds, minimize  # imported when sampling: a decided check never needs it

        free = space.free
        if not len(free):
            note = "no continuous coordinate with lower < upper: sampling only, no local optimisation"
            if note not in space.notes:
                space.notes.append(note)
            return []
        lo, hi = space.lower[free], space.upper[free]
        bounds = Bounds(lo, hi)
        maxfev = NM_MAXFEV_BASE + NM_MAXFEV_PER_DIM * len(free)
        out = []
        for p0 in starts:
            y0 = np.clip(p0[free], lo, hi)
            simplex = [y0]
            for k in range(len(free)):
                step = NM_SIMPLEX_STEP * (hi[k] - lo[k])
                y = y0.copy()
                y[k] = y0[k] + step if y0[k] + step <= hi[k] else y0[k] - step
                simplex.append(y)

            def fun(y: np.ndarray, p0: np.ndarray = p0) -> float:
                p = p0.copy()
                p[free] = np.clip(y, lo, hi)
                return merit(p)

            res = minimize(
                fun,
                y0,
                method="Nelder-Mead",
                bounds=bounds,
                options={
                    "maxfev": maxfev,
                    "initial_simplex": np.array(simplex),
                    "xatol": 1e-12 * space.scale,
                    "fatol": 1e-15,
                },
            )
            self.n_starts += 1
            self.n_merit += int(res.nfev)
            p = p0.copy()
            p[free] = np.clip(res.x, lo, hi)
            out.append(p)
        return out

    # ---------------------------------------------------------------- one mode
    def search_mode(self, space: SearchSpace, rng: np.random.Generator) -> tuple[list[Finding], ModeSearch]:
        self.n_starts = self.n_merit = self.n_boundary = 0
        calls0 = self.o.calls
        sampled = space.sample(rng, self.samples)
        faces = space.faces(rng, int(FACE_FRACTION * self.samples))
        corners = space.corners()
        points = [self.point(space, p) for p in np.vstack([sampled, faces, corners])]
        findings: list[Finding] = []
        findings += self.nondeterminism(space, points)
        findings += self.deadlock(space, points, rng)
        for t in self.o.outgoing[space.mode]:
            findings += self.reset_outside_invariant(space, points, t)
        for t in self.o.outgoing[space.mode]:
            findings += self.reset_retriggers(space, points, t)
        summary = ModeSearch(
            mode=space.mode,
            box=space.box.describe(),
            samples=len(sampled),
            corners=len(corners),
            face_samples=len(faces),
            boundary_points=self.n_boundary,
            starts=self.n_starts,
            merit_evaluations=self.n_merit,
            function_calls=self.o.calls - calls0,
            notes=tuple(space.notes),
        )
        return findings, summary

    # ---------------------------------------------------------------- nondeterminism
    def nondeterminism(self, space: SearchSpace, points: list[_Point]) -> list[Finding]:
        q = space.mode
        outgoing = self.o.outgoing[q]
        if len(outgoing) < 2:
            return []
        inv = np.array([pt.inv for pt in points])
        enab = np.array([pt.enab for pt in points])
        findings = []
        for i, j in itertools.combinations(range(len(outgoing)), 2):
            t1, t2 = outgoing[i], outgoing[j]
            overlap = np.minimum(np.minimum(enab[:, i], enab[:, j]), inv)
            best = int(np.argmax(overlap))
            found: _Point | None = points[best] if overlap[best] >= 0.0 else None
            if found is None:

                def merit(p: np.ndarray, i: int = i, j: int = j) -> float:
                    pt = self.point(space, p)
                    return -_squash(min(pt.enab[i], pt.enab[j], pt.inv))

                order = np.argsort(-overlap, kind="stable")[: self.starts]
                found = self._confirm(
                    space,
                    self.minimise(space, merit, [points[k].p for k in order]),
                    lambda pt, i=i, j=j: min(pt.enab[i], pt.enab[j], pt.inv),
                    threshold=-self.tol,
                )
            if found is None:
                continue
            margin = min(found.enab[i], found.enab[j], found.inv)
            values = {f"guard {t1.name}": found.raw[i], f"guard {t2.name}": found.raw[j]}
            if self.o.invariants[q] is not None:
                values[f"invariant {q}"] = found.inv
            within = "" if margin >= 0.0 else f" (within tol = {self.tol:g})"
            detail = (
                f"at {self.o.where(found.x, found.m)}: guard {t1.name} = {format_g(found.raw[i])}, "
                f"guard {t2.name} = {format_g(found.raw[j])}"
                + (f", invariant = {format_g(found.inv)}" if self.o.invariants[q] is not None else "")
                + within
                + _crossing_note((t1, t2))
            )
            if t1.priority == t2.priority:
                findings.append(
                    Finding(
                        kind="nondeterminism",
                        severity=KIND_SEVERITY["nondeterminism"],
                        message=(
                            f"mode {q!r}: transitions {t1.name!r} and {t2.name!r} have the same priority "
                            f"{t1.priority} and are both enabled {detail}; give them distinct priorities "
                            "or exclusive guards"
                        ),
                        modes=(q,),
                        transitions=(t1.name, t2.name),
                        witness=self.witness(found, values),
                    )
                )
            else:
                findings.append(
                    Finding(
                        kind="priority_overlap",
                        severity=KIND_SEVERITY["priority_overlap"],
                        message=(
                            f"mode {q!r}: transitions {t1.name!r} (priority {t1.priority}) and {t2.name!r} "
                            f"(priority {t2.priority}) are both enabled {detail}; the priority resolves it "
                            f"in favour of {t1.name!r}"
                        ),
                        modes=(q,),
                        transitions=(t1.name, t2.name),
                        witness=self.witness(found, values),
                    )
                )
        return findings

    def _confirm(
        self,
        space: SearchSpace,
        candidates: Sequence[np.ndarray],
        score: Callable[[_Point], float],
        threshold: float,
    ) -> _Point | None:
        """Best candidate (or a rounding of it) whose ``score >= threshold``; exact ``>= 0`` preferred."""
        best: _Point | None = None
        best_score = -math.inf
        for p in candidates:
            for r in space.snapped(p):
                pt = self.point(space, r)
                s = score(pt)
                if s >= 0.0 and best_score < 0.0:
                    best, best_score = pt, s
                    break
                if s > best_score:
                    best, best_score = pt, s
        if best is None or best_score < threshold:
            return None
        return best

    # ---------------------------------------------------------------- deadlock
    def _leaving_rate(self, space: SearchSpace, pt: _Point) -> float:
        """Centred finite difference of ``inv`` along the flow at ``pt`` (``d/dt inv``)."""
        f = self.o.flow(space.mode, pt.x, pt.m)
        speed = max(abs(c) for c in f)
        if speed == 0.0:
            return 0.0
        h = FD_DISPLACEMENT * space.scale / speed
        plus = tuple(a + h * b for a, b in zip(pt.x, f))
        minus = tuple(a - h * b for a, b in zip(pt.x, f))
        i_plus = self.o.invariant(space.mode, plus, self.o.signals(plus, pt.m), pt.m)
        i_minus = self.o.invariant(space.mode, minus, self.o.signals(minus, pt.m), pt.m)
        return (i_plus - i_minus) / (2.0 * h)

    def _deadlock_merit(self, space: SearchSpace, pt: _Point) -> tuple[float, float]:
        """``(merit, d/dt inv)``; ``merit < 0`` exactly when ``pt`` is a deadlock (given it is on the boundary)."""
        terms = [e + self.tol for e in pt.enab]
        rate = math.nan
        if self.o.system is not None:
            rate = self._leaving_rate(space, pt)
            terms.append(rate + self.tol)
        return (max(terms) if terms else -1.0), rate

    def _boundary(self, space: SearchSpace, a: _Point, c: np.ndarray, fc: float) -> _Point:
        """Point of the invariant's boundary on segment ``[a, c]`` (``inv(a) >= 0 > inv(c)``), inside end."""
        q = space.mode
        pa, fa = a.p, a.inv
        free = space.free
        widths = np.where(space.upper[free] > space.lower[free], space.upper[free] - space.lower[free], 1.0)
        for it in range(BOUNDARY_MAXITER):
            if fa <= self.tol or np.max(np.abs(pa[free] - c[free]) / widths, initial=0.0) <= BOUNDARY_XTOL:
                break
            s = 0.5
            if it % 2 and math.isfinite(fa) and math.isfinite(fc):
                s = min(max(fa / (fa - fc), 0.01), 0.99)  # false position, kept off the ends
            pm = pa + s * (c - pa)
            x, m = space.split(pm)
            fm = self.o.invariant(q, x, self.o.signals(x, m), m)
            if fm >= 0.0:
                pa, fa = pm, fm
            else:
                c, fc = pm, fm
        return self.point(space, pa) if pa is not a.p else a

    def deadlock(self, space: SearchSpace, points: list[_Point], rng: np.random.Generator) -> list[Finding]:
        q = space.mode
        if self.o.invariants[q] is None:
            space.notes.append("deadlock: mode has no invariant, so no boundary to leave through")
            return []
        inside = [pt for pt in points if pt.inv >= 0.0]
        candidates = self._deadlock_candidates(space, points, rng)
        if not candidates:
            space.notes.append(
                "deadlock: no point of the invariant's boundary in the box (the invariant holds "
                + ("everywhere" if inside else "nowhere")
                + " on the samples); widen the box across the boundary to search it"
            )
            return []
        best = min(range(len(candidates)), key=lambda k: candidates[k][0])
        merit, rate, found, _, _ = candidates[best]
        if merit >= 0.0:
            merit, rate, found = self._deadlock_refine(space, candidates, merit, rate, found)
        if merit >= 0.0:
            return []
        return [self._deadlock_finding(space, found, rate)]

    def _deadlock_candidates(
        self, space: SearchSpace, points: list[_Point], rng: np.random.Generator
    ) -> list[tuple[float, float, _Point, _Point | None, np.ndarray | None]]:
        """Boundary points of the invariant of ``space.mode``: the samples within ``tol`` of it, then the
        boundary located on random segments from a sample inside to one outside; ``(merit, rate, point, inside
        end or None, outside end or None)`` each."""
        q = space.mode
        inside = [pt for pt in points if pt.inv >= 0.0]
        outside = [pt for pt in points if pt.inv < 0.0]
        candidates: list[tuple[float, float, _Point, _Point | None, np.ndarray | None]] = []
        for pt in points:
            if 0.0 <= pt.inv <= self.tol:
                self.n_boundary += 1
                merit, rate = self._deadlock_merit(space, pt)
                candidates.append((merit, rate, pt, None, None))
        n_discrete = len(space.box.names) - len(space.box.bounds)
        n_cont = len(space.box.bounds)
        jumps = 0  # boundary searches that ended on a jump of the invariant (inv > tol next to inv < 0)
        if inside and outside:
            probes = min(BOUNDARY_PROBES, len(inside) * len(outside))
            ia = rng.integers(len(inside), size=probes)
            ic = rng.integers(len(outside), size=probes)
            for k_a, k_c in zip(ia, ic):
                a = inside[int(k_a)]
                c = outside[int(k_c)].p.copy()
                fc = outside[int(k_c)].inv
                if n_discrete:
                    c[n_cont:len(space.box.names)] = a.p[n_cont:len(space.box.names)]
                    x, m = space.split(c)
                    fc = self.o.invariant(q, x, self.o.signals(x, m), m)
                    if fc >= 0.0:
                        continue
                b = self._boundary(space, a, c, fc)
                if b.inv > self.tol:
                    jumps += 1
                    continue
                self.n_boundary += 1
                merit, rate = self._deadlock_merit(space, b)
                candidates.append((merit, rate, b, a, c))
        if jumps:
            space.notes.append(
                f"deadlock: {jumps} boundary searches ended where the invariant jumps (inv > tol right next to "
                "inv < 0); those points were not examined (a discontinuous invariant is only checked where it "
                "is continuous)"
            )
        return candidates

    def _deadlock_refine(
        self, space: SearchSpace, candidates: list[tuple[float, float, _Point, _Point | None, np.ndarray | None]],
        merit: float, rate: float, found: _Point,
    ) -> tuple[float, float, _Point]:
        """The best deadlock candidate after moving the outside end of the most promising segments (the boundary
        re-located each time)."""
        q = space.mode
        # refine: move the outside end of the most promising segments, re-locating the boundary each time
        anchored = sorted(
            (k for k in range(len(candidates)) if candidates[k][3] is not None), key=lambda k: candidates[k][0]
        )[: self.starts]
        for k in anchored:
            anchor = candidates[k][3]
            assert anchor is not None

            def merit_fn(p: np.ndarray, anchor: _Point = anchor) -> float:
                x, m = space.split(p)
                fy = self.o.invariant(q, x, self.o.signals(x, m), m)
                if fy >= 0.0:
                    return _INFEASIBLE + _squash(fy)
                b = self._boundary(space, anchor, p, fy)
                return 1.0 if b.inv > self.tol else _squash(self._deadlock_merit(space, b)[0])

            end = candidates[k][4]
            assert end is not None
            for p in self.minimise(space, merit_fn, [end]):
                x, m = space.split(p)
                fy = self.o.invariant(q, x, self.o.signals(x, m), m)
                if fy >= 0.0:
                    continue
                b = self._boundary(space, anchor, p, fy)
                if b.inv > self.tol:
                    continue
                m_b, r_b = self._deadlock_merit(space, b)
                if m_b < merit:
                    merit, rate, found = m_b, r_b, b
        return merit, rate, found

    def _deadlock_finding(self, space: SearchSpace, found: _Point, rate: float) -> Finding:
        """The deadlock finding at ``found``, a boundary point of the invariant of ``space.mode`` that the flow
        leaves (rate ``rate``) with no outgoing transition enabled."""
        q = space.mode
        outgoing = self.o.outgoing[q]
        values = {f"invariant {q}": found.inv}
        if self.o.system is not None:
            values[f"d/dt invariant {q}"] = rate
        values.update({f"guard {t.name}": g for t, g in zip(outgoing, found.raw)})
        guards = ", ".join(f"guard {t.name} = {format_g(g)}" for t, g in zip(outgoing, found.raw))
        leaving = (
            f"the flow leaves it (d/dt inv = {format_g(rate)} < -tol)"
            if self.o.system is not None
            else "(no flow: every boundary point counts)"
        )
        enabled = (
            f"no outgoing transition is enabled ({guards}, all below -tol = {-self.tol:g}{_crossing_note(outgoing)})"
            if outgoing
            else "the mode has no outgoing transition"
        )
        return Finding(
            kind="deadlock",
            severity=KIND_SEVERITY["deadlock"],
            message=(
                f"mode {q!r}: deadlock at {self.o.where(found.x, found.m)} on the boundary of the invariant "
                f"(inv = {format_g(found.inv)}): {leaving} and {enabled}; add a transition enabled there or "
                "widen the invariant"
            ),
            modes=(q,),
            transitions=tuple(t.name for t in outgoing),
            witness=self.witness(found, values),
        )

    # ---------------------------------------------------------------- resets
    def _violation(self, pt: _Point, k: int) -> float:
        """How far ``pt`` is from the guard set of outgoing transition ``k`` intersected with the invariant."""
        return max(0.0, -pt.enab[k]) + max(0.0, -pt.inv)

    def _post(self, t: Transition, pt: _Point) -> tuple[tuple[float, ...], dict[str, float], tuple[float, ...]]:
        x, m = self.o.jump(t, pt.x, pt.v, pt.m)
        return x, m, self.o.signals(x, m)

    def reset_outside_invariant(self, space: SearchSpace, points: list[_Point], t: Transition) -> list[Finding]:
        q, target = space.mode, t.target
        if self.o.invariants[target] is None:
            return []
        k = self.o.outgoing[q].index(t)

        def after(pt: _Point) -> float:
            x, m, v = self._post(t, pt)
            return self.o.invariant(target, x, v, m)

        feasible = [pt for pt in points if self._violation(pt, k) == 0.0]
        scored = [(after(pt), n) for n, pt in enumerate(feasible)]
        found: _Point | None = None
        if scored:
            value, n = min(scored)
            if value < -self.tol:
                found = feasible[n]
        if found is None:

            def merit(p: np.ndarray) -> float:
                pt = self.point(space, p)
                violation = self._violation(pt, k)
                if violation > 0.0:
                    return _INFEASIBLE + _squash(violation)
                return _squash(after(pt))

            if scored:
                starts = [feasible[n].p for _, n in sorted(scored)[: self.starts]]
            else:
                order = sorted(range(len(points)), key=lambda n: self._violation(points[n], k))
                starts = [points[n].p for n in order[: self.starts]]
            found = self._confirm(
                space,
                self.minimise(space, merit, starts),
                lambda pt: -after(pt) - self.tol if self._violation(pt, k) == 0.0 else -math.inf,
                threshold=0.0,
            )
            if found is not None and after(found) >= -self.tol:
                found = None
        if found is None:
            return []
        x, m, v = self._post(t, found)
        inv_after = self.o.invariant(target, x, v, m)
        values = {f"guard {t.name}": found.raw[k]}
        if self.o.invariants[q] is not None:
            values[f"invariant {q}"] = found.inv
        values[f"invariant {target} after {t.name}"] = inv_after
        values.update({f"post {n}": c for n, c in zip(self.o.coords, x)})
        values.update({f"post memory {n}": c for n, c in m.items() if found.m.get(n) != c})
        post = self.o.where(x, m)
        return [
            Finding(
                kind="reset_outside_invariant",
                severity=KIND_SEVERITY["reset_outside_invariant"],
                message=(
                    f"transition {t.name!r} ({q} -> {target}): from {self.o.where(found.x, found.m)} "
                    f"(guard = {format_g(found.raw[k])}"
                    + (f", invariant of {q!r} = {format_g(found.inv)}" if self.o.invariants[q] is not None else "")
                    + f"{_crossing_note((t,))}) the jump lands at {post} where the invariant of {target!r} is "
                    f"{format_g(inv_after)} < -tol = {-self.tol:g}; fix the reset or the target invariant"
                ),
                modes=(q, target),
                transitions=(t.name,),
                witness=self.witness(found, values),
            )
        ]

    def _chain(
        self, t: Transition, pt: _Point, limit: int
    ) -> tuple[list[Transition], float | None, float, dict[str, float]]:
        """Fire ``t`` at ``pt``, then the rest of the instant by :func:`hybrid.instant.settle_instant`.

        The instant after ``t`` is the executors' (level-triggered guards, ties
        resolved by declaration order, at most ``limit`` further jumps); it
        stops when ``t`` wins again.  Returns the chain fired after ``t``, the
        guard of ``t`` when it fires again (``None`` if it does not), a
        closeness (``<= 0`` when the chain re-fires ``t``) and the post-jump
        values for the witness.
        """
        x, m, _ = self._post(t, pt)
        post_values = {f"post {n}": c for n, c in zip(self.o.coords, x)}
        current = [x]

        def signals(_mode: str, state: tuple[float, ...]) -> tuple[float, ...]:
            return self.o.signals(state, m)

        def guard(u: Transition, v: Sequence[float], mm: Mapping[str, float]) -> float:
            return self.o.guard(u, current[0], v, mm)

        def fire(u: Transition, state: tuple[float, ...], v: Sequence[float], mm: Mapping[str, float]
                 ) -> tuple[tuple[float, ...], dict[str, float]]:
            post = self.o.jump(u, state, v, mm)
            current[0] = post[0]
            return post

        instant = settle_instant(self.o.outgoing, t.target, x, m, signals=signals, guard=guard, fire=fire,
                                 ties="record", max_jumps=limit, stop_before=t)
        chain = [step.transition for step in instant.jumps]
        q, x, m = instant.mode, instant.state, instant.memory
        v = self.o.signals(x, m)
        if instant.stopped:
            again = self.o.guard(t, x, v, m)
            return chain, again, -again, post_values
        if instant.zeno is not None:
            return chain, None, 3.0, post_values
        guards = {u.name: self.o.guard(u, x, v, m) for u in self.o.outgoing[q] if u.direction == 0}
        if q == t.source:
            closeness = -guards[t.name]
        else:
            back = [-guards[u.name] for u in self.o.outgoing[q] if u.direction == 0 and u.target == t.source]
            rest = [-g for g in guards.values()]
            closeness = min(back) if back else (1.0 + min(rest) if rest else 2.0)
        return chain, None, closeness, post_values

    def _retriggers(self, space: SearchSpace, t: Transition, k: int, pt: _Point, limit: int) -> bool:
        return self._violation(pt, k) == 0.0 and self._chain(t, pt, limit)[1] is not None

    def _isolated_exception(self, space: SearchSpace, t: Transition, k: int, pt: _Point, limit: int) -> _Point | None:
        """A guard state next to ``pt`` (one coordinate moved by ``RETRIGGER_PROBE`` of its width) that
        does *not* re-trigger, or ``None`` if every such neighbour in the guard set re-triggers too."""
        for i in space.free:
            step = RETRIGGER_PROBE * (space.upper[i] - space.lower[i])
            for sign in (-1.0, 1.0):
                p = pt.p.copy()
                p[i] = min(max(p[i] + sign * step, space.lower[i]), space.upper[i])
                if p[i] == pt.p[i]:
                    continue
                near = self.point(space, p)
                if self._violation(near, k) == 0.0 and self._chain(t, near, limit)[1] is None:
                    return near
        return None

    def reset_retriggers(self, space: SearchSpace, points: list[_Point], t: Transition) -> list[Finding]:
        if t.direction != 0:
            return []
        q = space.mode
        k = self.o.outgoing[q].index(t)
        limit = MAX_JUMPS_PER_INSTANT - 1  # t itself is the instant's first jump
        feasible = [pt for pt in points if self._violation(pt, k) == 0.0]
        runs = [self._chain(t, pt, limit) for pt in feasible]
        again = {n: r[1] for n, r in enumerate(runs) if r[1] is not None}
        hits = sorted(again, key=lambda n: (-again[n], n))  # deepest re-fire first
        candidates = [feasible[n] for n in hits[: max(self.starts, 1)]]
        if not candidates:

            def merit(p: np.ndarray) -> float:
                pt = self.point(space, p)
                violation = self._violation(pt, k)
                if violation > 0.0:
                    return _INFEASIBLE + _squash(violation)
                return _squash(self._chain(t, pt, limit)[2])

            if feasible:
                order = sorted(range(len(feasible)), key=lambda n: runs[n][2])[: self.starts]
                starts = [feasible[n].p for n in order]
            else:
                order = sorted(range(len(points)), key=lambda n: self._violation(points[n], k))[: self.starts]
                starts = [points[n].p for n in order]
            for p in self.minimise(space, merit, starts):
                for r in space.snapped(p):
                    pt = self.point(space, r)
                    if self._retriggers(space, t, k, pt, limit):
                        candidates.append(pt)
                        break
        if not candidates:
            return []
        # A re-triggering state whose neighbours in the guard set do not re-trigger is a point of measure
        # zero in the guard set (the rest state of a bouncing ball, the corner of the water tanks): a Zeno
        # point of the physics, reported as info.  Otherwise the reset re-triggers on a whole region.
        exception: _Point | None = None
        found = candidates[0]
        for pt in candidates:
            exception = self._isolated_exception(space, t, k, pt, limit)
            if exception is None:
                found = pt
                break
        chain, again, _, post_values = self._chain(t, found, limit)
        assert again is not None
        path = [t.name] + [u.name for u in chain] + [t.name]
        values = {f"guard {t.name}": found.raw[k]}
        if self.o.invariants[q] is not None:
            values[f"invariant {q}"] = found.inv
        values.update(post_values)
        values[f"guard {t.name} after {' -> '.join(path[:-1])}"] = again
        modes = [q] + [u.target for u in [t, *chain]]
        fires = (
            f"transition {t.name!r} ({q} -> {t.target}) fires again at the same instant: from "
            f"{self.o.where(found.x, found.m)} (guard = {format_g(found.raw[k])}) the jumps "
            f"{' -> '.join(path)} are all enabled, the last with guard {t.name} = {format_g(again)} >= 0"
        )
        if exception is None:
            kind = "reset_retriggers"
            message = (
                f"{fires}; make the reset leave the guard set, add hysteresis or a dwell time, or make the "
                "guard crossing-triggered (direction=+1/-1)"
            )
        else:
            kind = "zeno_point"
            message = (
                f"{fires}, but only on a part of its guard set of measure zero: the neighbouring guard state "
                f"{self.o.where(exception.x, exception.m)} does not re-trigger.  A Zeno point of the dynamics "
                "(e.g. a bouncing ball at rest), not a modelling defect; executions that reach it need Zeno "
                "handling"
            )
        return [
            Finding(
                kind=kind,
                severity=KIND_SEVERITY[kind],
                message=message,
                modes=tuple(modes),
                transitions=tuple(path),
                witness=self.witness(found, values),
            )
        ]
