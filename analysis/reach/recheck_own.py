"""The independent re-check of an affine flowpipe on its own sets (the saved flowpipe as a schedule only).

:func:`own_recheck` decides the requirement on sets the re-check computes itself, from the model (exact
rationals, :mod:`analysis.reach.model`) and the initial box, with outward-rounded float intervals
(:mod:`analysis.reach.recheck_interval`, :mod:`analysis.reach.recheck_sets`).  The saved flowpipe
(:meth:`~analysis.reach.result.ReachResult.to_json`) gives only the schedule: the step per mode (``time_step``,
``schedule.mode_time_steps``), the jump clustering (``schedule.jump_cluster``) and the jump bound.  Its boxes are
never a containment target.  Per flowpipe of the re-check (a mode, a start set ``Z₀``, entry times
``[τ_lo, τ_hi]``, a jump depth), breadth first:

1. **Entry.** The start set's box must lie in the invariant or in one guard polyhedron (else a deadlock at entry
   is possible).  Every guard the entry set may meet gives a jump at the entry times (instantaneous chains).
   The requirement is decided on the start set.
2. **Steps.** With ``δ`` the schedule's step of the mode (halved until ``‖A_aug δ‖∞ <= 1``), ``e^{Aδ}`` and
   ``∫₀^δ e^{Aτ}c dτ`` are enclosed (Taylor series in interval arithmetic plus a tail bound), and each step
   ``k`` gives ``Z_{k+1} = Φ Z_k + v`` (same generator weights: the initial generators are never reduced, so
   the set does not wrap) and the tube of ``[τ_lo + kδ, τ_hi + (k+1)δ]`` (convex hull of the two ends plus the
   interpolation error).  Bounded inputs (``u = u_c + u₀``, ``u₀ ∈ U₀ = [−r, r]``, ``B u_c`` in the constant):
   the state is ``h(t) + v(t)`` with ``h`` the input-free solution (the tube of ``H_k``, ``H_{k+1}``) and ``v(t)``
   the response to ``u₀`` from 0 since the flowpipe's entry, which lies in the reach set ``R(t)`` of
   ``v̇ = A v + B u₀``.  ``R`` grows with ``t`` because ``0 ∈ U₀`` (an input that is 0 for ``t' − t`` and then
   plays the one reaching ``v`` reaches ``v`` at ``t'``), so ``R(t) ⊆ R((k+1)δ) ⊆ S_{k+1}`` on the piece ``k``,
   with ``S_{k+1} = S_k ⊕ P_k``, ``P_{k+1} = Φ P_k`` and ``P₀ ⊇ R(δ)`` (sub-steps: :func:`input_start`); the
   piece is the tube of ``H`` plus ``S_{k+1}`` (no interpolation of the inputs' part, no tube of one step's
   inputs).  ``P_k``'s error is bounded in the modal basis as ``H_k``'s (it would wrap as a box).  The
   tube's box is clipped to the invariant (exact rationals); an empty clip ends the flowpipe (every solution has
   left the invariant); the window's end ends it too.
3. **Requirement.** Each atom ``c·x <= d`` is decided on each piece by a rigorous upper bound of ``max c·x``
   over the box and over the tube's zonotope (the smaller), compared with ``d`` in exact rationals.
4. **Deadlock.** Every piece that may reach a face of the invariant must have its face part inside a guard
   (:func:`analysis.reach.deadlock.face_uncovered`, narrowed by the tube's zonotope).
5. **Jumps.** Each piece's part in a guard ∩ the invariant (exact box clipping, narrowed by the zonotope's
   generator weights) joins the transition's cluster (all of the flowpipe, or runs of consecutive steps of at
   most ``jump_cluster`` schedule steps); each cluster's box hull is mapped exactly by the reset and starts a
   flowpipe of the target over the cluster's times — or, for a cluster of at most
   :data:`~analysis.reach.recheck_jumps.OWN_JUMP_PIECES` pieces and a one-polyhedron guard ∩ invariant, the
   re-check's own zonotope jump set (:mod:`analysis.reach.recheck_jumps`, exact rationals; the exact image box still
   serves the entry checks).  A chain longer than the jump bound fails.

With inputs, the whole re-check runs with the step split of :data:`INPUT_SPLITS` one after the other until one
passes (each complete on its own sets).

Anything the re-check cannot decide fails it with the part and the place (:class:`OwnFailure`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from .deadlock import clip_exact, clock_offsets, contract_zonotope, entry_uncovered, face_uncovered, image_covered, open_rows, reached_late
from .fragment import Conj, LabelAtom, LinearAtom, Nnf, SafetyFragment, label_holds
from .recheck_interval import TINY, U, ExpEnclosure, add_up, float_interval, nn_up, point_product, sum_up, up
from .recheck_carry import KEPT_INPUTS, KEPT_JUMP_INPUTS, carry
from .recheck_inputs import InputSet, input_tube
from .recheck_jumps import OWN_JUMP_PIECES, own_jump_set
from .recheck_modal import ModalTracker, modal_tracker
from .recheck_sets import FZ, exact_image, tube

__all__ = ["own_recheck", "OwnFailure", "OwnOutcome", "MAX_OWN_FLOWPIPES", "SIZE_LIMIT", "KEPT_INPUTS", "INPUT_SPLIT",
           "INPUT_SPLITS", "input_start"]

MAX_OWN_FLOWPIPES = 4_000
"""Flowpipes the re-check follows before it fails (a run that keeps jumping is not re-checked)."""
SIZE_LIMIT = 1e6
"""A set whose half-width exceeds this (or is not finite) fails the re-check (it blew up)."""
INPUT_SPLIT = 4
"""A mode with inputs is re-checked with a quarter of the schedule's step: each piece holds the inputs' reach set one
step ahead (``S_{k+1}``, module docstring, 2.), whose excess over the piece a shorter step makes smaller."""
OWN_WIDER = 1.0
"""The re-check's own zonotope jump set is used unless its hull is wider than the box route's image in some
coordinate by more than this fraction of that coordinate's width (plus 10⁻¹²); then the box route."""
INPUT_SPLITS = (INPUT_SPLIT, 1)
"""The splits tried one after the other with inputs, until one re-check passes (each a complete re-check on own
sets): a quarter step first, then the schedule's step (fewer reductions of the carried inputs, which matters for
long horizons through jumps: PLAD01-BND30)."""
Box = list[tuple[Fraction, Fraction]]


