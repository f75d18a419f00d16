"""Time steps per mode chosen from the dynamics, for a verdict run without step options.

The flowpipe's series needs ``‖A_aug‖∞ δ <= 4`` in every mode (``A_aug = [[A, c/s], [0, 0]]``, ``s >= max|c|``, so
``‖A_aug‖∞ <= max_i Σ_j |a_ij| + 1``); the window's end / 1000 (the default step) breaks it in fast modes (the
spacecraft's attempt mode ``P3``, the 48-state building), and the run was refused.  A step only changes the
precision of a sound flowpipe, never its soundness, so a verdict may choose it: each affine mode whose
``(max_i Σ_j |a_ij| + 1)·δ`` exceeds ``κ`` gets the step ``κ / (max_i Σ_j |a_ij| + 1)`` (``mode_time_steps``), for
``κ`` in :data:`AUTO_NORM_STEPS` in turn, the next only when the previous choice did not prove the requirement and
re-check it.  A choice needing more than :data:`AUTO_MAX_STEPS` steps in one flowpipe is not tried (time), and a
run of more than half the verdict's segment bound stores merged segments (``merge_segments``, about
:data:`AUTO_STORED` stored boxes per flowpipe).  Modes given in ``mode_time_steps`` by the caller keep their steps;
nonlinear modes keep theirs (their linearisation names the step to lower).  With the whole ladder (no step options
given), steps chosen for some mode and transitions in the model, a last choice adds ``jump_cluster``
(:data:`AUTO_JUMP_CLUSTER`) to the finest steps unless the caller gave one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["AUTO_NORM_STEPS", "AUTO_MAX_STEPS", "AUTO_STORED", "AUTO_JUMP_CLUSTER", "mode_norms", "auto_options",
           "auto_choices", "chosen_text", "AUTO_INPUT_STEPS"]

AUTO_NORM_STEPS = (3.9, 0.4)
"""The bounds ``κ`` of ``‖A_aug‖∞ δ`` tried in turn (below the series' 4; then a step ten times finer)."""
AUTO_INPUT_STEPS = (3.9, 0.4, 0.1)
"""The bounds ``κ`` tried in turn for a model with bounded non-deterministic inputs (``ẋ = Ax + c + Bu``).

The input's spread entered each step as ``V = δ B U₀ ⊕ box(S |B U₀|)``, ``S = Σ_{k>=1} |A|^k δ^{k+1}/(k+1)!``: for
a stable scalar mode ``ẋ = −a x + u`` that is ``δ (e^κ − 1)/κ`` per unit of input against the exact
``δ (1 − e^{−κ})/κ``, ``κ = aδ``, the factor ``e^κ`` (49 at ``κ = 3.9``).  The one-step input set is now computed
through sub-steps (:mod:`analysis.reach.input_step`, within about 10 % of the reach set at any ``κ``); the third,
finer choice (within :data:`AUTO_MAX_STEPS`) is kept for what the finer step does to the rest of the flowpipe."""
AUTO_MAX_STEPS = 100_000
"""A choice whose smallest step needs more steps than this over the window is not tried."""
AUTO_STORED = 2_000
"""About this many stored segments per flowpipe when a run is merged."""
AUTO_JUMP_CLUSTER = 25
"""The last choice of a model with transitions (no step options given): the jump sets cut into runs of at most
this many steps (``jump_cluster``), so a long stretch of guard-meeting steps does not start one flowpipe over its
whole time interval (the spacecraft SRA02's passive mode)."""


def mode_norms(model: Any) -> dict[str, float]:
    """``{mode: max_i Σ_j |a_ij| + 1}`` (an upper bound of ``‖A_aug‖∞``) for every affine mode, rounded up."""
    out = {}
    for name, mode in model.modes.items():
        if getattr(mode, "smooth", None) is not None or mode.a is None:
            continue
        rows = [sum((abs(q) for q in row), 0) for row in mode.a]
        out[name] = math.nextafter(float(max(rows, default=0) + 1), math.inf)
    return out


def auto_options(model: Any, end: float, step: float, engine: Mapping[str, Any], kappa: float,
                 segment_bound: int) -> dict[str, Any] | None:
    """The engine options of one choice ``κ`` (the caller's ``engine`` options kept); ``None`` when it needs more
    than :data:`AUTO_MAX_STEPS` steps.

    Parameters
    ----------
    model : AffineHybridModel
    end, step : float
        The window's end and the base step [s] (the model's time).
    engine : mapping
        The caller's options (``mode_time_steps`` entries win; a given ``merge_segments`` is kept).
    kappa : float
        The bound of ``‖A_aug‖∞ δ``.
    segment_bound : int
        The verdict's bound on stored segments.
    """
    given = dict(engine.get("mode_time_steps") or {})
    steps = dict(given)
    for mode, norm in mode_norms(model).items():
        if mode not in given and norm * step > kappa:
            steps[mode] = min(kappa / norm, end)
    smallest = min([step, *steps.values()])
    count = math.ceil(end / smallest)
    if count > AUTO_MAX_STEPS:
        return None
    out = dict(engine)
    if steps:
        out["mode_time_steps"] = steps
    if "merge_segments" not in engine and count > segment_bound // 2:
        out["merge_segments"] = math.ceil(count / AUTO_STORED)
    return out


def auto_choices(model: Any, end: float, step: float, engine: Mapping[str, Any], kappas: tuple[float, ...],
                 segment_bound: int) -> list[tuple[float, dict[str, Any]]]:
    """The choices ``(κ, options)`` to try in turn (see the module), without repeats."""
    out: list[tuple[float, dict[str, Any]]] = []
    for kappa in kappas:
        options = auto_options(model, end, step, engine, kappa, segment_bound)
        if options is not None and all(options != o for _, o in out):
            out.append((kappa, options))
    given = dict(engine.get("mode_time_steps") or {})
    chosen = bool(out) and any(m not in given for m in out[-1][1].get("mode_time_steps", {}))
    if len(kappas) > 1 and chosen and "jump_cluster" not in engine and getattr(model, "transitions", ()):
        kappa, last = out[-1]
        out.append((kappa, {**last, "jump_cluster": AUTO_JUMP_CLUSTER}))
    return out


def chosen_text(kappa: float | None, options: Mapping[str, Any], given: Mapping[str, Any] | None = None) -> str:
    """`` (steps chosen from the dynamics, ‖A‖·step <= κ: 'mode' δ s, ...[, jump_cluster n])``, or ``""`` when the
    choice chose no step (the modes in ``given["mode_time_steps"]`` and a given ``jump_cluster`` are the caller's)."""
    given = dict(given or {})
    mine = {k: v for k, v in dict(options.get("mode_time_steps") or {}).items()
            if k not in dict(given.get("mode_time_steps") or {})}
    if kappa is None or not mine:
        return ""
    text = ", ".join(f"{k!r} {v:.4g} s" for k, v in sorted(mine.items()))
    cut = f", jump_cluster {options['jump_cluster']}" if "jump_cluster" in options and "jump_cluster" not in given \
        else ""
    return f" (steps chosen from the dynamics, ‖A‖·step <= {kappa:g}: {text}{cut})"
