"""What happens at one instant of a hybrid execution: the single rule of the toolkit.

Every executor and check that fires transitions calls :func:`settle_instant`:
the sampled-data executor at every sample, the continuous-time executor at
every located event and at the initial time, the structural checks when they
follow the jumps a reset triggers, and the sequence runners of the fuzzing
tools.  There is no second copy of this logic.

The rule
--------
At an instant the discrete state is ``(q, x, m)`` (mode, state, memory) and
the signals are ``v = h(x)`` (the state itself when there is no output map).

1. **Enabled transitions.**  A level-triggered transition (``direction = 0``)
   is enabled when its guard ``g(v, m) >= 0``.  A crossing-triggered one is
   enabled only on the *first* jump of the instant, and only when the caller
   gives the signals of the previous evaluation ``v_prev`` (the previous
   sample, or the left end of a located event's bracket): it detects a
   crossing that happened while flowing in ``q``.  With ``g0 = g(v_prev, m)``
   and ``g1 = g(v, m)``, a rising transition (``+1``) fires when
   ``g0 <= 0 <= g1`` and ``g0 < g1`` (the guard reached zero from below or left
   zero upwards); a falling one (``-1``) mirrors it (:func:`crossed`).  A
   guard that *starts* on zero (the initial time, or entered on zero by
   another transition's jump) therefore fires as soon as it moves in its
   direction.

   **One event per crossing.**  A crossing guard that has had its crossing
   (it fired, or was enabled and outranked, at an instant) and sits on its
   zero or beyond it afterwards is *disarmed*: it fires again only after its
   guard has been strictly on the pre-crossing side (``g < 0`` for a rising
   one).  Leaving zero in its direction is the same crossing continuing, not
   a new one: ``x' = 1`` with the rising guard ``x - 1`` and the jump
   ``x := 1`` fires once, not at every step.  The caller, which knows the
   history, passes the disarmed transitions (``disarmed``); for them the
   crossing test is ``g0 < 0 <= g1``.  The continuous executor tracks them
   along each flow (:mod:`hybrid.events`: the guard's samples must go strictly
   below zero to re-arm it); the sampled executor and the fuzz runner do not
   pass them yet (a sample exactly on zero followed by one above it fires
   twice there).
2. **Priority.**  The enabled transition with the smallest priority number
   fires; the others are reported as ``enabled``.  Equal priorities among the
   enabled set are non-determinism: ``ties="raise"`` raises
   :class:`~hybrid.errors.ExecutionError`; ``ties="record"`` fires the first
   in declaration order and reports the others as ``tied``.
3. **The jump.**  The winner's jump map (``fire``) gives the new state and its
   reset the new memory; both read the pre-jump values.  The new mode's
   level-triggered transitions are then evaluated at the new state, at the
   same instant (back to 1, without crossings).
4. **Zeno.**  At most ``max_jumps`` jumps happen at one instant; if a
   transition is still enabled after them, the instant ends with
   :attr:`Instant.zeno` set to a message naming the cycle.  Callers decide
   whether that is an error (the sampled executor raises
   :class:`~hybrid.errors.ZenoError`, the continuous one ends the run with
   termination ``"zeno"``, the fuzz runners record it).

:data:`MAX_JUMPS_PER_INSTANT` is the one default limit of every caller.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, NamedTuple

from .errors import ExecutionError
from .model import Transition, crossed, guard_value

__all__ = [
    "MAX_JUMPS_PER_INSTANT",
    "TIE_POLICIES",
    "InstantJump",
    "Instant",
    "crossed",
    "guard_value",
    "apply_reset",
    "settle_instant",
]

MAX_JUMPS_PER_INSTANT = 8
"""Default number of jumps allowed at one instant before it is reported as Zeno."""

TIE_POLICIES = ("raise", "record")
"""What :func:`settle_instant` does when equal priorities are enabled together."""

GuardEvaluator = Callable[[Transition, Sequence[float], Mapping[str, float]], float]
"""``guard(t, v, m) -> float``: the guard value of ``t`` (errors already named)."""

JumpFunction = Callable[[Transition, Any, Sequence[float], Mapping[str, float]], tuple[Any, Mapping[str, float]]]
"""``fire(t, x, v, m) -> (x', m')``: state and memory after the jump of ``t``."""


@dataclass(frozen=True, kw_only=True, slots=True)
class InstantJump:
    """One jump taken at an instant.

    Attributes
    ----------
    transition : Transition
        What fired.
    source, target : str
        Modes before and after.
    state_before, state_after : Any
        The state (a tuple of floats) before and after the jump map.
    memory_before, memory_after : Mapping[str, float]
        Read-only memory before and after the reset.
    enabled : tuple of str
        Every transition enabled at this jump, priority order, winner first.
    tied : tuple of str
        Those enabled with the winner's priority (only with ``ties="record"``).
    guard_value : float
        The winner's guard value.
    """

    transition: Transition
    source: str
    target: str
    state_before: Any
    state_after: Any
    memory_before: Mapping[str, float]
    memory_after: Mapping[str, float]
    enabled: tuple[str, ...]
    tied: tuple[str, ...]
    guard_value: float

    @property
    def outranked(self) -> tuple[str, ...]:
        """The enabled transitions that lost on priority (or on declaration order in a tie)."""
        return self.enabled[1:]


class Instant(NamedTuple):
    """The discrete state after an instant and the jumps that led there.

    An immutable record like the toolkit's frozen dataclasses, but a named
    tuple: one is made at every sample of every run, and a tuple costs a
    fifth of a frozen dataclass to build.

    Attributes
    ----------
    mode : str
    state : Any
    memory : Mapping[str, float]
        Read-only.
    jumps : tuple of InstantJump
    zeno : str or None
        Set when ``max_jumps`` jumps happened and a transition was still enabled.
    stopped : bool
        ``True`` when the instant ended because ``stop_before`` won (not fired).
    """

    mode: str
    state: Any
    memory: Mapping[str, float]
    jumps: tuple[InstantJump, ...]
    zeno: str | None = None
    stopped: bool = False


def apply_reset(t: Transition, x: Any, v: Sequence[float], memory: Mapping[str, float]) -> tuple[Any, dict[str, float]]:
    """The jump of ``t`` for an automaton without a jump map: state unchanged, memory reset.

    Raises
    ------
    ExecutionError
        The reset does not return exactly its declared ``writes``.
    """
    new_memory = dict(memory)
    if t.reset is not None:
        update = t.reset(v, memory)
        if not isinstance(update, Mapping) or set(update) != set(t.writes):
            got = sorted(update) if isinstance(update, Mapping) else repr(update)
            raise ExecutionError(
                f"reset of transition {t.name!r} returned {got}; expected a mapping with exactly the "
                f"declared writes {sorted(t.writes)}"
            )
        new_memory.update(update)
    return x, new_memory


def _enabled(
    transitions: Sequence[Transition],
    v: Sequence[float],
    memory: Mapping[str, float],
    previous: Sequence[float] | None,
    guard: GuardEvaluator,
    disarmed: Collection[str] = (),
) -> list[tuple[Transition, float]]:
    """Enabled transitions with their guard values, priority order (``previous`` only for crossings)."""
    out = []
    for t in transitions:
        if t.direction == 0:
            g = guard(t, v, memory)
            if g >= 0.0:
                out.append((t, g))
        elif previous is not None:
            g = guard(t, v, memory)
            g0 = guard(t, previous, memory)
            if crossed(t.direction, g0, g) and not (g0 == 0.0 and t.name in disarmed):
                out.append((t, g))
    return out


def _tie_error(mode: str, names: list[str], priority: int, time: float, where: str) -> ExecutionError:
    return ExecutionError(
        f"non-determinism at t = {time:.17g} s in mode {mode!r}{where}: transitions {names} are enabled "
        f"together with the same priority {priority}; give them distinct priorities or exclusive guards"
    )


def _zeno_message(mode: str, jumps: Sequence[InstantJump], max_jumps: int, time: float) -> str:
    cycle = " -> ".join(j.transition.name for j in jumps)
    return (
        f"instantaneous Zeno at t = {time:.17g} s in mode {mode!r}: {len(jumps)} jumps at one instant ({cycle}) "
        f"and a transition is still enabled; limit max_jumps = {max_jumps}.  Make the guards of the target "
        "modes exclusive of what the resets and jump maps produce (hysteresis, a dwell time), or use a "
        "crossing-triggered guard"
    )


def settle_instant(
    outgoing: Mapping[str, Sequence[Transition]],
    mode: str,
    state: Any,
    memory: Mapping[str, float],
    *,
    signals: Callable[[str, Any], Sequence[float]] | None = None,
    previous: Sequence[float] | None = None,
    guard: GuardEvaluator = guard_value,
    fire: JumpFunction = apply_reset,
    ties: str = "raise",
    max_jumps: int = MAX_JUMPS_PER_INSTANT,
    time: float = 0.0,
    where: Callable[[Any], str] | None = None,
    stop_before: Transition | None = None,
    disarmed: Collection[str] = (),
) -> Instant:
    """Fire the transitions enabled at one instant until none is (the rule of the module docstring).

    Parameters
    ----------
    outgoing : Mapping[str, sequence of Transition]
        Every mode's outgoing transitions in priority order
        (:meth:`~hybrid.model.HybridAutomaton.outgoing`).
    mode, state, memory
        Discrete state and continuous state before the instant (a read-only
        ``memory`` is used as it is, any other mapping is copied).
    signals : callable or None
        ``signals(mode, state) -> v``; ``None`` when the state *is* the
        signal vector (an automaton driven by signals).
    previous : sequence of float or None
        Signals at the previous evaluation, for crossing-triggered guards;
        ``None``: they cannot fire at this instant.
    guard : callable
        ``guard(t, v, m)``; the default checks for NaN.
    fire : callable
        ``fire(t, x, v, m) -> (x', m')``; the default applies the reset only.
    ties : {"raise", "record"}
        Equal priorities enabled together: raise, or fire the first declared and record the tie.
    max_jumps : int
        Jumps allowed at this instant (>= 1) before :attr:`Instant.zeno` is set.
    time : float
        Time of the instant [s] (messages only).
    where : callable or None
        ``where(state) -> text`` appended to messages (e.g. the state's coordinates).
    stop_before : Transition or None
        End the instant, without firing it, when this transition wins
        (the structural checks ask "does the reset re-trigger t?").
    disarmed : collection of str
        Crossing-triggered transitions disarmed by their own earlier crossing
        (the module docstring): they fire only from strictly below zero
        (``g0 < 0 <= g1`` rising), not when they leave zero.

    Returns
    -------
    Instant

    Raises
    ------
    ExecutionError
        Non-determinism with ``ties="raise"``; errors of the guard, reset or jump map.
    """
    if ties != "raise" and ties != "record":
        raise ExecutionError(f"settle_instant: ties = {ties!r}; expected one of {TIE_POLICIES}")
    if type(max_jumps) is not int or max_jumps < 1:
        raise ExecutionError(f"settle_instant: max_jumps = {max_jumps!r}; expected an int >= 1")
    frozen = memory if type(memory) is MappingProxyType else MappingProxyType(dict(memory))
    jumps: list[InstantJump] = []
    while True:
        v = state if signals is None else signals(mode, state)
        enabled = _enabled(outgoing[mode], v, frozen, previous if not jumps else None, guard, disarmed)
        if not enabled:
            return Instant(mode, state, frozen, tuple(jumps))
        winner, g = enabled[0]
        tied = [t.name for t, _ in enabled[1:] if t.priority == winner.priority] if len(enabled) > 1 else []
        if tied and ties == "raise":
            raise _tie_error(mode, [winner.name, *tied], winner.priority, time,
                             "" if where is None else f", {where(state)}")
        if winner is stop_before:
            return Instant(mode=mode, state=state, memory=frozen, jumps=tuple(jumps), stopped=True)
        if len(jumps) >= max_jumps:
            return Instant(mode=mode, state=state, memory=frozen, jumps=tuple(jumps),
                           zeno=_zeno_message(mode, jumps, max_jumps, time))
        new_state, new_memory = fire(winner, state, v, frozen)
        after = MappingProxyType(dict(new_memory))
        jumps.append(InstantJump(
            transition=winner, source=mode, target=winner.target, state_before=state, state_after=new_state,
            memory_before=frozen, memory_after=after, enabled=tuple([t.name for t, _ in enabled]),
            tied=tuple(tied), guard_value=g,
        ))
        mode, state, frozen = winner.target, new_state, after