class OwnFailure(Exception):
    """The re-check failed (the message names the part and the place)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class OwnOutcome:
    """What the re-check decided: pieces (time pieces and entries), jumps and flowpipes it followed, its margin."""

    segments: int
    jumps: int
    flowpipes: int
    margin: Fraction | None


@dataclass(slots=True)
class _Work:
    mode: str
    start: FZ
    t_lo: Fraction
    t_hi: Fraction
    depth: int
    box: Box | None = None  # the exact start box (the initial one)
    pre: tuple[Any, Box, Any] | None = None  # (transition, box before, rows holding the states before)


@dataclass(slots=True)
class _Run:
    model: Any
    fragment: SafetyFragment
    steps: dict[str, float]
    cluster: int | None
    max_jumps: int
    inputs: Mapping[str, InputSet]
    end: Fraction
    encl: dict[tuple[str, float], Any] = field(default_factory=dict)
    modal: dict[tuple[str, float], ModalTracker | None] = field(default_factory=dict)
    margin: Fraction | None = None
    pieces: int = 0
    jumps: int = 0
    atoms: dict[str, Any] = field(default_factory=dict)
    split: int = INPUT_SPLIT


def _fbox(lo: np.ndarray, hi: np.ndarray) -> Box:
    return [(Fraction(float(a)), Fraction(float(b))) for a, b in zip(lo, hi)]


def _round_box(box: Box) -> tuple[np.ndarray, np.ndarray]:
    lo = np.array([float(a) for a, _ in box])
    hi = np.array([float(b) for _, b in box])
    lo = np.where([Fraction(float(v)) > a for v, (a, _) in zip(lo, box)], np.nextafter(lo, -np.inf), lo)
    hi = np.where([Fraction(float(v)) < b for v, (_, b) in zip(hi, box)], np.nextafter(hi, np.inf), hi)
    return lo, hi


_ROWS: dict[int, tuple[Any, np.ndarray, float]] = {}


def _row_floats(row: Any) -> tuple[np.ndarray, float]:
    key = id(row)
    got = _ROWS.get(key)
    if got is None or got[0] is not row:
        if len(_ROWS) > 50_000:  # rows of models no longer used: the cache keeps them alive, so bound it
            _ROWS.clear()
        got = (row, np.array([float(v) for v in row.normal]), float(row.offset))
        _ROWS[key] = got
    return got[1], got[2]


def _maybe_above(row: Any, lo: np.ndarray, hi: np.ndarray) -> bool:
    """False only when ``max a·x < b`` over the box for sure (a float test with a margin that dominates its
    rounding by many orders of magnitude: ``10⁻⁹ (1 + |b| + Σ|a_i| max|x_i|)``)."""
    a, offset = _row_floats(row)
    top = float(np.sum(np.maximum(a * lo, a * hi)))
    scale = 1.0 + abs(offset) + float(np.sum(np.abs(a) * np.maximum(np.abs(lo), np.abs(hi))))
    return top >= offset - 1e-9 * scale


def _surely_beyond(row: Any, lo: np.ndarray, hi: np.ndarray) -> bool:
    """True only when ``min a·x > b`` over the box for sure (the margin of :func:`_maybe_above`)."""
    a, offset = _row_floats(row)
    bottom = float(np.sum(np.minimum(a * lo, a * hi)))
    scale = 1.0 + abs(offset) + float(np.sum(np.abs(a) * np.maximum(np.abs(lo), np.abs(hi))))
    return bottom > offset + 1e-9 * scale


def _contract(z: FZ, rows: Sequence[Any]) -> Box | None:
    """A box holding ``z ∩ {a·x <= b}``: the weights ``ξ ∈ [−1, 1]`` narrowed row by row (exact rationals)."""
    center, gens = z.exact()
    return contract_zonotope(center, gens, rows, rounds=2)


DUAL_GENERATORS = 80
"""Zonotopes with at most this many generators get the dual bound of :func:`_dual` in their guard parts."""


def _dual(z: FZ, rows: Sequence[Any]) -> Box | None:
    """A box holding ``z ∩ rows`` by weak duality with one row at a time: for ``a·x <= b`` and ``μ >= 0``,
    ``±x_i <= ±c_i − μ a·c + μ b + Σ_j |±g_ij − μ a·g_j|`` on ``z ∩ {a·x <= b}`` (``z = c + Σ g_j ξ_j``, the error
    box as generators); the minimum over ``μ >= 0`` of this convex piecewise-linear function is found exactly at
    ``μ = 0`` or the breakpoint where its slope turns non-negative (any ``μ >= 0`` gives a valid bound).  For one row (or an equality, given as two rows) this is the exact
    maximum over ``z`` (LP duality); the boxes of all rows are intersected.  ``None``: shown empty."""
    center, gens = z.exact()
    n = len(center)
    out: Box = [(c - sum((abs(g[i]) for g in gens), Fraction(0)), c + sum((abs(g[i]) for g in gens), Fraction(0)))
                for i, c in enumerate(center)]
    for row in rows:
        a, b = row.normal, row.offset
        ac = sum((ai * ci for ai, ci in zip(a, center) if ai), Fraction(0))
        ag = [sum((ai * g[i] for i, ai in enumerate(a) if ai and g[i]), Fraction(0)) for g in gens]
        if ac - sum((abs(v) for v in ag), Fraction(0)) > b:
            return None
        weights = [abs(v) for v in ag]
        for i in range(n):
            for sign in (1, -1):
                # the slope of the convex function just right of μ = 0, then its breakpoints in order: the
                # minimum is where the slope turns non-negative (a weighted median)
                points = sorted((sign * g[i] / v, w) for g, v, w in zip(gens, ag, weights) if v)
                slope = b - ac + sum((w if mu <= 0 else -w for mu, w in points), Fraction(0))
                mu = Fraction(0)
                for at, w in points:
                    if slope >= 0:
                        break
                    if at > 0:
                        slope += 2 * w
                        mu = at
                best = sign * center[i] - mu * ac + mu * b + sum((abs(sign * g[i] - mu * v) for g, v in
                                                                   zip(gens, ag)), Fraction(0))
                lo, hi = out[i]
                out[i] = (lo, min(hi, best)) if sign > 0 else (max(lo, -best), hi)
            if out[i][0] > out[i][1]:
                return None
    return out


def _meet(a: Box, b: Box) -> Box | None:
    out = [(max(p[0], q[0]), min(p[1], q[1])) for p, q in zip(a, b)]
    return None if any(lo > hi for lo, hi in out) else out


def _part(rows: Sequence[Any], lo: np.ndarray, hi: np.ndarray, z: FZ) -> Box | None:
    """A box holding ``(box ∩ z) ∩ rows`` (``None``: empty); float pre-test, then exact."""
    for row in rows:
        if _surely_beyond(row, lo, hi):  # min a·x > b for sure: empty
            return None
    clipped = clip_exact(_fbox(lo, hi), rows)
    if clipped is None:
        return None
    tight = _contract(z, rows)
    if tight is not None and z.gens.shape[1] + z.center.size <= DUAL_GENERATORS:
        dual = _dual(z, rows)
        tight = None if dual is None else _meet(tight, dual)
    return None if tight is None else _meet(clipped, tight)


def _atoms(run: _Run) -> tuple[list[int], np.ndarray, np.ndarray]:
    """The fragment's linear atoms (by id) and their coefficients as floats ``cm ± cr`` (rows)."""
    if not run.atoms:
        found: list[LinearAtom] = []

        def walk(node: Nnf) -> None:
            if isinstance(node, LinearAtom):
                found.append(node)
            elif not isinstance(node, LabelAtom):
                for p in node.parts:
                    walk(p)
        walk(run.fragment.body)
        pairs = [float_interval(list(a.coefficients)) for a in found]
        n = len(run.model.state_names)
        run.atoms = {"ids": [id(a) for a in found],
                     "cm": np.array([p[0] for p in pairs]).reshape(len(found), n),
                     "cr": np.array([p[1] for p in pairs]).reshape(len(found), n)}
    return run.atoms["ids"], run.atoms["cm"], run.atoms["cr"]


