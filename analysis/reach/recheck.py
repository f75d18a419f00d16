"""An independent re-check of a reachability proof from the saved flowpipe (JSON) and the system.

The re-check shares no set code with the producer (:mod:`analysis.reach.zonotope`, ``flowpipe``, ``series``,
``sets``, ``engine`` are not imported); it reads the exact model (:func:`analysis.reach.model.affine_model`,
rationals) and the JSON of :meth:`~analysis.reach.result.ReachResult.to_json`.  Two routes:

**Affine models (every mode affine, with or without bounded inputs)** — :mod:`analysis.reach.recheck_schedule`
and :mod:`analysis.reach.recheck_own`.  The saved flowpipe is a *schedule* only: it must be a well-formed,
complete run of this model from this initial box (flowpipe, jump and termination counts; boxes finite and
non-empty; every saved jump a transition of the model whose ``after`` box holds the exact reset image of its
``before`` box; conclusive ends, not the jump bound; the first entry holds the initial box; the saved inputs
cover the model's), and it gives the step per mode (``time_step``, ``schedule.mode_time_steps``), the jump
clustering (``schedule.jump_cluster``) and the jump bound.  Everything else is the re-check's own: its sets per
step (``e^{Aδ}`` enclosed in outward-rounded float intervals, zonotopes mapped without reduction, tubes with the
interpolation error), the requirement's atoms on them (rigorous bounds compared in exact rationals), its guard
parts (exact box clipping, the zonotope's weights, one-row LP duality), reset images and chaining, and the
deadlock checks (:mod:`analysis.reach.deadlock`: the reached part of each invariant face must lie in a guard;
an entry box, or the image of the states before its jump, in the invariant or a guard).  The saved boxes are
never a containment target: runs with ``mode_time_steps``, ``merge_segments`` or ``jump_cluster`` are
re-checked, a saved box that is too small cannot make a false requirement pass, and one that is corrupted
while the requirement holds changes nothing (docs/reachability.md).

**Models with a nonlinear (smooth) mode** — this module with :mod:`analysis.reach.recheck_smooth`: per
flowpipe, from the problem's initial box or the exact reset image of the saved box before the jump, the
re-checker's own zonotope per step; affine modes by an interval Picard box ``W`` and Taylor boxes of order
:data:`TAYLOR_ORDER` in exact rationals (``m`` = 4, 16, 64, 256 time pieces), nonlinear ones by the centred
second-order Taylor map (:data:`SUB_STEPS` sub-steps), then its slope form (:data:`SLOPE_SUB_STEPS`; first on a
wide set).  Every piece must lie in the saved segment box (the saved
times covering the step's), every guard part in the ``before`` box of a saved jump of that transition, every
``after`` box must hold the exact reset image of ``before``; flowpipes ending at the horizon must reach it, those
leaving the invariant must have their states there outside it; no deadlock at the exits and entries
(:func:`exit_uncovered`, :func:`entry_uncovered`); the requirement's atoms are decided in exact rationals on the
re-checker's own sets (box and zonotope).  Inputs are refused in a nonlinear mode.  A segment of an adaptive step
saves its own step (``"step"``): the re-check reads it (a positive finite float, in a nonlinear mode only), sums the
steps in rationals and checks the saved times and the horizon against those sums (:func:`_segment_step`).

Anything failing fails the re-check, with the part and the place; it never passes by looseness.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .fragment import Conj, Disj, LabelAtom, LinearAtom, Nnf, SafetyFragment, label_holds
from .model import AffineHybridModel, affine_model
from .deadlock import clip_exact, contract_zonotope, entry_uncovered
from .recheck_own import OwnFailure
from .recheck_schedule import OWN_PARTS, schedule_recheck
from .recheck_inputs import InputDynamics, InputFlow, InputMismatch, checked_inputs, model_inputs
from .recheck_smooth import SmoothSet, SmoothStepper, StepFailed, reduced

__all__ = ["RecheckResult", "recheck_flowpipe", "RECHECKED_PARTS", "exit_uncovered", "entry_uncovered"]

Box = list[tuple[Fraction, Fraction]]
TAYLOR_ORDER = 4
PICARD_TRIES = 40  # a chain of couplings from a point start widens one coordinate of the chain per try
SUB_STEPS = (1, 2, 8)
"""Sub-steps tried per segment of a nonlinear mode (each a time piece) with the centred Taylor map."""
SUB_STEP_FRACTION = 2
"""A segment with its own (adaptive) step is re-checked with sub-steps of at most ``time_step / SUB_STEP_FRACTION``
times each ``m`` of :data:`SUB_STEPS` and :data:`SLOPE_SUB_STEPS` (a power of two more)."""
SLOPE_SUB_STEPS = (1, 4)
"""Sub-steps tried next with the slope form of the Taylor map (``recheck_smooth.SmoothStepper.slope_taylor``:
wide sets); when these fail too the re-check fails (a bounded number of attempts)."""
RECHECKED_PARTS = ("segments by interval Picard and Taylor boxes", "chaining of flowpipes and their ends",
                   "no deadlock where a flowpipe leaves its invariant or a jump lands",
                   "jumps (guards and resets)", "requirement atoms in exact rationals")


@dataclass(frozen=True, kw_only=True, slots=True)
class RecheckResult:
    """The re-check's answer: ``passed`` and, if not, the first ``failure`` (part and place).

    ``margin`` is the exact smallest slack of the requirement over the saved boxes (a float
    rounded down; ``None`` when the re-check stopped before the requirement).
    """

    passed: bool
    failure: str
    segments: int
    jumps: int
    margin: float | None
    parts: tuple[str, ...] = RECHECKED_PARTS


class _Fail(Exception):
    pass


def _down(q: Fraction) -> Fraction:
    f = float(q)
    if Fraction(f) > q:
        f = math.nextafter(f, -math.inf)
    return Fraction(f)


def _up(q: Fraction) -> Fraction:
    f = float(q)
    if Fraction(f) < q:
        f = math.nextafter(f, math.inf)
    return Fraction(f)


def _outward(box: Box) -> Box:
    return [(_down(lo), _up(hi)) for lo, hi in box]


def _matvec(m: Sequence[Sequence[Fraction]], box: Box) -> Box:
    """The exact range of ``M x`` over the box (row by row)."""
    out = []
    for row in m:
        lo = sum((min(a * l, a * h) for a, (l, h) in zip(row, box)), Fraction(0))
        hi = sum((max(a * l, a * h) for a, (l, h) in zip(row, box)), Fraction(0))
        out.append((lo, hi))
    return out


def _add(a: Box, b: Box) -> Box:
    return [(p[0] + q[0], p[1] + q[1]) for p, q in zip(a, b)]


def _shift(a: Box, v: Sequence[Fraction]) -> Box:
    return [(p[0] + x, p[1] + x) for p, x in zip(a, v)]


def _scale0(a: Box, s: Fraction) -> Box:
    """``[0, s]·a`` (``s >= 0``): the hull of 0 and ``s a``."""
    return [(min(Fraction(0), s * lo), max(Fraction(0), s * hi)) for lo, hi in a]


def _hull(a: Box, b: Box) -> Box:
    return [(min(p[0], q[0]), max(p[1], q[1])) for p, q in zip(a, b)]


def _meet(a: Box, b: Box) -> Box | None:
    out = [(max(p[0], q[0]), min(p[1], q[1])) for p, q in zip(a, b)]
    return None if any(lo > hi for lo, hi in out) else out


def _inside(a: Box, b: Box, strict: bool = False) -> bool:
    if strict:
        return all(q[0] < p[0] and p[1] < q[1] for p, q in zip(a, b))
    return all(q[0] <= p[0] and p[1] <= q[1] for p, q in zip(a, b))


def _matmul(a: Sequence[Sequence[Fraction]], b: Sequence[Sequence[Fraction]]) -> list[list[Fraction]]:
    return [[sum((a[i][k] * b[k][j] for k in range(len(b))), Fraction(0)) for j in range(len(b[0]))]
            for i in range(len(a))]


def _clip(box: Box, halfspaces: Sequence[Any]) -> Box | None:
    """A box holding ``box ∩ {a·x <= b}`` (exact interval propagation, one round); ``None`` when proven empty."""
    return clip_exact(box, halfspaces, rounds=1)


def _clip_union(box: Box, polyhedra: Sequence[Any]) -> Box | None:
    boxes = [c for p in polyhedra if (c := _clip(box, p.halfspaces)) is not None]
    if not boxes:
        return None
    result = boxes[0]
    for c in boxes[1:]:
        result = _hull(result, c)
    return result


@dataclass(slots=True)
class _Mode:
    a: list[list[Fraction]]
    c: list[Fraction]
    invariant: Any
    power: list[list[Fraction]]  # A^p

    def f(self, box: Box) -> Box:
        return _shift(_matvec(self.a, box), self.c)

    def taylor(self, s: Fraction) -> tuple[list[list[Fraction]], list[Fraction]]:
        """``M(s) = Σ_{i<=p} (sA)^i/i!`` and ``N(s) c`` with ``N(s) = Σ_{1<=i<=p} s^i A^{i-1}/i!``."""
        n = len(self.a)
        m = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
        term = [row[:] for row in m]
        nc = [Fraction(0)] * n
        cterm = list(self.c)  # A^{i-1} c
        fact = 1
        for i in range(1, TAYLOR_ORDER + 1):
            fact *= i
            term = _matmul(term, self.a)
            m = [[x + y * s ** i / fact for x, y in zip(r, t)] for r, t in zip(m, term)]
            nc = [x + y * s ** i / fact for x, y in zip(nc, cterm)]
            cterm = [sum((self.a[r][k] * cterm[k] for k in range(n)), Fraction(0)) for r in range(n)]
        return m, nc


@dataclass(slots=True)
class _Zono:
    """The re-checker's own set ``{center + Σ gens[j] ξ_j : |ξ| <= 1} ⊕ [-err, err]`` (float-valued rationals)."""

    center: list[Fraction]
    gens: list[list[Fraction]]  # columns
    err: list[Fraction]

    @staticmethod
    def of_box(box: Box) -> "_Zono":
        n = len(box)
        center = [(lo + hi) / 2 for lo, hi in box]
        gens = [[(hi - lo) / 2 if i == j else Fraction(0) for i in range(n)] for j, (lo, hi) in enumerate(box)]
        return _Zono(center=center, gens=[g for g in gens if any(g)], err=[Fraction(0)] * n).rounded()

    def rounded(self) -> "_Zono":
        """Every number rounded to the nearest float, the rounding moved into ``err`` (rounded up)."""
        err = list(self.err)
        center = []
        for i, v in enumerate(self.center):
            f = Fraction(float(v))
            err[i] += abs(v - f)
            center.append(f)
        gens = []
        for g in self.gens:
            col = []
            for i, v in enumerate(g):
                f = Fraction(float(v))
                err[i] += abs(v - f)
                col.append(f)
            gens.append(col)
        return _Zono(center=center, gens=gens, err=[_up(e) for e in err])

    def mapped(self, m: Sequence[Sequence[Fraction]], shift: Sequence[Fraction], extra: Box | None = None) -> "_Zono":
        """``M Z + shift (+ extra box)``, exact, then :meth:`rounded`."""
        n = len(m)
        center = [sum((m[i][k] * self.center[k] for k in range(n)), Fraction(0)) + shift[i] for i in range(n)]
        gens = [[sum((m[i][k] * g[k] for k in range(n)), Fraction(0)) for i in range(n)] for g in self.gens]
        err = [sum((abs(m[i][k]) * self.err[k] for k in range(n)), Fraction(0)) for i in range(n)]
        if extra is not None:
            center = [c + (lo + hi) / 2 for c, (lo, hi) in zip(center, extra)]
            err = [e + (hi - lo) / 2 for e, (lo, hi) in zip(err, extra)]
        return _Zono(center=center, gens=gens, err=err).rounded()

    def hull(self) -> Box:
        """The exact interval hull."""
        out = []
        for i, c in enumerate(self.center):
            r = sum((abs(g[i]) for g in self.gens), Fraction(0)) + self.err[i]
            out.append((c - r, c + r))
        return out


