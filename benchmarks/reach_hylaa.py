"""Hylaa 2.0.2 on the affine instances of ``bench_reach.py`` (a peer, for the benchmark only).

The affine model read by :func:`analysis.reach.affine_model` (exact rationals, rounded to floats here) becomes a
Hylaa automaton: one Hylaa state more, the constant 1 (flow 0), carries the affine terms of flows and resets; each
mode's invariant (one polyhedron: Hylaa has no disjunctive invariants) and each guard polyhedron (one Hylaa
transition per disjunct) are copied; each unsafe set becomes transitions into a mode ``error`` from the modes it
concerns.  Hylaa reports ``has_concrete_error`` when a reachable state at a *step instant* meets an error guard
(its flowpipe is exact at the step instants, in floating point, and says nothing between them).

Hylaa needs ``swiglpk <= 5.0.10``: from 5.0.12 on, ``swiglpk.as_intArray`` fills the array from index 0, and
Hylaa's ``glp_set_mat_row`` calls then read the column index 0 ("column index out of range").  Install the peers
outside the project's environment (``pip install --no-deps --target DIR``) and put them on ``PYTHONPATH``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

__all__ = ["hylaa_available", "hylaa_run"]


def hylaa_available() -> str | None:
    """``None`` when Hylaa can run here, else why not (one line)."""
    try:
        import swiglpk

        import hylaa.core  # noqa: F401  (needs graphviz, matplotlib, scipy)
    except Exception as exc:  # any import failure: the peer is optional
        return f"Hylaa not importable: {type(exc).__name__}: {exc}"
    probe = swiglpk.as_intArray([7])
    if probe[1] != 7:
        version = getattr(swiglpk, "__version__", "?")
        return (f"swiglpk {version} fills as_intArray from index 0 (Hylaa needs the 1-based arrays of "
                "swiglpk <= 5.0.10: pip install --no-deps --target DIR swiglpk==5.0.10)")
    return None


def _rows(polyhedron: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    mat = np.array([[float(q) for q in h.normal] + [0.0] for h in polyhedron.halfspaces]).reshape(-1, n + 1)
    rhs = np.array([float(h.offset) for h in polyhedron.halfspaces])
    return mat, rhs


def _float_rows(polyhedron: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    mat = np.array([list(h.normal) + [0.0] for h in polyhedron]).reshape(-1, n + 1)
    rhs = np.array([h.offset for h in polyhedron])
    return mat, rhs


def _automaton(model: Any, unsafe: Any) -> tuple[Any, str | None]:
    from hylaa.hybrid_automaton import HybridAutomaton

    n = len(model.state_names)
    ha = HybridAutomaton(model.name)
    modes = {}
    for name, mode in model.modes.items():
        if len(mode.invariant) > 1:
            return None, f"mode {name!r} has a disjunctive invariant (Hylaa takes one polyhedron)"
        a = np.zeros((n + 1, n + 1))
        a[:n, :n] = [[float(q) for q in row] for row in mode.a]
        a[:n, n] = [float(q) for q in mode.c]
        m = ha.new_mode(name)
        m.set_dynamics(a)
        if mode.invariant and mode.invariant[0].halfspaces:
            m.set_invariant(*_rows(mode.invariant[0], n))
        modes[name] = m
    for t in model.transitions:
        reset = np.eye(n + 1)
        reset[:n, :n] = [[float(q) for q in row] for row in t.r_matrix]
        reset[:n, n] = [float(q) for q in t.r_offset]
        for poly in t.guard:
            tr = ha.new_transition(modes[t.source], modes[t.target], t.name)
            tr.set_guard(*_rows(poly, n))
            tr.set_reset(reset)
    error = ha.new_mode("error")
    for u in unsafe:
        for name in (u.modes or tuple(model.modes)):
            for poly in u.polyhedra:
                ha.new_transition(modes[name], error, f"unsafe {u.name}").set_guard(*_float_rows(poly, n))
    return ha, None


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """GLPK's C library prints its simplex log on file descriptor 1: silence it for the run."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def hylaa_run(system: Any, box: dict[str, tuple[float, float]], initial_mode: str | None, unsafe: Any,
              horizon: float, step: float) -> dict[str, Any]:
    """Hylaa's verdict (``"safe"``/``"unsafe"`` at its step instants) and its wall time [s], or why it did not run.

    Returns
    -------
    dict
        ``{"verdict", "seconds", "note"}`` (``verdict`` ``None`` when Hylaa could not run the instance).
    """
    why = hylaa_available()
    if why:
        return {"verdict": None, "seconds": None, "note": why}
    from hylaa import lputil
    from hylaa.core import Core
    from hylaa.settings import HylaaSettings, PlotSettings
    from hylaa.stateset import StateSet

    from analysis.reach import affine_model

    model = affine_model(system)
    start = time.perf_counter()
    ha, why = _automaton(model, unsafe)
    if ha is None:
        return {"verdict": None, "seconds": None, "note": why}
    mode = ha.modes[initial_mode or model.initial_mode]
    bounds = [tuple(map(float, box[s])) for s in model.state_names] + [(1.0, 1.0)]
    init = [StateSet(lputil.from_box(bounds, mode), mode)]
    settings = HylaaSettings(step, horizon)
    settings.plot.plot_mode = PlotSettings.PLOT_NONE
    settings.stdout = HylaaSettings.STDOUT_NONE
    try:
        with _quiet():
            result = Core(ha, settings).run(init)
    except Exception as exc:  # a peer's failure is reported, never hidden
        return {"verdict": None, "seconds": time.perf_counter() - start,
                "note": f"Hylaa failed: {type(exc).__name__}: {str(exc)[:120]}"}
    verdict = "unsafe" if result.has_concrete_error else "safe"
    return {"verdict": verdict, "seconds": time.perf_counter() - start,
            "note": f"Hylaa step {step:g} (exact at the step instants only)"}