def _tops(run: _Run, lo: np.ndarray, hi: np.ndarray, z: FZ | None) -> dict[int, Fraction]:
    """A rigorous upper bound of ``max c·x`` over the box (∩ the zonotope) for every atom ``c ∈ [cm ± cr]``."""
    ids, cm, cr = _atoms(run)
    if not ids:
        return {}
    mag = np.maximum(np.abs(lo), np.abs(hi))
    terms = up(np.maximum(cm * lo, cm * hi))
    k = lo.size
    top = up(up(up(np.sum(terms, axis=1)) + up(sum_up(np.abs(terms), axis=1) * ((k + 2) * U)) + (k + 2) * TINY)
             + nn_up(cr, mag))
    if z is not None:
        y0, r0 = point_product(cm, z.center)
        spread = 0.0
        if z.gens.shape[1]:
            y, ry = point_product(cm, z.gens)
            spread = sum_up(up(np.abs(y) + ry), axis=1)
        rest = add_up(r0, spread, nn_up(np.abs(cm), z.err), nn_up(cr, z.magnitude()))
        top = np.minimum(top, up(y0 + rest))
    return {i: Fraction(float(v)) for i, v in zip(ids, top)}


def _value(node: Nnf, mode: str, tops: Mapping[int, Fraction]) -> tuple[bool, Fraction | None]:
    if isinstance(node, LabelAtom):
        return label_holds(node, mode), None
    if isinstance(node, LinearAtom):
        slack = node.bound - tops[id(node)]
        return (slack > 0 if node.strict else slack >= 0), slack
    results = [_value(p, mode, tops) for p in node.parts]
    slacks = [v for _, v in results if v is not None]
    if isinstance(node, Conj):
        return all(ok for ok, _ in results), (min(slacks) if slacks else None)
    good = [v for ok, v in results if ok]
    if good and any(v is None for v in good):
        return True, None
    return bool(good), (max(good) if good else (max(slacks) if slacks else None))