def _halfspace_in(a: Sequence[Fraction], b: Fraction, row: Any) -> bool:
    """Whether ``{x : a·x >= b}`` lies in ``{x : g·x <= e}`` (exact: ``g = −λ a`` with ``λ >= 0`` and ``−λ b <= e``)."""
    g, e = row.normal, row.offset
    if not any(g):
        return e >= 0
    k = next(i for i, v in enumerate(a) if v != 0) if any(a) else None
    if k is None:
        return False
    lam = -g[k] / a[k]
    return lam >= 0 and all(gi == -lam * ai for gi, ai in zip(g, a)) and -lam * b <= e


def exit_uncovered(model: AffineHybridModel, mode: str, boxes: Sequence[Box] | None = None) -> str | None:
    """``None`` when every state where a flow of ``mode`` can leave its invariant enables a transition.

    Sufficient check (exact): the invariant is one polyhedron, and for each of its rows ``a·x <= b`` the
    closed outside ``a·x >= b`` lies in the guard of some outgoing transition (a guard polyhedron whose
    rows all contain it).  With ``boxes`` (boxes holding the flowed states of the mode), only the rows
    some box reaches (``max a·x >= b`` over it) are checked.  Otherwise the message: a flow reaching
    that face may deadlock, which the executor reports as an early end; reachability then proves nothing.
    """
    invariant = model.modes[mode].invariant
    if len(invariant) == 1 and not invariant[0].halfspaces:
        return None
    if len(invariant) != 1:
        return f"mode {mode!r}: a disjunctive invariant (deadlock freedom at its exits is not checked)"
    for h in invariant[0].halfspaces:
        if boxes is not None and not any(
                sum((max(a * lo, a * hi) for a, (lo, hi) in zip(h.normal, box)), Fraction(0)) >= h.offset
                for box in boxes):
            continue
        if not any(all(_halfspace_in(h.normal, h.offset, row) for row in poly.halfspaces)
                   for t in model.outgoing(mode) for poly in t.guard):
            return (f"mode {mode!r}: where the flow leaves the invariant ({h.text or 'a face'}) no guard is "
                    "shown enabled (a possible deadlock: the run would end early)")
    return None


