"""Unbounded-time safety by cycle induction: the automaton surgery, the cycle's bound and the search for ``W``.

Every run of an automaton whose runs keep returning to one location ``home`` with some states reset to constants is
a sequence of *cycles*, each starting in ``home`` with those states at their constants.  If a set ``W`` of the other
(*carried*) states holds the initial carried state and, from every state of ``W`` (``home``, reset states at their
constants), every run until its next entry into ``home`` (a) satisfies the requirement and (b) enters ``home`` with
its carried state in ``W``, then by induction over the cycles every run satisfies the requirement for all time —
provided the automaton does not read time (affine flows, constant input bounds: the engine refuses time) and the
requirement reads states and locations only (the safety fragment).

(a) and (b) are one bounded-time safety problem of the *cycle model* (:func:`cycle_model`): every transition into
``home`` is redirected to a new terminal location :data:`ENTERED` (zero flow, invariant true, no transition out),
the initial set is ``W`` at ``home``, and the requirement is ``body and (mode != ENTERED or x ∈ W)``
(:func:`cycle_fragment`) over a horizon longer than the longest cycle.  The longest cycle is bounded exactly from
the model (:func:`cycle_bound`): the locations other than ``ENTERED`` reachable from ``home`` form an acyclic graph
and each has a clock (flow exactly 1, set to a constant on every entry, bounded above by its invariant), so no run
of the cycle model is cut by the horizon: every run is in ``ENTERED`` before it.  Anything else is refused with
:class:`NoCycle` naming why; the verdict then stays undecided.

:func:`find_invariant` searches ``W`` as a box of the carried states: from the initial box, ``W_{k+1}`` is the hull
of ``W_k`` and the entry box of the flowpipe from ``W_k`` (the hull of the ``ENTERED`` segments), bloated, until
the flowpipe decides the cycle requirement.  The flowpipe is :func:`analysis.reach.reach` with the model's inputs;
its independent re-check is the caller's (:mod:`analysis.spaceex_induction`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

from .fragment import Conj, Disj, LabelAtom, LinearAtom, Nnf, SafetyFragment
from .model import AffineHybridModel, AffineMode
from .affine import Polyhedron

__all__ = ["ENTERED", "NoCycle", "CycleModel", "cycle_model", "cycle_bound", "cycle_fragment", "entry_box",
           "InductionStep", "InductionSearch", "find_invariant", "BLOAT", "MAX_ROUNDS", "HORIZON_PAD"]

ENTERED = "cycle_entered"
"""The terminal location of the cycle model: the state at the next entry into ``home`` (its name is never a label
pattern's wildcard)."""

BLOAT = 0.15
"""``W_{k+1}`` is the hull of ``W_k`` and the entry box widened by this fraction of its width on each side."""

MAX_ROUNDS = 5
"""Flowpipes of the search for ``W`` at most."""

HORIZON_PAD = 1.0
"""The cycle flowpipe's horizon is the cycle bound plus this [s]."""


class NoCycle(ValueError):
    """The cycle induction does not apply; the message says why."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"cycle induction not applicable: {reason}")
        self.reason = reason


@dataclass(frozen=True, kw_only=True, slots=True)
class CycleModel:
    """The cycle model of an automaton (see the module).

    Attributes
    ----------
    model : AffineHybridModel
        The surgery: transitions into ``home`` retargeted to :data:`ENTERED`.
    home : str
    reset : tuple of (int, Fraction)
        State indices set to a constant on every entry into ``home`` (and initially), with the constant.
    carried : tuple of int
        The other state indices (the coordinates of ``W``).
    redirected : tuple of str
        The retargeted transitions.
    bound : Fraction
        The longest cycle [s] (exact, :func:`cycle_bound`).
    """

    model: AffineHybridModel
    home: str
    reset: tuple[tuple[int, Fraction], ...]
    carried: tuple[int, ...]
    redirected: tuple[str, ...]
    bound: Fraction


def _constant_row(t: Any, k: int) -> Fraction | None:
    """The constant a transition's reset gives state ``k`` (``None`` when it reads a state)."""
    return None if any(t.r_matrix[k]) else t.r_offset[k]


def cycle_model(model: AffineHybridModel, home: str, initial: Mapping[str, tuple[float, float]],
                inputs: Mapping[str, Any] | None = None) -> CycleModel:
    """The cycle model of ``model`` at ``home`` with its exact cycle bound.

    Parameters
    ----------
    model : AffineHybridModel
        Every mode affine.
    home : str
        The initial location, through which every cycle passes.
    initial : mapping {state: (lo, hi)}
        The initial box; the reset states must be points there, at their reset constants.
    inputs : mapping {mode: ModeInput} or None
        The bounded inputs (a clock's row of ``B`` must be zero: its rate is then exactly 1).

    Raises
    ------
    NoCycle
        A nonlinear mode, no transition into ``home``, no state reset to a constant by all of them, or no bound on
        the cycle's duration (:func:`cycle_bound`).
    """
    if home not in model.modes or ENTERED in model.modes:
        raise NoCycle(f"the location {home!r} is not a location of the model, or {ENTERED!r} already is one")
    smooth = [m for m, mode in model.modes.items() if mode.smooth is not None]
    if smooth:
        raise NoCycle(f"the location {smooth[0]!r} has a nonlinear flow (affine flows only)")
    into = [t for t in model.transitions if t.target == home]
    if not into:
        raise NoCycle(f"no transition returns to {home!r}: there is no cycle")
    reset = []
    for k, name in enumerate(model.state_names):
        values = {_constant_row(t, k) for t in into}
        lo, hi = initial[name]
        if len(values) == 1 and None not in values and Fraction(lo) == Fraction(hi) == next(iter(values)):
            reset.append((k, next(iter(values))))
    if not reset:
        raise NoCycle(f"no state is set to its initial value by every transition into {home!r} "
                      f"({', '.join(t.name for t in into)}): the cycles do not start alike")
    n = len(model.state_names)
    modes = dict(model.modes)
    modes[ENTERED] = AffineMode(name=ENTERED, a=tuple((Fraction(0),) * n for _ in range(n)), c=(Fraction(0),) * n,
                                invariant=(Polyhedron(halfspaces=()),))
    # the guard P of a redirected transition is written P ∪ P (the same set): a union takes the engine's box route,
    # so no zonotope jump set is kept per segment (the W check reads boxes; tens of thousands of such jumps)
    transitions = tuple(replace(t, target=ENTERED, guard=(*t.guard, *t.guard)) if t.target == home else t
                        for t in model.transitions)
    surgery = AffineHybridModel(name=f"{model.name} (cycle at {home})", state_names=model.state_names, modes=modes,
                                transitions=transitions, initial_mode=home)
    fixed = {k for k, _ in reset}
    driven = {m: frozenset(k for k, row in enumerate(spec.matrix) if any(float(v) != 0.0 for v in row))
              for m, spec in dict(inputs or {}).items()}
    bound = cycle_bound(surgery, home, {k: v for k, v in reset}, driven)
    return CycleModel(model=surgery, home=home, reset=tuple(reset),
                      carried=tuple(k for k in range(n) if k not in fixed),
                      redirected=tuple(t.name for t in into), bound=bound)


def _clock_bound(mode: AffineMode, entries: Sequence[Mapping[int, Fraction | None]],
                 driven: frozenset[int] = frozenset()) -> Fraction | None:
    """The longest dwell in ``mode``: ``u − v`` for a clock ``k`` (flow exactly 1, no input in its row: ``driven``
    holds the states an input drives, invariant ``x_k <= u`` in its one polyhedron) that every entry sets to a
    constant ``>= v``; ``None`` without such a clock."""
    if len(mode.invariant) != 1:
        return None
    best = None
    for h in mode.invariant[0].halfspaces:
        ks = [k for k, a in enumerate(h.normal) if a]
        if len(ks) != 1 or h.normal[ks[0]] <= 0:
            continue
        k = ks[0]
        if any(mode.a[k]) or mode.c[k] != 1 or k in driven:
            continue
        values = [e.get(k) for e in entries]
        if not values or any(v is None for v in values):
            continue
        dwell = max(h.offset / h.normal[k] - min(values), Fraction(0))
        best = dwell if best is None else min(best, dwell)
    return best


def cycle_bound(model: AffineHybridModel, home: str, start: Mapping[int, Fraction],
                driven: Mapping[str, frozenset[int]] | None = None) -> Fraction:
    """The longest duration of a run from ``home`` until :data:`ENTERED` (exact) [s]; ``driven``: per mode, the
    states a bounded input drives (no clock).

    Raises
    ------
    NoCycle
        A location reachable from ``home`` without passing :data:`ENTERED` lies on a loop, or has no clock bounding
        its dwell (flow exactly 1, set to a constant on every entry, bounded above by the invariant).
    """
    reach, order, stack = {home}, [], [(home, iter(model.outgoing(home)))]
    on_path = {home}
    while stack:  # depth first: a loop among the locations before ENTERED is refused
        mode, it = stack[-1]
        t = next(it, None)
        if t is None:
            stack.pop()
            on_path.discard(mode)
            order.append(mode)
            continue
        if t.target == ENTERED:
            continue
        if t.target in on_path:
            raise NoCycle(f"the locations {mode!r} and {t.target!r} lie on a loop that avoids {home!r}: a cycle "
                          "may never end")
        if t.target not in reach:
            reach.add(t.target)
            on_path.add(t.target)
            stack.append((t.target, iter(model.outgoing(t.target))))
    longest: dict[str, Fraction] = {}
    for mode in order:  # reverse topological: successors first
        entries = [start] if mode == home else [
            {k: _constant_row(t, k) for k in range(len(model.state_names))}
            for t in model.transitions if t.target == mode]
        dwell = _clock_bound(model.modes[mode], entries, dict(driven or {}).get(mode, frozenset()))
        if dwell is None:
            raise NoCycle(f"no clock bounds the dwell in {mode!r} (a state with flow exactly 1, set to a constant on "
                          "every entry, bounded above by the invariant)")
        after = [longest[t.target] for t in model.outgoing(mode) if t.target != ENTERED]
        longest[mode] = dwell + max(after, default=Fraction(0))
    return longest[home]


def cycle_fragment(body: Nnf, cycle: CycleModel, w: Mapping[int, tuple[float, float]], horizon: float,
                   text: str) -> SafetyFragment:
    """``always[0, horizon] (body and (mode != ENTERED or x ∈ W))`` over the cycle model's states, ``W`` a box
    ``{index: (lo, hi)}`` of carried states."""
    n = len(cycle.model.state_names)
    inside = []
    for k, (lo, hi) in sorted(w.items()):
        unit = tuple(Fraction(int(j == k)) for j in range(n))
        name = cycle.model.state_names[k]
        inside.append(LinearAtom(coefficients=unit, bound=Fraction(hi), strict=False, text=f"{name} <= {hi!r}"))
        inside.append(LinearAtom(coefficients=tuple(-q for q in unit), bound=-Fraction(lo), strict=False,
                                 text=f"{name} >= {lo!r}"))
    away = LabelAtom(label="mode", pattern=ENTERED, negated=True)
    return SafetyFragment(start=0.0, end=float(horizon), state_names=cycle.model.state_names,
                          body=Conj(parts=(body, Disj(parts=(away, Conj(parts=tuple(inside)))))),
                          text=f"{text}, and at the entry into {cycle.home!r} the carried states in W")


def entry_box(result: Any, cycle: CycleModel) -> dict[int, tuple[float, float]]:
    """The hull of the :data:`ENTERED` segments over the carried states (empty when none was reached)."""
    boxes = [s for s in result.segments if s.mode == ENTERED]
    if not boxes:
        return {}
    return {k: (min(float(s.lo[k]) for s in boxes), max(float(s.hi[k]) for s in boxes)) for k in cycle.carried}


def _grown(w: Mapping[int, tuple[float, float]], entry: Mapping[int, tuple[float, float]],
           bloat: float) -> dict[int, tuple[float, float]]:
    """The hull of ``w`` and ``entry`` widened by ``bloat`` of the entry's width (at least 1e-3) on each side."""
    out = {}
    for k, (lo, hi) in w.items():
        elo, ehi = entry.get(k, (lo, hi))
        pad = bloat * max(ehi - elo, 1e-3 * (1.0 + abs(elo) + abs(ehi)))
        out[k] = (min(lo, elo - pad), max(hi, ehi + pad))
    return out


@dataclass(frozen=True, kw_only=True, slots=True)
class InductionStep:
    """One flowpipe of the search: ``W``, its decision, and the entry box the flowpipe gave."""

    w: tuple[tuple[str, float, float], ...]
    holds: bool
    margin: float
    reason: str
    entry: tuple[tuple[str, float, float], ...]
    segments: int
    flowpipes: int
    seconds: float


@dataclass(frozen=True, kw_only=True, slots=True)
class InductionSearch:
    """The search's rounds; ``result`` and ``fragment`` of the last (held or not)."""

    steps: tuple[InductionStep, ...]
    result: Any
    fragment: SafetyFragment | None
    initial: dict[str, tuple[float, float]]

    @property
    def holds(self) -> bool:
        """Whether the last round's flowpipe decided the cycle requirement."""
        return bool(self.steps) and self.steps[-1].holds


def _named(cycle: CycleModel, box: Mapping[int, tuple[float, float]]) -> tuple[tuple[str, float, float], ...]:
    return tuple((cycle.model.state_names[k], lo, hi) for k, (lo, hi) in sorted(box.items()))


def find_invariant(cycle: CycleModel, body: Nnf, text: str, initial: Mapping[str, tuple[float, float]],
                   flowpipe: Callable[[Mapping[str, tuple[float, float]], float], Any],
                   decide: Callable[[Any, SafetyFragment, Mapping[str, tuple[float, float]]], tuple[bool, float, str]],
                   *, bloat: float = BLOAT, rounds: int = MAX_ROUNDS) -> InductionSearch:
    """Search a box ``W`` that closes the induction (see the module).

    Parameters
    ----------
    cycle : CycleModel
    body : Nnf
        The requirement's state predicate.
    text : str
        The requirement in words.
    initial : mapping {state: (lo, hi)}
        The initial box of the original problem (``W_0`` is its carried part).
    flowpipe : callable
        ``flowpipe(box, horizon) -> ReachResult`` of the cycle model from ``box`` at ``home``.
    decide : callable
        ``decide(result, fragment, box) -> (holds, margin, reason)`` (:func:`analysis.reach.verdict.decide`).
    bloat : float
    rounds : int

    Returns
    -------
    InductionSearch
        Stops at the first round that holds, at a round whose requirement fails outside ``W`` (the forbidden set
        may be reached), or after ``rounds`` flowpipes.
    """
    import time

    horizon = float(cycle.bound) + HORIZON_PAD
    names = cycle.model.state_names
    w = {k: (float(initial[names[k]][0]), float(initial[names[k]][1])) for k in cycle.carried}
    steps: list[InductionStep] = []
    result, fragment, box = None, None, dict(initial)
    for _ in range(rounds):
        box = {**{names[k]: w[k] for k in cycle.carried}, **{names[k]: (float(v), float(v)) for k, v in cycle.reset}}
        fragment = cycle_fragment(body, cycle, w, horizon, text)
        start = time.process_time()
        result = flowpipe(box, horizon)
        holds, margin, reason = decide(result, fragment, box)
        entry = entry_box(result, cycle)
        steps.append(InductionStep(w=_named(cycle, w), holds=holds, margin=margin, reason=reason,
                                   entry=_named(cycle, entry), segments=len(result.segments),
                                   flowpipes=len(result.terminations), seconds=time.process_time() - start))
        if holds or not entry or not decide(result, replace(fragment, body=body), box)[0]:
            break  # held, or the requirement itself is not decided: a wider W cannot help
        w = _grown(w, entry, bloat)
    return InductionSearch(steps=tuple(steps), result=result, fragment=fragment, initial=box)