def _decide(run: _Run, mode: str, lo: np.ndarray, hi: np.ndarray, z: FZ | None, t_lo: Fraction, t_hi: Fraction,
            where: str) -> None:
    f = run.fragment
    if t_lo > Fraction(f.end) or t_hi < Fraction(f.start):
        return
    ok, slack = _value(f.body, mode, _tops(run, lo, hi, z))
    if not ok:
        raise OwnFailure(f"requirement: the atoms do not hold on the re-check's own states of {where} (mode {mode!r},"
                         f" t in [{float(t_lo):.6g}, {float(t_hi):.6g}] s, slack {float(slack) if slack is not None else 'n/a'})")
    if slack is not None:
        run.margin = slack if run.margin is None else min(run.margin, slack)


def _enclosure(run: _Run, mode: str) -> tuple[ExpEnclosure, float, Any]:
    """The mode's enclosure, its step (the schedule's, halved until ``q <= 1``) and its input terms."""
    step = run.steps.get(mode)
    key = (mode, step)
    if key in run.encl:
        return run.encl[key]
    m = run.model.modes[mode]
    spec = run.inputs.get(mode)
    c = list(m.c) if spec is None else [x + y for x, y in zip(m.c, spec.shift())]
    a = [list(r) for r in m.a]
    h = step if spec is None else step / run.split
    for _ in range(40):
        try:
            enc = ExpEnclosure(a, c, h)
            if enc.q <= 1.0:
                break
        except ValueError:
            pass
        h = h / 2
    else:
        raise OwnFailure(f"steps: mode {mode!r}: no step gives an enclosure of e^(A step)")
    terms = None if spec is None else input_start(a, spec, h)  # P₀ ⊇ the inputs' reach set after one step
    run.encl[key] = (enc, h, terms)
    return run.encl[key]


