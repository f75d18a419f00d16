"""How :mod:`visnav.scenario` reports a bad scenario: :class:`ScenarioError` (source, dotted key, value, what was
expected, how to fix it, TOML position), how a value and a key are shown in its message (bounded, for hostile
files), and the hints for TOML syntax errors.

:mod:`visnav.scenario` re-exports :class:`ScenarioError` and :data:`MAX_KEY_PARTS`.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping

# Helpers shared with visnav.scenario have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = ["ScenarioError", "MAX_KEY_PARTS", "show_value"]


#: Most parts of one dotted key or table header (``a.b.c = 1``: 3; a scenario needs 2).  Checked
#: before parsing: ``tomllib`` takes time quadratic in the parts (20,000 parts: 17 s).
MAX_KEY_PARTS = 64

MISSING_VALUE = object()
"""The value of a key absent from the scenario (the message says the key is missing)."""


class ScenarioError(ValueError):
    """A scenario file or mapping that cannot describe a run.

    Attributes
    ----------
    source : str
        The file, built-in name or label the scenario came from.
    key : str or None
        Dotted path of the offending entry (``"envelopes.d_zero_m"``,
        ``"obstacles[1].radius_m"``); ``None`` for problems with the file itself.
    value : object
        The value found (``None`` when the key is missing or for file problems).
    expected : str
        What a valid entry looks like.
    fix : str
        How to correct it.
    line, column : int or None
        Position of a TOML syntax error (1-based), else ``None``.
    """

    def __init__(
        self,
        source: str,
        key: str | None,
        value: object,
        expected: str,
        fix: str,
        *,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        self.source = source
        self.key = key
        self.value = value
        self.expected = expected
        self.fix = fix
        self.line = line
        self.column = column
        if key is None:
            where = ""
        elif value is MISSING_VALUE:
            where = f"{key} is missing: "
        else:
            where = f"{key} = {show_value(value)}: "
        super().__init__(f"scenario {source!r}: {where}expected {expected}; fix: {fix}")
        if value is MISSING_VALUE:
            self.value = None

    def __reduce__(self):  # keep the exception picklable (multiprocessing campaigns)
        return (
            _rebuild_error,
            (self.source, self.key, self.value, self.expected, self.fix, self.line, self.column),
        )


def _rebuild_error(source, key, value, expected, fix, line, column) -> ScenarioError:
    return ScenarioError(source, key, value, expected, fix, line=line, column=column)

_SHOW_ITEMS = 8  # array entries / table keys shown in a message

_SHOW_DEPTH = 4  # nesting levels shown in a message

_SHOW_CHARS = 200  # longest value shown in a message


def show_value(value: object) -> str:
    """The value as the message shows it: TOML-like, at most :data:`_SHOW_CHARS` characters (and the count)."""
    text = _show_part(value, _SHOW_DEPTH)
    if len(text) <= _SHOW_CHARS:
        return text
    count = f" ({len(value):,} entries)" if isinstance(value, (list, tuple, Mapping)) else ""
    return text[: _SHOW_CHARS - 1] + "…" + count


def _show_part(value: object, depth: int) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 200:
        try:
            digits = f"{len(str(abs(value)))}"
        except ValueError:  # beyond Python's int-to-str digit limit
            digits = f"about {int(value.bit_length() * math.log10(2)) + 1}"
        return f"<an integer of {digits} digits>"
    if isinstance(value, str) and len(value) > _SHOW_CHARS:
        return repr(value[:_SHOW_CHARS]) + f"… ({len(value)} characters)"
    if isinstance(value, (list, tuple, Mapping)):
        if depth <= 0:
            return "[…]" if not isinstance(value, Mapping) else "{…}"
        head = (list(itertools.islice(value.items(), _SHOW_ITEMS)) if isinstance(value, Mapping)
                else list(value[:_SHOW_ITEMS]))
        more = f", … ({len(value):,} entries)" if len(value) > _SHOW_ITEMS else ""
        if isinstance(value, Mapping):
            return "{" + ", ".join(f"{short_key(k)} = {_show_part(v, depth - 1)}" for k, v in head) + more + "}"
        return "[" + ", ".join(_show_part(v, depth - 1) for v in head) + more + "]"
    return repr(value)


def short_key(key: object, limit: int = 60) -> str:
    """A key as messages show it (a key of a hostile file may be very long)."""
    text = str(key)
    return text if len(text) <= limit else text[: limit - 1] + "…"

# strings and comments of a TOML text, in the order the parser meets them (a '#' inside a string is not a comment)
_STRINGS_AND_COMMENTS = re.compile(
    r'"""(?:[^"\\]|\\.|"(?!""))*+"""|\'\'\'(?:[^\']|\'(?!\'\'))*+\'\'\'|"(?:[^"\\\n]|\\.)*+"|\'[^\'\n]*+\'|#[^\n]*+',
    re.DOTALL,
)

# a chain of MAX_KEY_PARTS + 1 dotted parts (strings already replaced by one letter); linear: possessive, and
# a chain starts only at the beginning of a part
_DOTTED_CHAIN = re.compile(rf"(?<![A-Za-z0-9_-])(?:[A-Za-z0-9_-]++[ \t]*+\.[ \t]*+){{{MAX_KEY_PARTS},}}[A-Za-z0-9_-]")


def long_dotted_key(text: str, source: str) -> None:
    """Refuse a dotted key or header of more than :data:`MAX_KEY_PARTS` parts before ``tomllib`` sees it."""
    bare = _STRINGS_AND_COMMENTS.sub(lambda m: "" if m[0].startswith("#") else "s" + "\n" * m[0].count("\n"), text)
    found = _DOTTED_CHAIN.search(bare)
    if found:
        line = bare.count("\n", 0, found.start()) + 1
        parts = found[0].count(".") + 1
        raise ScenarioError(
            source, None, None,
            f"dotted keys and table headers of at most {MAX_KEY_PARTS} parts (visnav.scenario.MAX_KEY_PARTS): "
            f"line {line} has a key of {parts:,} parts (a.b.c... is a table nested once per part)",
            "a scenario nests tables at most 2 levels deep ([robot] then pan_offset_m, or robot.pan_offset_m): "
            f"shorten the key at line {line}",
            line=line,
        )


def deepest_line(text: str) -> str:
    """`` (line N)``: the line that opens the most arrays and inline tables (strings and comments skipped)."""
    bare = _STRINGS_AND_COMMENTS.sub(lambda m: "" if m[0].startswith("#") else "s" + "\n" * m[0].count("\n"), text)
    counts = [line.count("[") + line.count("{") for line in bare.split("\n")]
    best = max(range(len(counts)), key=counts.__getitem__) if counts else 0
    return f" (line {best + 1} opens {counts[best]:,})" if counts and counts[best] else ""

_BARE_KEY_PREFIX = re.compile(r"\s*\[{0,2}\s*[A-Za-z0-9_\-. \t\"']*\Z")


def syntax_hint(text: str, message: str, line: int | None, column: int | None) -> tuple[str, str]:
    """``(expected, fix)`` for the TOML syntax errors whose position alone does not say what to change."""
    if line is None or column is None:
        return "", ""
    lines = text.splitlines()
    source_line = lines[line - 1] if 0 < line <= len(lines) else ""
    char = source_line[column - 1] if 0 < column <= len(source_line) else ""
    at = f"line {line}, column {column}"
    if char and ord(char) > 127 and _BARE_KEY_PREFIX.match(source_line[: column - 1]):
        key = re.split(r"\s*[=\]]", source_line.strip().lstrip("["), maxsplit=1)[0].strip()
        return (
            f"a bare key of ASCII letters, digits, '-' and '_' only (found {char!r}, U+{ord(char):04X}, in the key "
            f"{short_key(key)!r} at {at})",
            f'quote the key ("{short_key(key)}" = ...) or spell it in ASCII; the keys of a scenario are ASCII '
            "(docs/scenarios.md)",
        )
    if message.startswith("Cannot declare"):  # a [table] header given twice
        header = source_line.strip().split("#", 1)[0].strip()
        first = next((n for n, text_line in enumerate(lines[: line - 1], start=1)
                      if text_line.split("#", 1)[0].strip() == header), None)
        earlier = f" (first at line {first})" if first else ""
        return (
            f"each table defined once: TOML refuses the header {short_key(header)} at {at}, the table is "
            f"already defined{earlier}",
            f"merge the keys of both {short_key(header)} tables under one header and delete the other one "
            "([[obstacles]] and [[requirements]], with two brackets, may repeat)",
        )
    if message.startswith("Cannot overwrite a value"):  # a key given twice in one table
        key = re.split(r"\s*=", source_line.strip(), maxsplit=1)[0].strip()
        return (
            f"each key defined once per table: TOML refuses {short_key(key)!r} at {at}, the same table "
            "already defines it",
            f"delete one of the two lines {short_key(key)} = ... (the second is line {line})",
        )
    return "", ""
