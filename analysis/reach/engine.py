"""Bounded reachability of an affine hybrid system: flowpipes per mode, guards, jumps, invariants.

:func:`reach` reads the system exactly (:func:`analysis.reach.model.affine_model`), then
processes *flowpipes* breadth first: a flowpipe is a mode entered with a set (the initial set, or
the image of a jump) at a time interval.  Along it (:func:`analysis.reach.flowpipe.segments`)

* every segment is clipped to the mode's invariant (a state reached by flowing satisfies it);
  a segment proven outside the invariant ends the flowpipe (``"left_invariant"``);
* every outgoing transition whose guard the segment may meet collects the segment's box clipped
  to the guard; at the end the collected box (the hull over the flowpipe) is mapped by the jump
  map and starts a flowpipe in the target mode, unless the jump bound is reached — or, when at most
  :data:`~analysis.reach.jumpsets.JUMP_ZONOTOPES` segments met the guard, their guard parts kept as one
  zonotope (:mod:`analysis.reach.jumpsets`: the correlations of the states survive the jump);
* the flowpipe stops at the time horizon, or inconclusively when it blows up (a radius above
  ``size_limit``, a NaN or inf) or exceeds ``max_segments``.

Semantics (over-approximating the executor's urgent, priority-ordered semantics): a transition
may fire wherever its guard (its level set ``g >= 0``, also for crossing guards, which fire where
``g = 0``) meets the flowpipe, whatever the priorities; the flow may continue past an enabled
guard while the invariant may hold.  Both only add behaviours.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np


from .flowpipe import ModeDynamics, mode_dynamics, segments
from .initial import ReachError, initial_zonotope
from .jumpsets import (JUMP_ORDER, JUMP_ZONOTOPES, JumpFold, ResetImage, fold, meet_box, reduce_jump, reset_image,
                       strip_meet)
from .model import AffineHybridModel, AffineTransition, affine_model
from .nonlinear import ADAPTIVE_LEVELS, ADAPTIVE_RATIO, adaptive_segments, smooth_segments
from .result import ReachJump, ReachResult, ReachSegment, Termination
from .series import MAX_NORM_STEP
from .sets import (UnsafeSet, box_position, clip_box, definitely_outside, halfspace_rows, polyhedra_to_float,
                   tighten_box)
from .zonotope import Zonotope, from_box, interval_hull, linear_map, reduce_order, round_down, round_up, with_error

__all__ = ["ReachError", "ModeInput", "reach"]


ZONOTOPE_WIDER = 0.01
"""A zonotope jump set is used unless its image's box hull is wider than the box route's image in some coordinate by
more than this fraction of that coordinate's width (plus 10⁻¹²): the box route is then kept (a zonotope looser than
the box somewhere — an oblique guard, a reset that mixes coordinates — can lose more than its correlations give:
the gearbox GRBX01-MES01)."""

MAX_STORED_NUMBERS = 25_000_000
"""The stored segments hold at most this many floats (200 MB): memory stays bounded whatever the options."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModeInput:
    """A bounded non-deterministic input of one mode: the flow becomes ``ẋ = A x + c + B u``, ``u(t) ∈ U``.

    Attributes
    ----------
    matrix : array_like, shape (n, p)
        ``B``.
    bounds : Zonotope of dimension p, or pair of array_like of shape (p,)
        ``U``: a zonotope, or a box ``(lo, hi)``.
    """

    matrix: Any
    bounds: Any


@dataclass(slots=True)
class _Work:
    mode: str
    start: Zonotope  # state coordinates (n)
    t_lo: float
    t_hi: float
    jumps: int
    box: tuple[np.ndarray, np.ndarray] | None = None  # a box holding the start set too (a zonotope jump set's)
    saved: tuple[np.ndarray, np.ndarray] | None = None  # the entry segment's saved box (the jump's ``after``)


@dataclass(slots=True)
class _Run:
    model: AffineHybridModel
    step: float
    horizon: float
    max_jumps: int
    order: int
    stored_order: int
    size_limit: float
    max_segments: int
    mode_steps: Mapping[str, float]
    cluster: int | None
    merge: int
    adaptive: float  # the adaptive step's ratio in smooth modes (0: fixed steps)
    inputs: Mapping[str, tuple[list[list[Fraction]], Zonotope]]
    dynamics: dict[str, tuple[ModeDynamics, float]]
    segments: list[ReachSegment]
    jumps: list[ReachJump]
    terminations: list[Termination]
    stored: list[int]  # numbers held by the stored segments (one cell, mutable)


