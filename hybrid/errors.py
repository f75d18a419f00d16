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