def _picard(mode: _Mode, x: Box, step: Fraction) -> Box:
    """A box ``W`` with ``X + [0, δ] f(W) ⊂ int W`` (raises when none is found in :data:`PICARD_TRIES` tries)."""
    w = _hull(x, _add(x, _scale0(mode.f(x), step)))
    for _ in range(PICARD_TRIES):
        grow = [max(hi - lo, Fraction(1, 10 ** 9) * (1 + abs(lo) + abs(hi))) for lo, hi in w]
        w = _outward([(lo - g / 8, hi + g / 8) for (lo, hi), g in zip(w, grow)])
        image = _add(x, _scale0(mode.f(w), step))
        if _inside(image, w, strict=True):
            return w
        w = _hull(w, image)
    raise _Fail(f"no a-priori box found by the Picard operator in {PICARD_TRIES} tries (the step is too large for "
                "the re-check)")


def _taylor_set(mode: _Mode, z: _Zono, s: Fraction, rem: Box, cache: dict[Fraction, Any]) -> _Zono:
    """The states at ``s`` after the start: ``M(s) Z + N(s) c + [0, s^{p+1}/(p+1)!]·A^p f(W)``."""
    if s not in cache:
        cache[s] = mode.taylor(s)
    m, nc = cache[s]
    fact = math.factorial(TAYLOR_ORDER + 1)
    return z.mapped(m, nc, _scale0(rem, s ** (TAYLOR_ORDER + 1) / fact))


