"""Unbounded time by the arbitrary-switching relaxation: a box ``W`` the relaxation maps into itself.

Some automata switch among locations under timing rules (dwell clocks, guards on clocks) while the other states
follow affine flows that never read the clocks and that no transition resets (ARCH-COMP's PLAN01 platoon: a clock
``t``, ``t >= 10`` to break, ``t <= 20`` in each location, ``t := 0`` on each switch; ``e, v, a`` untouched).

**The clock-free projection** (:func:`clock_free`).  The *clocks* are the states some transition does not keep
(a reset row other than the identity).  If no flow, reset or requirement of the other states reads a clock and every
transition keeps the other states, every run's projection on the other states is a run of the projected automaton:
the same flows on the kept states, the invariants' and guards' halfspaces on kept states only (those on clocks alone
dropped: a weaker automaton), identity resets.  A halfspace that mixes a clock with a kept state is refused.

**The induction** (:func:`relaxed_induction`).  The projection's locations then switch freely
(:func:`analysis.reach.relaxed.switching_group`): every run of the original is, on the kept states, a solution of the
time-invariant inclusion ``ẋ ∈ conv{A_i x + c_i} + B U``.  With ``R_s(W)`` its reach set at time ``s`` from ``W``:
if the initial box lies in ``W``, ``R_T(W) ⊆ W`` and ``R_s(W)`` is safe for ``s ∈ [0, T]``, then every solution has
``x(kT) ∈ W`` for all ``k`` (induction) and ``x(kT + s) ∈ R_s(W)``: it is safe for all ``t >= 0``.  One flowpipe of the
relaxation from ``W`` (:func:`analysis.reach.relaxed.relaxed_reach`) decides both, as two requirements:
``always[0, T] φ`` and ``always[T, T] x ∈ W``; both are re-checked by
:func:`analysis.reach.recheck_relaxed.recheck_relaxed` on its own sets (by the caller), and the projection by
:func:`analysis.reach.recheck_relaxed.recheck_projection`.  ``W`` is found from the relaxation's flowpipe from the
initial box over :data:`PROBE` s: the hull of its last quarter, widened by :data:`WIDEN` of its width.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from .affine import Halfspace, Polyhedron
from .fragment import Conj, Disj, LabelAtom, LinearAtom, Nnf, SafetyFragment
from .model import AffineHybridModel, AffineMode, AffineTransition
from .relaxed import NoGroup, relaxed_reach, switching_group
from .verdict import MAX_SEGMENTS, decide

__all__ = ["ClockFree", "clock_free", "RelaxedInduction", "relaxed_induction", "PROBE", "WIDEN", "KAPPA"]

PROBE = 60.0
"""Seconds of the relaxation's flowpipe from the initial box (and from ``W``): long enough for a stable relaxation's
sets to settle (PLAN01: the hull stops growing after about 30 s)."""

WIDEN = 0.03
"""``W`` is the last quarter's hull widened by this share of its width on each side."""

KAPPA = 0.25
"""``‖A_aug‖∞ δ`` of the relaxation's step (PLAN01: 0.0187 s)."""

