"""Counterexample files: a versioned JSON envelope, exact values, typed records, and replay.

Robot-free.  A fuzzer that finds a failing example saves it so that it can be
run again later, by another process or another person.  This module is the
file machinery; what a counterexample *contains* is the caller's business.

:func:`read_counterexample_text`
    A file's text, refused with a :class:`CounterexampleError` when it is not
    a regular file, larger than :data:`MAX_FILE_BYTES` or not UTF-8.
:class:`CounterexampleFormat`
    The envelope: a ``format`` name and an integer ``version`` (a reader
    accepts only its own), deterministic text (sorted keys, one sample of a
    sequence per line), values through :func:`encode_value`.  Reading is
    strict JSON: no ``NaN``/``Infinity`` tokens, no number overflowing a float,
    integers of at most :data:`MAX_INT_DIGITS` digits, no duplicate key, no
    unpaired surrogate, at most :data:`MAX_DEPTH` levels of nesting, no
    byte-order mark, an object at the top level.
:func:`encode_value`
    The toolkit's JSON policy for files read back
    (:func:`hybrid.jsonable.to_jsonable` with ``nonfinite="string"``: ``inf``,
    ``-inf`` and ``nan`` as strings, floats exact).
``decode_*``
    Typed reading of the values back, every failure a
    :class:`CounterexampleError` naming the file and the field
    (``space.n_obstacles = 1.5: expected an integer``);
    :func:`decode_record` builds a frozen dataclass from its JSON object,
    type-checking each field from the class's annotations;
    :func:`check_keys` refuses missing and unknown keys of an object.
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
import itertools
import json
import math
import os
import re
import stat
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from hybrid.jsonable import float_from_json, to_jsonable

from analysis.fuzzing import PropertyViolation

__all__ = [
    "MAX_FILE_BYTES",
    "MAX_DEPTH",
    "MAX_INT_DIGITS",
    "CounterexampleError",
    "CounterexampleFormat",
    "read_counterexample_text",
    "parse_json",
    "json_type",
    "show_value",
    "check_keys",
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
    "TRACE_BYTES",
    "TRACE_ROWS",
    "stored_sample_indices",
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


MAX_FILE_BYTES = 50_000_000
"""Largest counterexample file read [bytes] (50 MB; the files written by the fuzzers are kilobytes)."""
TRACE_BYTES = MAX_FILE_BYTES // 5
"""Most bytes a written counterexample's stored trace may take (10 MB: a fifth of what a reader accepts)."""
TRACE_ROWS = 100_000
"""Most samples of a stored trace; a longer trace is decimated (:func:`stored_sample_indices`)."""
MAX_DEPTH = 64
"""Deepest nesting of arrays and objects read (the files written are at most 6 levels deep)."""
MAX_INT_DIGITS = 300
"""Most digits of an integer read (every integer read then also converts to a float)."""
_SHOWN = 80


