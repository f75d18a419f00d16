"""Hybrid automata: modes, transitions, latched memory, validated at construction.

A :class:`HybridAutomaton` reads a vector of real *signals* ``v`` (named by
``variables``: a plant state, or measurements of it in a sampled-data loop) and
carries *memory* variables ``m`` that only resets change (latched values such
as the paper's ``dL``).  A transition is enabled when its guard value
``g(v, m) >= 0``; with ``direction = +1`` (``-1``) it fires only when the guard
*crosses* zero upwards (downwards) between two evaluations, which is how a
guard that sits on zero after its own reset is kept from firing again.
Among enabled transitions the smallest ``priority`` number wins; equal
priorities are a modelling error reported at run time.

Examples
--------
Guards written once, symbolically (:mod:`hybrid.symbolic`): a comparison is the guard, and its text.

>>> from hybrid.model import HybridAutomaton, Mode, Transition, MemoryVariable
>>> from hybrid.symbolic import coordinates
>>> v = coordinates("T")
>>> heat = Transition(name="on", source="off", target="on", guard=v.T <= 19.0)
>>> cool = Transition(name="off", source="on", target="off", guard=v.T >= 21.0)
>>> thermostat = HybridAutomaton(name="thermostat", modes=(Mode(name="off"), Mode(name="on")),
...                              transitions=(heat, cool), variables=("T",), initial_mode="off")
>>> [t.name for t in thermostat.enabled("off", (18.0,), {})], heat.guard_text
(['on'], 'T <= 19')

The fallback, a plain function (its text given by hand; the structural checks can only sample it):

>>> Transition(name="on", source="off", target="on", guard=lambda v, m: 19.0 - v[0], guard_text="T <= 19").guard_text
'T <= 19'
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from .errors import ExecutionError, ModelDefinitionError
from .symbolic import (
    Condition,
    Coordinate,
    Expr,
    SymbolicReset,
    SymbolicVector,
    free_symbols,
    level_form,
    misplaced_coordinates,
    render,
    unsupported_terms,
)

# Helpers shared with hybrid.system have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "initial_mode_of",
    "symbolic_text",
    "Guard",
    "Reset",
    "Mode",
    "Transition",
    "MemoryVariable",
    "HybridAutomaton",
    "transition_fires",
    "crossed",
    "guard_value",
    "Conjunction",
    "all_of",
    "BOOL_GUARD_HINT",
    "refuse_bool",
    "not_a_number",
    "real_number",
]

BOOL_GUARD_HINT = (
    "a guard or invariant is a level function, >= 0 where it holds: write `lambda v, m: v[0] - 5.0` "
    "for v[0] >= 5 (not `v[0] > 5.0`, whose False would read as 0.0, i.e. enabled), "
    "all_of(g1, g2) for a conjunction, or a symbolic comparison (hybrid.symbolic: v.T >= 5.0)"
)


BOOL_TYPES = (bool, np.bool_)
"""Types a level function must not return (a truth value, not a level)."""


_TEXT_TYPES = (str, bytes, bytearray)


_FLOAT64 = np.float64
"""numpy's double: a real number, taken as fast as ``float`` (the other types are checked)."""


def not_a_number(value: Any) -> str | None:
    """Why ``value`` is not one real number as a guard, an invariant, a stop or a reset must return, or ``None``.

    The one rule of those values, shared by the executors and the structural checks: a bool (it would read
    as 0.0 or 1.0), text (``float("1")`` would silently read ``"1"`` as 1.0), a complex number, or anything
    ``float()`` does not take is not one; ints, floats and numpy's real scalars are.  NaN is a number: each
    caller refuses it with its own context.
    """
    if value.__class__ is float or value.__class__ is _FLOAT64:
        return None
    if isinstance(value, BOOL_TYPES):
        return "a bool"
    if isinstance(value, _TEXT_TYPES):
        return f"text ({type(value).__name__}), not a number: return the number itself, e.g. 1.0 rather than '1'"
    if isinstance(value, complex) or np.iscomplexobj(value):
        return "a complex number"
    try:
        float(value)
    except (TypeError, ValueError, OverflowError):
        return "not a number"
    return None