def reach(system: Any, initial: Any, *, horizon: float, time_step: float, initial_mode: str | None = None,
          max_jumps: int = 10, inputs: Mapping[str, ModeInput] | None = None, unsafe: Sequence[UnsafeSet] = (),
          order: int = 20, stored_order: int = 10, size_limit: float = 1e6, max_segments: int = 200_000,
          max_flowpipes: int = 1_000, mode_time_steps: Mapping[str, float] | None = None,
          jump_cluster: int | None = None, merge_segments: int = 1, adaptive_step: bool | float = False,
          progress: Callable[[float], None] | None = None) -> ReachResult:
    """An over-approximation of the states a symbolic hybrid system reaches.

    Parameters
    ----------
    system : hybrid.system.HybridSystem
        Symbolic; flows affine, or smooth (polynomials, sin, cos: conservative linearisation,
        :mod:`analysis.reach.nonlinear`); jump maps, guards, invariants and output affine.
    initial : Zonotope, mapping {state name: (lo, hi)}, array_like of shape (k, n), or symbolic condition
        The initial set: a zonotope, a box, a polytope given by its vertices, or a bounded polytope
        written as a conjunction of affine comparisons over the state names (both polytopes are
        enclosed in their bounding box, proven: :mod:`analysis.reach.initial`).
    horizon : float
        Time horizon ``T > 0`` [s].
    time_step : float
        ``0 < δ <= T`` [s].
    initial_mode : str or None
        Default: the automaton's initial mode.
    max_jumps : int
        Jump bound ``>= 0``.
    inputs : mapping {mode: ModeInput} or None
        Bounded non-deterministic inputs per mode (hybrid models have none; this adds them).
    unsafe : sequence of UnsafeSet
        Sets whose :meth:`~ReachResult.distance_to` is reported in the result.
    order, stored_order : int
        Zonotope order (generators per dimension) of the input sum and of the stored segments.
    size_limit : float
        A segment whose box radius exceeds this ends the run inconclusively (``"blow_up"``).
    max_segments, max_flowpipes : int
        Limits on the stored segments and on the flowpipes (memory and time are bounded).
    mode_time_steps : mapping {mode: float} or None
        A step [s] per mode, replacing ``time_step`` there (``0 < step <= horizon``): a fast mode needs a
        short step (the first segment's bloating grows with ``‖A‖·step``), a slow one does not.
    jump_cluster : int or None
        ``None`` (default): one jump per transition per flowpipe, from the box hull of every segment that
        may meet the guard.  ``k >= 1``: the segments meeting a guard are grouped into runs of at most
        ``k`` consecutive segments (a segment that does not meet it ends a run), and each run jumps on its
        own with its own box and time interval.  Smaller boxes, more flowpipes (``max_flowpipes``).
    merge_segments : int
        ``1`` (default): every flowed segment is stored (its zonotope reduced to ``stored_order``).
        ``m > 1``: each stored segment is the box hull of up to ``m`` consecutive flowed segments over
        the union of their times (the zonotope is that box): memory for long, high-dimensional runs.
        Guards, invariants and jumps still use every segment; only the stored result is coarser.
    adaptive_step : bool or float
        ``False`` (default): fixed steps.  ``True`` or a ratio ``r > 0``: in every nonlinear (smooth) mode the
        step is chosen per step as ``δ·2^j`` (``δ`` the mode's step, ``j`` in ``ADAPTIVE_LEVELS``) by the rule of
        :func:`analysis.reach.nonlinear.adaptive_segments` with the ratio ``r`` (``True``: ``ADAPTIVE_RATIO``);
        each segment saves its step.  Affine modes keep their fixed step.  Sound either way; faster where the
        set's remainder grows slowly with the step for part of the run (VDP), slower where it grows (LOVO).
    progress : callable or None
        ``progress(t)`` after each flowpipe, ``t`` [s] the latest time its segments reached so far.

    Returns
    -------
    ReachResult

    Raises
    ------
    ReachError
        An invalid parameter (naming it, its value, what was expected and the fix).
    analysis.reach.affine.AffineError
        The system is not symbolic, or a flow neither affine nor smooth, or another part not affine (naming it).
    """
    ratio = _adaptive_ratio(adaptive_step)
    _check_options(horizon, time_step, size_limit, jump_cluster,
                   (("max_jumps", max_jumps, 0), ("order", order, 2), ("stored_order", stored_order, 2),
                    ("merge_segments", merge_segments, 1), ("max_segments", max_segments, 1),
                    ("max_flowpipes", max_flowpipes, 1)))
    model = affine_model(system, nonlinear=True)
    steps = _mode_steps(mode_time_steps, model, float(horizon))
    mode = model.initial_mode if initial_mode is None else initial_mode
    if mode not in model.modes:
        raise ReachError("initial_mode", initial_mode, f"one of {list(model.modes)}", "name a mode of the automaton")
    start = initial_zonotope(initial, model.state_names)
    run = _Run(model=model, step=float(time_step), horizon=float(horizon), max_jumps=max_jumps, order=order,
               stored_order=stored_order, size_limit=float(size_limit), max_segments=max_segments,
               mode_steps=steps, cluster=jump_cluster, merge=merge_segments, adaptive=ratio,
               inputs=_inputs(inputs, model),
               dynamics={}, segments=[], jumps=[], terminations=[], stored=[0])
    _explore(run, _Work(mode=mode, start=start, t_lo=0.0, t_hi=0.0, jumps=0), max_flowpipes, progress)
    result = ReachResult(system=model.name, state_names=model.state_names, horizon=run.horizon,
                         max_jumps=max_jumps, time_step=run.step, segments=tuple(run.segments),
                         jumps=tuple(run.jumps), terminations=tuple(run.terminations))
    distances = tuple((u.name, result.distance_to(u)) for u in _unsafe(unsafe))
    return ReachResult(system=result.system, state_names=result.state_names, horizon=result.horizon,
                       max_jumps=max_jumps, time_step=result.time_step, segments=result.segments,
                       jumps=result.jumps, terminations=result.terminations, distances=distances,
                       inputs=_input_records(inputs, run.inputs), schedule=_schedule(mode_time_steps, jump_cluster))


