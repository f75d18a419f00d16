"""The searches behind :func:`analysis.verify.falsification.falsify`'s ``"guided"`` and ``"whitebox"`` methods.

Both work in unit coordinates ``u ∈ [-1, 1]^k`` on a :class:`analysis.verify.falsification.Search` (the budget,
the cache, the journal's evaluations) and share one design:

1. **Space-filling start**: a scrambled Sobol sequence (:func:`space_filling`, seeded by the search's
   seed) after the nominal point, in groups: the vertex of the box nearest the Sobol point
   (:func:`physical_vertex`: nearest in the parameters' values, so a folded coordinate, whose nominal
   value is an end of its interval, takes that end too), two **surrogate steps**, the point.  A
   surrogate step is a least-squares model of the robustness (linear, then with diagonal quadratic
   terms once there are enough points, weighted towards the lowest robustness seen) minimised over the
   box in closed form (it is separable), so that a violation at a face or corner of the box, where a
   monotone defect puts it, is tried after a handful of simulations.
2. **Adaptive allocation** (:func:`focus`): the budget goes in chunks to the requirement still holding
   whose lowest robustness is lowest relative to the spread of its values (robustness of different
   requirements has different units), with a bonus for a requirement whose lowest value fell in its
   last chunk (decreasing).
3. **Local search** on the chosen requirement: ``guided`` starts it after ``2 (k + 1)`` groups of the
   start and then alternates a chunk of it with one more group, until the start's share of the budget
   is spent.  A chunk is a local surrogate step (fitted to the points near the centre), ``k / 2``
   **coordinate moves** (a compass search: each coordinate has its own step, first the whole box so
   that the move ends on a face, its direction first where a local linear model descends; a failure
   turns the direction, a failure both ways halves the step; a folded coordinate moves in ``|u|``)
   and ``k`` steps of a (1+1) evolution strategy with the 1/5 success rule (step size adapted,
   isotropic in unit coordinates), restarted from the next space-filling point when its step has
   collapsed.  Many ARCH-COMP violations sit on faces of the box (full throttle, no brake on some
   segments) where an isotropic step arrives late.  ``whitebox`` runs the whole start first, then
   projected gradient descent with an Armijo backtracking line search, the gradient of the robustness
   by central finite differences (:func:`central_gradient`, ``2k`` simulations per gradient, one
   batch) and restarts the same way.  With the model's sensitivities (one simulation per gradient) it
   descends from the nominal point at once, and a descent that stalls (a zero gradient: a flat robustness;
   or no step decreased it) restarts with a group of the start at the next Sobol point (:func:`_restart_group`).

Every simulation evaluates every requirement, so points spent on one requirement serve the others,
and a violation of any requirement still holding is recorded at once.  The same seed gives the same
points in the same order (a resumed search reads them back from the cache).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.verify.falsification_book import BudgetExhausted, Evaluation, Search, unit_key

__all__ = ["START_SHARE", "space_filling", "surrogate_minimum", "folded", "physical_vertex", "focus",
           "central_gradient", "guided_search", "whitebox_search", "simulations_to_violation"]

START_SHARE = 0.25
"""The space-filling start of ``guided`` has ``max(2k + 2, START_SHARE * budget / 2)`` Sobol points, each with its
vertex and two surrogate steps (up to four simulations a point); ``whitebox``'s ``max(k + 1, START_SHARE *
budget / 4)``."""

_FINITE = 1e300
_SIGMA0 = 0.3
"""Initial step of the local search, in unit coordinates."""
_SIGMA_MIN = 2e-3
"""A local search whose step fell below this restarts from a new space-filling point."""
_FACE_SHARE = 0.5
"""Coordinate moves per chunk of ``guided``'s local search, per coordinate of the box (at least 2)."""
_FIRST_GROUPS = 2
"""``guided`` starts its local search after ``_FIRST_GROUPS * (k + 1)`` groups of the space-filling start (then
alternates a chunk of local search and a group)."""
_FD_STEP = 2e-3
"""Step of the central differences in unit coordinates."""