def real_number(value: Any, what: str, where: str, *, bool_what: str | None = None) -> float:
    """``float(value)`` for one real number (:func:`not_a_number`), else an :class:`ExecutionError`.

    Parameters
    ----------
    value : object
        What the user's guard, invariant, stop function or reset returned.
    what : str
        Names the function (``"guard of transition 'go'"``).
    where : str
        The context after the value (``"in mode 'a' at t = 1 s, x = (0)"``).
    bool_what : str, optional
        ``what`` for the bool message (:func:`refuse_bool`); ``what`` by default.

    Returns
    -------
    float
        The value, possibly NaN (the caller refuses it with its own message).
    """
    reason = not_a_number(value)
    if reason is None:
        return value if value.__class__ is float else float(value)
    if reason == "a bool":
        refuse_bool(value, bool_what or what)
    raise ExecutionError(f"{what} returned {value!r} {where}; expected one real number ({reason})")


def refuse_bool(value: Any, what: str) -> None:
    """Raise :class:`ExecutionError` when a guard or invariant returned a bool (it would read as 0.0 or 1.0)."""
    if isinstance(value, BOOL_TYPES):
        raise ExecutionError(f"{what} returned the bool {value!r}; {BOOL_GUARD_HINT}")


def refuse_unsupported(function: Any, what: str, timed: bool = True) -> None:
    """Raise :class:`ModelDefinitionError` when a symbolic function uses an unsupported operation (naming it).

    ``timed=False`` (guards, invariants, resets: they read ``(v, m)``) also refuses the time symbol.
    """
    bad = unsupported_terms(function)
    if bad:
        raise ModelDefinitionError(f"{what}: {bad[0].message()}")
    if timed:
        return
    parts = list(function.assignments.values()) if isinstance(function, SymbolicReset) else [function]
    if any(isinstance(p, (Expr, Condition)) and free_symbols(p)["time"] for p in parts):
        raise ModelDefinitionError(
            f"{what} reads the time t, which guards, invariants and resets do not receive (they read the "
            "signals v and the memory m); give time as a state (a clock with flow 1) or a signal of the output"
        )


def refuse_misplaced(function: Any, names: Sequence[str], what: str, kind: str) -> None:
    """Raise :class:`ModelDefinitionError` when a symbolic function reads a coordinate by a name that is not
    the vector's name at that index (it would read the wrong component)."""
    bad = misplaced_coordinates(function, names)
    if bad:
        raise ModelDefinitionError(
            f"{what} reads coordinate(s) {', '.join(bad)}; build them with "
            f"hybrid.symbolic.coordinates({', '.join(repr(n) for n in names)}) (the {kind}, in order)"
        )


def _as_level(function: Any) -> Any:
    """A symbolic condition as its level form; anything else unchanged."""
    return level_form(function) if isinstance(function, Condition) else function


def symbolic_text(function: Any) -> str:
    """The text of a symbolic guard, invariant or reset as written (``T <= 19.5``, ``dL := d``); ``""`` for a
    plain callable, whose text only its author can give (``guard_text=``)."""
    if isinstance(function, Condition):
        return render(function)
    if isinstance(function, Expr):
        return f"{render(function)} >= 0"
    if isinstance(function, SymbolicReset):
        return ", ".join(f"{name} := {render(e)}" for name, e in function.assignments.items())
    if isinstance(function, Conjunction):
        return " and ".join(function.texts)
    return ""