def _pieces(mode: _Mode, z: _Zono, step: Fraction, m: int, w: Box, rem: Box, afw: Box,
            cache: dict[Fraction, Any], tube: Any = None) -> list[tuple[Box, _Zono]]:
    """The tube in ``m`` time pieces: (the piece's box ``∩ W`` clipped to the invariant, a set holding the
    piece: ``Y_j ⊕ [0, h]·f(W)``); empty pieces dropped."""
    h = step / m
    n = len(mode.a)
    one = [[Fraction(int(i == j)) + h * v for j, v in enumerate(row)] for i, row in enumerate(mode.a)]
    eye = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    drift = _scale0(mode.f(w), h)
    out = []
    for j in range(m):
        y = _taylor_set(mode, z, j * h, rem, cache)
        moved = y.mapped(one, [h * v for v in mode.c])
        piece = _meet(_add(_hull(y.hull(), moved.hull()), _scale0(afw, h * h / 2)), w)
        inputs = None if tube is None else tube((j + 1) * h)  # the step's inputs up to the piece's end
        piece = piece if inputs is None or piece is None else _add(piece, inputs)
        clipped = None if piece is None else _clip_union(_outward(piece), mode.invariant)
        if clipped is not None:
            out.append((clipped, y.mapped(eye, [Fraction(0)] * n, drift if inputs is None else _add(drift, inputs))))
    return out


def _contract(z: _Zono, rows: Sequence[Any]) -> Box | None:
    """A box holding ``z ∩ {a·x <= b for each row}``: the generators' weights ``ξ ∈ [-1, 1]`` (and the error
    box's) narrowed by interval propagation through each row (3 rounds, exact rationals); ``None``: empty."""
    n = len(z.center)
    gens = list(z.gens) + [[e if i == k else Fraction(0) for i in range(n)] for k, e in enumerate(z.err) if e]
    return contract_zonotope(z.center, gens, rows, rounds=3)


@dataclass(slots=True)
class _SmoothMode:
    """A mode with a nonlinear flow: re-checked by :class:`~analysis.reach.recheck_smooth.SmoothStepper`."""

    stepper: SmoothStepper
    invariant: Any


def _hull_zono(start: SmoothSet, end: SmoothSet, bend: Sequence[Fraction]) -> _Zono:
    """A zonotope holding every state of one sub-step: the convex hull of its two ends (same generator weights:
    ``end = M start + box``, columns aligned) plus the interpolation error ``bend`` (exact rationals).

    ``λ a + (1 − λ) b`` with ``a = c + G ξ``, ``b = c' + G' ξ + e`` lies in
    ``(c + c')/2 + (G + G')/2 ξ + (c − c')/2 μ + (G − G')/2 ξ'`` ``⊕ [−|e|, |e|]`` (``μ = 2λ − 1``,
    ``ξ' = μ ξ``, all in ``[−1, 1]``); the guard check (:func:`_contract`) narrows ``μ``.
    """
    n = start.center.size
    m = start.gens.shape[1]
    c0 = [Fraction(float(v)) for v in start.center]
    c1 = [Fraction(float(v)) for v in end.center]
    g0 = [[Fraction(float(v)) for v in start.gens[:, j]] for j in range(m)]
    g1 = [[Fraction(float(v)) for v in end.gens[:, j]] for j in range(m)]
    gens = [[(a + b) / 2 for a, b in zip(x, y)] for x, y in zip(g0, g1)]
    gens += [[(a - b) / 2 for a, b in zip(c0, c1)]]
    gens += [[(a - b) / 2 for a, b in zip(x, y)] for x, y in zip(g0, g1)]
    err = [Fraction(float(start.err[i])) + Fraction(float(end.err[i])) + bend[i] for i in range(n)]
    return _Zono(center=[(a + b) / 2 for a, b in zip(c0, c1)], gens=[g for g in gens if any(g)], err=err).rounded()


