"""Continuous-time hybrid systems: an automaton plus flow maps, jump maps and an output.

In the vocabulary of the HyEQ toolbox, a :class:`HybridSystem` gives

* the **flow map** ``f_q(t, x, m)`` of every mode ``q`` (continuous state ``x``,
  memory ``m``), so that ``ẋ = f_q(t, x, m)`` while the mode is kept;
* the **flow set** of a mode through its invariant ``inv_q(v, m) >= 0``;
* the **jump set** of a transition through its guard ``g(v, m) >= 0`` (or
  its zero crossing, see :class:`hybrid.model.Transition`);
* the **jump map** of a transition: the continuous state reset
  ``x⁺ = r(x, m)`` (identity when absent) together with the memory reset of
  the transition itself;
* the **output** ``v = h(t, x)``: the signals that guards and invariants read
  (the identity when ``automaton.variables == state_names``).

The jump map and the memory reset both read the *pre-jump* values.

Every call into the model made through a :class:`HybridSystem` method
(:meth:`~HybridSystem.flow`, :meth:`~HybridSystem.signals`,
:meth:`~HybridSystem.jump`, :meth:`~HybridSystem.guard`,
:meth:`~HybridSystem.invariant`, :meth:`~HybridSystem.reset`) goes through
one mechanism, :func:`call_user`: an exception raised by the user's function
becomes a :class:`~hybrid.errors.UserFunctionError` naming the function, the
mode (the source mode for a transition's functions), the time and the state,
with the original chained (``raise ... from err``).  Two kinds pass through
unchanged: :class:`~hybrid.errors.NumericalFailure` (the executors turn it
into a :class:`~hybrid.errors.DivergenceError` with their own context) and
errors that already carry that context (``UserFunctionError``,
``DivergenceError``).  Wrong shapes, NaN and bools are refused with the same
naming.

Examples
--------
>>> from hybrid import HybridAutomaton, Mode, Transition
>>> ball = HybridAutomaton(
...     name="ball", modes=(Mode(name="fall", invariant=lambda v, m: v[0]),),
...     transitions=(Transition(name="bounce", source="fall", target="fall",
...                             guard=lambda v, m: -v[0], direction=+1),),
...     variables=("h", "v"))
>>> system = HybridSystem(automaton=ball, state_names=("h", "v"),
...     flows={"fall": lambda t, x, m: (x[1], -9.81)},
...     jumps={"bounce": lambda x, m: (0.0, -0.8 * x[1])})
>>> system.flow("fall", 0.0, (1.0, 0.0), {})
(0.0, -9.81)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from .errors import (
    DivergenceError,
    ExecutionError,
    ModelDefinitionError,
    NumericalFailure,
    ParameterError,
    UserFunctionError,
    format_time,
)
from .model import BOOL_TYPES, HybridAutomaton, Transition, real_number

__all__ = ["FlowMap", "JumpMap", "OutputMap", "HybridSystem", "call_user", "real_value", "format_state", "state_vector"]

PASSED_THROUGH: tuple[type[BaseException], ...] = (NumericalFailure, UserFunctionError, DivergenceError)
"""Exceptions that :func:`call_user` lets through unchanged (see the module docstring)."""

FlowMap = Callable[[float, Sequence[float], Mapping[str, float]], Sequence[float]]
"""``f(t, x, m) -> ẋ`` of one mode, shape ``(n,)``."""

JumpMap = Callable[[Sequence[float], Mapping[str, float]], Sequence[float]]
"""``r(x, m) -> x⁺`` of one transition, shape ``(n,)``."""

OutputMap = Callable[[float, Sequence[float]], Sequence[float]]
"""``h(t, x) -> v``, one value per automaton variable."""


@dataclass(frozen=True, kw_only=True, slots=True)
class HybridSystem:
    """A hybrid automaton with continuous dynamics, validated at construction.

    Attributes
    ----------
    automaton : HybridAutomaton
        Modes, transitions (guards, memory resets, priorities), invariants.
    state_names : tuple of str
        Names of the continuous state components (dimension ``n``).
    flows : Mapping[str, FlowMap]
        One flow map per mode (every mode must have one).
    jumps : Mapping[str, JumpMap]
        Continuous-state resets keyed by transition name; missing means identity.
    output : OutputMap or None
        Signals read by guards and invariants; ``None`` means ``v = x`` and then
        ``automaton.variables`` must equal ``state_names``.

    Raises
    ------
    ModelDefinitionError
        A mode without a flow, a flow or jump for an unknown mode or
        transition, a non-callable map, or ``output=None`` with variables that
        are not the state names.
    """

    automaton: HybridAutomaton
    state_names: tuple[str, ...]
    flows: Mapping[str, FlowMap]
    jumps: Mapping[str, JumpMap] = field(default_factory=dict)
    output: OutputMap | None = None

    def __post_init__(self) -> None:
        a = self.automaton
        if not isinstance(a, HybridAutomaton):
            raise ModelDefinitionError(
                f"HybridSystem.automaton = {a!r}: expected a HybridAutomaton"
            )
        object.__setattr__(self, "state_names", tuple(self.state_names))
        if not self.state_names:
            raise ModelDefinitionError(
                f"system {a.name!r}: state_names is empty; name at least one continuous state"
            )
        if len(set(self.state_names)) != len(self.state_names):
            raise ModelDefinitionError(f"system {a.name!r}: duplicate state names in {list(self.state_names)}")
        flows = dict(self.flows)
        mode_names = a.mode_names
        known = set(mode_names)  # one set: membership per flow in O(1), not a scan of the tuple (20,000 modes)
        missing = [m for m in mode_names if m not in flows]
        if missing:
            raise ModelDefinitionError(
                f"system {a.name!r}: no flow map for mode(s) {missing}; give flows={{mode: f(t, x, m)}} for "
                f"every mode of {list(a.mode_names)}"
            )
        unknown = [m for m in flows if m not in known]
        if unknown:
            raise ModelDefinitionError(
                f"system {a.name!r}: flows given for unknown mode(s) {unknown}; modes are {list(a.mode_names)}"
            )
        for mode, f in flows.items():
            if not callable(f):
                raise ModelDefinitionError(
                    f"system {a.name!r}: flow of mode {mode!r} = {f!r} is not callable; pass f(t, x, m) -> dx/dt"
                )
        jumps = dict(self.jumps)
        names = {t.name for t in a.transitions}
        unknown = [t for t in jumps if t not in names]
        if unknown:
            raise ModelDefinitionError(
                f"system {a.name!r}: jump maps given for unknown transition(s) {unknown}; "
                f"transitions are {sorted(names)}"
            )
        for name, r in jumps.items():
            if not callable(r):
                raise ModelDefinitionError(
                    f"system {a.name!r}: jump map of transition {name!r} = {r!r} is not callable; "
                    "pass r(x, m) -> new state"
                )
        if self.output is None:
            if tuple(a.variables) != self.state_names:
                raise ModelDefinitionError(
                    f"system {a.name!r}: output is None, so the automaton's variables {list(a.variables)} must be "
                    f"the state names {list(self.state_names)}; give output=h(t, x) -> signals otherwise"
                )
        elif not callable(self.output):
            raise ModelDefinitionError(f"system {a.name!r}: output = {self.output!r} is not callable")
        from .model import refuse_misplaced, refuse_unsupported

        for mode, f in flows.items():
            refuse_unsupported(f, f"system {a.name!r}: flow of mode {mode!r}")
            refuse_misplaced(f, self.state_names, f"system {a.name!r}: flow of mode {mode!r}", "state names")
        for name, r in jumps.items():
            refuse_unsupported(r, f"system {a.name!r}: jump map of transition {name!r}", timed=False)
            refuse_misplaced(r, self.state_names, f"system {a.name!r}: jump map of transition {name!r}",
                             "state names")
        refuse_unsupported(self.output, f"system {a.name!r}: output")
        refuse_misplaced(self.output, self.state_names, f"system {a.name!r}: output", "state names")
        object.__setattr__(self, "flows", MappingProxyType(flows))
        object.__setattr__(self, "jumps", MappingProxyType(jumps))

    # ------------------------------------------------------------------ evaluation
    @property
    def name(self) -> str:
        """Name of the automaton."""
        return self.automaton.name

    @property
    def dimension(self) -> int:
        """Number of continuous states ``n``."""
        return len(self.state_names)

    def flow(self, mode: str, t: float, x: Sequence[float], memory: Mapping[str, float]) -> tuple[float, ...]:
        """``ẋ`` in ``mode``, checked for shape and NaN.

        Raises
        ------
        UserFunctionError
            The flow raised (chained), naming the mode, the state and the time.
        ExecutionError
            Wrong length or a NaN, naming the mode, the state and the time.
        NumericalFailure
            Raised by the flow itself: passed through (see :func:`call_user`).
        """
        value = call_user(self.flows[mode], (t, x, memory), function=f"flow of mode {mode!r}", mode=mode,
                          time=t, state=x, state_names=self.state_names, system=self.name)
        return self._checked(value, f"flow of mode {mode!r}", t, x)

    def jump(self, transition: str, t: float, x: Sequence[float], memory: Mapping[str, float]) -> tuple[float, ...]:
        """Continuous state after ``transition`` (identity without a jump map).

        Raises
        ------
        UserFunctionError
            The jump map raised (chained), naming the transition, its source mode, the state and the time.
        ExecutionError
            Wrong length or a NaN.
        """
        r = self.jumps.get(transition)
        if r is None:
            return tuple(float(c) for c in x)
        try:
            value = r(x, memory)
        except PASSED_THROUGH:
            raise
        except Exception as err:
            raise self._failure(f"jump map of transition {transition!r}", err, self._source(transition), t, x) from err
        return self._checked(value, f"jump map of transition {transition!r}", t, x)

    def signals(self, t: float, x: Sequence[float], mode: str | None = None) -> tuple[float, ...]:
        """Signals ``v`` read by guards and invariants.

        Parameters
        ----------
        t : float
            Time [s].
        x : sequence of float
            Continuous state.
        mode : str or None
            The active mode, named by the errors (executors give it).

        Raises
        ------
        UserFunctionError
            The output map raised (chained).
        ExecutionError
            It returned the wrong number of values or a NaN.
        """
        if self.output is None:
            return tuple(float(c) for c in x)
        v = call_user(self.output, (t, x), function="output", mode=mode, time=t, state=x,
                      state_names=self.state_names, system=self.name)
        where = f"{'' if mode is None else f' in mode {mode!r}'} at t = {format_time(t)} s, x = {format_state(x)}"
        try:
            n = len(v)
        except TypeError:
            raise ExecutionError(
                f"system {self.name!r}: output returned {v!r}{where}; "
                f"expected {len(self.automaton.variables)} values ({', '.join(self.automaton.variables)})"
            ) from None
        if n != len(self.automaton.variables):
            raise ExecutionError(
                f"system {self.name!r}: output returned {n} values{where}; "
                f"expected {len(self.automaton.variables)} ({', '.join(self.automaton.variables)})"
            )
        for name, value in zip(self.automaton.variables, v):
            if value != value:
                raise ExecutionError(f"system {self.name!r}: output {name!r} is NaN{where}")
        return tuple(v)

    def guard(self, transition: Transition, t: float, x: Sequence[float], v: Sequence[float],
              memory: Mapping[str, float]) -> float:
        """``g(v, m)`` of ``transition``: one real number, named errors otherwise.

        Raises
        ------
        UserFunctionError
            The guard raised (chained).
        ExecutionError
            It returned a bool, a non-number or NaN.
        """
        what = f"guard of transition {transition.name!r}"
        value = call_user(transition.guard, (v, memory), function=what, mode=transition.source, time=t, state=x,
                          state_names=self.state_names, system=self.name)
        return real_value(value, what, transition.source, t, x)

    def invariant(self, mode: str, t: float, x: Sequence[float], v: Sequence[float],
                  memory: Mapping[str, float]) -> float:
        """``inv(v, m)`` of ``mode`` (``inf`` without an invariant); errors as :meth:`guard`."""
        inv = self.automaton.mode(mode).invariant
        if inv is None:
            return math.inf
        what = f"invariant of mode {mode!r}"
        value = call_user(inv, (v, memory), function=what, mode=mode, time=t, state=x,
                          state_names=self.state_names, system=self.name)
        return real_value(value, what, mode, t, x)

    def reset(self, transition: Transition, t: float, x: Sequence[float], v: Sequence[float],
              memory: Mapping[str, float]) -> dict[str, float]:
        """Memory after ``transition``'s reset (a copy of ``memory`` without one).

        Raises
        ------
        UserFunctionError
            The reset raised (chained).
        ExecutionError
            It did not return exactly the declared ``writes``, or a value is not a real number.
        """
        new_memory = dict(memory)
        if transition.reset is None:
            return new_memory
        what = f"reset of transition {transition.name!r}"
        update = call_user(transition.reset, (v, memory), function=what, mode=transition.source, time=t, state=x,
                           state_names=self.state_names, system=self.name)
        if not isinstance(update, Mapping) or set(update) != set(transition.writes):
            got = sorted(update) if isinstance(update, Mapping) else repr(update)
            raise ExecutionError(
                f"reset of transition {transition.name!r} at t = {format_time(t)} s, x = {format_state(x)} returned "
                f"{got}; expected a mapping with exactly the declared writes {sorted(transition.writes)}"
            )
        for name, value in update.items():
            new_memory[name] = real_value(value, f"{what} ({name})", transition.source, t, x)
        return new_memory

    def _source(self, transition: str) -> str | None:
        for tr in self.automaton.transitions:
            if tr.name == transition:
                return tr.source
        return None

    def _failure(self, what: str, err: Exception, mode: str | None, t: float, x: Sequence[float]) -> UserFunctionError:
        return UserFunctionError(what, err, mode=mode, time=t, state=_state_or_none(x),
                                 state_names=self.state_names, system=self.name)

    def _checked(self, value: Sequence[float], what: str, t: float, x: Sequence[float]) -> tuple[float, ...]:
        try:
            out = tuple(float(c) for c in value)
        except (TypeError, ValueError):
            raise ExecutionError(
                f"system {self.name!r}: {what} returned {value!r} at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {self.dimension} real numbers ({', '.join(self.state_names)})"
            ) from None
        if len(out) != self.dimension:
            raise ExecutionError(
                f"system {self.name!r}: {what} returned {len(out)} values at t = {t:.17g} s, x = {format_state(x)}; "
                f"expected {self.dimension} ({', '.join(self.state_names)})"
            )
        for name, c in zip(self.state_names, out):
            if math.isnan(c):
                raise ExecutionError(
                    f"system {self.name!r}: {what} gives NaN for {name!r} at t = {t:.17g} s, x = {format_state(x)}"
                )
        return out


def call_user(fn: Callable[..., Any], args: Sequence[Any], *, function: str, mode: str | None = None,
              time: float | None = None, state: Sequence[float] | None = None,
              state_names: Sequence[str] | None = None, system: str | None = None) -> Any:
    """``fn(*args)``, an exception it raises re-raised as :class:`~hybrid.errors.UserFunctionError`.

    The one way the executors call the user's functions (through the
    :class:`HybridSystem` methods, and directly for the continuous executor's
    stop functions).

    Parameters
    ----------
    fn : callable
        The user's function.
    args : sequence
        Its arguments.
    function : str
        Its description for the message (``"flow of mode 'on'"``).
    mode, time, state, state_names, system
        The context named by the message (see :class:`~hybrid.errors.UserFunctionError`).

    Returns
    -------
    object
        What ``fn`` returned (unchecked).

    Raises
    ------
    UserFunctionError
        ``fn`` raised; the original is chained as ``__cause__``.
    NumericalFailure, DivergenceError
        Passed through (:data:`PASSED_THROUGH`), as is an inner ``UserFunctionError``.

    Examples
    --------
    >>> from hybrid.errors import UserFunctionError
    >>> try:
    ...     call_user(lambda v, m: 1.0 / v[0], ((0.0,), {}), function="guard of transition 'hit'", mode="wait",
    ...               time=0.5, state=(0.0,), state_names=("x",))
    ... except UserFunctionError as err:
    ...     print(str(err).split("; fix")[0])
    guard of transition 'hit' raised ZeroDivisionError: float division by zero in mode 'wait' at t = 0.5 s, x = (x=0)
    """
    try:
        return fn(*args)
    except PASSED_THROUGH:
        raise
    except Exception as err:
        raise UserFunctionError(function, err, mode=mode, time=time, state=_state_or_none(state),
                                state_names=state_names, system=system) from err


def state_vector(name: str, value: Any, state_names: Sequence[str], *,
                 error: type[ParameterError] = ParameterError) -> np.ndarray:
    """A state given by a caller as a float array of shape ``(n,)``: one finite real number per state.

    The one validation of a state-valued parameter (an initial state, a guess, an equilibrium).
    Strings, bools, complex numbers, ``None``, a wrong length and NaN/inf are refused.

    Parameters
    ----------
    name : str
        The parameter's name, for the message.
    value : sequence of float, shape (n,)
    state_names : sequence of str, length n
    error : type
        The :class:`~hybrid.errors.ParameterError` subclass to raise.

    Raises
    ------
    ParameterError
        (or ``error``) naming the parameter, the value, the states expected and the fix.

    Examples
    --------
    >>> state_vector("guess", (1, 2.5), ("x", "y")).tolist()
    [1.0, 2.5]
    >>> state_vector("guess", "12", ("x", "y"))
    Traceback (most recent call last):
    ...
    hybrid.errors.ParameterError: guess = '12': expected 2 finite values (x, y); fix: give one number per state, in the order of the state names
    """
    expected = f"{len(state_names)} finite values ({', '.join(state_names)})"
    fix = "give one number per state, in the order of the state names"
    items = None if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") else list(value)
    if items is None or any(isinstance(c, BOOL_TYPES) or isinstance(c, complex) or np.iscomplexobj(c)
                            for c in items):
        raise error(name, value, expected, fix)
    try:
        x = np.asarray(items, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise error(name, value, expected, fix) from None
    if x.size != len(state_names) or len(items) != len(state_names) or not np.all(np.isfinite(x)):
        raise error(name, tuple(x.tolist()), expected, fix)
    return x


def real_value(value: Any, what: str, mode: str | None, t: float, x: Sequence[float]) -> float:
    """``float(value)`` of a guard, invariant, stop or reset value; a bool, text, non-number or NaN is refused
    (:func:`hybrid.model.real_number`, the rule the structural checks apply too).

    Raises
    ------
    ExecutionError
        Naming ``what``, the mode, the time and the state.
    """
    if value.__class__ is float and value == value:
        return value
    out = real_number(value, what, f"in mode {mode!r} at t = {t:.17g} s, x = {format_state(x)}",
                      bool_what=f"{what} (mode {mode!r}, t = {t:.17g} s)")
    if out != out:
        raise ExecutionError(f"{what} is NaN in mode {mode!r} at t = {t:.17g} s, x = {format_state(x)}")
    return out


def _state_or_none(x: Any) -> tuple[float, ...] | None:
    try:
        return tuple(float(c) for c in x)
    except (TypeError, ValueError):
        return None


def format_state(x: Sequence[float]) -> str:
    """``(x1, x2, ...)`` with 10 significant digits, for error messages (``repr`` if not numeric)."""
    try:
        return "(" + ", ".join(f"{float(c):.10g}" for c in x) + ")"
    except (TypeError, ValueError):
        return repr(x)