def jump_text(jump: Any, state_names: Sequence[str]) -> str:
    """The text of a symbolic jump map over ``state_names``: the components it changes (``v := (-0.8 * v)``).

    A component that keeps its state (``x.h`` for ``h``) is left out; a jump that keeps every component is
    written in full (``x := x``), so the text of a jump is never empty.  ``""`` for a plain callable, whose
    text only its author can give (``reset_text=``).

    Examples
    --------
    >>> from hybrid.symbolic import coordinates, jump_map
    >>> x = coordinates("h", "v")
    >>> jump_text(jump_map(x.h, -0.8 * x.v), ("h", "v"))
    'v := (-0.8 * v)'
    """
    if not isinstance(jump, SymbolicVector):
        return ""
    pairs = list(zip(state_names, jump.components))
    changed = [(n, e) for n, e in pairs if not (isinstance(e, Coordinate) and e.name == n)]
    return ", ".join(f"{n} := {render(e)}" for n, e in (changed or pairs))

Guard = Callable[[Sequence[float], Mapping[str, float]], float]
"""Guard value ``g(v, m)``; the transition is enabled when ``g >= 0``."""

Reset = Callable[[Sequence[float], Mapping[str, float]], Mapping[str, float]]
"""Reset ``r(v, m)`` returning the new values of the memory variables it writes."""

Invariant = Callable[[Sequence[float], Mapping[str, float]], float]
"""Invariant value; the state may stay in the mode while it is ``>= 0``."""


def _frozen_mapping(value: Mapping[str, Any] | None) -> Mapping[str, Any]:
    return MappingProxyType(dict(value or {}))


@dataclass(frozen=True, kw_only=True, slots=True)
class Mode:
    """A discrete mode.

    Attributes
    ----------
    name : str
        Unique name.
    description : str
        One line for humans (docs, DOT labels).
    invariant : callable or None
        ``inv(v, m) >= 0`` while the mode may be kept; ``None`` means always.
    invariant_text : str
        Human-readable invariant.
    labels : Mapping[str, Any]
        Read-only annotations (e.g. the flag values a mode stands for).
    """

    name: str
    description: str = ""
    invariant: Invariant | None = None
    invariant_text: str = ""
    labels: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ModelDefinitionError(f"Mode.name = {self.name!r}: expected a non-empty string")
        if not self.invariant_text:  # one definition: a symbolic invariant gives its own text
            object.__setattr__(self, "invariant_text", symbolic_text(self.invariant))
        object.__setattr__(self, "invariant", _as_level(self.invariant))
        refuse_unsupported(self.invariant, f"mode {self.name!r}: invariant", timed=False)
        if self.invariant is not None and not callable(self.invariant):
            raise ModelDefinitionError(
                f"mode {self.name!r}: invariant = {self.invariant!r} is not callable; "
                "pass a function inv(v, m) -> float (>= 0 inside) or None"
            )
        object.__setattr__(self, "labels", _frozen_mapping(self.labels))


