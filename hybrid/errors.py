"""Exceptions of the hybrid-automaton library.

Every message names the object concerned, the offending value, what was
expected and how to fix it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = [
    "HybridError",
    "ModelDefinitionError",
    "ExecutionError",
    "UserFunctionError",
    "ZenoError",
    "DivergenceError",
    "NumericalFailure",
    "ParameterError",
    "GuardResolutionWarning",
    "format_time",
    "format_named_state",
    "TIME_DIGITS",
    "STATE_COMPONENTS_SHOWN",
]

STATE_COMPONENTS_SHOWN = 8
"""States with more components are abbreviated in messages (the first ones, ``...``, the last one)."""


TIME_DIGITS = 12
"""Significant digits of a time in messages: 1e-10 s resolved at 100 s (``.6g`` printed 10.0000001 as 10)."""


def format_time(t: float, distinct_from: float | None = None) -> str:
    """A time for messages: :data:`TIME_DIGITS` significant digits, more when needed to tell two times apart.

    Parameters
    ----------
    t : float
        The time [s].
    distinct_from : float or None
        Another time printed in the same message (the step before, the time of
        a reported state): when the two differ but would print alike, ``t`` is
        printed in full (``repr``, the shortest text that reads back as it).

    Examples
    --------
    >>> format_time(0.0), format_time(0.35000000000000003), format_time(10.0000001), format_time(1e-7)
    ('0', '0.35', '10.0000001', '1e-07')
    >>> format_time(100.00000000000001, distinct_from=100.0)
    '100.00000000000001'
    """
    try:
        value = float(t)
    except (TypeError, ValueError):
        return repr(t)
    text = f"{value:.{TIME_DIGITS}g}"
    if distinct_from is not None and distinct_from != value and text == f"{float(distinct_from):.{TIME_DIGITS}g}":
        text = repr(value)
        if text.endswith(".0"):
            text = text[:-2]
    return text


def format_named_state(x: Sequence[float], names: Sequence[str] | None = None,
                       limit: int = STATE_COMPONENTS_SHOWN) -> str:
    """``(h=1.5, v=-2)``: a state for messages, 12 significant digits, abbreviated past ``limit`` components.

    Without ``names`` the components are numbered ``x[0]``, ``x[1]``, ...; a state
    longer than ``limit`` shows its first ``limit - 1`` components, ``...`` and
    the last one, with the dimension.

    Examples
    --------
    >>> format_named_state((1.5, -2.0), ("h", "v"))
    '(h=1.5, v=-2)'
    >>> format_named_state(range(20), limit=4)
    '(x[0]=0, x[1]=1, x[2]=2, ..., x[19]=19; 20 components)'
    """
    try:
        values = [float(c) for c in x]
    except (TypeError, ValueError):
        return repr(x)
    labels = list(names) if names is not None and len(names) == len(values) else [
        f"x[{i}]" for i in range(len(values))]
    items = [f"{n}={_number(v)}" for n, v in zip(labels, values)]
    if len(items) > limit >= 2:
        items = items[: limit - 1] + ["..."] + items[-1:]
        return "(" + ", ".join(items) + f"; {len(values)} components)"
    return "(" + ", ".join(items) + ")"


def _number(v: float) -> str:
    return f"{v:.12g}" if math.isfinite(v) else repr(v)


class HybridError(Exception):
    """Base class of every error raised by :mod:`hybrid`."""


class ModelDefinitionError(HybridError, ValueError):
    """An automaton is ill-defined (unknown mode, duplicate name, wrong dimension, ...)."""


class ExecutionError(HybridError, RuntimeError):
    """An execution could not proceed (bad arguments to an executor, reset returning garbage)."""


class UserFunctionError(ExecutionError):
    """A function of the model (flow, output, guard, invariant, jump map, reset, stop) raised.

    Raised with the original exception chained (``__cause__``).  The message is
    ``"[system 'name': ]<function> raised <Type>: <message> in mode 'q' at t = ... s,
    x = (...); fix: ..."``.  :class:`NumericalFailure` is not wrapped: the
    executors turn it into :class:`DivergenceError`.

    Parameters
    ----------
    function : str
        Which function, e.g. ``"guard of transition 'hit'"`` or ``"output"``.
    error : BaseException
        What it raised.
    mode : str or None
        The active mode (the source mode for a transition's functions).
    time : float or None
        Time of the call [s].
    state : sequence of float or None
        Continuous state (or, for an automaton without a system, the signals) at the call.
    state_names : sequence of str or None
        Names of the state components (numbered when absent).
    system : str or None
        Name of the system or automaton.

    Attributes
    ----------
    function, mode, time, state, state_names, system
        As given (``state`` a tuple).
    error_type, error_message : str
        Class name and text of the original exception (kept when pickled).
    """

    def __init__(self, function: str, error: BaseException | str, mode: str | None = None,
                 time: float | None = None, state: Sequence[float] | None = None,
                 state_names: Sequence[str] | None = None, system: str | None = None,
                 error_type: str | None = None) -> None:
        self.function = function
        self.mode = mode
        self.time = time
        self.state = None if state is None else tuple(state)
        self.state_names = None if state_names is None else tuple(state_names)
        self.system = system
        self.error_type = error_type or (type(error).__name__ if isinstance(error, BaseException) else "Exception")
        self.error_message = str(error)
        super().__init__(self.render())

    def render(self) -> str:
        """The message."""
        where = []
        if self.mode is not None:
            where.append(f"in mode {self.mode!r}")
        if self.time is not None:
            where.append(f"at t = {format_time(self.time)} s")
        text = f"{self.function} raised {self.error_type}: {self.error_message}"
        if where:
            text += " " + " ".join(where)
        if self.state is not None:
            text += f", x = {format_named_state(self.state, self.state_names)}"
        if self.system is not None:
            text = f"system {self.system!r}: {text}"
        return (text + f"; fix: make the {self.function} defined there (the traceback of the original error "
                "is chained), or raise hybrid.NumericalFailure(cause) if the model legitimately breaks down")

    def __reduce__(self):  # picklable across processes (the chained original is not)
        return (type(self), (self.function, self.error_message, self.mode, self.time, self.state,
                             self.state_names, self.system, self.error_type))


class ZenoError(ExecutionError):
    """More discrete jumps at one time instant than the executor allows."""


class NumericalFailure(HybridError, ArithmeticError):
    """Raised by user code (controllers, plants) when a computation breaks down.

    The executor catches it and re-raises it as :class:`DivergenceError` with the
    time and the mode at which it happened.

    Parameters
    ----------
    cause : str
        What broke, e.g. ``"depth of point 2 is -0.01 m (must be > 0)"``.
    """

    def __init__(self, cause: str) -> None:
        super().__init__(cause)
        self.cause = cause


class DivergenceError(ExecutionError):
    """A simulation diverged: carries the time, the mode, the cause and the last finite state.

    The message is ``"simulation diverged at t = <time> s in mode 'q': <cause>;
    last finite state [at t = <state_time> s] (x1=..., x2=...)"``.  Times are
    printed by :func:`format_time` (12 significant digits, where ``.6g`` could
    not tell a time from the step before it; in full when the two times of the
    message would otherwise print alike); the state with its names and 12
    significant digits (abbreviated past :data:`STATE_COMPONENTS_SHOWN`
    components).

    Parameters
    ----------
    time : float
        Time of the failure [s].
    mode : str
        Name of the active mode.
    cause : str
        Human-readable cause (NaN in a state, non-positive depth, singular matrix, ...).
    state : sequence of float or None
        The state at the last finite point (where the failing evaluation was
        made, or the last accepted point when that one is not finite).
    state_names : sequence of str or None
        Names of its components (numbered when absent).
    state_time : float or None
        Time of ``state`` when it is not ``time`` (the last accepted point).

    Attributes
    ----------
    time, mode, cause, state, state_names, state_time
        As given (``state`` a tuple, ``state_time`` equal to ``time`` when not given).
    """

    def __init__(self, time: float, mode: str, cause: str, state: Sequence[float] | None = None,
                 state_names: Sequence[str] | None = None, state_time: float | None = None) -> None:
        self.time = time
        self.mode = mode
        self.cause = cause
        self.state = None if state is None else tuple(state)
        self.state_names = None if state_names is None else tuple(state_names)
        self.state_time = time if state_time is None else state_time
        other = None if self.state is None or self.state_time == time else self.state_time
        text = f"simulation diverged at t = {format_time(time, other)} s in mode {mode!r}: {cause}"
        if self.state is not None:
            at = "" if other is None else f" at t = {format_time(other, time)} s"
            text += f"; last finite state{at} {format_named_state(self.state, self.state_names)}"
        super().__init__(text)

    def __reduce__(self):  # picklable across processes (campaign workers)
        return (type(self), (self.time, self.mode, self.cause, self.state, self.state_names,
                             None if self.state_time == self.time else self.state_time))


class ParameterError(ValueError):
    """A parameter with an invalid value: the one shape of every such error in the toolkit.

    The message is ``"<parameter> = <value>: expected <expected>; fix: <fix>"``.
    Subclasses name the family (campaign options, perturbations, ...);
    instances pickle with their fields (they cross process boundaries in
    campaigns).

    Attributes
    ----------
    parameter : str
        The offending parameter (``"samples"``, ``"Uniform"``, ``"workers"``, ...).
    value : object
        The value found.
    expected : str
        What a valid value looks like.
    fix : str
        How to correct it.
    """

    def __init__(self, parameter: str, value: object, expected: str, fix: str) -> None:
        self.parameter = parameter
        self.value = value
        self.expected = expected
        self.fix = fix
        super().__init__(self.render())

    def render(self) -> str:
        """The message."""
        return f"{self.parameter} = {self.value!r}: expected {self.expected}; fix: {self.fix}"

    def __reduce__(self):  # picklable across processes, as its own class
        return (type(self), (self.parameter, self.value, self.expected, self.fix))


class GuardResolutionWarning(UserWarning):
    """The continuous executor could not rule out a guard window between its samples.

    Issued by :func:`hybrid.simulate_continuous` (once per run) when, at the
    finest refinement of a step, the samples of a watched function (a guard,
    the invariant, a stop function) still bend towards zero by more than their
    distance from it: a window narrower than the finest spacing may have been
    missed there.  The places are listed in
    :attr:`hybrid.continuous.HybridTrajectory.unresolved`; a smaller
    ``max_step`` (or a larger ``sign_checks``) resolves them.
    """