def space_filling(dimension: int, count: int, seed: int, skip: int = 0) -> np.ndarray:
    """Points ``skip .. skip + count - 1`` of a scrambled Sobol sequence in ``[-1, 1]^dimension``, shape
    ``(count, dimension)``; the scrambling depends only on ``seed``."""
    from scipy.stats import qmc

    if count <= 0 or dimension == 0:
        return np.zeros((max(count, 0), dimension))
    sobol = qmc.Sobol(d=dimension, scramble=True, seed=np.random.default_rng([int(seed), 7001]))
    total = 1 << max(1, int(math.ceil(math.log2(skip + count))))
    points = sobol.random_base2(int(math.log2(total)))[skip:skip + count]
    return points * 2.0 - 1.0


def _rho(e: Evaluation, r: int) -> float | None:
    if not e.outcome.evaluated:
        return None
    value = e.outcome.robustness[r]
    return _FINITE if math.isnan(value) else max(-_FINITE, min(_FINITE, value))


def _data(search: Search, r: int, center: np.ndarray | None = None, radius: float = math.inf
          ) -> tuple[np.ndarray, np.ndarray]:
    """Evaluated points ``(n, k)`` and their finite robustness ``(n,)`` of requirement ``r`` (within
    ``radius`` of ``center`` in the max norm when given)."""
    xs, ys = [], []
    for e in search.evaluations:
        y = _rho(e, r)
        if y is None or abs(y) >= _FINITE:
            continue
        x = np.array(e.unit)
        if center is not None and np.max(np.abs(x - center)) > radius:
            continue
        xs.append(x)
        ys.append(y)
    k = search.problem.dimension
    return np.array(xs).reshape(-1, k), np.array(ys)


def surrogate_minimum(xs: np.ndarray, ys: np.ndarray, low: np.ndarray | None = None,
                      high: np.ndarray | None = None, alternatives: bool = False) -> Any:
    """The minimiser over the box ``[low, high]`` (default ``[-1, 1]^k``) of a least-squares model of
    ``ys`` (shape ``(n,)``) at ``xs`` (shape ``(n, k)``).

    Fewer than ``2k + 2`` points: a linear model, its slope the minimum-norm solution (with the mean
    removed: two points give the line through them, so a point worse than the nominal sends the next one
    to the opposite vertex); the minimiser is a vertex of the box (a zero slope keeps the lowest point's
    coordinate).  From ``2k + 2`` points: diagonal quadratic terms too, centred at the lowest point and
    weighted by rank (the lowest robustness counts most).  The model is separable, so its minimum over
    the box is exact, coordinate by coordinate.  ``None`` with fewer than two points or a flat model.
    With ``alternatives``, a list: the minimiser, then the points that move one coordinate to its
    runner-up value, cheapest in the model first (where to go when the minimiser was simulated already).
    """
    n, k = xs.shape
    if n < 2 or k == 0:
        return None
    low = -np.ones(k) if low is None else low
    high = np.ones(k) if high is None else high
    center = xs[int(np.argmin(ys))]
    if n < 2 * k + 2:
        g, *_ = np.linalg.lstsq(xs - xs.mean(axis=0), ys - ys.mean(), rcond=None)
        h = np.zeros(k)
    else:
        d = xs - center
        design = np.array([np.ones(n), *d.T, *(d.T ** 2)]).T
        ranks = np.argsort(np.argsort(ys, kind="stable"), kind="stable")
        w = np.sqrt(1.0 / (1.0 + ranks / max(1.0, n / 4.0)))
        coef, *_ = np.linalg.lstsq(design * w[:, None], (ys - ys.min()) * w, rcond=None)
        g, h = coef[1:k + 1], coef[k + 1:]
    scale = float(np.max(np.abs(g), initial=0.0))
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))) or (scale == 0.0 and np.max(h, initial=0.0) <= 0):
        return None
    g = np.where(np.abs(g) <= 1e-9 * scale, 0.0, g)
    lo, hi = low - center, high - center
    step = np.zeros(k)
    second = []
    for i in range(k):
        ends = [0.0, lo[i], hi[i]]
        if h[i] > 0:
            ends.append(float(np.clip(-g[i] / (2 * h[i]), lo[i], hi[i])))
        ranked = sorted(ends, key=lambda s: (g[i] * s + h[i] * s * s, abs(s)))
        step[i] = ranked[0]
        other = [e for e in ranked if abs(e - ranked[0]) > 1e-12 and e != 0.0]
        if other:  # the runner-up value of this coordinate and what it costs in the model
            second.append((g[i] * (other[0] - ranked[0]) + h[i] * (other[0] ** 2 - ranked[0] ** 2), i, other[0]))
    best = np.clip(center + step, low, high)
    if not alternatives:
        return best
    out = [best]
    for _, i, value in sorted(second):
        alt = step.copy()
        alt[i] = value
        out.append(np.clip(center + alt, low, high))
    return out