def _smooth_step(mode: _SmoothMode, z: _Zono, step: Fraction, saved: Box,
                 covered: Any, base: Fraction | None = None) -> tuple[_Zono, list[tuple[Box, _Zono | None]]]:
    """:func:`_step` for a nonlinear mode (:class:`~analysis.reach.recheck_smooth.SmoothStepper`): ``m`` sub-steps
    of ``δ/m`` (``m`` from :data:`SUB_STEPS` with the centred Taylor map, then from :data:`SLOPE_SUB_STEPS` with its
    slope form; the slope form first on a wide set), each a time piece: its box and the zonotope of
    :func:`_hull_zono`.  ``base``: the run's step, given for a segment with its own (adaptive) step: every ``m`` is
    multiplied by the least power of two ``p`` with ``step / p <= base / SUB_STEP_FRACTION`` (a precision choice:
    any sub-steps are sound)."""
    first = SmoothSet(center=np.array([float(v) for v in z.center]),
                      gens=np.array([[float(v) for v in g] for g in z.gens]).T.reshape(len(z.center), -1),
                      err=np.array([float(v) for v in z.err]))
    problem = ""
    try:
        whole = mode.stepper.prepare(reduced(first), float(step))
        attempts = [(m, False) for m in SUB_STEPS] + [(m, True) for m in SLOPE_SUB_STEPS]
        if mode.stepper.is_wide(whole):  # the slope form first (a precision choice: both forms are sound)
            attempts = attempts[len(SUB_STEPS):] + attempts[:len(SUB_STEPS)]
        scale = 1
        while base is not None and step / scale > base / SUB_STEP_FRACTION and scale < 2 ** 20:
            scale *= 2
        for m, slope in attempts:
            m *= scale
            h = float(step / m)  # exact: a float divided by a power of two (the sub-steps sum to δ exactly)
            if Fraction(h) * m != step:
                raise StepFailed(f"the step {float(step)!r} s is not divisible by {m} in floating point")
            current = reduced(first)
            pieces: list[tuple[Box, _Zono | None]] = []
            for _ in range(m):
                pre = whole if m == 1 else mode.stepper.prepare(current, h)
                after = (mode.stepper.slope_taylor if slope else mode.stepper.taylor)(current, h, pre)
                lo, hi = current.hull()
                lo2, hi2 = after.hull()
                q_lo, q_hi = pre["qw"]
                w_lo, w_hi = pre["w"]
                bend = [Fraction(h) ** 2 / 8 * Fraction(float(max(abs(a), abs(b)))) for a, b in zip(q_lo, q_hi)]
                box = [(max(Fraction(float(w0)), min(Fraction(float(a)), Fraction(float(a2))) - e),
                        min(Fraction(float(w1)), max(Fraction(float(b)), Fraction(float(b2))) + e))
                       for a, b, a2, b2, e, w0, w1 in zip(lo, hi, lo2, hi2, bend, w_lo, w_hi)]
                clipped = _clip_union(box, mode.invariant)
                if clipped is not None:
                    # built only when a guard or the requirement needs it (exact rationals are slow)
                    pieces.append((clipped, functools.partial(_hull_zono, current, after, bend)))
                current = reduced(after)
            outside = next((p for p, _ in pieces if not _inside(p, saved)), None)
            if outside is not None:
                problem = (f"the re-checked tube piece [{[float(v[0]) for v in outside]}, "
                           f"{[float(v[1]) for v in outside]}] is not inside the saved box "
                           f"[{[float(v[0]) for v in saved]}, {[float(v[1]) for v in saved]}]")
                continue
            problem = covered(pieces) or ""
            if not problem:
                return _Zono(center=[Fraction(float(v)) for v in current.center],
                             gens=[[Fraction(float(v)) for v in col] for col in current.gens.T],
                             err=[Fraction(float(v)) for v in current.err]), pieces
    except StepFailed as fail:
        raise _Fail(str(fail)) from None
    raise _Fail(problem)


def _widen(z: _Zono, carry: InputFlow | None) -> _Zono:
    """``z ⊕ S_k`` (the carried inputs, a zero-centred zonotope, as generators), or ``z`` without inputs."""
    return z if carry is None else _Zono(center=z.center, err=z.err, gens=z.gens + carry.generators())


def _step(mode: Any, z: _Zono, step: Fraction, saved: Box, cache: dict[Fraction, Any],
          covered: Any, carry: InputFlow | None = None, base: Fraction | None = None
          ) -> tuple[_Zono, list[tuple[Box, _Zono]]]:
    """Check one segment (the tube inside the saved box, its guard parts covered by saved jumps);
    the set at the step's end (not clipped to the invariant: a superset of the states still flowing).

    ``covered(pieces)`` returns ``None`` or the first uncovered guard part (a message).  Both checks
    are retried with ``m = 4, 16, 64, 256`` time pieces before failing.
    """
    if isinstance(mode, _SmoothMode):
        if carry is not None:  # refused in _run already; never re-check a nonlinear mode without its inputs
            raise _Fail("inputs in a nonlinear mode are not re-checked")
        return _smooth_step(mode, z, step, saved, covered, base)
    start = _widen(z, carry)
    w = _picard(mode, _outward(start.hull()), step)
    fw = mode.f(w)
    rem = _matvec(mode.power, fw)  # A^p f(W)
    afw = _matvec(mode.a, fw)  # A f(W)
    problem = ""
    for m in (4, 16, 64, 256):
        pieces = _pieces(mode, start, step, m, w, rem, afw, cache, None if carry is None else carry.tube)
        outside = next((p for p, _ in pieces if not _inside(p, saved)), None)
        if outside is not None:
            problem = (f"the re-checked tube piece [{[float(v[0]) for v in outside]}, {[float(v[1]) for v in outside]}]"
                       f" is not inside the saved box [{[float(v[0]) for v in saved]}, "
                       f"{[float(v[1]) for v in saved]}]")
            continue
        problem = covered(pieces) or ""
        if not problem:
            return _taylor_set(mode, z, step, rem, cache), pieces
    raise _Fail(problem)


def _value(node: Nnf, box: Box, mode: str, zono: _Zono | None = None) -> tuple[bool, Fraction | None]:
    """(holds on the whole set, its exact slack; ``None`` for label-only parts) on ``box`` (∩ ``zono``)."""
    if isinstance(node, LabelAtom):
        return label_holds(node, mode), None
    if isinstance(node, LinearAtom):
        c = node.coefficients
        top = sum((max(a * lo, a * hi) for a, (lo, hi) in zip(c, box)), Fraction(0))
        if zono is not None:
            around = sum((a * v for a, v in zip(c, zono.center)), Fraction(0))
            spread = sum((abs(sum((a * v for a, v in zip(c, g)), Fraction(0))) for g in zono.gens), Fraction(0))
            top = min(top, around + spread + sum((abs(a) * e for a, e in zip(c, zono.err)), Fraction(0)))
        slack = node.bound - top
        return (slack > 0 if node.strict else slack >= 0), slack
    return _combine(node, [_value(p, box, mode, zono) for p in node.parts])