def input_start(a: list[list[Fraction]], spec: InputSet, step: float) -> FZ:
    """``P₀ ⊇ R(δ) = {∫₀^δ e^{As} B u₀(s) ds : u₀(s) ∈ [−r, r]}`` through ``m`` sub-steps ``h = δ/m`` (``m`` a power
    of two, ``‖A‖∞ h <= 1/8``): ``R(δ) = ⊕_{j<m} e^{Ajh} R(h)`` exactly (the input's pieces are independent), and
    ``R(h) ⊆ h B U₀ ⊕ (h²/2) A B U₀ ⊕ [−ρ, ρ]`` (:func:`analysis.reach.recheck_inputs.input_tube` of order 2: the two
    Picard terms as generators, ``ρ = |A²| w h²/2``).  Each sub-step's set is mapped ``j`` times by the re-check's
    own enclosure of ``e^{Ah}`` (:class:`ExpEnclosure`, outward-rounded intervals).  A single Taylor series over
    ``δ`` (``‖A‖δ`` near 1) would bound ``|∫ e^{As}|`` by about ``(e^{‖A‖δ} − 1)/‖A‖δ`` instead of the stable
    ``(1 − e^{−‖A‖δ})/‖A‖δ``: 2.6 times the reach set of a stiff scalar mode at ``‖A‖δ = 0.975``.
    """
    n = len(a)
    norm = max((sum((abs(v) for v in row), Fraction(0)) for row in a), default=Fraction(0))
    m = 1
    while norm * Fraction(step) > Fraction(m, 8):
        m *= 2
    h = step / m  # a power-of-two division: exact
    _, _, first, rest = input_tube(a, spec.matrix, spec.radius(), Fraction(h), order=2)
    gens = np.array([[float(v) for v in col] for col in first]).T.reshape(n, -1) if first else np.zeros((n, 0))
    gerr = [sum((abs(Fraction(float(col[i])) - col[i]) for col in first), Fraction(0)) for i in range(n)]
    part = FZ(center=np.zeros(n), gens=gens, err=np.array([float(up(float(e + r))) for e, r in zip(gerr, rest)]))
    phi = ExpEnclosure(a, [Fraction(0)] * n, h).phi if m > 1 else None
    kept, err = [], np.zeros(n)
    for j in range(m):
        kept.append(part.gens)
        err = add_up(err, part.err)
        if j + 1 < m:
            part = part.mapped(phi, None)
    return FZ(center=np.zeros(n), gens=np.hstack(kept), err=err)


