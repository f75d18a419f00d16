"""Input signals as problem parameters: a piecewise-constant signal with a fixed number of control points.

Falsification benchmarks (ARCH-COMP FALS, ``docs/arch.md``) search over *input signals*, not over
initial states: the throttle and the brake of a car over 30 s, say.  The field parametrises such a
signal by its values at a fixed number of control points: a piecewise-constant signal on ``[0, span]``
with ``n`` equal segments takes one value per segment, each in ``[low, high]``.  Each value is a
:class:`~analysis.verify.verification.Parameter` of the problem's box (named ``<signal>_<k>``, ``k = 0..n-1``),
so every search of :mod:`analysis.verify.falsification` searches the signals unchanged.

:class:`PiecewiseConstantInput`
    One input signal: its name, range, number of control points and span; its parameters, its values
    at a point of the box, its samples at given times.
:func:`input_parameters`
    The parameters of several signals, in order (distinct names checked).
:func:`signal_problem`
    A :class:`~analysis.verify.verification.VerificationProblem` whose box is the input signals (and any further
    parameters) and whose simulator takes the signals: ``simulate(inputs, point) -> SignalTrace`` with
    ``inputs`` the signal name -> :class:`InputSignal`.  Its ``min_budget`` is the number of control
    points: a search with fewer simulations than coordinates cannot even take one step per coordinate,
    and is refused.

Bad input is refused with a :class:`~analysis.verify.verification.ProblemError` naming the parameter: a
number of control points that is not a positive integer, bounds that are not finite or not ordered
(``low <= high``), a nominal value outside them, a span that is not positive, two signals of one
name, a requirement on a signal the model does not output (the problem's formulas are parsed against
the model's outputs), a budget below the number of control points (:func:`analysis.verify.verdicts.verify`).

Examples
--------
>>> throttle = PiecewiseConstantInput(name="throttle", low=0.0, high=100.0, control_points=3, span=30.0)
>>> [p.name for p in throttle.parameters()]
['throttle_0', 'throttle_1', 'throttle_2']
>>> signal = throttle.signal({"throttle_0": 10.0, "throttle_1": 50.0, "throttle_2": 0.0})
>>> signal.at([0.0, 9.99, 10.0, 29.0, 35.0]).tolist()
[10.0, 10.0, 50.0, 0.0, 0.0]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, ProblemError, VerificationProblem

__all__ = ["PiecewiseConstantInput", "InputSignal", "input_parameters", "signal_problem", "dual_signals",
           "InputSensitivities"]


def _finite(parameter: str, value: object, fix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(value)):
        raise ProblemError(parameter, value, "a finite number", fix)
    return float(value)


@dataclass(frozen=True, kw_only=True, slots=True)
class InputSignal:
    """One input signal of a simulation: piecewise constant, right-continuous.

    Attributes
    ----------
    name : str
    starts : numpy.ndarray, shape (n,)
        The start of each segment [s], increasing, ``starts[0] = 0``; the last value holds to the end of the run.
    values : numpy.ndarray, shape (n,)
        The value on each segment (in the signal's unit).
    """

    name: str
    starts: np.ndarray
    values: np.ndarray

    def at(self, times: Sequence[float] | np.ndarray) -> np.ndarray:
        """The signal at ``times`` [s], shape ``(m,)``: the value of the last segment started (right-continuous)."""
        index = np.searchsorted(self.starts, np.asarray(times, dtype=float), side="right") - 1
        return self.values[np.clip(index, 0, self.values.size - 1)]


@dataclass(frozen=True, kw_only=True, slots=True)
class PiecewiseConstantInput:
    """A piecewise-constant input signal with ``control_points`` equal segments over ``[0, span]``.

    Attributes
    ----------
    name : str
        The signal's name (its samples are the trace's signal of that name; its parameters are
        ``<name>_0 .. <name>_<n-1>``).
    low, high : float
        The range of every value, ``low <= high`` (both finite).
    control_points : int
        The number of segments (values), ``>= 1``; segment ``k`` starts at ``k * span / control_points``.
    span : float
        The time the control points cover [s], ``> 0``; the last value holds after it.
    nominal : float or None
        The nominal value of every control point (``u = 0`` of the search); the midpoint when ``None``.
    unit : str
        The unit, for reports.
    """

    name: str
    low: float
    high: float
    control_points: int
    span: float
    nominal: float | None = None
    unit: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ProblemError("PiecewiseConstantInput.name", self.name, "an identifier (letters, digits, _)",
                               "name the signal as the model's trace names it, e.g. 'throttle'")
        where = f"input signal {self.name!r}"
        n = self.control_points
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ProblemError(f"{where}: control_points", n, "a positive integer (the number of segments)",
                               "give control_points >= 1 (1 is a constant signal)")
        low = _finite(f"{where}: low", self.low, "give a finite lower bound of the signal's range")
        high = _finite(f"{where}: high", self.high, "give a finite upper bound of the signal's range")
        if high < low:
            raise ProblemError(f"{where}: [low, high]", (low, high), "low <= high", "swap the two bounds")
        span = _finite(f"{where}: span", self.span, "give the time the control points cover [s]")
        if span <= 0:
            raise ProblemError(f"{where}: span", span, "a positive duration [s]", "give span > 0")
        if self.nominal is not None:
            nominal = _finite(f"{where}: nominal", self.nominal, "give a finite nominal value or None")
            if not low <= nominal <= high:
                raise ProblemError(f"{where}: nominal", nominal, f"a value in [{low}, {high}]",
                                   "move the nominal value into the range")
        object.__setattr__(self, "control_points", int(n))
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        object.__setattr__(self, "span", span)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """``<name>_0 .. <name>_<n-1>``: the box coordinates of the control points, in time order."""
        return tuple(f"{self.name}_{k}" for k in range(self.control_points))

    @property
    def starts(self) -> np.ndarray:
        """The start of each segment [s], shape ``(control_points,)``."""
        return np.arange(self.control_points) * (self.span / self.control_points)

    def parameters(self) -> tuple[Parameter, ...]:
        """One :class:`Parameter` per control point, range ``[low, high]``."""
        return tuple(Parameter(name=name, low=self.low, high=self.high, nominal=self.nominal, unit=self.unit)
                     for name in self.parameter_names)

    def values(self, point: Mapping[str, float]) -> np.ndarray:
        """The control-point values at ``point``, shape ``(control_points,)``; each must lie in ``[low, high]``."""
        out = np.empty(self.control_points)
        for k, name in enumerate(self.parameter_names):
            if name not in point:
                raise ProblemError(f"point[{name!r}]", "missing", f"the value of control point {k} of "
                                   f"{self.name!r}", "pass a point of the problem's box")
            value = _finite(f"point[{name!r}]", point[name], "give a finite value")
            if not self.low <= value <= self.high:
                raise ProblemError(f"point[{name!r}]", value, f"a value in [{self.low}, {self.high}]",
                                   f"keep {self.name!r} within its range")
            out[k] = value
        return out

    def signal(self, point: Mapping[str, float]) -> InputSignal:
        """The signal at ``point``."""
        return InputSignal(name=self.name, starts=self.starts, values=self.values(point))


def input_parameters(inputs: Sequence[PiecewiseConstantInput]) -> tuple[Parameter, ...]:
    """The parameters of ``inputs``, signal after signal; the signals' names must be distinct."""
    inputs = tuple(inputs)
    for item in inputs:
        if not isinstance(item, PiecewiseConstantInput):
            raise ProblemError("inputs", item, "PiecewiseConstantInput objects",
                               "write PiecewiseConstantInput(name=..., low=..., high=..., control_points=..., "
                               "span=...)")
    names = [item.name for item in inputs]
    if len(set(names)) != len(names):
        raise ProblemError("inputs", names, "distinct signal names", "rename the duplicate input signal")
    return tuple(p for item in inputs for p in item.parameters())


