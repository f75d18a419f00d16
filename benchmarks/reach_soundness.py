"""Soundness benchmark of ``bench_reach.py``: executor runs inside the flowpipe, planted sets never proven.

* ``simulations_inside``: ``N`` seeded runs of :func:`hybrid.continuous.simulate_continuous` (scipy's RK45 at
  ``rtol = 1e-10``, ``atol = 1e-12``, events located to ``1e-12`` s) from the corners of the initial box and
  uniform points in it.  Every step point (both sides of every jump) must lie in a stored segment of its mode
  whose time interval holds its time.  Membership is tested with the segment's box and, on the zonotope, with
  the support in the directions of its generators and of 16 seeded random directions (for ``n <= 2``: every facet
  normal, so exact).  A point failing any test is outside (a real failure); for ``n > 2`` passing is a
  necessary condition only.  Tolerance ``1e-6·max(1, |x|)`` in state and ``1e-6`` s in time: the executor's error
  over these horizons is around ``1e-8`` relative.  ``closed_form=True``: the executor's closed form of affine modes
  (:mod:`hybrid.closed_form`: exact solution pieces, events located by the same rules to ``1e-12`` s) instead of
  RK45; a mode without one (``affine_flow`` gives ``None``) keeps RK45.  Long resumable runs:
  ``reach_soundness_long.py``.
* ``planted``: the instance's unsafe sets placed 0.01 inside the true reach set (closed forms) must never be
  proven; those placed 0.01 outside are reported (proven or not: precision, not soundness).
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

__all__ = ["simulations_inside", "planted", "starts", "run_points", "outside_points", "example"]

TOL = 1e-6


def _directions(z: Any, rng: np.random.Generator) -> np.ndarray:
    g = z.generators
    n = z.dimension
    if n == 1:
        return np.ones((1, 1))
    if n == 2:
        normals = np.vstack([np.vstack([-g[1], g[0]]).T, g.T])
    else:
        normals = np.vstack([g.T, rng.normal(size=(16, n))])
    norms = np.linalg.norm(normals, axis=1)
    return normals[norms > 0] / norms[norms > 0, None]


def _inside(segment: Any, points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    scale = TOL * np.maximum(1.0, np.abs(points))
    ok = np.all((points >= segment.lo - scale) & (points <= segment.hi + scale), axis=1)
    z = segment.zonotope
    d = _directions(z, rng)
    reach = np.abs(d @ z.generators).sum(axis=1)
    slack = (scale @ np.abs(d).T)
    return ok & np.all(np.abs((points - z.center) @ d.T) <= reach + slack, axis=1)


def starts(instance: Any, count: int, seed: int) -> np.ndarray:
    """The ``count`` seeded initial states, shape ``(max(count, 1), n)``: up to 16 corners of the initial box, then
    uniform points in it (run ``i`` is the same whatever ``count >= i`` or the chunking)."""
    names = instance.system.state_names
    lo = np.array([instance.box[s][0] for s in names], dtype=float)
    hi = np.array([instance.box[s][1] for s in names], dtype=float)
    rng = np.random.default_rng(seed)
    wide = [i for i in range(lo.size) if hi[i] > lo[i]]
    corners = []
    for bits in itertools.islice(itertools.product((0, 1), repeat=len(wide)), 16):
        c = lo.copy()
        for i, b in zip(wide, bits):
            c[i] = hi[i] if b else lo[i]
        corners.append(c)
    points = np.vstack([np.array(corners), rng.uniform(lo, hi, size=(max(count - len(corners), 0), lo.size))])
    return points[:max(count, 1)]


def run_points(instance: Any, initial: np.ndarray, closed_form: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step points (both sides of every jump) of one executor run per row of ``initial``: times ``(m,)`` [s],
    modes ``(m,)`` and states ``(m, n)``.  ``closed_form``: the executor's exact solution of affine modes
    (:mod:`hybrid.closed_form`, events located by the same rules to ``1e-12`` s) instead of RK45."""
    from hybrid.continuous import simulate_continuous

    times, modes, points = [], [], []
    kwargs = dict(instance.simulation)
    duration = kwargs.pop("duration")
    for x0 in initial:
        tr = simulate_continuous(instance.system, tuple(x0), duration=duration, rtol=1e-10, atol=1e-12,
                                 initial_mode=instance.initial_mode, closed_form=closed_form, **kwargs)
        times.append(np.asarray(tr.times))
        modes.extend(tr.modes)
        points.append(np.asarray(tr.states))
    return np.concatenate(times), np.array(modes), np.concatenate(points)


def outside_points(result: Any, times: np.ndarray, modes: np.ndarray, points: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray:
    """Indices of the points in no stored segment of their mode whose time interval holds their time."""
    covered = np.zeros(times.size, dtype=bool)
    order = np.argsort(times, kind="stable")
    t_sorted = times[order]
    for s in result.segments:
        a = np.searchsorted(t_sorted, s.t_lo - TOL, side="left")
        b = np.searchsorted(t_sorted, s.t_hi + TOL, side="right")
        rows = order[a:b]
        rows = rows[(modes[rows] == s.mode) & ~covered[rows]]
        if rows.size:
            covered[rows] = _inside(s, points[rows], rng)
    return np.nonzero(~covered)[0]


def example(times: np.ndarray, modes: np.ndarray, points: np.ndarray, missing: np.ndarray) -> dict[str, Any] | None:
    """The first point outside (``None`` when there is none)."""
    if not missing.size:
        return None
    i = int(missing[0])
    return {"t": float(times[i]), "mode": str(modes[i]), "x": [float(v) for v in points[i]]}


def simulations_inside(instance: Any, result: Any, count: int, seed: int = 0, closed_form: bool = False
                       ) -> dict[str, Any]:
    """Executor runs against the flowpipe: ``{"runs", "points", "outside", "example"}``."""
    initial = starts(instance, count, seed)
    times, modes, points = run_points(instance, initial, closed_form)
    missing = outside_points(result, times, modes, points, np.random.default_rng(seed + 1))
    return {"runs": int(len(initial)), "points": int(times.size), "outside": int(missing.size),
            "example": example(times, modes, points, missing)}


def planted(instance: Any, result: Any) -> dict[str, Any]:
    """The planted sets: ``{"inside_proven": [...], "outside_proven": k, "outside": m}`` (the first must be empty)."""
    complete = result.status == "complete"
    inside = [u.name for u in instance.planted_inside if complete and result.distance_to(u) > 0]
    outside = sum(1 for u in instance.planted_outside if complete and result.distance_to(u) > 0)
    return {"inside_proven": inside, "inside": len(instance.planted_inside), "outside_proven": outside,
            "outside": len(instance.planted_outside)}