@dataclass
class _Book:
    """Per-requirement state of the allocation: lowest robustness at its last choice, the local search."""

    last_best: float = math.inf
    center: tuple[float, ...] | None = None
    sigma: float = _SIGMA0
    fails: int = 0
    deltas: np.ndarray | None = None
    directions: np.ndarray | None = None
    flipped: np.ndarray | None = None
    cursor: int = 0
    fold: np.ndarray | None = None
    stalled: bool = False


def focus(search: Search, open_: Sequence[int], books: dict[int, _Book]) -> int:
    """The requirement to spend the next chunk on: lowest ``(best - 0) / spread``, minus its last fall."""
    best_score, chosen = math.inf, open_[0]
    for r in open_:
        _, ys = _data(search, r)
        if ys.size == 0:
            continue
        best = float(ys.min())
        spread = max(float(np.std(ys)), 1e-9 * max(1.0, abs(best)))
        fall = books[r].last_best - best if math.isfinite(books[r].last_best) else 0.0
        score = best / spread - 0.5 * fall / spread
        if score < best_score:
            best_score, chosen = score, r
    return chosen


def _record(search: Search, falsified: dict, how: str) -> None:
    for r in range(len(search.problem.requirements)):
        if r not in falsified:
            hits = search.violated(r)
            if hits:
                worst = min(hits, key=lambda e: e.outcome.robustness[r])
                falsified[r] = (worst.unit, how)


def _open(search: Search, falsified: dict) -> list[int]:
    return [r for r in range(len(search.problem.requirements)) if r not in falsified]


def _try(search: Search, x: np.ndarray, phase: str, falsified: dict, how: str) -> Evaluation:
    """Simulate ``x`` clipped to the box (a point already seen comes from the cache, free); record any
    violation it shows."""
    e = search.run(tuple(float(u) for u in np.clip(x, -1.0, 1.0)), phase)
    _record(search, falsified, how)
    return e


def _surrogate_step(search: Search, falsified: dict, books: dict[int, _Book], how: str) -> None:
    """Simulate the minimiser of the global surrogate of the requirement :func:`focus` picks."""
    open_ = _open(search, falsified)
    if open_:
        r = focus(search, open_, books)
        for proposal in surrogate_minimum(*_data(search, r), alternatives=True) or ():
            key = tuple(float(u) for u in proposal)
            if unit_key(key) not in search.seen:
                _try(search, proposal, "surrogate", falsified, how)
                return


def _start(search: Search, seed: int, falsified: dict, count: int, how: str) -> int:
    """The space-filling start: for each of ``count`` Sobol points, the vertex of its orthant, two surrogate
    steps (for the requirement :func:`focus` picks), the point.  Returns the Sobol points used."""
    k = search.problem.dimension
    design = space_filling(k, count, seed)
    used = 0
    books = {r: _Book() for r in range(len(search.problem.requirements))}
    for i in range(count):
        if not _open(search, falsified):
            break
        # the vertex of the point's orthant first (defects sit at the box's extremes; the Sobol points'
        # orthants are stratified, so the vertices are too), a surrogate step, then the point itself
        _try(search, np.where(design[i] >= 0.0, 1.0, -1.0), "start", falsified, how)
        used += 1
        _surrogate_step(search, falsified, books, how)
        _surrogate_step(search, falsified, books, how)
        if _open(search, falsified):
            _try(search, design[i], "start", falsified, how)
    return used