InputSimulator = Callable[[Mapping[str, InputSignal], Mapping[str, float]], SignalTrace]
"""``simulate(inputs, point) -> SignalTrace``: the input signals by name, and the whole point."""

InputSensitivities = Callable[[Mapping[str, InputSignal], Mapping[str, float]],
                              tuple[SignalTrace, Mapping[str, np.ndarray]]]
"""``sensitivities(inputs, point) -> (trace, {signal: array (n, k)})``: the same run as the simulator, with each
signal's value on a segment an :class:`analysis.dual.Dual` seeded with its coordinate of the box (``k`` the box's
dimension, the signals' control points first); it returns the trace and ``d signal(t_i) / d p_j``."""


def dual_signals(inputs: Sequence[PiecewiseConstantInput], point: Mapping[str, float], k: int
                 ) -> dict[str, InputSignal]:
    """The signals at ``point`` with dual values: control point ``j`` of the box (signals in order) carries the
    unit gradient ``j`` of length ``k``."""
    from analysis.dual import seeded

    out, offset = {}, 0
    for item in inputs:
        values = item.values(point)
        duals = np.empty(values.size, dtype=object)
        for j, v in enumerate(values):
            duals[j] = seeded(float(v), offset + j, k)
        out[item.name] = InputSignal(name=item.name, starts=item.starts, values=duals)
        offset += item.control_points
    return out