def _combine(node: Nnf, results: list[tuple[bool, Fraction | None]]) -> tuple[bool, Fraction | None]:
    """And/or of parts; a slack ``None`` is a part without a numeric constraint (a label atom)."""
    slacks = [v for _, v in results if v is not None]
    if isinstance(node, Conj):
        return all(ok for ok, _ in results), (min(slacks) if slacks else None)
    ok = any(o for o, _ in results)
    good = [v for o, v in results if o]
    if ok and any(v is None for v in good):
        return True, None  # a label disjunct holds: no numeric constraint on this box
    return ok, (max(good) if good else (max(slacks) if slacks else None))


@dataclass(slots=True)
class _Pipe:
    mode: str
    start: Box
    t_lo: Fraction
    t_hi: Fraction
    segments: list[dict[str, Any]]
    termination: dict[str, Any]
    before: Box | None = None  # the box a jump left from: the start set is its exact reset image
    transition: str | None = None


def _box_of(pair: Sequence[Sequence[float]]) -> Box:
    return [(Fraction(lo), Fraction(hi)) for lo, hi in zip(pair[0], pair[1])]


def _pipes(data: Mapping[str, Any], initial: Box, initial_mode: str) -> list[_Pipe]:
    groups: list[list[dict[str, Any]]] = []
    for seg in data["segments"]:
        if seg["entry"]:
            groups.append([])
        if not groups:
            raise _Fail("chaining: the first saved segment is not an entry segment")
        groups[-1].append(seg)
    jumps, ends = data["jumps"], data["terminations"]
    if len(groups) != len(ends) or len(groups) != len(jumps) + 1:
        raise _Fail(f"chaining: {len(groups)} flowpipes, {len(ends)} terminations and {len(jumps)} jumps do not match "
                    "(one flowpipe per termination, one per jump plus the initial one)")
    pipes = [_Pipe(mode=initial_mode, start=initial, t_lo=Fraction(0), t_hi=Fraction(0), segments=groups[0],
                   termination=ends[0])]
    for j, group, end in zip(jumps, groups[1:], ends[1:]):
        pipes.append(_Pipe(mode=j["target"], start=_box_of(j["after"]), t_lo=Fraction(j["t"][0]),
                           t_hi=Fraction(j["t"][1]), segments=group, termination=end, before=_box_of(j["before"]),
                           transition=j["transition"]))
    return pipes


def recheck_flowpipe(saved: str | Mapping[str, Any], system: Any, initial: Mapping[str, tuple[float, float]],
                     fragment: SafetyFragment, *, initial_mode: str | None = None,
                     inputs: Mapping[str, Any] | None = None) -> RecheckResult:
    """Re-check a reachability proof of ``fragment`` from the saved flowpipe (see the module docstring).

    Parameters
    ----------
    saved : str or mapping
        :meth:`ReachResult.to_json` text (or its parsed dict).
    system : hybrid.system.HybridSystem
        The symbolic system the flowpipe claims to cover.
    initial : mapping {state: (lo, hi)}
        The initial box (the problem's, not the saved one).
    fragment : SafetyFragment
    initial_mode : str or None
        Default: the automaton's initial mode.
    inputs : mapping {mode: ModeInput or (B, (lo, hi))} or None
        The model's bounded inputs (:mod:`analysis.reach.recheck_inputs`); the saved JSON must carry them.
        The re-check is about the system and the inputs given: a flowpipe saved with inputs, re-checked without
        them, confirms the input-free system only (a caller proving a claim about the inputs must pass them).

    Returns
    -------
    RecheckResult
        ``passed`` only when every part (a)–(d) was decided and holds.
    """
    model = affine_model(system, nonlinear=True)
    if set(initial) != set(model.state_names) or not all(
            isinstance(v, (tuple, list)) and len(v) == 2 and all(math.isfinite(float(e)) for e in v) and v[0] <= v[1]
            for v in initial.values()):
        from hybrid.errors import ParameterError

        raise ParameterError("initial", dict(initial), f"{{state: (lo, hi)}} for exactly {list(model.state_names)}",
                             "give the box the flowpipe was computed from")
    try:
        given = model_inputs(inputs, len(model.state_names))
    except (InputMismatch, TypeError, ValueError) as exc:
        from hybrid.errors import ParameterError

        raise ParameterError("inputs", inputs, f"{{mode: ModeInput(matrix=B, bounds=(lo, hi))}}, B with "
                             f"{len(model.state_names)} rows", f"give the model's inputs ({exc})") from None
    try:
        data = json.loads(saved) if isinstance(saved, str) else saved
        return _run(data, model, initial, fragment, initial_mode or model.initial_mode, given)
    except (_Fail, InputMismatch, OwnFailure) as fail:
        return RecheckResult(passed=False, failure=str(fail), segments=0, jumps=0, margin=None)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        return RecheckResult(passed=False, failure=f"the saved flowpipe is malformed: {exc!r}", segments=0, jumps=0,
                             margin=None)