def _schedule(steps: Mapping[str, float] | None, cluster: int | None) -> tuple[tuple[str, Any], ...]:
    """The options saved for the re-check's schedule (``()`` with the defaults: the JSON is then unchanged)."""
    out: list[tuple[str, Any]] = []
    if steps:
        out.append(("mode_time_steps", {k: float(v) for k, v in sorted(steps.items())}))
    if cluster is not None:
        out.append(("jump_cluster", int(cluster)))
    return tuple(out)


def _input_records(inputs: Mapping[str, ModeInput] | None, checked: Mapping[str, tuple[list[list[Fraction]], Zonotope]]
                   ) -> tuple[tuple[str, list[list[float]], list[float], list[float]], ...]:
    """``(mode, B, lo, hi)`` per mode with inputs (sorted): a box ``U`` as given, a zonotope as its hull."""
    out = []
    for mode in sorted(checked):
        b, u = checked[mode]
        given = dict(inputs or {})[mode].bounds
        if isinstance(given, Zonotope):
            lo, hi = interval_hull(u)
        else:
            lo, hi = (np.asarray(v, dtype=float).reshape(-1) for v in given)
        out.append((mode, [[float(v) for v in row] for row in b], [float(v) for v in lo], [float(v) for v in hi]))
    return tuple(out)


def _adaptive_ratio(value: Any) -> float:
    """The adaptive step's ratio of ``adaptive_step`` (0.0: fixed steps)."""
    if value is False:
        return 0.0
    if value is True:
        return ADAPTIVE_RATIO
    top = 2.0 ** ADAPTIVE_LEVELS[1]
    if isinstance(value, (int, float)) and not isinstance(value, bool) and 0 < value <= top:
        return float(value)
    raise ReachError("adaptive_step", value, f"False, True or a ratio 0 < r <= {top:g}",
                     "pass adaptive_step=True (the default ratio), a ratio such as 1.4, or False")


def _check_options(horizon: Any, time_step: Any, size_limit: Any, jump_cluster: Any,
                   counts: Sequence[tuple[str, Any, int]]) -> None:
    _check_number("horizon", horizon, lambda v: v > 0, "a finite time horizon > 0 [s]")
    _check_number("time_step", time_step, lambda v: 0 < v <= horizon,
                  f"a step 0 < time_step <= horizon = {horizon!r} [s]")
    for name, value, low in counts:
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ReachError(name, value, f"an int >= {low}", f"give {name} as a whole number >= {low}")
    _check_number("size_limit", size_limit, lambda v: v > 0, "a finite radius > 0")
    if jump_cluster is not None and (isinstance(jump_cluster, bool) or not isinstance(jump_cluster, int)
                                     or jump_cluster < 1):
        raise ReachError("jump_cluster", jump_cluster, "None or an int >= 1",
                         "give the number of consecutive segments per jump, or None for one jump per flowpipe")