def _coordinates(search: Search, r: int, book: _Book, x: np.ndarray, count: int) -> list[int]:
    """The next ``count`` coordinates of the compass search (round robin over those whose step is not spent).

    Each coordinate has its own step (first 2: the whole box, so the move ends on a face) and direction
    (first where a least-squares plane through the ``4k + 2`` points nearest ``x`` descends, a folded
    coordinate read as ``|u|``); a failed move turns the direction, a failure both ways halves the step."""
    k = x.size
    if book.deltas is None:
        xs, ys = _data(search, r)
        near = np.argsort(np.max(np.abs(xs - x), axis=1), kind="stable")[:4 * k + 2] if len(xs) else []
        book.fold = folded(search.problem)
        g = np.zeros(k)
        if len(near) >= 2:
            zs = np.where(book.fold, np.abs(xs[near]), xs[near])  # a folded coordinate's value grows with |u|
            g, *_ = np.linalg.lstsq(zs - zs.mean(axis=0), ys[near] - ys[near].mean(), rcond=None)
        book.deltas, book.flipped = np.full(k, 2.0), np.zeros(k, dtype=bool)
        book.directions = np.where(np.isfinite(g) & (g > 0), -1.0, 1.0)
    out: list[int] = []
    for _ in range(k):
        if len(out) == count:
            break
        i = book.cursor % k
        book.cursor += 1
        if book.deltas[i] >= _SIGMA_MIN:
            out.append(i)
    return out


def folded(problem: Any) -> np.ndarray:
    """Which coordinates are folded, shape ``(k,)``: a parameter whose nominal value is an end of its interval
    maps ``u`` and ``-u`` to the same value (:meth:`~analysis.verify.verification.Parameter.at`), so its low end
    is ``u = 0`` and ``u = ±1`` is its high end."""
    return np.array([p.high > p.low and (p.nominal == p.low or p.nominal == p.high) for p in problem.parameters],
                    dtype=bool)


def physical_vertex(point: np.ndarray, fold: np.ndarray) -> np.ndarray:
    """The vertex of the box (in the parameters' values) nearest ``point`` (shape ``(k,)``), in unit coordinates:
    ``±1`` by the sign of a coordinate, and for a folded one (:func:`folded`) ``0`` (its nominal end) when
    ``|u| < 1/2``, its sign otherwise."""
    signs = np.where(point >= 0.0, 1.0, -1.0)
    return np.where(fold, np.where(np.abs(point) < 0.5, 0.0, signs), signs)


def _coordinate_move(book: _Book, x: np.ndarray, i: int) -> np.ndarray:
    """``x`` with coordinate ``i`` moved by its step in its direction, clipped to the box; a folded coordinate
    moves in ``|u|`` (its value is monotone in ``|u|``), keeping its sign."""
    y = x.copy()
    if book.fold is not None and book.fold[i]:
        sign = -1.0 if x[i] < 0 else 1.0
        y[i] = sign * float(np.clip(abs(x[i]) + book.directions[i] * book.deltas[i], 0.0, 1.0))
    else:
        y[i] = float(np.clip(x[i] + book.directions[i] * book.deltas[i], -1.0, 1.0))
    return y


def _coordinate_outcome(book: _Book, i: int, better: bool) -> None:
    """Update coordinate ``i``'s step and direction after its move (success: kept; failure: turn, then halve)."""
    if better:
        book.flipped[i] = False
    elif not book.flipped[i]:
        book.directions[i], book.flipped[i] = -book.directions[i], True
    else:
        book.deltas[i], book.flipped[i] = book.deltas[i] / 2.0, False


def _es_chunk(search: Search, r: int, book: _Book, rng: np.random.Generator, falsified: dict, chunk: int,
              restart: np.ndarray, faces: int = 0) -> bool:
    """``chunk`` steps of the (1+1)-ES on requirement ``r``; a local surrogate step first, then ``faces`` moves
    of single coordinates (the compass search of :func:`_coordinates`, towards the faces of the box).  Returns
    whether the step collapsed and ``restart`` was taken as the new centre."""
    k = search.problem.dimension
    if book.center is None:
        best = search.lowest(r)
        book.center = best.unit if best is not None else (0.0,) * k
    x = np.array(book.center)
    fx = _rho(search.evaluations[search.seen[book.center]], r) if book.center in search.seen else None
    xs, ys = _data(search, r, x, 2.0 * book.sigma)
    proposal = surrogate_minimum(xs, ys, np.maximum(x - 2 * book.sigma, -1.0), np.minimum(x + 2 * book.sigma, 1.0))
    candidates = [("surrogate", proposal)] if proposal is not None else []
    if faces:
        candidates.extend(("face", i) for i in _coordinates(search, r, book, x, faces))
    candidates.extend(("step", None) for _ in range(chunk))
    for kind, y in candidates:
        if r in falsified:
            return False
        if kind == "face":  # a move of one coordinate by its own step, towards a face
            i, y = y, _coordinate_move(book, x, y)
        elif y is None:  # a step of the (1+1)-ES from the current centre, with the current step size
            y = x + book.sigma * rng.standard_normal(k)
        e = _try(search, y, "local", falsified, "local search")
        fy = _rho(e, r)
        better = fy is not None and (fx is None or fy < fx)
        if better:
            x, fx = np.array(e.unit), fy
        if kind == "face":  # a coordinate move says nothing about the step size of the ES
            _coordinate_outcome(book, i, better)
        elif better:
            book.sigma = min(1.0, book.sigma * 1.5)
        else:
            book.sigma *= 0.9
    book.center = tuple(float(v) for v in x)
    if book.sigma < _SIGMA_MIN:
        book.center, book.sigma, book.deltas = tuple(float(v) for v in restart), _SIGMA0, None
        return True
    return False