def signal_problem(*, name: str, simulate: InputSimulator, inputs: Sequence[PiecewiseConstantInput],
                   outputs: Sequence[str], horizon: float, requirements: Sequence[Requirement],
                   parameters: Sequence[Parameter] = (), labels: Mapping[str, tuple[str, ...]] | None = None,
                   description: str = "", sensitivities: InputSensitivities | None = None) -> VerificationProblem:
    """A verification problem over input signals.

    Parameters
    ----------
    name : str
    simulate : callable
        ``simulate(inputs, point) -> SignalTrace`` over ``[0, horizon]``; ``inputs`` maps each signal's name
        to its :class:`InputSignal`.  The trace carries the ``outputs`` (and may carry the inputs).
    inputs : sequence of PiecewiseConstantInput
        The input signals; their control points are the box (first, in order).
    outputs : sequence of str
        The numeric signals every trace carries: the requirements may read these (and the box's parameters).
    horizon : float
        The simulated time [s]; no requirement may look further.
    requirements : sequence of Requirement
    parameters : sequence of Parameter
        Further coordinates of the box (constant model parameters).
    labels : mapping or None
        String-valued signals and their values.
    description : str
    sensitivities : callable or None
        :data:`InputSensitivities`: the model's run with the derivatives of its signals with respect to the box
        (:attr:`analysis.verify.verification.VerificationProblem.sensitivities`); ``None``: none.

    Returns
    -------
    VerificationProblem
        With ``min_budget`` the total number of control points.
    """
    inputs = tuple(inputs)
    box = input_parameters(inputs) + tuple(parameters)
    if not inputs:
        raise ProblemError("inputs", inputs, "at least one input signal", "give the model's input signals")

    def run(point: Mapping[str, float]) -> SignalTrace:
        return simulate({item.name: item.signal(point) for item in inputs}, point)

    def differentiate(point: Mapping[str, float]) -> tuple[SignalTrace, Mapping[str, np.ndarray]]:
        return sensitivities(dual_signals(inputs, point, len(box)), point)  # type: ignore[misc]

    return VerificationProblem(name=name, simulate=run, parameters=box, horizon=horizon,
                               requirements=tuple(requirements), signals=tuple(outputs), labels=labels or {},
                               description=description, min_budget=sum(item.control_points for item in inputs),
                               sensitivities=None if sensitivities is None else differentiate)