def _check_number(name: str, value: Any, ok: Any, expected: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not math.isfinite(float(value)) or not ok(float(value)):
        raise ReachError(name, value, expected, f"give {name} as {expected}")


def _mode_steps(steps: Mapping[str, float] | None, model: AffineHybridModel, horizon: float) -> dict[str, float]:
    if steps is None:
        return {}
    if not isinstance(steps, Mapping):
        raise ReachError("mode_time_steps", steps, "a mapping {mode: step}", "key each step by the name of its mode")
    out = {}
    for mode, step in steps.items():
        if mode not in model.modes:
            raise ReachError("mode_time_steps", {mode: step}, f"modes among {list(model.modes)}",
                             "key each step by the name of its mode")
        _check_number(f"mode_time_steps[{mode!r}]", step, lambda v: 0 < v <= horizon,
                      f"a step 0 < step <= horizon = {horizon!r} [s]")
        out[mode] = float(step)
    return out


def _step(run: _Run, mode: str) -> float:
    return run.mode_steps.get(mode, run.step)


def _unsafe(unsafe: Sequence[UnsafeSet]) -> tuple[UnsafeSet, ...]:
    items = (unsafe,) if isinstance(unsafe, UnsafeSet) else tuple(unsafe)
    for u in items:
        if not isinstance(u, UnsafeSet):
            raise ReachError("unsafe", u, "UnsafeSet objects", "build them with analysis.reach.unsafe_set()")
    return items


def _inputs(inputs: Mapping[str, ModeInput] | None, model: AffineHybridModel
            ) -> dict[str, tuple[list[list[Fraction]], Zonotope]]:
    out = {}
    n = len(model.state_names)
    for mode, spec in dict(inputs or {}).items():
        if mode not in model.modes or not isinstance(spec, ModeInput):
            raise ReachError("inputs", {mode: spec}, f"{{mode: ModeInput}} with modes among {list(model.modes)}",
                             "key each ModeInput by the name of its mode")
        b = np.asarray(spec.matrix, dtype=float)
        if b.ndim != 2 or b.shape[0] != n or not np.all(np.isfinite(b)):
            raise ReachError(f"inputs[{mode!r}].matrix", spec.matrix, f"a finite array of shape ({n}, p)",
                             "give one row per state")
        u = spec.bounds
        if not isinstance(u, Zonotope):
            try:
                lo, hi = (np.asarray(v, dtype=float).reshape(-1) for v in u)
            except (TypeError, ValueError):
                raise ReachError(f"inputs[{mode!r}].bounds", u, "a Zonotope or (lo, hi)", "give a box") from None
            if lo.shape != hi.shape or not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)) \
                    or np.any(lo > hi):
                raise ReachError(f"inputs[{mode!r}].bounds", u, "finite lo <= hi", "bound every input")
            u = from_box(lo, hi)
        if u.dimension != b.shape[1] or not u.is_finite():
            raise ReachError(f"inputs[{mode!r}].bounds", u, f"a bounded set of dimension {b.shape[1]}",
                             "match the columns of the matrix")
        out[mode] = ([[Fraction(float(v)) for v in row] for row in b], u)
    return out


def _dynamics(run: _Run, mode: str) -> tuple[ModeDynamics, float]:
    """The mode's discretised dynamics and the scale of its constant coordinate (a power of 2)."""
    if mode not in run.dynamics:
        m = run.model.modes[mode]
        b, u = run.inputs.get(mode, (None, None))
        c = list(m.c)
        if b is not None:  # the input's centre B u_c joins the constant, exactly; U is then centred on 0
            centre = [Fraction(float(v)) for v in u.center]
            c = [ci + sum((b[i][j] * centre[j] for j in range(len(centre))), Fraction(0)) for i, ci in enumerate(c)]
        biggest = max([abs(float(q)) for q in c] + [1.0])
        scale = 2.0 ** math.ceil(math.log2(biggest)) if math.isfinite(biggest) else 1.0
        c = [q / Fraction(scale) for q in c]
        a = [list(row) for row in m.a]
        norm = max([sum(abs(q) for q in row) + abs(ci) for row, ci in zip(a, c)] + [Fraction(0)])
        step = _step(run, mode)
        if float(norm) * step > MAX_NORM_STEP:
            limit = MAX_NORM_STEP / float(norm)
            name = f"mode_time_steps[{mode!r}]" if mode in run.mode_steps else "time_step"
            raise ReachError(name, step, f"a step with ‖A‖·time_step <= {MAX_NORM_STEP:g} in mode "
                             f"{mode!r} (‖A‖ = {float(norm):.6g})", f"use time_step <= {limit:.3g}")
        dyn = mode_dynamics(mode, a, c, step, b, u)
        run.dynamics[mode] = (dyn, scale)
    return run.dynamics[mode]