def _allocate(search: Search, seed: int, falsified: dict, step: str, skip: int) -> None:
    """Chunks of local search until the budget is spent or every requirement is falsified."""
    k = search.problem.dimension
    books = {r: _Book() for r in range(len(search.problem.requirements))}
    rng = np.random.default_rng([int(seed), 7002])
    restarts = space_filling(k, 64, seed, skip) if k else np.zeros((0, 0))
    used_restarts = 0
    chunk = max(2, k)
    groups = {r: _Book() for r in range(len(search.problem.requirements))}
    while _open(search, falsified) and search.used < search.budget:
        open_ = _open(search, falsified)
        r = focus(search, open_, books)
        _, ys = _data(search, r)
        books[r].last_best = float(ys.min()) if ys.size else math.inf
        before = search.used
        restart = restarts[used_restarts % len(restarts)]
        if step == "es":
            collapsed = _es_chunk(search, r, books[r], rng, falsified, chunk, restart)
        else:
            collapsed = _descent_chunk(search, r, books[r], falsified, restart)
        if collapsed and books[r].stalled:  # a descent with sensitivities stalled: a group, not the bare point
            used_restarts += 1
            books[r].stalled = False
            _restart_group(search, r, books[r], restart, falsified, groups)
        elif collapsed:
            used_restarts += 1
            _try(search, restart, "start", falsified, "space-filling restart")
        if search.used == before and not collapsed:  # nothing new to simulate near this centre
            books[r].center, books[r].sigma = tuple(float(v) for v in restart), _SIGMA0
            used_restarts += 1
            _try(search, restart, "start", falsified, "space-filling restart")
            if used_restarts > 4 * len(restarts):
                return


def _group(search: Search, point: np.ndarray, falsified: dict, books: dict[int, _Book], how: str) -> None:
    """One group of the space-filling start: the vertex nearest ``point`` (:func:`physical_vertex`), two surrogate
    steps, the point."""
    _try(search, physical_vertex(point, folded(search.problem)), "start", falsified, how)
    _surrogate_step(search, falsified, books, how)
    _surrogate_step(search, falsified, books, how)
    if _open(search, falsified):
        _try(search, point, "start", falsified, how)


def _interleave(search: Search, seed: int, falsified: dict, design: np.ndarray, first: int, count: int) -> None:
    """After ``first`` groups of the start: chunks of local search on the requirement :func:`focus` picks, each
    followed by the next group of the start until ``count`` groups are done; a collapsed local search restarts
    from the next point of ``design``."""
    k = search.problem.dimension
    books = {r: _Book() for r in range(len(search.problem.requirements))}
    start_books = {r: _Book() for r in range(len(search.problem.requirements))}
    rng = np.random.default_rng([int(seed), 7002])
    cursor, chunk, restarts, faces = first, max(2, k), 0, max(2, round(_FACE_SHARE * k))
    while _open(search, falsified) and search.used < search.budget:
        r = focus(search, _open(search, falsified), books)
        _, ys = _data(search, r)
        books[r].last_best = float(ys.min()) if ys.size else math.inf
        before = search.used
        restart = design[cursor % len(design)]
        collapsed = _es_chunk(search, r, books[r], rng, falsified, chunk, restart, faces=faces)
        stuck = search.used == before and not collapsed  # nothing new to simulate near this centre
        if stuck:
            books[r].center, books[r].sigma, books[r].deltas = tuple(float(v) for v in restart), _SIGMA0, None
        if collapsed or stuck:
            cursor, restarts = cursor + 1, restarts + 1
            _try(search, restart, "start", falsified, "space-filling restart")
            if restarts > 4 * len(design):
                return
        if cursor < count and _open(search, falsified):
            _group(search, design[cursor], falsified, start_books, "space-filling start")
            cursor += 1