@dataclass(frozen=True, kw_only=True, slots=True)
class Transition:
    """A discrete transition (edge of the mode graph).

    Attributes
    ----------
    name : str
        Unique name.
    source, target : str
        Mode names.
    guard : callable
        ``g(v, m) -> float``, enabled when ``>= 0``.
    reset : callable or None
        ``r(v, m) -> {memory name: new value}`` for exactly the names in ``writes``.
    writes : tuple of str
        Memory variables the reset assigns.
    reads : tuple of str
        Signals the guard reads (documentation and structural checks; validated).
    direction : int
        ``0`` level-triggered, ``+1`` fires on an upward zero crossing of the
        guard, ``-1`` on a downward one.
    priority : int
        Smaller fires first when several transitions are enabled together.
    guard_text, reset_text : str
        Human-readable guard and reset, used by the exports and the docs.
    """

    name: str
    source: str
    target: str
    guard: Guard
    reset: Reset | None = None
    writes: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    direction: int = 0
    priority: int = 0
    guard_text: str = ""
    reset_text: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ModelDefinitionError(f"Transition.name = {self.name!r}: expected a non-empty string")
        if isinstance(self.reset, SymbolicVector):
            raise ModelDefinitionError(
                f"transition {self.name!r}: reset = a {self.reset.kind} map of the state; a reset assigns memory "
                "variables (reset(name=expression), or r(v, m) -> dict); a jump of the state belongs to the system: "
                f"HybridSystem(..., jumps={{{self.name!r}: jump_map(...)}})"
            )
        if not self.guard_text:  # one definition: a symbolic guard and reset give their own text
            object.__setattr__(self, "guard_text", symbolic_text(self.guard))
        if not self.reset_text:
            object.__setattr__(self, "reset_text", symbolic_text(self.reset))
        object.__setattr__(self, "guard", _as_level(self.guard))
        refuse_unsupported(self.guard, f"transition {self.name!r}: guard", timed=False)
        refuse_unsupported(self.reset, f"transition {self.name!r}: reset", timed=False)
        if isinstance(self.reset, SymbolicReset):
            if not self.writes:
                object.__setattr__(self, "writes", self.reset.writes)
            elif set(self.writes) != set(self.reset.writes):
                raise ModelDefinitionError(
                    f"transition {self.name!r}: writes = {tuple(self.writes)!r} but the symbolic reset assigns "
                    f"{self.reset.writes!r}; drop `writes` (it is taken from the reset) or make them agree"
                )
        if not callable(self.guard):
            raise ModelDefinitionError(
                f"transition {self.name!r}: guard = {self.guard!r} is not callable; "
                "pass a function g(v, m) -> float that is >= 0 when the transition may fire"
            )
        if self.reset is not None and not callable(self.reset):
            raise ModelDefinitionError(
                f"transition {self.name!r}: reset = {self.reset!r} is not callable; "
                "pass a function r(v, m) -> dict of new memory values, or None"
            )
        if self.reset is None and self.writes:
            raise ModelDefinitionError(
                f"transition {self.name!r}: writes = {self.writes!r} but reset is None; "
                "give a reset that assigns these memory variables or drop `writes`"
            )
        if self.direction not in (-1, 0, 1):
            raise ModelDefinitionError(
                f"transition {self.name!r}: direction = {self.direction!r}; expected -1, 0 or +1 "
                "(falling crossing, level, rising crossing)"
            )
        if isinstance(self.priority, bool) or not isinstance(self.priority, int):
            raise ModelDefinitionError(
                f"transition {self.name!r}: priority = {self.priority!r}; expected an int (smaller fires first)"
            )
        object.__setattr__(self, "writes", tuple(self.writes))
        object.__setattr__(self, "reads", tuple(self.reads))


@dataclass(frozen=True, kw_only=True, slots=True)
class MemoryVariable:
    """A latched real variable changed only by resets (e.g. ``dL``)."""

    name: str
    initial: float = 0.0
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ModelDefinitionError(f"MemoryVariable.name = {self.name!r}: expected a non-empty string")
        if isinstance(self.initial, bool) or not isinstance(self.initial, (int, float)):
            raise ModelDefinitionError(
                f"memory variable {self.name!r}: initial = {self.initial!r}; expected a real number"
            )