def _augment(z: Zonotope, scale: float) -> Zonotope:
    return Zonotope(center=np.append(z.center, scale),
                    generators=np.vstack([z.generators, np.zeros((1, z.order))]))


def _explore(run: _Run, first: _Work, max_flowpipes: int, progress: Callable[[float], None] | None = None) -> None:
    queue = deque([first])
    affine_only = all(m.smooth is None for m in run.model.modes.values())
    count = 0
    reached = 0.0
    while queue:
        work = queue.popleft()
        if count >= max_flowpipes:
            run.terminations.append(Termination(
                reason="flowpipe_limit", mode=work.mode, time=work.t_lo, jumps=work.jumps,
                detail=f"inconclusive: {max_flowpipes} flowpipes computed and {len(queue) + 1} left "
                       f"(raise max_flowpipes); the first left starts in mode {work.mode!r} at t = {work.t_lo:.6g} s"))
            return
        count += 1
        collected = _flow(run, work)
        if progress is not None and run.segments:
            reached = max(reached, min(run.segments[-1].t_hi, run.horizon))
            progress(reached)
        if collected and work.jumps >= run.max_jumps:
            run.terminations.append(Termination(
                reason="max_jumps", mode=work.mode, time=min(c[2] for v in collected.values() for c in v),
                jumps=work.jumps,
                detail=f"jump bound {run.max_jumps} reached in mode {work.mode!r}: "
                       f"{', '.join(sorted(collected))} may fire after it (not followed)"))
            continue
        for t in run.model.outgoing(work.mode):
            for cluster in collected.get(t.name, ()):
                # zonotope jump sets in affine automata only: a smooth mode's re-check contains its own tube (from
                # the reset image of the saved box before the jump) in the saved boxes, so its producer keeps boxes
                zono = cluster[6] if cluster[7] and affine_only else None
                queue.append(_jump(run, work, t, *cluster[:4], zono=zono))


def _jump(run: _Run, work: _Work, t: AffineTransition, lo: np.ndarray, hi: np.ndarray, t_lo: float,
          t_hi: float, zono: JumpFold | None = None) -> _Work:
    """The jump of a cluster: the box route (the guard part's box hull mapped by the reset), or with ``zono`` (the
    cluster's zonotope jump set, :mod:`analysis.reach.jumpsets`) its reset image, kept when it is finite and its
    hull is nowhere wider than the box route's (:data:`ZONOTOPE_WIDER`); the saved ``after`` box holds both."""
    n = len(run.model.state_names)
    rc = np.array([[float(q) for q in row] + [float(off)] for row, off in zip(t.r_matrix, t.r_offset)]
                  + [[0.0] * n + [1.0]])
    exact = [list(row) + [off] for row, off in zip(t.r_matrix, t.r_offset)]
    rr = np.zeros_like(rc)
    for i, row in enumerate(exact):
        for j, q in enumerate(row):
            rr[i, j] = float(round_up(float(abs(q - Fraction(rc[i, j])))))
    image, err = linear_map(_augment(from_box(lo, hi), 1.0), rc, rr)
    start = with_error(image, err).project(n)
    after_lo, after_hi = interval_hull(start)
    box = None
    kept = None if zono is None else _zonotope_image(t, zono, lo, hi, after_hi - after_lo)
    if kept is not None:
        zlo, zhi = kept.hull()
        start = kept.start()
        box = (np.maximum(zlo, after_lo), np.minimum(zhi, after_hi))  # both hold the states after the jump
        after_lo, after_hi = np.minimum(zlo, after_lo), np.maximum(zhi, after_hi)
    run.jumps.append(ReachJump(transition=t.name, source=t.source, target=t.target, jumps=work.jumps + 1,
                               t_lo=t_lo, t_hi=t_hi, before_lo=lo, before_hi=hi, after_lo=after_lo,
                               after_hi=after_hi, zonotope=kept))
    return _Work(mode=t.target, start=start, t_lo=t_lo, t_hi=t_hi, jumps=work.jumps + 1, box=box,
                 saved=None if box is None else (after_lo, after_hi))


