"""Counterexample files: a versioned JSON envelope, exact values, typed records, and replay.

Robot-free.  A fuzzer that finds a failing example saves it so that it can be
run again later, by another process or another person.  This module is the
file machinery; what a counterexample *contains* is the caller's business.

:class:`CounterexampleFormat`
    The envelope: a ``format`` name and an integer ``version`` (a reader
    accepts only its own), deterministic text (sorted keys, one sample of a
    sequence per line), values through :func:`encode_value`.
:func:`encode_value`
    The toolkit's JSON policy for files read back
    (:func:`hybrid.jsonable.to_jsonable` with ``nonfinite="string"``: ``inf``,
    ``-inf`` and ``nan`` as strings, floats exact).
``decode_*``
    Typed reading of the values back, every failure a
    :class:`CounterexampleError` naming the file and the field
    (``space.n_obstacles = 1.5: expected an integer``);
    :func:`decode_record` builds a frozen dataclass from its JSON object,
    type-checking each field from the class's annotations.
:func:`replay_counterexample`
    Runs a decoded counterexample again through a caller-supplied function and
    reports whether its property still fails (:class:`Replay`).

Nothing here prints or writes files: the caller writes :meth:`CounterexampleFormat.dumps`'s text.

Examples
--------
>>> fmt = CounterexampleFormat(name="demo-counterexample", version=1, reader="this demo")
>>> text = fmt.dumps({"property": "below"}, rows_key="samples", rows=[(0.5,), (float("inf"),)])
>>> data = fmt.loads(text, "demo.json")
>>> decode_rows(data["samples"], 1, "samples", "demo.json")
((0.5,), (inf,))
"""

from __future__ import annotations

import dataclasses
import json
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from hybrid.jsonable import float_from_json, to_jsonable

from analysis.fuzzing import PropertyViolation

__all__ = [
    "CounterexampleError",
    "CounterexampleFormat",
    "encode_value",
    "decode_float",
    "decode_int",
    "decode_str",
    "decode_optional_int",
    "decode_record",
    "decode_rows",
    "Replay",
    "TraceRecorder",
    "replay_counterexample",
]


class CounterexampleError(ValueError):
    """A counterexample file that cannot be replayed (missing, corrupt, wrong format or version, malformed).

    Attributes
    ----------
    source : str
        The file (or label).
    problem : str
        What is wrong.
    """

    def __init__(self, source: str, problem: str) -> None:
        super().__init__(f"counterexample {source!r}: {problem}")
        self.source = source
        self.problem = problem


def encode_value(value: Any) -> Any:
    """JSON-ready copy of ``value`` for a file that is read back (non-finite floats as strings).

    :func:`hybrid.jsonable.to_jsonable` with ``nonfinite="string"``; any other
    object (violation details are free-form) becomes its ``repr`` without
    memory addresses.
    """
    return to_jsonable(value, nonfinite="string", fallback="repr")


@dataclass(frozen=True, kw_only=True, slots=True)
class CounterexampleFormat:
    """The envelope of a family of counterexample files.

    Attributes
    ----------
    name : str
        Value of the ``format`` key.
    version : int
        Value of the ``version`` key; :meth:`loads` accepts only this one.
    reader : str
        How messages name the reading program (``"this visnav"`` gives
        "... (this visnav reads version 1)").
    """

    name: str
    version: int
    reader: str = "this reader"

    def dumps(
        self,
        fields: Mapping[str, Any],
        *,
        rows_key: str | None = None,
        rows: Sequence[Sequence[Any]] | None = None,
    ) -> str:
        """Deterministic JSON text: the envelope and ``fields`` (sorted keys), then the rows, one per line.

        Parameters
        ----------
        fields : Mapping[str, Any]
            Top-level keys (encoded with :func:`encode_value`); ``format`` and
            ``version`` are added.
        rows_key, rows :
            A sequence of samples written last under ``rows_key``, one sample
            per line (readable diffs of long runs); ``rows=None`` writes none.
        """
        data = {"format": self.name, "version": self.version, **{k: encode_value(v) for k, v in fields.items()}}
        if rows is None:
            return json.dumps(data, indent=1, sort_keys=True) + "\n"
        if rows_key is None:
            raise ValueError("CounterexampleFormat.dumps: rows given without rows_key")
        head = json.dumps(data, indent=1, sort_keys=True)
        lines = ",\n".join("  " + json.dumps(encode_value(row)) for row in rows)
        return f'{head[:-2]},\n {json.dumps(rows_key)}: [\n{lines}\n ]\n}}\n'

    def loads(self, text: str, source: str) -> Mapping[str, Any]:
        """Parse ``text`` and check its envelope; return the top-level object.

        Raises
        ------
        CounterexampleError
            Not JSON, not an object of this format, or another version.
        """
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise CounterexampleError(
                source, f"not valid JSON ({err.msg} at line {err.lineno}, column {err.colno})"
            ) from err
        if not isinstance(data, Mapping) or data.get("format") != self.name:
            found = data.get("format") if isinstance(data, Mapping) else type(data).__name__
            raise CounterexampleError(source, f"not a counterexample file (format = {found!r}, expected {self.name!r})")
        version = data.get("version")
        if version != self.version:
            raise CounterexampleError(
                source, f"format version {version!r} is not supported ({self.reader} reads version {self.version})"
            )
        return data


# ---- typed decoding ---------------------------------------------------------------------------------------