def own_recheck(model: Any, initial: Box, initial_mode: str, fragment: SafetyFragment, *, steps: Mapping[str, float],
                cluster: int | None, max_jumps: int, inputs: Mapping[str, InputSet]) -> OwnOutcome:
    """Re-check ``fragment`` from ``initial`` in ``initial_mode`` on the re-check's own sets (see the module).

    Parameters
    ----------
    model : AffineHybridModel
        Every mode affine (exact rationals).
    initial : list of (Fraction, Fraction)
        The initial box.
    steps : mapping {mode: float}
        The schedule's step per mode [s] (floats).
    cluster : int or None
        The schedule's jump clustering (``None``: one jump per transition per flowpipe).
    max_jumps : int
        Chains of more jumps fail.
    inputs : mapping {mode: InputSet}

    Raises
    ------
    OwnFailure
        With the part and the place.
    """
    failures = []
    for split in (INPUT_SPLITS if inputs else INPUT_SPLITS[:1]):
        try:
            return _own_run(model, initial, initial_mode, fragment, steps, cluster, max_jumps, inputs, split)
        except OwnFailure as fail:
            failures.append(f"{fail}" if len(failures) == 0 else f"with the input step split {split}: {fail}")
    raise OwnFailure("; ".join(failures))


def _own_run(model: Any, initial: Box, initial_mode: str, fragment: SafetyFragment, steps: Mapping[str, float],
             cluster: int | None, max_jumps: int, inputs: Mapping[str, InputSet], split: int) -> OwnOutcome:
    """One complete re-check with the inputs' step split ``split`` (:data:`INPUT_SPLITS`)."""
    run = _Run(model=model, fragment=fragment, steps=dict(steps), cluster=cluster, max_jumps=max_jumps,
               inputs=inputs, end=Fraction(fragment.end), split=split)
    lo, hi = _round_box(initial)
    queue = deque([_Work(mode=initial_mode, start=FZ.of_box(lo, hi), t_lo=Fraction(0), t_hi=Fraction(0), depth=0,
                         box=initial)])
    count = 0
    while queue:
        work = queue.popleft()
        count += 1
        if count > MAX_OWN_FLOWPIPES:
            raise OwnFailure(f"jumps: the re-check's run needs more than {MAX_OWN_FLOWPIPES} flowpipes")
        queue.extend(_flowpipe(run, work, count - 1))
    return OwnOutcome(segments=run.pieces, jumps=run.jumps, flowpipes=count, margin=run.margin)


def _jump(run: _Run, t: Any, box: Box, t_lo: Fraction, t_hi: Fraction, depth: int, where: str,
          rows: Sequence[Any] = (), pieces: Sequence[FZ] | None = None) -> _Work | None:
    if t_lo > run.end:
        return None  # after the window: nothing to decide there
    if depth + 1 > run.max_jumps:
        raise OwnFailure(f"jumps: {where} may take {t.name!r} at t in [{float(t_lo):.6g}, {float(t_hi):.6g}] s, "
                         f"beyond the jump bound {run.max_jumps}: not every behaviour is covered")
    run.jumps += 1
    image = exact_image(t.r_matrix, t.r_offset, [a for a, _ in box], [b for _, b in box])
    if pieces and rows:  # the own zonotope jump set (analysis.reach.recheck_jumps), unless wider than the box's image
        zono = own_jump_set(pieces, rows, t.r_matrix, t.r_offset, box)
        if zono is not None:
            zlo, zhi = zono.hull()
            blo, bhi = image.hull()
            if np.all(zhi - zlo <= (bhi - blo) * (1.0 + OWN_WIDER) + 1e-12):
                image = zono
    exact = [(sum((min(a * l, a * h) for a, (l, h) in zip(row, box) if a), Fraction(0)) + off,
              sum((max(a * l, a * h) for a, (l, h) in zip(row, box) if a), Fraction(0)) + off)
             for row, off in zip(t.r_matrix, t.r_offset)]  # the exact image box (the zonotope's hull is rounded)
    return _Work(mode=t.target, start=image, t_lo=t_lo, t_hi=t_hi, depth=depth + 1, box=exact, pre=(t, box, rows))