def guided_search(search: Search, seed: int, falsified: dict) -> None:
    """The ``guided`` method after the nominal point (module docstring); fills ``falsified``
    (requirement index -> (unit point, how found)).  Stops at the budget or when every requirement is
    falsified."""
    k = search.problem.dimension
    if k == 0 or not _open(search, falsified):
        return
    count = max(2 * k + 2, round(START_SHARE * search.budget / 2))
    first = min(count, _FIRST_GROUPS * (k + 1))
    design = space_filling(k, count + 64, seed)
    books = {r: _Book() for r in range(len(search.problem.requirements))}
    try:
        for i in range(first):
            if not _open(search, falsified):
                return
            _group(search, design[i], falsified, books, "space-filling start")
        _interleave(search, seed, falsified, design, first, count)
    except BudgetExhausted:
        pass


def central_gradient(search: Search, r: int, x: np.ndarray, step: float = _FD_STEP,
                     phase: str = "gradient") -> tuple[float | None, np.ndarray | None]:
    """Robustness of requirement ``r`` at ``x`` (shape ``(k,)``) and its gradient in unit coordinates
    (shape ``(k,)``) by central differences of half-width ``step`` (one-sided at a face of the box): the
    ``2k`` stencil points are one batch of simulations.  ``(None, None)`` when a stencil point was not
    evaluated (invalid, diverged, an error).  Raises :class:`BudgetExhausted` when the budget ends."""
    k = x.size
    base = search.run(tuple(float(v) for v in x), phase)
    f0 = _rho(base, r)
    if f0 is None:
        return None, None
    points = []
    for i in range(k):
        lo, hi = x.copy(), x.copy()
        lo[i], hi[i] = max(-1.0, x[i] - step), min(1.0, x[i] + step)
        points.append((lo, hi))
    g = np.zeros(k)
    for i, (lo, hi) in enumerate(points):
        e_lo, e_hi = (search.run(tuple(float(v) for v in p), phase) for p in (lo, hi))
        f_lo, f_hi = _rho(e_lo, r), _rho(e_hi, r)
        if f_lo is None or f_hi is None:
            return f0, None
        g[i] = (f_hi - f_lo) / (hi[i] - lo[i])
    return f0, g


def _descent_chunk(search: Search, r: int, book: _Book, falsified: dict, restart: np.ndarray) -> bool:
    """One projected-gradient step with Armijo backtracking on requirement ``r``.  Returns whether the
    descent stalled and ``restart`` was taken as the new centre."""
    from analysis.verify.falsification_gradient import (differentiate_restart, sensitivity_gradient,
                                                         simulate_with_gradient)

    k = search.problem.dimension
    if book.center is None:
        best = search.lowest(r)
        book.center = best.unit if best is not None else (0.0,) * k
    x = np.array(book.center)
    how = "gradient descent (central finite differences)"
    if search.problem.sensitivities is not None:  # the model's sensitivities: one simulation per gradient
        f0, g = sensitivity_gradient(search, r, x)
        how = "gradient descent (sensitivities)"
        _record(search, falsified, how)
        if g is None and f0 is not None and r not in falsified:  # none for this requirement: said in the journal
            f0, g = central_gradient(search, r, x)
            how = "gradient descent (central finite differences)"
    else:
        f0, g = central_gradient(search, r, x)
    _record(search, falsified, how)
    if r in falsified:
        return False
    norm = 0.0 if g is None else float(np.max(np.abs(g)))
    if f0 is None or g is None or not math.isfinite(norm) or norm == 0.0:
        book.center, book.sigma = tuple(float(v) for v in restart), _SIGMA0
        book.stalled = search.problem.sensitivities is not None  # the caller restarts with a group
        return differentiate_restart(search, restart) if not book.stalled else True
    direction = -g / norm
    alpha = book.sigma
    sens = how.endswith("(sensitivities)")
    vertex = sens  # first the box's vertex that minimises the linearisation (Frank-Wolfe)
    while alpha >= _SIGMA_MIN:
        y = np.clip(x - np.sign(g), -1.0, 1.0) if vertex else np.clip(x + alpha * direction, -1.0, 1.0)
        if sens:  # each trial with its sensitivities: the point accepted has its gradient for the next step
            e = simulate_with_gradient(search, y, "descent")
            _record(search, falsified, how)
        else:
            e = _try(search, y, "descent", falsified, how)
        fy = _rho(e, r)
        moved = float(np.dot(g, y - x))
        if fy is not None and fy <= f0 + 1e-4 * moved and np.any(y != x):
            book.center, book.sigma = tuple(float(v) for v in e.unit), min(1.0, 2.0 * alpha)
            return False
        if r in falsified:
            return False
        if vertex:
            vertex = False
            continue
        alpha *= 0.5
    book.center, book.sigma = tuple(float(v) for v in restart), _SIGMA0
    if sens:  # no step along a non-zero gradient decreased the robustness: the caller restarts with a group
        book.stalled = True
        return True
    return differentiate_restart(search, restart)