ROUNDS = 3
"""Tries of ``W``: each widens the hull of ``W`` and the last quarter of the flowpipe from ``W``."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ClockFree:
    """The projection of an automaton on its non-clock states (see the module)."""

    model: AffineHybridModel
    kept: tuple[int, ...]
    clocks: tuple[str, ...]
    inputs: dict[str, Any]


def _kept_halfspaces(poly: Polyhedron, kept: tuple[int, ...], clocks: set[int], where: str) -> Polyhedron:
    out = []
    for h in poly.halfspaces:
        on_clock = any(h.normal[j] != 0 for j in clocks)
        on_kept = any(h.normal[j] != 0 for j in kept)
        if on_clock and on_kept:
            raise NoGroup(f"{where}: the halfspace {h.text or h.normal} mixes a clock with other states")
        if on_kept or not on_clock:
            out.append(Halfspace(normal=tuple(h.normal[j] for j in kept), offset=h.offset, text=h.text))
    return Polyhedron(halfspaces=tuple(out))


def _row_type(matrix: Any, rows: tuple[int, ...]) -> Any:
    picked = [matrix[i] for i in rows]
    return type(matrix)(picked) if isinstance(matrix, (list, tuple)) else matrix[list(rows)]


def clock_free(model: AffineHybridModel, inputs: Mapping[str, Any] | None = None) -> ClockFree:
    """The projection on the states every transition keeps (raises :class:`NoGroup` naming what prevents it)."""
    n = len(model.state_names)
    clocks = {i for t in model.transitions for i in range(n)
              if any(t.r_matrix[i][j] != (1 if i == j else 0) for j in range(n)) or t.r_offset[i] != 0}
    if not clocks:
        raise NoGroup("no clock: every transition keeps every state (the relaxation applies as it is)")
    kept = tuple(i for i in range(n) if i not in clocks)
    names = [model.state_names[c] for c in sorted(clocks)]
    for m in model.modes.values():
        if m.smooth is not None:
            raise NoGroup(f"mode {m.name!r} is not affine")
        if any(m.a[i][c] != 0 for i in kept for c in clocks):
            raise NoGroup(f"mode {m.name!r}: a flow of the other states reads a clock ({', '.join(names)})")
    for t in model.transitions:
        if any(t.r_matrix[i][c] != 0 for i in kept for c in clocks):
            raise NoGroup(f"transition {t.name!r}: a reset of the other states reads a clock")
    modes = {k: AffineMode(name=m.name, a=tuple(tuple(m.a[i][j] for j in kept) for i in kept),
                           c=tuple(m.c[i] for i in kept),
                           invariant=tuple(_kept_halfspaces(p, kept, clocks, f"mode {k!r}") for p in m.invariant))
             for k, m in model.modes.items()}
    size = len(kept)
    ident = tuple(tuple(Fraction(int(i == j)) for j in range(size)) for i in range(size))
    transitions = tuple(AffineTransition(
        name=t.name, source=t.source, target=t.target, r_matrix=ident, r_offset=(Fraction(0),) * size,
        guard=tuple(_kept_halfspaces(p, kept, clocks, f"transition {t.name!r}") for p in t.guard),
        direction=t.direction, priority=t.priority) for t in model.transitions)
    projected = AffineHybridModel(name=f"{model.name} without {', '.join(names)}",
                                  state_names=tuple(model.state_names[i] for i in kept), modes=modes,
                                  transitions=transitions, initial_mode=model.initial_mode)
    moved = {k: type(v)(matrix=_row_type(v.matrix, kept), bounds=v.bounds) for k, v in dict(inputs or {}).items()}
    return ClockFree(model=projected, kept=kept, clocks=tuple(names), inputs=moved)


def _project(body: Nnf, kept: tuple[int, ...], clocks: tuple[str, ...]) -> Nnf:
    if isinstance(body, LinearAtom):
        n = len(body.coefficients)
        if any(body.coefficients[j] != 0 for j in range(n) if j not in kept):
            raise NoGroup(f"the requirement reads a clock ({', '.join(clocks)}): {body.text}")
        return LinearAtom(coefficients=tuple(body.coefficients[j] for j in kept), bound=body.bound,
                          strict=body.strict, text=body.text)
    if isinstance(body, (Conj, Disj)):
        return type(body)(parts=tuple(_project(p, kept, clocks) for p in body.parts))
    if isinstance(body, LabelAtom):
        raise NoGroup(f"the requirement reads the location ({body.pattern!r}): the relaxation forgets it")
    raise NoGroup(f"a requirement part the relaxation does not read: {body!r}")


def _inside(w: Mapping[str, tuple[float, float]], names: tuple[str, ...]) -> Nnf:
    atoms = []
    for k, name in enumerate(names):
        lo, hi = w[name]
        unit = tuple(Fraction(int(j == k)) for j in range(len(names)))
        atoms.append(LinearAtom(coefficients=unit, bound=Fraction(hi), strict=False, text=f"{name} <= {hi!r}"))
        atoms.append(LinearAtom(coefficients=tuple(-q for q in unit), bound=-Fraction(lo), strict=False,
                                text=f"{name} >= {lo!r}"))
    return Conj(parts=tuple(atoms))


@dataclass(frozen=True, kw_only=True, slots=True)
class RelaxedInduction:
    """The producer's side of the induction (see the module): ``W``, ``P``, ``T``, the two flowpipes and the four
    decisions ``checks``, each ``(flowpipe, its initial box, fragment, holds, margin, reason)``: from the initial box
    ``always[0, P + T] φ`` and ``always[P, P] x ∈ W``; from ``W`` ``always[T, 2T] φ`` and ``always[T, T] x ∈ W``.
    ``holds`` when all four hold on the flowpipes."""

    projection: ClockFree
    w: dict[str, tuple[float, float]]
    probe: float
    period: float
    checks: tuple[tuple[Any, dict[str, tuple[float, float]], SafetyFragment, bool, float, str], ...]
    time_step: float

    @property
    def holds(self) -> bool:
        """Every decision holds."""
        return all(c[3] for c in self.checks)

    @property
    def margin(self) -> float:
        """The smallest margin of the two safety decisions (``φ``'s units)."""
        return min(self.checks[0][4], self.checks[2][4])

    @property
    def reason(self) -> str:
        """The first decision that does not hold, in words (``"holds"``)."""
        return next((f"{c[2].text}: {c[5]}" for c in self.checks if not c[3]), "holds")


def _hull(result: Any, names: tuple[str, ...], lo: float, hi: float) -> dict[str, tuple[float, float]] | None:
    """The hull of the segments within ``[lo, hi]`` s (``None``: none, or not finite)."""
    part = [s for s in result.segments if s.t_lo >= lo and s.t_hi <= hi]
    if not part or not all(math.isfinite(v) for s in part for v in (*s.lo, *s.hi)):
        return None
    return {n: (min(float(s.lo[k]) for s in part), max(float(s.hi[k]) for s in part)) for k, n in enumerate(names)}


def _widened(box: Mapping[str, tuple[float, float]], also: Mapping[str, tuple[float, float]]) -> dict[str, Any]:
    out = {}
    for n, (lo, hi) in box.items():
        lo, hi = min(lo, also[n][0]), max(hi, also[n][1])
        pad = WIDEN * (hi - lo) + 1e-9 * max(1.0, abs(lo), abs(hi))
        out[n] = (lo - pad, hi + pad)
    return out


def _period(result: Any, w: Mapping[str, tuple[float, float]], names: tuple[str, ...], step: float) -> float | None:
    """The first ``T = (k + 1) δ <= PROBE`` (``k >= 1``) where segments ``k`` and ``k + 1`` lie in ``W``."""
    segs = sorted(result.segments, key=lambda s: s.t_lo)
    inside = [all(w[n][0] < float(s.lo[i]) and float(s.hi[i]) < w[n][1] for i, n in enumerate(names)) for s in segs]
    for k in range(1, len(segs) - 1):
        if inside[k] and inside[k + 1] and (k + 1) * step <= PROBE:
            return (k + 1) * step
    return None


def _search(model: AffineHybridModel, group: Any, probe: Any, step: float
            ) -> tuple[dict[str, tuple[float, float]], float, Any]:
    """``(W, T, flowpipe from W over [0, 2 PROBE])``: the probe's hull over ``[3/4 P, P]`` widened, widened again
    with the flowpipe from ``W`` until it returns into ``W`` within ``P``."""
    names = model.state_names
    hull = _hull(probe, names, 0.75 * PROBE, PROBE)
    if hull is None:
        raise NoGroup(f"the relaxation's flowpipe from the initial box has no finite sets over [{0.75 * PROBE:g}, "
                      f"{PROBE:g}] s")
    w = _widened(hull, hull)
    for _ in range(ROUNDS):
        result = relaxed_reach(model, group, w, horizon=2 * PROBE, time_step=step, max_segments=MAX_SEGMENTS)
        period = _period(result, w, names, step) if result.complete else None
        if period is not None:
            return w, period, result
        again = _hull(result, names, 0.75 * PROBE, PROBE) if result.complete else None
        if again is None:
            raise NoGroup("the relaxation's flowpipe from W blows up: no box W found")
        w = _widened(w, again)
    raise NoGroup(f"no box W found in {ROUNDS} tries (the relaxation's sets from W do not return into W within "
                  f"{PROBE:g} s)")


def relaxed_induction(model: AffineHybridModel, inputs: Mapping[str, Any], initial_mode: str,
                      initial: Mapping[str, tuple[float, float]], body: Nnf, text: str) -> RelaxedInduction:
    """Find ``W`` and ``T`` and decide the four requirements on the two flowpipes (see the module).

    Raises
    ------
    NoGroup
        The projection or the relaxation does not apply, or no ``W`` was found (the reason).
    """
    from .autostep import mode_norms

    cf = clock_free(model, inputs)
    proj, names = cf.model, cf.model.state_names
    group = switching_group(proj, cf.inputs, initial_mode)
    step = KAPPA / max(mode_norms(proj).values())
    start = {n: (float(initial[n][0]), float(initial[n][1])) for n in names}
    probe = relaxed_reach(proj, group, start, horizon=2 * PROBE, time_step=step, max_segments=MAX_SEGMENTS)
    if not probe.complete:
        raise NoGroup(f"the relaxation's flowpipe blows up ({'; '.join(t.detail for t in probe.terminations)})")
    w, period, result = _search(proj, group, probe, step)
    phi = _project(body, cf.kept, cf.clocks)
    wanted = ((probe, start, SafetyFragment(start=0.0, end=PROBE + period, body=phi, state_names=names,
                                            text=f"{text} over [0, P + T] from the initial box")),
              (probe, start, SafetyFragment(start=PROBE, end=PROBE, body=_inside(w, names), state_names=names,
                                            text="the states in W at P from the initial box")),
              (result, w, SafetyFragment(start=period, end=2 * period, body=phi, state_names=names,
                                         text=f"{text} over [T, 2T] from W")),
              (result, w, SafetyFragment(start=period, end=period, body=_inside(w, names), state_names=names,
                                         text="the states in W at T from W")))
    checks = tuple((r, b, f, *decide(r, f, proj, b)) for r, b, f in wanted)
    return RelaxedInduction(projection=cf, w=w, probe=PROBE, period=period, checks=checks, time_step=step)