def _run(data: Mapping[str, Any], model: AffineHybridModel, initial: Mapping[str, tuple[float, float]],
         fragment: SafetyFragment, initial_mode: str, given: Mapping[str, Any]) -> RecheckResult:
    names = model.state_names
    given = checked_inputs(data, given, len(names))
    if tuple(data["state_names"]) != names or tuple(fragment.state_names) != names:
        raise _Fail(f"the saved states {data['state_names']} are not the system's {list(names)}")
    step, horizon = Fraction(data["time_step"]), Fraction(data["horizon"])
    if horizon < Fraction(fragment.end):
        raise _Fail(f"the saved horizon {float(horizon)} s ends before the window's end {fragment.end} s")
    start = [(Fraction(initial[k][0]), Fraction(initial[k][1])) for k in names]
    if all(m.smooth is None for m in model.modes.values()):  # affine: the own-set re-check (recheck_own)
        own = schedule_recheck(data, model, start, initial_mode, fragment, given)
        return RecheckResult(passed=True, failure="", segments=own.segments, jumps=own.jumps, parts=OWN_PARTS,
                             margin=None if own.margin is None else float(_down(own.margin)))
    modes: dict[str, Any] = {}
    for name, m in model.modes.items():
        if m.smooth is not None:
            if name in given:
                raise _Fail(f"inputs: mode {name!r} has a nonlinear flow and a bounded input; the re-check takes "
                            "inputs only in modes with affine flows (analysis.reach.recheck_inputs), so it cannot "
                            "re-check this flowpipe")
            modes[name] = _SmoothMode(stepper=SmoothStepper(m.smooth), invariant=m.invariant)
            continue
        a = [list(r) for r in m.a]
        power = [[Fraction(int(i == j)) for j in range(len(a))] for i in range(len(a))]
        for _ in range(TAYLOR_ORDER):
            power = _matmul(power, a)
        c = [x + y for x, y in zip(m.c, given[name].shift())] if name in given else list(m.c)  # B u_c
        modes[name] = _Mode(a=a, c=c, invariant=m.invariant, power=power)
    flows = {name: InputDynamics(a=modes[name].a, spec=spec, step=step) for name, spec in given.items()}
    pipes = _pipes(data, start, initial_mode)
    jumps = data["jumps"]
    for j, jump in enumerate(jumps):
        _check_reset(model, jump, j)
    margin: Fraction | None = None
    count = 0
    for i, pipe in enumerate(pipes):
        for k, sets, t_lo, t_hi in _segments(pipe, modes[pipe.mode], step, horizon, model, jumps, i,
                                             flows.get(pipe.mode)):
            count += 1
            if t_lo > Fraction(fragment.end) or t_hi < Fraction(fragment.start):
                continue
            for box, zono in sets:
                ok, slack = _value(fragment.body, box, pipe.mode, None if callable(zono) else zono)
                if callable(zono) and not ok:  # a nonlinear piece: its zonotope only when the box does not decide
                    ok, slack = _value(fragment.body, box, pipe.mode, zono())
                if not ok:
                    raise _Fail(f"requirement: the atoms do not hold on the re-checked states of flowpipe {i} "
                                f"segment {k} (mode {pipe.mode!r}, t in [{float(t_lo):.6g}, {float(t_hi):.6g}] s)")
                if slack is not None:
                    margin = slack if margin is None else min(margin, slack)
    return RecheckResult(passed=True, failure="", segments=count, jumps=len(jumps),
                         margin=None if margin is None else float(_down(margin)))


def _check_reset(model: AffineHybridModel, jump: Mapping[str, Any], j: int) -> None:
    t = next((t for t in model.transitions if t.name == jump["transition"]), None)
    if t is None or t.source != jump["source"] or t.target != jump["target"]:
        raise _Fail(f"jump {j}: {jump['transition']!r} from {jump['source']!r} to {jump['target']!r} is not a "
                    "transition of the system")
    image = _shift(_matvec(t.r_matrix, _box_of(jump["before"])), t.r_offset)
    if not _inside(image, _box_of(jump["after"])):
        raise _Fail(f"jump {j} ({t.name}): the reset image of the box before is not inside the box after")