def _enter(run: _Run, work: _Work, where: str) -> tuple[np.ndarray, np.ndarray, list[_Work]]:
    """The entry of a flowpipe (module, part 1): its deadlock check, the requirement on the start set, and the
    jumps its guards allow at once; returns the start set's box and those jumps."""
    model, mode = run.model, work.mode
    lo, hi = work.start.hull()
    box = work.box if work.box is not None else _fbox(lo, hi)
    why = entry_uncovered(model, mode, box)
    if why and work.pre is not None and image_covered(model, *work.pre):
        why = None  # the image of the states before the jump (not only its box) is covered
    if why:
        raise OwnFailure(f"entries: {where}: {why}")
    if work.box is not None:  # the exact box (rounded outward) holds the start set too
        blo, bhi = _round_box(work.box)
        lo, hi = np.maximum(lo, blo), np.minimum(hi, bhi)
    out = []
    run.pieces += 1
    _decide(run, mode, lo, hi, work.start, work.t_lo, work.t_hi, f"{where} entry")
    for t in model.outgoing(mode):
        for guard in t.guard:
            part = _part(guard.halfspaces, lo, hi, work.start)
            if part is not None:
                new = _jump(run, t, part, work.t_lo, work.t_hi, work.depth, f"{where} entry", guard.halfspaces)
                if new is not None:
                    out.append(new)
    return lo, hi, out


def _flowpipe(run: _Run, work: _Work, index: int) -> list[_Work]:
    """One flowpipe of the re-check (module, parts 1–5); returns the flowpipes its jumps start."""
    model, mode = run.model, work.mode
    where = f"flowpipe {index} (mode {mode!r})"
    lo, hi, out = _enter(run, work, where)
    enc, step, terms = _enclosure(run, mode)
    invariant = model.modes[mode].invariant
    spec = run.inputs.get(mode)
    given = None if spec is None else (spec.matrix, spec.low, spec.high)
    faces = open_rows(model, mode, given)
    entry = work.box if work.box is not None else _fbox(lo, hi)  # holds the entry set (clock offsets)
    ratio = max(1, round(run.steps[mode] / step))
    limit = None if run.cluster is None else run.cluster * ratio
    clusters: dict[str, list[Any]] = {}
    h, s_gens, s_box = work.start, np.zeros((lo.size, 0)), np.zeros(lo.size)
    p = terms
    keep = KEPT_JUMP_INPUTS if model.outgoing(mode) else KEPT_INPUTS  # carried into its own jump sets
    key = (mode, step)
    if key not in run.modal:
        run.modal[key] = modal_tracker(enc.phi[0])
    tracker = run.modal[key]
    r = None if tracker is None else tracker.coordinates(h.err)
    rp = None if tracker is None or p is None else tracker.coordinates(p.err)
    k = 0
    fstep = Fraction(step)
    while work.t_lo + k * fstep <= run.end:
        h1, r = _advance(h, enc, tracker, r)
        piece = tube(h, h1, enc)
        if p is not None:  # S_{k+1} = S_k ⊕ P_k holds the inputs' part at every time of the piece (module, 2.)
            s_gens, s_box = carry(s_gens, s_box, p, keep)
            piece = piece.plus(FZ(center=np.zeros(lo.size), gens=s_gens, err=s_box))
            p, rp = _advance(p, enc, tracker, rp, shifted=False)
        radius = piece.radius()
        if not np.all(np.isfinite(radius)) or float(np.max(radius, initial=0.0)) > SIZE_LIMIT:
            raise OwnFailure(f"segments: {where} step {k}: the re-check's set blew up (half-width "
                             f"{float(np.max(radius)):.3g})")
        plo, phi_ = piece.hull()
        t_lo, t_hi = work.t_lo + k * fstep, work.t_hi + (k + 1) * fstep
        clipped = _clip_invariant(invariant, plo, phi_)
        if clipped is None:
            break  # every solution has left the invariant
        clo, chi = clipped
        run.pieces += 1
        _decide(run, mode, clo, chi, piece, t_lo, t_hi, f"{where} step {k}")
        if any(_maybe_above(r, clo, chi) for r in faces):
            why = face_uncovered(model, mode, [(_fbox(clo, chi), lambda rows, z=piece: _contract(z, rows))],
                                 inputs=given, late=lambda _, face: reached_late(
                                     face, clock_offsets(model, mode, entry, work.t_lo, given), run.end))
            if why:
                raise OwnFailure(f"deadlock: {where} step {k} (t in [{float(t_lo):.6g}, {float(t_hi):.6g}] s): {why}")
        for t in model.outgoing(mode):
            part = None
            for guard in t.guard:
                for inv in invariant:
                    got = _part([*guard.halfspaces, *inv.halfspaces], clo, chi, piece)
                    if got is not None:
                        part = got if part is None else [(min(a[0], b[0]), max(a[1], b[1])) for a, b in zip(part, got)]
            _cluster(run, clusters, t, part, k, t_lo, t_hi, limit, work.depth, where, out, piece)
        h = h1
        k += 1
    for t in model.outgoing(mode):
        _cluster(run, clusters, t, None, -1, Fraction(0), Fraction(0), 0, work.depth, where, out, None, flush=True)
    return out