def _duplicates(names: Sequence[str]) -> list[str]:
    seen: set[str] = set()
    return sorted({n for n in names if n in seen or seen.add(n)})  # type: ignore[func-returns-value]


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridAutomaton:
    """A validated hybrid automaton.

    Raises
    ------
    ModelDefinitionError
        On duplicate names, unknown modes or variables, or an empty automaton.
    """

    name: str
    modes: tuple[Mode, ...]
    transitions: tuple[Transition, ...]
    variables: tuple[str, ...]
    memory: tuple[MemoryVariable, ...] = ()
    initial_mode: str = ""
    description: str = ""
    _outgoing: Mapping[str, tuple[Transition, ...]] = field(init=False, repr=False, compare=False)
    _mode_index: Mapping[str, int] = field(init=False, repr=False, compare=False)
    initial_mode_given: bool = field(init=False, repr=False, compare=False)
    """Whether ``initial_mode`` was written (otherwise it is the first mode, and a problem infers the initial mode
    of each point from the invariants: :func:`initial_mode_of`)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "modes", tuple(self.modes))
        object.__setattr__(self, "transitions", tuple(self.transitions))
        object.__setattr__(self, "variables", tuple(self.variables))
        object.__setattr__(self, "memory", tuple(self.memory))
        if not self.modes:
            raise ModelDefinitionError(f"automaton {self.name!r}: no modes; give at least one Mode")
        for kind, items in (
            ("mode", [m.name for m in self.modes]),
            ("transition", [t.name for t in self.transitions]),
            ("variable", list(self.variables)),
            ("memory variable", [m.name for m in self.memory]),
        ):
            dup = _duplicates(items)
            if dup:
                raise ModelDefinitionError(
                    f"automaton {self.name!r}: duplicate {kind} name(s) {dup}; every {kind} needs a unique name"
                )
        mode_names = [m.name for m in self.modes]
        known = set(mode_names)
        object.__setattr__(self, "initial_mode_given", bool(self.initial_mode))
        initial = self.initial_mode or mode_names[0]
        if initial not in known:
            raise ModelDefinitionError(
                f"automaton {self.name!r}: initial_mode = {initial!r} is not a mode; expected one of {mode_names}"
            )
        object.__setattr__(self, "initial_mode", initial)
        memory_names = {m.name for m in self.memory}
        variable_names = set(self.variables)
        for t in self.transitions:
            for end, value in (("source", t.source), ("target", t.target)):
                if value not in known:
                    raise ModelDefinitionError(
                        f"transition {t.name!r}: {end} = {value!r} is not a mode of automaton "
                        f"{self.name!r}; expected one of {mode_names}"
                    )
            unknown = [w for w in t.writes if w not in memory_names]
            if unknown:
                raise ModelDefinitionError(
                    f"transition {t.name!r}: writes unknown memory variable(s) {unknown}; "
                    f"declared memory: {sorted(memory_names)}"
                )
            unknown = [r for r in t.reads if r not in variable_names]
            if unknown:
                raise ModelDefinitionError(
                    f"transition {t.name!r}: reads unknown signal(s) {unknown}; "
                    f"declared variables: {list(self.variables)}"
                )
        outgoing: dict[str, list[Transition]] = {n: [] for n in mode_names}
        for t in self.transitions:
            outgoing[t.source].append(t)
        object.__setattr__(
            self,
            "_outgoing",
            MappingProxyType({k: tuple(sorted(v, key=lambda tr: tr.priority)) for k, v in outgoing.items()}),
        )
        object.__setattr__(self, "_mode_index", MappingProxyType({n: i for i, n in enumerate(mode_names)}))
        self._probe_levels()

    def _probe_levels(self) -> None:
        """Refuse a guard or invariant that returns a bool, probed at zero signals and the initial memory.

        A probe that raises proves nothing and is ignored (the function may be undefined at zero);
        the executors and checks refuse a bool at every evaluation as well (:func:`refuse_bool`).
        """
        for what, function in [(f"invariant of mode {q.name!r}", q.invariant) for q in self.modes] + [
                (f"guard of transition {t.name!r}", t.guard) for t in self.transitions] + [
                (f"reset of transition {t.name!r}", t.reset) for t in self.transitions]:
            refuse_misplaced(function, self.variables, f"automaton {self.name!r}: {what}", "variables")
        zeros = tuple(0.0 for _ in self.variables)
        memory = MappingProxyType(self.initial_memory())
        probes = [(f"invariant of mode {q.name!r}", q.invariant) for q in self.modes if q.invariant is not None]
        probes += [(f"guard of transition {t.name!r}", t.guard) for t in self.transitions]
        for what, function in probes:
            try:
                value = function(zeros, memory)
            except Exception:  # noqa: BLE001 - a probe only looks for bools
                continue
            if isinstance(value, BOOL_TYPES):
                raise ModelDefinitionError(f"automaton {self.name!r}: {what} returns a bool ({value!r}); "
                                           f"{BOOL_GUARD_HINT}")
            if isinstance(value, _TEXT_TYPES):
                raise ModelDefinitionError(f"automaton {self.name!r}: {what} returns {value!r}; "
                                           f"expected one real number ({not_a_number(value)})")

    # ------------------------------------------------------------------ queries
    @property
    def mode_names(self) -> tuple[str, ...]:
        """Mode names in declaration order (the index used by traces)."""
        return tuple(self._mode_index)

    def mode(self, name: str) -> Mode:
        """The mode called ``name``."""
        try:
            return self.modes[self._mode_index[name]]
        except KeyError:
            raise ModelDefinitionError(
                f"automaton {self.name!r}: no mode {name!r}; expected one of {list(self.mode_names)}"
            ) from None

    def mode_index(self, name: str) -> int:
        """Index of mode ``name`` in :attr:`modes`."""
        self.mode(name)
        return self._mode_index[name]

    def outgoing(self, mode: str) -> tuple[Transition, ...]:
        """Transitions leaving ``mode``, sorted by priority (smallest first)."""
        self.mode(mode)
        return self._outgoing[mode]

    def initial_memory(self) -> dict[str, float]:
        """A fresh dict of the memory variables' initial values."""
        return {m.name: float(m.initial) for m in self.memory}

    def check_signals(self, v: Sequence[float]) -> None:
        """Raise :class:`ExecutionError` unless ``v`` has one finite-or-inf real per variable."""
        if len(v) != len(self.variables):
            raise ExecutionError(
                f"automaton {self.name!r}: got {len(v)} signal values, expected {len(self.variables)} "
                f"({', '.join(self.variables)})"
            )
        for name, value in zip(self.variables, v):
            if isinstance(value, float) and math.isnan(value):
                raise ExecutionError(f"automaton {self.name!r}: signal {name!r} is NaN")

    def enabled(
        self,
        mode: str,
        v: Sequence[float],
        memory: Mapping[str, float],
        previous: Sequence[float] | None = None,
    ) -> tuple[Transition, ...]:
        """Transitions of ``mode`` enabled at signals ``v`` (priority order).

        Parameters
        ----------
        previous : sequence of float or None
            Signals at the previous evaluation, needed by crossing-triggered
            transitions (``direction != 0``); without them such transitions are
            never enabled.
        """
        result = []
        for t in self.outgoing(mode):
            if transition_fires(t, v, memory, previous):
                result.append(t)
        return tuple(result)