def json_type(value: Any) -> str:
    """What a decoded JSON value is, as a message says it (``"an array"``, ``"null"``, ...)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, (list, tuple)):
        return "an array"
    return f"a {type(value).__name__}"


def show_value(value: Any, limit: int = _SHOWN) -> str:
    """``repr(value)`` for a message, cut to about ``limit`` characters (a file's value can be megabytes)."""
    text = repr(value)
    if len(text) <= limit:
        return text
    if isinstance(value, str):
        return f"{text[:limit]}... (a string of {len(value):,} characters)"
    if isinstance(value, (list, tuple, Mapping)):
        return f"{text[:limit]}... ({json_type(value)} of {len(value):,} entries)"
    return f"{text[:limit]}..."


def _names(keys: Sequence[Any], limit: int = 8) -> str:
    """``'a', 'b'`` (at most ``limit`` of them, then how many more)."""
    shown = ", ".join(show_value(k, 40) for k in list(keys)[:limit])
    return shown + (f" and {len(keys) - limit} more" if len(keys) > limit else "")


def read_counterexample_text(path: str | os.PathLike[str], *, max_bytes: int = MAX_FILE_BYTES) -> str:
    """The text of a counterexample file: a regular file of at most ``max_bytes`` bytes of UTF-8.

    A FIFO or a device is refused before it is opened (reading one could block or never end).

    Raises
    ------
    CounterexampleError
        ``source`` is ``str(path)``; the problem says what the path is
        instead (missing, a folder, not a regular file, too large, not UTF-8,
        unreadable).
    """
    source = os.fspath(path)
    try:
        info = os.stat(source)
    except FileNotFoundError:
        raise CounterexampleError(source, "no such file") from None
    except (OSError, ValueError) as err:  # ValueError: a NUL byte in the path
        raise CounterexampleError(source, f"cannot read the file ({getattr(err, 'strerror', None) or err})") from None
    if stat.S_ISDIR(info.st_mode):
        raise CounterexampleError(source, "is a folder, not a file")
    if not stat.S_ISREG(info.st_mode):
        raise CounterexampleError(source, "is not a regular file (a device, FIFO or socket)")
    def too_big(size: str) -> CounterexampleError:
        return CounterexampleError(source, f"the file is {size} bytes, more than the {max_bytes:,} bytes a "
                                           "counterexample file may have (the fuzzers write kilobytes)")

    if info.st_size > max_bytes:
        raise too_big(f"{info.st_size:,}")
    try:
        with open(source, "rb") as handle:  # a regular file: opening it does not block
            if not stat.S_ISREG(os.fstat(handle.fileno()).st_mode):  # replaced since the stat above
                raise CounterexampleError(source, "is not a regular file")
            data = handle.read(max_bytes + 1)
    except OSError as err:
        raise CounterexampleError(source, f"cannot read the file ({err.strerror or err})") from None
    if len(data) > max_bytes:  # grew since the stat above, or a file system reporting no size
        raise too_big(f"over {max_bytes:,}")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line, column = _position(data, err.start)
        raise CounterexampleError(
            source, f"not UTF-8 text: byte 0x{data[err.start]:02x} at line {line}, column {column} ({err.reason}); "
                    "a counterexample file is UTF-8 JSON"
        ) from None


def _position(text: str | bytes, offset: int) -> tuple[int, int]:
    """1-based line and column of ``offset`` in ``text``."""
    newline = b"\n" if isinstance(text, bytes) else "\n"
    return text.count(newline, 0, offset) + 1, offset - (text.rfind(newline, 0, offset) + 1) + 1


# ---- strict JSON ------------------------------------------------------------------------------------


class _Refused:
    """A number token strict JSON reading refuses, kept in place so that the message can name its path."""

    __slots__ = ("problem",)

    def __init__(self, problem: str) -> None:
        self.problem = problem


class _Duplicated(dict):
    """An object in which a key occurs twice (the first duplicated key in ``duplicate``)."""

    duplicate: Any = None


def _constant(name: str) -> _Refused:
    return _Refused(f"{name} is not a JSON number (non-finite values are written as the strings "
                    "\"nan\", \"inf\", \"-inf\" where they are allowed)")


def _int(text: str) -> int | _Refused:
    digits = len(text) - text.startswith("-")
    if digits > MAX_INT_DIGITS:
        return _Refused(f"an integer of {digits} digits (at most {MAX_INT_DIGITS} are read)")
    return int(text)


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    data = dict(pairs)
    if len(data) == len(pairs):
        return data
    seen: set[str] = set()
    duplicate = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
    refused = _Duplicated(data)
    refused.duplicate = duplicate
    return refused


_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _path(trail: Any) -> str:
    """``violation.details.x[2]`` from the linked trail ``(parent, key)`` of a value (``""``: the top level)."""
    keys: list[Any] = []
    while trail is not None:
        trail, key = trail
        keys.append(key)
    text = ""
    for key in reversed(keys):
        if isinstance(key, int):
            text += f"[{key}]"
        elif _IDENTIFIER.match(key):
            text += f".{key}" if text else key
        else:
            text += f"[{show_value(key, 40)}]"
    return text if len(text) <= 160 else text[:80] + " ... " + text[-75:]


def _unpaired_surrogate(text: str) -> bool:
    if text.isascii():
        return False
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return True
    return False


_NUMBERS = {float, int}
_OVERFLOW = ("a number too large for a float (it reads as infinity); write a finite number, or the string "
             "\"inf\" where infinity is allowed")


def _number_rows(value: list[Any]) -> bool:
    """Whether ``value`` is a list of lists of finite numbers (checked without a Python call per value)."""
    if set(map(type, value)) != {list}:
        return False
    values = itertools.chain.from_iterable(value)
    return set(map(type, values)) <= _NUMBERS and math.isfinite(sum(itertools.chain.from_iterable(value)))


def _check_tree(data: Any, source: str) -> None:
    """Refuse what :func:`json.loads` accepted but strict reading does not (module docstring).

    ``NaN``, ``Infinity`` and over-long integers were kept in place by the
    parser's hooks as :class:`_Refused`, duplicate keys as :class:`_Duplicated`;
    a float that is not finite can only be a literal that overflowed.
    """

    def fail(problem: str, trail: Any) -> typing.NoReturn:
        where = _path(trail) or "the top-level object"
        raise CounterexampleError(source, f"malformed counterexample file: {where}: {problem}")

    stack: list[tuple[Any, int, Any]] = [(data, 1, None)]
    while stack:
        value, depth, trail = stack.pop()
        if isinstance(value, (dict, list)):
            if depth > MAX_DEPTH:
                fail(f"nested more than {MAX_DEPTH} levels deep (arrays and objects)", trail)
            if isinstance(value, dict):
                if isinstance(value, _Duplicated):
                    fail(f"duplicate key {show_value(value.duplicate, 40)} (each key may occur once per object)",
                         trail)
                items = list(value.items())
                for key, _ in items:
                    if _unpaired_surrogate(key):
                        fail(f"key {show_value(key, 40)} has an unpaired surrogate (not Unicode text)", trail)
            elif depth + 1 <= MAX_DEPTH and _number_rows(value):  # a sequence of samples: nothing more to check
                continue
            else:
                items = list(enumerate(value))
            for key, child in reversed(items):
                kind = type(child)
                if kind is float:
                    if not math.isfinite(child):
                        fail(_OVERFLOW, (trail, key))
                elif kind is not int:
                    stack.append((child, depth + 1, (trail, key)))
        elif isinstance(value, str):
            if _unpaired_surrogate(value):
                fail(f"string {show_value(value, 40)} has an unpaired surrogate (not Unicode text)", trail)
        elif isinstance(value, _Refused):
            fail(value.problem, trail)


_BRACKETS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def _too_deep_at(text: str) -> str:
    """``line L, column C``: where the nesting first exceeds :data:`MAX_DEPTH` (for the parser's own limit)."""
    depth = 0
    for match in _BRACKETS.finditer(text):
        token = match.group()
        if token in ("[", "{"):
            depth += 1
            if depth > MAX_DEPTH:
                line, column = _position(text, match.start())
                return f"line {line}, column {column}"
        elif token in ("]", "}"):
            depth -= 1
    return "the top-level value"  # not reached for text the parser gave up on


def parse_json(text: str, source: str) -> Any:
    """Strict JSON (module docstring): the decoded value, or a :class:`CounterexampleError` saying what and where.

    The problem starts with ``"not valid JSON"`` for syntax errors (with line
    and column) and ``"malformed counterexample file: "`` for the rest, followed
    by where: the path of the value (``measurements[3][0]: NaN is not a JSON
    number ...``), or the line and column when the parser itself gave up.
    """
    if not text.strip():
        raise CounterexampleError(source, "malformed counterexample file: the file is empty; expected a JSON object")
    if text.startswith("\ufeff"):
        raise CounterexampleError(source, "malformed counterexample file: it starts with a byte-order mark (U+FEFF), "
                                          "which JSON does not allow; save it as UTF-8 without BOM")
    try:
        data = json.loads(text, parse_constant=_constant, parse_int=_int, object_pairs_hook=_object)
    except json.JSONDecodeError as err:
        raise CounterexampleError(
            source, f"not valid JSON ({err.msg} at line {err.lineno}, column {err.colno})"
        ) from None
    except RecursionError:
        raise CounterexampleError(source, f"malformed counterexample file: {_too_deep_at(text)}: nested more than "
                                          f"{MAX_DEPTH} levels deep (arrays and objects)") from None
    _check_tree(data, source)
    return data


def check_keys(
    data: Mapping[str, Any], where: str, source: str, required: Sequence[str], optional: Sequence[str] = ()
) -> None:
    """Refuse an object missing one of ``required`` or holding a key in neither list (``where``: its path)."""
    at = f"{where}: " if where else ""
    known = (*required, *optional)
    missing = [k for k in required if k not in data]
    if missing:
        raise CounterexampleError(source, f"{at}missing key {_names(missing)} (required: {', '.join(required)})")
    unknown = [k for k in data if k not in known]
    if unknown:
        raise CounterexampleError(
            source, f"{at}unknown key{'s' if len(unknown) > 1 else ''} {_names(unknown)}; "
                    f"the known keys are {', '.join(sorted(known))} (remove the others)"
        )


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
        """Parse ``text`` (strict JSON, :func:`parse_json`) and check its envelope; return the top-level object.

        Raises
        ------
        CounterexampleError
            Not strict JSON, not an object of this format, or another version.
        """
        data = parse_json(text, source)
        if not isinstance(data, Mapping):
            raise CounterexampleError(source, f"not a counterexample file: the top level is {json_type(data)}, "
                                              f"expected an object with format = {self.name!r}")
        if "format" not in data:
            raise CounterexampleError(source, f"not a counterexample file: no 'format' key "
                                              f"(expected format = {self.name!r})")
        found = data["format"]
        if found != self.name:
            raise CounterexampleError(source, f"not a counterexample file (format = {show_value(found)}, "
                                              f"expected {self.name!r})")
        if "version" not in data:
            raise CounterexampleError(source, f"no 'version' key (expected version = {self.version}: "
                                              f"{self.reader} reads version {self.version})")
        version = data["version"]
        if not isinstance(version, int) or isinstance(version, bool):
            raise CounterexampleError(source, f"version = {show_value(version)}: expected the integer "
                                              f"{self.version}, found {json_type(version)}")
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
    except OverflowError:  # an integer beyond the float range
        raise CounterexampleError(source, f"{where} = {show_value(value)}: expected a number within the float range") from None


def decode_int(value: Any, where: str, source: str) -> int:
    """An integer (booleans refused)."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise CounterexampleError(source, f"{where} = {show_value(value)}: expected an integer")
    return value


def decode_optional_int(value: Any, where: str, source: str) -> int | None:
    """An integer or ``null``."""
    if value is not None and (not isinstance(value, int) or isinstance(value, bool)):
        raise CounterexampleError(source, f"{where} = {show_value(value)}: expected an integer or null")
    return value


def decode_str(value: Any, where: str, source: str) -> str:
    """A string."""
    if not isinstance(value, str):
        raise CounterexampleError(source, f"{where} = {show_value(value)}: expected a string")
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
            raise CounterexampleError(source, f"{where} = {show_value(value)}: expected true or false")
        return value
    if kind is float:
        return decode_float(value, where, source)
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        if not isinstance(value, list):
            raise CounterexampleError(source, f"{where} = {show_value(value)}: expected a list")
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
        raise CounterexampleError(source, f"{where}: expected an object, found {json_type(data)}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise CounterexampleError(source, f"{where}: unknown key(s) {unknown[:8]}"
                                          f"{f' and {len(unknown) - 8} more' if len(unknown) > 8 else ''}; "
                                          f"expected some of {names}")
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
    if set(map(type, rows)) == {list} and set(map(len, rows)) == {width}:  # the common case, in bulk
        kinds = set(map(type, itertools.chain.from_iterable(rows)))
        if kinds == {float}:
            return tuple(map(tuple, rows))
        if kinds <= _NUMBERS:
            return tuple(tuple(map(float, row)) for row in rows)
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


# ---- bounded traces ---------------------------------------------------------------------------------


def _change_indices(values: Any) -> np.ndarray:
    """Both samples of every change of ``values`` (a jump count or a label), shape (2 * changes,), sorted."""
    array = np.asarray(values)
    if array.shape[0] < 2:
        return np.zeros(0, dtype=np.int64)
    after = np.flatnonzero(array[1:] != array[:-1]) + 1
    return np.unique(np.concatenate([after - 1, after]))


def stored_sample_indices(times: Any, *, instants: Sequence[float] = (), changes: Sequence[Any] = (),
                          max_rows: int = TRACE_ROWS) -> tuple[np.ndarray, bool]:
    """Which samples of a trace a counterexample file stores: all of them, or at most about ``max_rows``.

    A trace of at most ``max_rows`` samples is kept whole.  A longer one keeps its first and last
    samples, the two samples around each of ``instants`` (e.g. the violation's time), both samples
    of every change of each array in ``changes`` (jump counts, mode labels) and evenly spaced samples
    in between, up to ``max_rows`` in all.  Where the changes alone exceed that budget they are
    thinned evenly (the second value then says so).

    Parameters
    ----------
    times : array_like, shape (n,)
        Sample times [s], non-decreasing.
    instants : sequence of float
        Times [s] whose neighbouring samples are always kept.
    changes : sequence of array_like, each shape (n,)
        Arrays whose changes are kept.
    max_rows : int
        The budget of samples (>= 8).

    Returns
    -------
    indices : numpy.ndarray of int, shape (m,)
        Sorted, distinct indices into the trace.
    all_changes_kept : bool
        Whether both samples of every change are among them.
    """
    t = np.asarray(times, dtype=float)
    n = t.shape[0]
    if n <= max_rows:
        return np.arange(n), True
    must = [0, n - 1]
    for instant in instants:
        k = int(np.searchsorted(t, instant))
        must += [min(max(k - 1, 0), n - 1), min(k, n - 1)]
    must_set = np.unique(np.asarray(must, dtype=np.int64))
    events = np.unique(np.concatenate([_change_indices(c) for c in changes] or [np.zeros(0, dtype=np.int64)]))
    room = max(max_rows - must_set.size, 0)
    all_kept = events.size <= room
    if not all_kept:  # thinned evenly: every part of the run keeps some of its changes
        events = events[np.linspace(0, events.size - 1, room).round().astype(np.int64)] if room else events[:0]
    kept = np.union1d(must_set, events)
    spread = max_rows - kept.size
    if spread > 0:
        kept = np.union1d(kept, np.linspace(0, n - 1, spread).round().astype(np.int64))
    return kept, all_kept