def _restart_group(search: Search, r: int, book: _Book, restart: np.ndarray, falsified: dict,
                   books: dict[int, _Book]) -> None:
    """Where a descent with the model's sensitivities stalled, a group of the space-filling start at ``restart``
    (shape ``(k,)``) instead of the bare point: the vertex of its orthant and the point, each simulated with its
    sensitivities, between them two surrogate steps (:func:`surrogate_minimum`, plain runs; the ``whitebox``
    start without sensitivities, :func:`_start`).  The descent goes on from the lowest of them for ``r``, a point
    with its gradient at a tie.

    A descent stalls where the gradient is zero (a flat robustness: discrete atoms, e.g. a gear, make it piecewise
    constant; the gradient says nothing, and the global surrogate of the values seen is the only guide) or where
    no step along it decreased the robustness (a local minimum; or the side of a ``min``/``max`` that decides
    switches from one iterate to the next, so the gradient of one side is undone by another)."""
    from analysis.verify.falsification_gradient import simulate_with_gradient

    how, first = "space-filling restart", search.used
    for kind in ("vertex", "surrogate", "surrogate", "point"):
        if not _open(search, falsified):
            return
        if kind == "surrogate":
            _surrogate_step(search, falsified, books, how)
            continue
        y = np.where(restart >= 0.0, 1.0, -1.0) if kind == "vertex" else restart
        simulate_with_gradient(search, y, "start")
        _record(search, falsified, how)
    fresh = [(f, e.unit not in search.differentiated, e.index) for e in search.evaluations[first:]
             if (f := _rho(e, r)) is not None]
    center = search.evaluations[min(fresh)[2]].unit if fresh else tuple(float(v) for v in np.clip(restart, -1, 1))
    book.center, book.sigma = tuple(float(v) for v in center), _SIGMA0


def whitebox_search(search: Search, seed: int, falsified: dict) -> None:
    """The ``whitebox`` method after the nominal point: the same space-filling start as ``guided``, then
    gradient descent on the robustness (module docstring), its gradients from the model's sensitivities when
    the problem gives them (:mod:`analysis.verify.falsification_gradient`, one simulation each), otherwise by
    :func:`central_gradient`."""
    k = search.problem.dimension
    if k == 0 or not _open(search, falsified):
        return
    count = max(k + 1, round(START_SHARE * search.budget / 4))
    if search.problem.sensitivities is not None:  # a gradient costs one simulation: descend from the nominal
        count = 0                                 # point at once, restarts from the Sobol points
    try:
        used = _start(search, seed, falsified, count, "space-filling start")
        _allocate(search, seed, falsified, "descent", used)
    except BudgetExhausted:
        pass


def simulations_to_violation(search: Search, requirement: int | None = None) -> int | None:
    """Simulations spent up to and including the first one that violates ``requirement`` (any requirement
    when ``None``); ``None`` when no simulation of the search violates it."""
    n = len(search.problem.requirements)
    wanted = range(n) if requirement is None else (requirement,)
    for e in search.evaluations:
        if any(e.violates(r) for r in wanted):
            return e.index + 1
    return None