def _zonotope_image(t: AffineTransition, folded: JumpFold, lo: np.ndarray, hi: np.ndarray,
                    width: np.ndarray) -> ResetImage | None:
    """The reset image of the cluster's paired fold, else of its reduced fold (:class:`~analysis.reach.jumpsets.
    JumpFold`), reduced to ``JUMP_ORDER`` and met with the guard part's box ``[lo, hi]`` (it holds the guard part
    too): the first that is finite and nowhere wider than the box route's image (``width``, :data:`ZONOTOPE_WIDER`);
    ``None`` when neither is (the box route).  The paired fold comes first: a narrower hull does not mean tighter
    correlations (on the platoon PLAD01-BND30 the reduced fold's hull is no wider, yet the flowpipe after it misses by
    0.074 m where the paired one's holds with 0.85 m); the reduced fold serves where the paired one is too wide (the
    gearbox GRBX01's oblique guards: margin 0.0393 with it, 0.0357 with the box route)."""
    for z in (folded.paired, folded.reduced):
        met = meet_box(reduce_jump(z), lo, hi)
        if met is None:
            continue
        image = reset_image(met, t.r_matrix, t.r_offset)
        zlo, zhi = image.hull()
        if np.all(np.isfinite(zlo)) and np.all(np.isfinite(zhi)) and not bool(
                np.any(zhi - zlo > width * (1.0 + ZONOTOPE_WIDER) + 1e-12)):
            return image
    return None


def _flow(run: _Run, work: _Work) -> dict[str, list[Any]]:
    """One flowpipe: stores its segments and termination; returns ``{transition: [[lo, hi, t_lo, t_hi, ...], ...]}``
    (one entry per cluster of segments meeting the guard, see ``jump_cluster``)."""
    mode = run.model.modes[work.mode]
    n = len(run.model.state_names)
    guards = [(t.name, _rows(polyhedra_to_float(t.guard))) for t in run.model.outgoing(work.mode)]
    invariant = _rows(polyhedra_to_float(mode.invariant))
    # a jump from a state reached by flowing: that state is in the guard and (closed) in the invariant
    flowed_guards = [(name, _rows(tuple(g + i for g, _ in polys for i, _ in invariant))) for name, polys in guards]
    collected: dict[str, list[Any]] = {}
    lo, hi = interval_hull(work.start)
    saved = (lo, hi) if work.saved is None else work.saved  # a zonotope jump's entry box: its ``after`` (holds both)
    if work.box is not None:  # the guard meets below use the tighter meet of both images' hulls
        lo, hi = np.maximum(lo, work.box[0]), np.minimum(hi, work.box[1])
    run.segments.append(ReachSegment(mode=work.mode, t_lo=work.t_lo, t_hi=work.t_hi, jumps=work.jumps,
                                     zonotope=reduce_order(work.start, run.stored_order), lo=saved[0], hi=saved[1],
                                     entry=True))
    _collect(run, collected, guards, work.start, lo, hi, work.t_lo, work.t_hi, -1)
    step = _step(run, work.mode)  # the mode's step, affine or smooth (``mode_time_steps``)
    pending: list[Any] = []  # [lo, hi, t_lo, t_hi, count] of the flowed segments not stored yet (merging)
    unit = math.ldexp(step, ADAPTIVE_LEVELS[0])  # adaptive steps: local times a·unit, exactly (a an integer)
    room = (Fraction(run.horizon) - Fraction(work.t_lo)) / Fraction(unit)  # local > room: past the horizon, exactly
    local: int | None = None  # the adaptive step's local start in units (None: k steps of ``step``)
    delta = None
    for k, segment in enumerate(_mode_segments(run, work, step)):
        if isinstance(segment, tuple):  # an adaptive step: (tube, a, b), local times [a·unit, b·unit]
            segment, local, end = segment
            delta = (end - local) * unit  # a power of two times unit: exact
            # as for fixed steps: the product and the addition, two roundings, each within half an ulp of the sum
            t_lo = math.nextafter(math.nextafter(work.t_lo + local * unit, -math.inf), -math.inf)
            t_hi = math.nextafter(math.nextafter(work.t_hi + end * unit, math.inf), math.inf)
        elif local is not None:  # the adaptive generator's reason string: dated at the end of its last step
            local = end
            t_lo = work.t_lo + local * unit
        else:
            t_lo = math.nextafter(math.nextafter(work.t_lo + k * step, -math.inf), -math.inf)
            t_hi = math.nextafter(math.nextafter(work.t_hi + (k + 1) * step, math.inf), math.inf)
        stop, z, lo, hi = _stop_reason(run, work, k, segment, n, t_lo, None if local is None else local > room)
        if stop is not None:
            run.terminations.append(stop)
            break
        box = _clip_union(z, lo, hi, invariant)
        if box is None:
            run.terminations.append(Termination(
                reason="left_invariant", mode=work.mode, time=t_lo, jumps=work.jumps,
                detail=f"the flowpipe left the invariant of mode {work.mode!r} by t = {t_lo:.6g} s"))
            break
        _store(run, work, pending, z, box, t_lo, t_hi, delta)
        _collect(run, collected, flowed_guards, z, box[0], box[1], t_lo, t_hi, k)
    if pending:
        _flush(run, work, pending)
    return collected