def _segments(pipe: _Pipe, mode: _Mode, step: Fraction, horizon: Fraction, model: AffineHybridModel,
              jumps: Sequence[Mapping[str, Any]], index: int, flow: InputDynamics | None = None) -> Any:
    """Yield (k, the re-checked sets [(box, zonotope or None)], saved t_lo, t_hi) of each segment after checking it
    (parts a–c); the saved times cover the step's exact times."""
    entry = pipe.segments[0]
    box = _box_of(entry["box"])
    if entry["mode"] != pipe.mode or not _inside(pipe.start, box) or Fraction(entry["t"][0]) > pipe.t_lo \
            or Fraction(entry["t"][1]) < pipe.t_hi:
        raise _Fail(f"chaining: the entry segment of flowpipe {index} does not hold its start set (mode, box or times)")
    why = _jumps_from(model, pipe.mode, pipe.start, pipe.t_lo, pipe.t_hi, jumps, index, flowed=False) \
        or entry_uncovered(model, pipe.mode, pipe.start)
    if why:
        raise _Fail(why)
    yield -1, [(pipe.start, None)], Fraction(entry["t"][0]), Fraction(entry["t"][1])
    x = _Zono.of_box(pipe.start)
    if pipe.before is not None:  # the exact reset image of the box before the jump (inside ``after``: checked)
        t = next(t for t in model.transitions if t.name == pipe.transition)
        x = _Zono.of_box(pipe.before).mapped(t.r_matrix, t.r_offset)
    carry = None if flow is None else flow.start()
    cache: dict[Fraction, Any] = {}
    local = Fraction(0)  # the exact local time of the segment's start: the sum of the steps before it
    for k, seg in enumerate(pipe.segments[1:]):
        own = _segment_step(seg, mode, step, index, k)
        t_lo, t_hi = pipe.t_lo + local, pipe.t_hi + local + own
        if seg["mode"] != pipe.mode or Fraction(seg["t"][0]) > t_lo or Fraction(seg["t"][1]) < t_hi:
            raise _Fail(f"segments: flowpipe {index} segment {k}: mode or times do not cover "
                        f"[{float(t_lo):.9g}, {float(t_hi):.9g}] s")
        saved = _box_of(seg["box"])

        def covered(pieces: list[Box], t_lo: Fraction = t_lo, t_hi: Fraction = t_hi) -> str | None:
            for piece, zono in pieces:
                why = _jumps_from(model, pipe.mode, piece, t_lo, t_hi, jumps, index, flowed=True, zono=zono)
                if why:
                    return why
            return None

        try:
            x, pieces = _step(mode, x, own, saved, cache, covered, carry, step if "step" in seg else None)
        except _Fail as fail:
            raise _Fail(f"segments: flowpipe {index} (mode {pipe.mode!r}) segment {k}: {fail}") from None
        if carry is not None:
            carry.advance()
        local += own
        yield k, pieces, Fraction(seg["t"][0]), Fraction(seg["t"][1])
    _check_end(pipe, len(pipe.segments) - 1, _widen(x, carry), local, horizon, index, mode.invariant)
    flowed = [_box_of(seg["box"]) for seg in pipe.segments[1:]]
    why = exit_uncovered(model, pipe.mode, None if pipe.termination["reason"] == "left_invariant" else flowed)
    if why:
        raise _Fail(f"ends: flowpipe {index}: {why}")


def _segment_step(seg: Mapping[str, Any], mode: Any, step: Fraction, index: int, k: int) -> Fraction:
    """The step of a saved segment: its own ``"step"`` (an adaptive step, in a nonlinear mode only: a positive
    finite float, read as the exact rational of that float), else the run's ``step``."""
    if "step" not in seg:
        return step
    value = seg["step"]
    if not isinstance(mode, _SmoothMode):
        raise _Fail(f"segments: flowpipe {index} segment {k} carries its own step in a mode with an affine flow "
                    "(adaptive steps are taken in nonlinear modes only)")
    number = math.nan
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        number = float(value) if isinstance(value, float) or abs(value) < 2 ** 1000 else math.inf
    if not (math.isfinite(number) and number > 0):
        raise _Fail(f"segments: flowpipe {index} segment {k}: its step {value!r} is not a positive finite number")
    return Fraction(number)


def _check_end(pipe: _Pipe, flowed: int, x: Any, elapsed: Fraction, horizon: Fraction, index: int,
               invariant: Any) -> None:
    """The flowpipe's end (``elapsed``: the exact sum of its steps) against its saved termination."""
    reason = pipe.termination["reason"]
    if reason == "horizon":
        if pipe.t_lo + elapsed <= horizon:
            raise _Fail(f"ends: flowpipe {index} claims the horizon but its {flowed} steps end at "
                        f"{float(pipe.t_lo + elapsed):.9g} s <= {float(horizon):.9g} s")
    elif reason == "left_invariant":
        if _clip_union(_outward(x.hull()), invariant) is not None:
            raise _Fail(f"ends: flowpipe {index} claims to leave the invariant of {pipe.mode!r} after {flowed} steps, "
                        "but the re-checked states there are not all outside it")
    else:
        raise _Fail(f"ends: flowpipe {index} ended with {reason!r}: the flowpipe does not cover every behaviour "
                    "(a jump bound or a limit); nothing is proven")


def _jumps_from(model: AffineHybridModel, mode: str, box: Box, t_lo: Fraction, t_hi: Fraction,
                jumps: Sequence[Mapping[str, Any]], index: int, *, flowed: bool, zono: _Zono | None = None
                ) -> str | None:
    """``None`` when every part of ``box`` in a guard lies in a saved jump's box before; else the message."""
    invariant = model.modes[mode].invariant
    for t in model.outgoing(mode):
        for guard in t.guard:
            for inv in (invariant if flowed else (None,)):
                rows = guard.halfspaces + (inv.halfspaces if inv is not None else ())
                part = _clip(box, rows)
                if part is not None and zono is not None:
                    narrow = _contract(zono() if callable(zono) else zono, rows)
                    part = None if narrow is None else _meet(part, narrow)
                if part is None:
                    continue
                # the times first: cheaper than the box (the same conjunction)
                if not any(j["transition"] == t.name and Fraction(j["t"][0]) <= t_lo and Fraction(j["t"][1]) >= t_hi
                           and _inside(part, _box_of(j["before"])) for j in jumps):
                    return (f"jumps: flowpipe {index} (mode {mode!r}) may take {t.name!r} from "
                            f"[{[float(v[0]) for v in part]}, {[float(v[1]) for v in part]}] at t in "
                            f"[{float(t_lo):.6g}, {float(t_hi):.6g}] s, which no saved jump covers")
    return None