def transition_fires(
    t: Transition, v: Sequence[float], memory: Mapping[str, float], previous: Sequence[float] | None
) -> bool:
    """Whether ``t`` is enabled at ``v`` given the previous signals (crossing semantics of :func:`crossed`).

    This is the test of one transition on one evaluation; what fires at an
    instant (priorities, ties, successive jumps) is :func:`hybrid.instant.settle_instant`.

    Raises
    ------
    ExecutionError
        The guard returned NaN (a NaN compares false and would silently disable it).
    """
    g = guard_value(t, v, memory)
    if t.direction == 0:
        return g >= 0.0
    if previous is None:
        return False
    return crossed(t.direction, t.guard(previous, memory), g)


def guard_value(t: Transition, v: Sequence[float], memory: Mapping[str, float]) -> float:
    """``g(v, m)`` of ``t``; NaN is an error (it would silently disable the transition).

    Raises
    ------
    ExecutionError
        The guard returned NaN.
    """
    g = t.guard(v, memory)
    if g.__class__ is not float and g.__class__ is not _FLOAT64:  # the two real types guards return: no check
        g = real_number(g, f"guard of transition {t.name!r} (from mode {t.source!r})", f"at signals {tuple(v)!r}")
    if g != g:
        raise ExecutionError(
            f"guard of transition {t.name!r} (from mode {t.source!r}) is NaN at signals {tuple(v)!r}; "
            "a guard must return a real number (>= 0 when enabled)"
        )
    return g


