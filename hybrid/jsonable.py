"""The one JSON policy of the toolkit: how a result value becomes plain JSON, and back.

Every ``as_dict``, export, summary and counterexample file goes through
:func:`to_jsonable`.  Python containers become JSON containers (tuples and
sets as lists, mapping keys as strings), numpy scalars and arrays become
Python numbers and nested lists, complex numbers ``[re, im]``, enum members
their value, frozen dataclasses the mapping of their fields in declaration
order.  A field declared ``field(metadata={"json": False})`` is left out, so
that ``def as_dict(self): return to_jsonable(self)`` is the whole ``as_dict``
of a result; a result that renames or derives keys builds its mapping and
converts that.  A nested dataclass is converted field by field too: its own
``as_dict`` is not called.

Non-finite numbers have two encodings, chosen by the caller, never by accident:

``nonfinite="null"`` (results, summaries, reports)
    ``inf``, ``-inf`` and ``nan`` become ``null``: JSON has no such numbers and
    a summary reader should not have to parse strings.  Lossy by design; the
    field's documentation says what ``null`` means there (e.g. "no crossover").
``nonfinite="string"`` (files that are read back: counterexamples, inputs)
    they become the strings ``"inf"``, ``"-inf"`` and ``"nan"``, and
    :func:`float_from_json` reads them back exactly.

Examples
--------
>>> to_jsonable({"gm": float("inf"), "poles": (1 + 2j,)})
{'gm': None, 'poles': [[1.0, 2.0]]}
>>> to_jsonable([float("-inf")], nonfinite="string")
['-inf']
>>> float_from_json("-inf", where="x")
-inf
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["NONFINITE", "to_jsonable", "float_from_json", "canonical_json"]

NONFINITE = ("null", "string")
"""The two encodings of non-finite floats (see the module docstring)."""

_ADDRESS = re.compile(r" at 0x[0-9A-Fa-f]+")
_NONFINITE_TEXT = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def _float(value: float, nonfinite: str) -> float | str | None:
    if math.isfinite(value):
        return float(value)  # a plain float, also for subclasses such as numpy.float64
    if nonfinite == "null":
        return None
    return "nan" if value != value else ("inf" if value > 0 else "-inf")


def to_jsonable(
    value: Any, *, nonfinite: str = "null", sort_mappings: bool = False, fallback: str = "error"
) -> Any:
    """A copy of ``value`` made only of JSON types (dict, list, str, int, float, bool, None).

    Parameters
    ----------
    value : Any
        Numbers, strings, containers, numpy values, dataclass instances, enums.
    nonfinite : {"null", "string"}
        Encoding of ``inf``/``-inf``/``nan`` (module docstring).
    sort_mappings : bool
        Order every mapping by its (string) keys, so that the output does not
        depend on insertion order (user-supplied labels).
    fallback : {"error", "repr"}
        What to do with any other object: raise :class:`TypeError`, or use its
        ``repr`` with memory addresses removed (deterministic text for
        arbitrary user data such as labels).

    Raises
    ------
    TypeError
        An object JSON cannot hold, with ``fallback="error"``.
    ValueError
        An unknown ``nonfinite`` or ``fallback``.
    """
    if nonfinite not in NONFINITE:
        raise ValueError(f"to_jsonable: nonfinite = {nonfinite!r}; expected one of {NONFINITE}")
    if fallback not in ("error", "repr"):
        raise ValueError(f"to_jsonable: fallback = {fallback!r}; expected 'error' or 'repr'")
    return _convert(value, nonfinite, sort_mappings, fallback)


def _convert(value: Any, nonfinite: str, sort_mappings: bool, fallback: str) -> Any:
    if isinstance(value, enum.Enum):  # first: IntEnum and StrEnum members are also ints and strings
        return _convert(value.value, nonfinite, sort_mappings, fallback)
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, float):
        return _float(value, nonfinite)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return _float(float(value), nonfinite)
    if isinstance(value, (complex, np.complexfloating)):
        return [_float(float(value.real), nonfinite), _float(float(value.imag), nonfinite)]
    if isinstance(value, Mapping):
        items = [(str(k), v) for k, v in value.items()]
        if sort_mappings:
            items.sort(key=lambda kv: kv[0])
        return {k: _convert(v, nonfinite, sort_mappings, fallback) for k, v in items}
    if isinstance(value, (list, tuple)):
        return [_convert(v, nonfinite, sort_mappings, fallback) for v in value]
    if isinstance(value, np.ndarray):
        return _convert(value.tolist(), nonfinite, sort_mappings, fallback)
    if isinstance(value, (set, frozenset)):
        return sorted((_convert(v, nonfinite, sort_mappings, fallback) for v in value), key=repr)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: _convert(getattr(value, f.name), nonfinite, sort_mappings, fallback)
            for f in dataclasses.fields(value)
            if f.metadata.get("json", True)
        }
    if fallback == "repr":
        return _ADDRESS.sub("", repr(value))
    raise TypeError(
        f"to_jsonable: cannot encode a {type(value).__name__} ({value!r:.80}); give the result a JSON-ready "
        "field type (numbers, strings, containers, dataclasses) or pass fallback='repr'"
    )


def float_from_json(value: Any, *, where: str) -> float:
    """Read a float written with ``nonfinite="string"``.

    Parameters
    ----------
    value : Any
        A JSON number or one of ``"inf"``, ``"-inf"``, ``"nan"``.
    where : str
        What the value is (named in the error).

    Raises
    ------
    ValueError
        Anything else (booleans included), naming ``where`` and the value.
    """
    if isinstance(value, bool):
        raise ValueError(f"{where} = {value!r}: expected a number (or 'inf', '-inf', 'nan'), not a boolean")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str) and value in _NONFINITE_TEXT:
        return _NONFINITE_TEXT[value]
    raise ValueError(f"{where} = {value!r:.80}: expected a number or one of 'inf', '-inf', 'nan'")


def canonical_json(value: Any) -> str:
    """Compact JSON with sorted keys and ``repr`` floats: the byte-stable text used for hashes."""
    return json.dumps(to_jsonable(value), sort_keys=True, separators=(",", ":"), allow_nan=False)
