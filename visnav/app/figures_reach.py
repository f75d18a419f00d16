"""Figures of a reachability run (``visnav reach --out``): 2-D projections of the flowpipes.

Rendering code: it builds matplotlib figures (Agg backend, nothing shown) and returns them; the
command writes them (:func:`visnav.app.files.write_figures`).

:func:`sets_over_time`
    One state against time: each stored segment as the rectangle ``[t_lo, t_hi] × [lo_i, hi_i]``
    (its interval hull), coloured by mode.
:func:`phase_plane`
    Two states: each segment's zonotope projected onto them (an exact convex polygon: the
    projection of a zonotope is the zonotope of the projected generators), coloured by mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

__all__ = ["sets_over_time", "phase_plane", "zonotope_polygon"]

MAX_DRAWN = 20_000
"""Segments drawn per figure at most (evenly thinned beyond: a figure, not a proof)."""


def zonotope_polygon(center: np.ndarray, generators: np.ndarray) -> np.ndarray:
    """The vertices, counter-clockwise, of the 2-D zonotope ``{c + G ξ : ‖ξ‖∞ <= 1}`` (shape ``(2·m, 2)``).

    Parameters
    ----------
    center : ndarray, shape (2,)
    generators : ndarray, shape (2, m)
    """
    g = np.asarray(generators, dtype=float).reshape(2, -1)
    g = g[:, np.any(g != 0.0, axis=0)]
    if g.shape[1] == 0:
        return np.asarray(center, dtype=float).reshape(1, 2)
    g = np.where(g[1] < 0, -g, g)  # every generator in the upper half-plane
    g = np.where((g[1] == 0) & (g[0] < 0), -g, g)
    g = g[:, np.argsort(np.arctan2(g[1], g[0]), kind="stable")]
    start = np.asarray(center, dtype=float) - g.sum(axis=1)
    steps = np.concatenate([2 * g.T, -2 * g.T])
    return start + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)[:-1]])


def _thinned(items: Sequence[Any]) -> Sequence[Any]:
    if len(items) <= MAX_DRAWN:
        return items
    keep = np.linspace(0, len(items) - 1, MAX_DRAWN).round().astype(int)
    return [items[i] for i in sorted(set(keep.tolist()))]


def _colours(modes: Sequence[str]) -> dict[str, Any]:
    import matplotlib.pyplot as plt

    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    return {m: cycle[i % len(cycle)] for i, m in enumerate(sorted(set(modes)))}


def sets_over_time(runs: Sequence[Any], state: str, title: str, time_label: str = "time t [s]") -> Any:
    """One state's reachable intervals over time (every start's flowpipe), as a matplotlib figure.

    Parameters
    ----------
    runs : sequence of (mode, box, ReachResult)
    state : str
        A name of the flowpipes' ``state_names``.
    """
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    segments = [s for _, _, r in runs for s in r.segments]
    i = runs[0][2].state_names.index(state)
    colours = _colours([s.mode for s in segments])
    fig, ax = plt.subplots(figsize=(8, 4))
    drawn = _thinned(segments)
    patches = [Rectangle((s.t_lo, float(s.lo[i])), max(s.t_hi - s.t_lo, 0.0), float(s.hi[i] - s.lo[i]))
               for s in drawn]
    ax.add_collection(PatchCollection(patches, facecolors=[colours[s.mode] for s in drawn], edgecolors="none",
                                      alpha=0.5))
    if segments:
        ax.set_xlim(min(s.t_lo for s in segments), max(s.t_hi for s in segments))
        low, high = min(float(s.lo[i]) for s in segments), max(float(s.hi[i]) for s in segments)
        pad = 0.05 * (high - low) or 0.5
        ax.set_ylim(low - pad, high + pad)
    for mode, colour in colours.items():
        ax.plot([], [], color=colour, linewidth=6, alpha=0.5, label=f"mode {mode}")
    ax.set_xlabel(time_label)
    ax.set_ylabel(state)
    ax.set_title(title)
    ax.legend(loc="best", fontsize="small")
    fig.tight_layout()
    return fig


def phase_plane(runs: Sequence[Any], x: str, y: str, title: str) -> Any:
    """The flowpipes projected onto the states ``x`` (horizontal) and ``y`` (vertical), as a figure."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    names = runs[0][2].state_names
    i, j = names.index(x), names.index(y)
    segments = [s for _, _, r in runs for s in r.segments]
    colours = _colours([s.mode for s in segments])
    drawn = _thinned(segments)
    polygons = []
    for s in drawn:
        z = s.zonotope
        poly = zonotope_polygon(z.center[[i, j]], z.generators[[i, j], :])
        lo = np.array([s.lo[i], s.lo[j]], dtype=float)
        hi = np.array([s.hi[i], s.hi[j]], dtype=float)
        polygons.append(np.clip(poly, lo, hi))  # the segment is zonotope ∩ box: clipped for the picture
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.add_collection(PolyCollection(polygons, facecolors=[colours[s.mode] for s in drawn], edgecolors="none",
                                     alpha=0.4))
    if segments:
        xs = [float(v) for s in segments for v in (s.lo[i], s.hi[i])]
        ys = [float(v) for s in segments for v in (s.lo[j], s.hi[j])]
        px, py = 0.05 * (max(xs) - min(xs)) or 0.5, 0.05 * (max(ys) - min(ys)) or 0.5
        ax.set_xlim(min(xs) - px, max(xs) + px)
        ax.set_ylim(min(ys) - py, max(ys) + py)
    for mode, colour in colours.items():
        ax.plot([], [], color=colour, linewidth=6, alpha=0.4, label=f"mode {mode}")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(title)
    ax.legend(loc="best", fontsize="small")
    fig.tight_layout()
    return fig
