"""Sampled signals on a hybrid time domain: the input of Signal Temporal Logic monitoring.

A :class:`SignalTrace` is a finite sequence of samples ordered
lexicographically by ``(t, j)``: ``times`` is non-decreasing and a repeated
time is a *jump* -- the samples on both sides of a jump are kept, in order, and
the jump counter ``j`` increases across it.  Numeric signals are float arrays,
labels are string-valued signals (the mode of an automaton, say).  Two numeric
signals are always present: ``time`` (the sample times) and ``jumps`` (the jump
counter as a float).

Every array is copied and made read-only; every value must be finite -- a NaN
or an infinity is refused with the signal, the sample index and the time,
never carried silently into a robustness value.

Examples
--------
>>> trace = SignalTrace(times=[0.0, 1.0, 1.0, 2.0], signals={"x": [1.0, 2.0, -1.0, 0.5]},
...                     labels={"mode": ("A", "A", "B", "B")})
>>> trace.n, trace.names, trace.label_names
(4, ('x', 'time', 'jumps'), ('mode',))
>>> trace.signal("jumps").tolist()
[0.0, 0.0, 1.0, 1.0]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from hybrid.errors import ParameterError

__all__ = ["BUILTIN_SIGNALS", "TraceError", "SignalTrace"]

BUILTIN_SIGNALS = ("time", "jumps")
"""Numeric signals every trace provides: the sample times [s] and the jump counter."""


class TraceError(ParameterError):
    """A trace is ill-formed, or lacks a signal a formula reads.

    Same shape as every parameter error of the toolkit:
    ``"<parameter> = <value>: expected <expected>; fix: <fix>"``; a
    :class:`ValueError`.
    """


def _where(index: int, times: np.ndarray) -> str:
    return f"sample {index} (t = {float(times[index]):.9g} s)"


def _times(times: object) -> np.ndarray:
    try:
        t = np.array(times, dtype=float)
    except (TypeError, ValueError):
        raise TraceError("times", times, "a 1-D array of numbers [s]", "pass the sample times as floats") from None
    if t.ndim != 1 or t.size == 0:
        raise TraceError("times.shape", t.shape, "(n,) with n >= 1", "pass at least one sample time, as a 1-D array")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        k = int(bad[0])
        raise TraceError(f"times[{k}]", float(t[k]), "a finite time [s]",
                         "remove or repair the non-finite sample times")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise TraceError(f"times[{k}]", float(t[k]), f"a time >= times[{k - 1}] = {float(t[k - 1])!r} (non-decreasing)",
                         "sort the samples by (time, jump); a repeated time is a jump")
    t.setflags(write=False)
    return t


def _numeric(name: str, values: object, times: np.ndarray) -> np.ndarray:
    if not isinstance(name, str) or not name:
        raise TraceError("signal name", name, "a non-empty string", "name every signal with a string")
    if name in BUILTIN_SIGNALS:
        raise TraceError(f"signals[{name!r}]", "given", f"no signal called {name!r} (built in: {BUILTIN_SIGNALS})",
                         f"rename the signal; {name!r} is provided by the trace itself")
    try:
        x = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise TraceError(f"signals[{name!r}]", type(values).__name__, "numbers",
                         "pass string-valued signals in labels=, not in signals=") from None
    if x.shape != times.shape:
        raise TraceError(f"signals[{name!r}].shape", x.shape, f"{times.shape} (one value per sample time)",
                         "give every signal the length of times")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        k = int(bad[0])
        raise TraceError(f"signals[{name!r}] at {_where(k, times)}", float(x[k]), "a finite number",
                         f"remove or repair the non-finite values of {name!r} ({bad.size} of {x.size} samples) "
                         "before monitoring")
    x.setflags(write=False)
    return x


def _label(name: str, values: object, times: np.ndarray) -> tuple[str, ...]:
    if not isinstance(name, str) or not name:
        raise TraceError("label name", name, "a non-empty string", "name every label with a string")
    if isinstance(values, str) or not isinstance(values, Sequence | np.ndarray):
        raise TraceError(f"labels[{name!r}]", type(values).__name__, "a sequence of strings, one per sample",
                         "pass e.g. a tuple of mode names")
    out = tuple(values)
    if len(out) != times.size:
        raise TraceError(f"len(labels[{name!r}])", len(out), f"{times.size} (one value per sample time)",
                         "give every label the length of times")
    if all(v.__class__ is str for v in out):  # the common case, checked at once
        return out
    for k, v in enumerate(out):
        if not isinstance(v, str):
            raise TraceError(f"labels[{name!r}] at {_where(k, times)}", v, "a string",
                             "labels are string-valued; put numbers in signals=")
    return tuple(str(v) for v in out)


def _jumps(jumps: object, times: np.ndarray) -> np.ndarray:
    repeated = np.concatenate(([False], np.diff(times) == 0))
    if jumps is None:
        j = np.cumsum(repeated).astype(np.int64)
    else:
        raw = np.asarray(jumps)
        if raw.shape != times.shape or not (np.issubdtype(raw.dtype, np.integer) or raw.dtype == bool):
            raise TraceError("jumps", f"{raw.dtype} array of shape {raw.shape}",
                             f"an int array of shape {times.shape}", "pass the jump counter j of each sample")
        j = raw.astype(np.int64)
        step = np.diff(j)
        bad = np.flatnonzero((step < 0) | ((step == 0) & repeated[1:]))
        if bad.size:
            k = int(bad[0]) + 1
            raise TraceError(f"jumps[{k}] at {_where(k, times)}", int(j[k]),
                             f"a counter > jumps[{k - 1}] = {int(j[k - 1])} at a repeated time, >= it otherwise",
                             "order the samples lexicographically by (t, j)")
    j.setflags(write=False)
    return j


@dataclass(frozen=True, eq=False)
class SignalTrace:
    """Samples of numeric signals and labels on a hybrid time domain.

    Parameters
    ----------
    times : array_like, shape (n,)
        Sample times [s], finite and non-decreasing, ``n >= 1``.  Two equal
        consecutive times are the two sides of a jump.
    signals : mapping of str to array_like, shape (n,)
        Numeric signals, finite.  ``time`` and ``jumps`` are reserved.
    labels : mapping of str to sequence of str, length n
        String-valued signals (e.g. ``"mode"``).
    jumps : array_like of int, shape (n,), optional
        Jump counter ``j``; non-decreasing and strictly increasing at each
        repeated time.  Default: 0 at the first sample, incremented at every
        repeated time.
    termination : str or None, optional
        How the run that produced the trace ended, as the simulator says it:
        ``"end_time"`` (it reached its horizon), ``"final:<reason>"`` (a stop the
        problem declares final: nothing changes after it), or an early end
        (``"zeno"``, ``"invariant_violated"`` (a deadlock), ``"jump_limit"``,
        ``"stop:<name>"``, ``"diverged"``, ``"error"``, ...).  ``None``: not said
        (the trace is then judged by where it ends, :mod:`analysis.verify.falsification`).
    termination_detail : str, optional
        Why, in words (the time, the mode, the cause).

    Raises
    ------
    TraceError
        On any ill-formed array, naming the signal, the sample and the time.
    """

    times: np.ndarray
    signals: Mapping[str, np.ndarray] = field(default_factory=dict)
    labels: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    jumps: np.ndarray | None = None
    termination: str | None = None
    termination_detail: str = ""

    def __post_init__(self) -> None:
        t = _times(self.times)
        if not isinstance(self.signals, Mapping) or not isinstance(self.labels, Mapping):
            raise TraceError("signals/labels", (type(self.signals).__name__, type(self.labels).__name__),
                             "mappings from names to per-sample values", "pass dicts")
        sig = {name: _numeric(name, v, t) for name, v in self.signals.items()}
        lab = {name: _label(name, v, t) for name, v in self.labels.items()}
        both = sorted(set(sig) & set(lab) | set(lab) & set(BUILTIN_SIGNALS))
        if both:
            raise TraceError("labels", both, "names distinct from the numeric signals and from time/jumps",
                             "rename the label or the signal")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "signals", MappingProxyType(sig))
        object.__setattr__(self, "labels", MappingProxyType(lab))
        object.__setattr__(self, "jumps", _jumps(self.jumps, t))
        if self.termination is not None and not isinstance(self.termination, str):
            raise TraceError("termination", self.termination, "a string such as 'end_time' or None",
                             "say how the run ended, or leave it None")
        if not isinstance(self.termination_detail, str):
            raise TraceError("termination_detail", self.termination_detail, "a string", "describe the end in words")

    def __reduce__(self):  # mapping proxies do not pickle; rebuild from plain dicts
        return (_rebuild, (self.times, dict(self.signals), dict(self.labels), self.jumps, self.termination,
                           self.termination_detail))

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.times.size)

    @property
    def names(self) -> tuple[str, ...]:
        """Numeric signal names, the built-in ``time`` and ``jumps`` last."""
        return (*self.signals, *BUILTIN_SIGNALS)

    @property
    def label_names(self) -> tuple[str, ...]:
        """Label (string-valued signal) names."""
        return tuple(self.labels)

    def signal(self, name: str) -> np.ndarray:
        """Values of the numeric signal ``name``, shape (n,) (``time`` and ``jumps`` included)."""
        if name == "time":
            return self.times
        if name == "jumps":
            out = self.jumps.astype(float)
            out.setflags(write=False)
            return out
        try:
            return self.signals[name]
        except KeyError:
            raise TraceError("signal", name, f"one of {', '.join(self.names)}", "use a signal of the trace") from None

    def label(self, name: str) -> tuple[str, ...]:
        """Values of the label ``name``, one string per sample."""
        try:
            return self.labels[name]
        except KeyError:
            raise TraceError("label", name, f"one of {', '.join(self.label_names) or '(no labels)'}",
                             "use a label of the trace") from None


def _rebuild(times: np.ndarray, signals: dict, labels: dict, jumps: np.ndarray, termination: str | None = None,
             detail: str = "") -> SignalTrace:
    return SignalTrace(times=times, signals=signals, labels=labels, jumps=jumps, termination=termination,
                       termination_detail=detail)