def _advance(h: FZ, enc: ExpEnclosure, tracker: ModalTracker | None, r: np.ndarray | None, *, shifted: bool = True
             ) -> tuple[FZ, np.ndarray | None]:
    """``Φ h + v`` (``Φ h`` when not ``shifted``: the carried inputs) with its error bounded both as a box
    (``|Φm| |ε| + f``) and, with a tracker, in the modal basis (:mod:`analysis.reach.recheck_modal`): two bounds of
    the same error, the smaller kept."""
    shift = enc.shift if shifted else None
    if tracker is None or r is None:
        return h.mapped(enc.phi, shift), None
    fresh = h.mapped(enc.phi, shift, carry=False)
    boxed = add_up(fresh.err, nn_up(np.abs(enc.phi[0]), h.err))
    r1 = tracker.advance(r, fresh.err)
    return FZ(center=fresh.center, gens=fresh.gens, err=np.minimum(boxed, tracker.box(r1))), r1


def _cluster(run: _Run, clusters: dict[str, list[Any]], t: Any, part: Box | None, k: int, t_lo: Fraction,
             t_hi: Fraction, limit: int | None, depth: int, where: str, out: list[_Work], piece: FZ | None = None,
             flush: bool = False) -> None:
    """Add a guard part to the transition's open cluster; emit the cluster when it is full, broken or flushed.
    The cluster keeps its pieces (up to :data:`~analysis.reach.recheck_jumps.OWN_JUMP_PIECES`) for its own zonotope
    jump set."""
    open_ = clusters.get(t.name)
    if open_ is not None and (flush or (limit is not None and (part is None or k - open_[3] >= limit))):
        new = _jump(run, t, open_[0], open_[1], open_[2], depth, f"{where} steps {open_[3]}..{open_[4]}",
                    _flowed_rows(run.model, t), open_[5])
        if new is not None:
            out.append(new)
        clusters.pop(t.name)
        open_ = None
    if part is None or flush:
        return
    if open_ is None:
        open_ = clusters[t.name] = [part, t_lo, t_hi, k, k, []]
    else:
        open_[0] = [(min(a[0], b[0]), max(a[1], b[1])) for a, b in zip(open_[0], part)]
        open_[2], open_[4] = max(open_[2], t_hi), k
    if open_[5] is not None:
        open_[5] = open_[5] + [piece] if piece is not None and len(open_[5]) < OWN_JUMP_PIECES else None


def _flowed_rows(model: Any, t: Any) -> tuple[Any, ...]:
    """Rows every flowed state before ``t`` satisfies: its guard and the source's invariant (one polyhedron each)."""
    invariant = model.modes[t.source].invariant
    if len(t.guard) != 1 or len(invariant) != 1:
        return ()
    return (*t.guard[0].halfspaces, *invariant[0].halfspaces)


def _clip_invariant(invariant: Any, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The box clipped to the invariant (a union: the hull of the clips), rounded outward; ``None``: outside."""
    if len(invariant) == 1 and not invariant[0].halfspaces:
        return lo, hi
    found = None
    for poly in invariant:
        active = [r for r in poly.halfspaces if _maybe_above(r, lo, hi)]
        if not active:
            return lo, hi
        # only the coordinates the active rows read are clipped (clip_exact reads no other): exact there
        support = sorted({i for r in active for i, v in enumerate(r.normal) if v})
        box: list[Any] = [None] * lo.size
        for i in support:
            box[i] = (Fraction(float(lo[i])), Fraction(float(hi[i])))
        got = clip_exact(box, active)
        if got is None:
            continue
        slo, shi = _round_box([got[i] for i in support])
        glo, ghi = lo.copy(), hi.copy()
        glo[support], ghi[support] = slo, shi
        found = (glo, ghi) if found is None else (np.minimum(found[0], glo), np.maximum(found[1], ghi))
    return found