def crossed(direction: int, before: float, after: float) -> bool:
    """Whether a guard went from ``before`` to ``after`` across zero in ``direction`` (+1 rising, -1 falling).

    Rising: ``before <= 0 <= after`` and ``before < after`` (zero reached from
    below, or left upwards); falling mirrors it.  A guard that starts on zero
    thus fires as soon as it moves in its direction; one that stays on zero
    does not (see :mod:`hybrid.instant`).

    Examples
    --------
    >>> crossed(+1, -1.0, 0.0), crossed(+1, 0.0, 0.5), crossed(+1, 0.0, 0.0), crossed(-1, 0.0, -2.0)
    (True, True, False, True)
    """
    if direction > 0:
        return before <= 0.0 <= after and before < after
    return before >= 0.0 >= after and before > after


@dataclass(frozen=True, slots=True)
class Conjunction:
    """A guard or invariant ``min(g_1, ..., g_k)``: ``>= 0`` exactly when every term is.

    Built by :func:`all_of`.  Keeping the terms lets the exports recognise a
    conjunction of affine constraints (SpaceEx writes it as ``g_1 >= 0 & ...``)
    and lets the structural checks name the term that fails.
    """

    terms: tuple[Guard, ...]
    texts: tuple[str, ...] = ()
    """The text of each term when every term is symbolic (``symbolic_text``), else empty."""

    def __call__(self, v: Sequence[float], m: Mapping[str, float]) -> float:
        return min(term(v, m) for term in self.terms)


def all_of(*terms: Guard) -> Conjunction:
    """Conjunction of guards (or invariants): the minimum of their values.

    Examples
    --------
    >>> g = all_of(lambda v, m: -v[0], lambda v, m: -v[1])   # h <= 0 and v <= 0
    >>> g((0.0, -1.0), {}), g((0.0, 2.0), {})
    (-0.0, -2.0)

    Symbolic terms (comparisons, or level expressions) give the conjunction its text, so a mode or
    transition needs no ``invariant_text=`` / ``guard_text=``:

    >>> from hybrid.symbolic import coordinates
    >>> v = coordinates("h", "v")
    >>> Mode(name="fly", invariant=all_of(v.h >= 0.0, v.v <= 10.0)).invariant_text
    'h >= 0 and v <= 10'
    """
    if not terms:
        raise ModelDefinitionError("all_of(): give at least one guard term")
    for i, term in enumerate(terms):
        if not callable(term):
            raise ModelDefinitionError(f"all_of(): term {i} = {term!r} is not callable; pass g(v, m) -> float")
    flat: list[Guard] = []
    texts: list[str] = []
    for term in terms:
        if isinstance(term, Conjunction):
            flat.extend(term.terms)
            texts.extend(term.texts if term.texts else [""])
        else:  # a symbolic comparison is kept as its level form (the terms are level functions), with its text
            texts.append(symbolic_text(term))
            flat.append(_as_level(term))
    return Conjunction(tuple(flat), tuple(texts) if all(texts) else ())


def initial_mode_of(automaton: HybridAutomaton, signals: Sequence[float], memory: Mapping[str, float]) -> str:
    """The one mode whose invariant holds at ``signals`` (with ``memory``): the initial mode the invariants decide.

    Raises
    ------
    ModelDefinitionError
        When no invariant or more than one holds there, naming the candidates and the fix (give the
        initial mode: ``HybridAutomaton(initial_mode=...)`` or the problem's ``initial_mode=``).
    """
    holds = []
    for mode in automaton.modes:
        value = math.inf if mode.invariant is None else float(mode.invariant(tuple(signals), dict(memory)))
        if value >= 0.0:
            holds.append(mode.name)
    if len(holds) != 1:
        shown = ", ".join(f"{n}={float(v):.6g}" for n, v in zip(automaton.variables, signals))
        raise ModelDefinitionError(
            f"automaton {automaton.name!r}: the initial mode is not decided by the invariants at ({shown}): "
            f"{'no invariant holds' if not holds else 'the invariants of ' + ', '.join(holds) + ' all hold'}; "
            "give it: HybridAutomaton(initial_mode=...) or the problem's initial_mode=NAME or a function of the point")
    return holds[0]
