"""Exceptions of the hybrid-automaton library.

Every message names the object concerned, the offending value, what was
expected and how to fix it.
"""

from __future__ import annotations

__all__ = [
    "HybridError",
    "ModelDefinitionError",
    "ExecutionError",
    "ZenoError",
    "DivergenceError",
    "NumericalFailure",
    "ParameterError",
]


class HybridError(Exception):
    """Base class of every error raised by :mod:`hybrid`."""


class ModelDefinitionError(HybridError, ValueError):
    """An automaton is ill-defined (unknown mode, duplicate name, wrong dimension, ...)."""


class ExecutionError(HybridError, RuntimeError):
    """An execution could not proceed (bad arguments to an executor, reset returning garbage)."""


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
    """A simulation diverged: carries the time, the mode and the cause.

    Attributes
    ----------
    time : float
        Time of the failure [s].
    mode : str
        Name of the active mode.
    cause : str
        Human-readable cause (NaN in a state, non-positive depth, singular matrix, ...).
    """

    def __init__(self, time: float, mode: str, cause: str) -> None:
        super().__init__(f"simulation diverged at t = {time:.6g} s in mode {mode!r}: {cause}")
        self.time = time
        self.mode = mode
        self.cause = cause


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