def _store(run: _Run, work: _Work, pending: list[Any], z: Zonotope, box: tuple[np.ndarray, np.ndarray],
           t_lo: float, t_hi: float, step: float | None = None) -> None:
    """Stores a flowed segment (``merge == 1``) or adds it to the pending merged one (``step``: the adaptive
    step's length, saved with an unmerged segment)."""
    if run.merge == 1:
        kept = reduce_order(z, run.stored_order)
        run.stored[0] += kept.dimension * (kept.order + 3)
        run.segments.append(ReachSegment(mode=work.mode, t_lo=t_lo, t_hi=t_hi, jumps=work.jumps,
                                         zonotope=kept, lo=box[0], hi=box[1], step=step))
        return
    if not pending:
        pending.extend([box[0], box[1], t_lo, t_hi, 1])
    else:
        pending[0] = np.minimum(pending[0], box[0])
        pending[1] = np.maximum(pending[1], box[1])
        pending[3] = t_hi
        pending[4] += 1
    if pending[4] >= run.merge:
        _flush(run, work, pending)


def _flush(run: _Run, work: _Work, pending: list[Any]) -> None:
    lo, hi, t_lo, t_hi, _ = pending
    kept = from_box(lo, hi)  # holds the box exactly (radius rounded up)
    run.stored[0] += kept.dimension * (kept.order + 3)
    run.segments.append(ReachSegment(mode=work.mode, t_lo=t_lo, t_hi=t_hi, jumps=work.jumps,
                                     zonotope=kept, lo=lo, hi=hi))
    pending.clear()


def _mode_segments(run: _Run, work: _Work, step: float) -> Any:
    """The mode's segments (augmented zonotopes) of ``step`` [s] each (the mode's, :func:`_step`): affine flowpipe,
    or conservative linearisation of a smooth flow (:mod:`analysis.reach.nonlinear`, which yields a reason string
    when a step cannot be enclosed)."""
    smooth = run.model.modes[work.mode].smooth
    if smooth is not None:
        if run.inputs.get(work.mode) is not None:
            raise ReachError("inputs", work.mode, "inputs only in modes with affine flows",
                             "drop the input of this nonlinear mode (or add it to the flow as a state)")
        if run.adaptive > 0:
            return adaptive_segments(smooth, work.mode, work.start, step, run.order, ratio=run.adaptive)
        return smooth_segments(smooth, work.mode, work.start, step, run.order)
    dyn, scale = _dynamics(run, work.mode)
    if dyn.step != step:  # one step for the segments and their times (both from _step)
        raise AssertionError(f"mode {work.mode!r}: flowpipe step {dyn.step!r} != {step!r}")
    # a mode that may jump in an affine automaton (zonotope jump sets) carries its inputs' correlations to the jump
    may_jump = bool(run.model.outgoing(work.mode)) and all(
        m.smooth is None for m in run.model.modes.values())
    return segments(dyn, _augment(work.start, scale), run.order,
                    input_order=max(run.order, JUMP_ORDER) if may_jump else run.order)


def _stop_reason(run: _Run, work: _Work, k: int, segment: Zonotope | str, n: int, t_lo: float,
                 late: bool | None = None) -> tuple[Termination | None, Any, Any, Any]:
    """Why the flowpipe stops at segment ``k`` (or ``None``), with the segment's projection and its box (once).
    ``late``: whether the segment starts after the horizon, decided exactly (adaptive steps; ``None``: ``k`` steps of
    the mode's step, compared in floats as before)."""
    where = dict(mode=work.mode, time=t_lo, jumps=work.jumps)
    if late is None:
        late = work.t_lo + k * _step(run, work.mode) > run.horizon
    if late:
        return Termination(reason="horizon", detail=f"time horizon {run.horizon:g} s reached in mode "
                                                    f"{work.mode!r}", **where), None, None, None
    if isinstance(segment, str):
        return Termination(reason="blow_up", detail=(
            f"inconclusive: the over-approximation blew up at t = {t_lo:.6g} s in mode {work.mode!r} ({segment})"),
            **where), None, None, None
    if not segment.is_finite():
        return Termination(reason="not_finite", detail=f"inconclusive: a NaN or inf appeared at t = {t_lo:.6g} s "
                                                       f"in mode {work.mode!r}", **where), None, None, None
    z = segment.project(n)
    lo, hi = interval_hull(z)
    radius = float(np.max(hi - lo)) / 2 if n else 0.0
    if not math.isfinite(radius) or radius > run.size_limit:
        return Termination(reason="blow_up", detail=(
            f"inconclusive: the over-approximation blew up at t = {t_lo:.6g} s in mode {work.mode!r} "
            f"(box radius {radius:.3g} > size_limit {run.size_limit:g})"), **where), z, lo, hi
    if len(run.segments) >= run.max_segments or run.stored[0] >= MAX_STORED_NUMBERS:
        return Termination(reason="segment_limit", detail=(
            f"inconclusive: {len(run.segments)} segments ({run.stored[0]} numbers) stored by t = {t_lo:.6g} s in "
            f"mode {work.mode!r}, the limit (max_segments = {run.max_segments}, {MAX_STORED_NUMBERS} numbers); "
            "raise max_segments or time_step, or shorten the horizon"), **where), z, lo, hi
    return None, z, lo, hi