def decode_float(value: Any, where: str, source: str) -> float:
    """A float written by :func:`encode_value` (a number or ``"inf"``, ``"-inf"``, ``"nan"``)."""
    try:
        return float_from_json(value, where=where)
    except ValueError as err:
        raise CounterexampleError(source, str(err)) from None


def decode_int(value: Any, where: str, source: str) -> int:
    """An integer (booleans refused)."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise CounterexampleError(source, f"{where} = {value!r}: expected an integer")
    return value


def decode_optional_int(value: Any, where: str, source: str) -> int | None:
    """An integer or ``null``."""
    if value is not None and (not isinstance(value, int) or isinstance(value, bool)):
        raise CounterexampleError(source, f"{where} = {value!r}: expected an integer or null")
    return value


def decode_str(value: Any, where: str, source: str) -> str:
    """A string."""
    if not isinstance(value, str):
        raise CounterexampleError(source, f"{where} = {value!r}: expected a string")
    return value


def _decode_typed(kind: Any, value: Any, where: str, source: str) -> Any:
    """``value`` read as annotation ``kind``: a dataclass, int, str, bool, float or a tuple of those."""
    if dataclasses.is_dataclass(kind):
        return decode_record(kind, value, where, source)
    if kind is int:
        return decode_int(value, where, source)
    if kind is str:
        return decode_str(value, where, source)
    if kind is bool:
        if not isinstance(value, bool):
            raise CounterexampleError(source, f"{where} = {value!r}: expected true or false")
        return value
    if kind is float:
        return decode_float(value, where, source)
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        if not isinstance(value, list):
            raise CounterexampleError(source, f"{where} = {value!r}: expected a list")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_decode_typed(args[0], x, f"{where}[{i}]", source) for i, x in enumerate(value))
        if len(value) != len(args):
            raise CounterexampleError(source, f"{where}: expected a list of {len(args)} values, found {len(value)}")
        return tuple(_decode_typed(a, x, f"{where}[{i}]", source) for i, (a, x) in enumerate(zip(args, value)))
    raise TypeError(f"decode_record: field {where!r} has an unsupported annotation {kind!r}")


def decode_record(cls: type, data: Any, where: str, source: str) -> Any:
    """A frozen dataclass from its JSON object, every value type-checked against the annotations.

    Keys left out take the field's default; unknown keys, values of the wrong
    type and values the class itself refuses (its ``__post_init__``) are
    errors naming ``where.field``.  Supported annotations: nested dataclasses,
    ``int``, ``str``, ``bool``, ``float`` and tuples of those.

    Raises
    ------
    CounterexampleError
    """
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"{where}: expected an object, found {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise CounterexampleError(source, f"{where}: unknown key(s) {unknown}; expected some of {names}")
    kwargs = {name: _decode_typed(hints[name], value, f"{where}.{name}", source) for name, value in data.items()}
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as err:
        raise CounterexampleError(source, f"{where}: {err}") from err


def decode_rows(
    rows: Any, width: int, where: str, source: str, names: Sequence[str] = ()
) -> tuple[tuple[float, ...], ...]:
    """A non-empty list of samples, each a list of ``width`` floats (``names``: the columns, for messages)."""
    if not isinstance(rows, list) or not rows:
        raise CounterexampleError(source, f"{where}: expected a non-empty list of rows")
    columns = f" ({', '.join(names)})" if names else ""
    parsed = []
    for k, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != width:
            raise CounterexampleError(source, f"{where}[{k}]: expected a list of {width} numbers{columns}")
        parsed.append(tuple(decode_float(x, f"{where}[{k}]", source) for x in row))
    return tuple(parsed)


# ---- replay -------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class Replay:
    """A counterexample run again.

    Attributes
    ----------
    counterexample : Any
        What was replayed (the caller's decoded counterexample).
    violated : bool
        Whether the property still fails.
    message : str
        The violation now (or ``"holds"``).
    sample : int or None
        Sample of the violation, when the property names one.
    trace : tuple of Mapping
        The rows the re-run recorded (read-only), in order.
    """

    counterexample: Any
    violated: bool
    message: str
    sample: int | None
    trace: tuple[Mapping[str, Any], ...]


TraceRecorder = Callable[[Mapping[str, Any]], None]
"""``record(row)``: one row of a replay's trace."""


def replay_counterexample(counterexample: Any, rerun: Callable[[Any, TraceRecorder], None]) -> Replay:
    """Run a decoded counterexample again: ``rerun(counterexample, record)`` re-runs it and checks its property.

    ``rerun`` records trace rows with ``record(row)`` as it goes and raises
    :class:`~analysis.fuzzing.PropertyViolation` when the property fails; any
    other exception counts as a failure too ("never an exception" is part of
    every property), reported as ``"ExceptionType: text"``.  Rows recorded
    before a failure are kept.
    """
    trace: list[Mapping[str, Any]] = []

    def record(row: Mapping[str, Any]) -> None:
        trace.append(MappingProxyType(dict(row)))

    try:
        rerun(counterexample, record)
    except PropertyViolation as err:
        return Replay(counterexample=counterexample, violated=True, message=err.message, sample=err.sample,
                      trace=tuple(trace))
    except Exception as err:
        return Replay(counterexample=counterexample, violated=True, message=f"{type(err).__name__}: {err}",
                      sample=None, trace=tuple(trace))
    return Replay(counterexample=counterexample, violated=False, message="holds", sample=None, trace=tuple(trace))