def _rows(polyhedra: Sequence[Sequence[Any]]) -> tuple[tuple[Any, Any], ...]:
    """Each polyhedron with its stacked rows (:func:`~analysis.reach.sets.halfspace_rows`; ``None`` when empty)."""
    return tuple((tuple(p), halfspace_rows(p) if p else None) for p in polyhedra)


def _clip_union(z: Zonotope, lo: np.ndarray, hi: np.ndarray, polyhedra: Sequence[tuple[Any, Any]],
                tight: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """The box hull of ``z ∩ [lo, hi]`` clipped to each polyhedron that ``z`` may meet; ``None`` if it meets none.

    ``polyhedra``: pairs (halfspaces, their stacked rows) from :func:`_rows`.  ``tight``: bound each
    polyhedron's part by linear programs with rigorous dual bounds (:func:`~analysis.reach.sets.tighten_box`)
    rather than by interval propagation on the box.
    """
    boxes = []
    for poly, rows in polyhedra:
        position = box_position(lo, hi, poly, rows)  # the box holds z: a cheap proven pre-test
        if position < 0:
            continue
        if position > 0:
            boxes.append((lo, hi))  # inside every halfspace: clipping would change nothing
            continue
        # a row with one non-zero coefficient is decided as tightly by clip_box on the box (the hull of z)
        if any(definitely_outside(z, h) for h in rows.oblique):
            continue
        clipped = tighten_box(z, lo, hi, poly) if tight else clip_box(lo, hi, poly)
        if clipped is not None:
            boxes.append(clipped)
    if not boxes:
        return None
    if len(boxes) == 1:
        return boxes[0]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def _collect(run: _Run, collected: dict[str, list[list[Any]]], guards: Sequence[tuple[str, Any]], z: Zonotope,
             lo: np.ndarray, hi: np.ndarray, t_lo: float, t_hi: float, index: int) -> None:
    """Adds segment ``index`` (-1: the entry set) to the jump clusters of every guard it may meet."""
    for name, polyhedra in guards:
        box = _clip_union(z, lo, hi, polyhedra, tight=True)
        if box is None:
            continue
        clusters = collected.setdefault(name, [])
        last = clusters[-1] if clusters else None
        if last is not None and (run.cluster is None or (last[5] == index - 1 and last[4] < run.cluster)):
            last[0] = np.minimum(last[0], box[0])
            last[1] = np.maximum(last[1], box[1])
            last[2] = min(last[2], t_lo)
            last[3] = max(last[3], t_hi)
            last[4] += 1
            last[5] = index
        else:
            last = [box[0], box[1], t_lo, t_hi, 1, index, None, True]
            clusters.append(last)
        _collect_zonotope(run, last, z, polyhedra)


def _collect_zonotope(run: _Run, cluster: list[Any], z: Zonotope, polyhedra: Sequence[tuple[Any, Any]]) -> None:
    """Adds the segment's guard part, as a zonotope, to the cluster's zonotope jump set (``cluster[6]``); a cluster
    of more than :data:`~analysis.reach.jumpsets.JUMP_ZONOTOPES` segments, or a guard ∩ invariant that is a union
    of polyhedra, keeps the box route (``cluster[7] = False``)."""
    if not cluster[7]:
        return
    if cluster[4] > JUMP_ZONOTOPES or len(polyhedra) != 1:
        cluster[6], cluster[7] = None, False
        return
    part = strip_meet(z, polyhedra[0][0])
    if part is not None:  # None: proven empty (nothing of this segment jumps)
        cluster[6] = fold(cluster[6], part, run.order)
