"""Wildcard patterns of label atoms (``mode == "AVOID|*"``), matched without backtracking.

``*`` matches any string (the empty one too), ``?`` any one character, every
other character itself (``[`` too: no character classes, unlike
:mod:`fnmatch`).  A label's value comes from a trace and a pattern from a
formula that may come from a file, so matching must not blow up: a regular
expression with ``.*`` per star backtracks exponentially on a failing match
(``"*" * 22 + "Z"`` against a long label took minutes).

:class:`LabelPattern` splits the pattern at its stars (runs of stars count as
one) into star-free *segments* and matches them in one left-to-right pass: the
first segment at the start, the last at the end, each middle one at its
leftmost occurrence after the previous one (leftmost is optimal: segments
have fixed lengths, so an earlier match leaves every later choice open).
Nothing is revisited, so a match costs ``O(len(text) * k + len(pattern))``,
``k`` the longest segment (the search of a segment holding ``?`` tries each
start once; :meth:`str.find` for the others).

Examples
--------
>>> p = LabelPattern("AVOID|*")
>>> p.fullmatch("AVOID|CLEAR"), p.fullmatch("FAR|CLEAR")
(True, False)
>>> LabelPattern("*" * 200 + "Z").fullmatch("A" * 10_000)
False
>>> LabelPattern("a?c*").fullmatch("abcdef"), LabelPattern("[x]").fullmatch("[x]")
(True, True)
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

__all__ = ["LabelPattern"]


def _segment_regex(segment: str) -> re.Pattern[str] | None:
    """A quantifier-free regex of a segment holding ``?`` (``None`` for a plain literal, searched with find)."""
    if "?" not in segment:
        return None
    return re.compile("".join("." if c == "?" else re.escape(c) for c in segment), re.DOTALL)


def _fits(segment: str, text: str, at: int) -> bool:
    """Whether ``segment`` (with ``?``) matches ``text`` at offset ``at`` (the caller checked the length)."""
    return all(p == "?" or p == c for p, c in zip(segment, text[at:at + len(segment)]))


@dataclass(frozen=True, slots=True)
class LabelPattern:
    """A compiled label pattern; :meth:`fullmatch` tells whether a whole value matches.

    Attributes
    ----------
    pattern : str
        The pattern as written.
    """

    pattern: str
    _segments: tuple[str, ...] = field(init=False, repr=False, compare=False)
    _regexes: tuple[re.Pattern[str] | None, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.pattern, str):
            raise TypeError(f"LabelPattern(pattern={self.pattern!r}): expected a string")
        segments = tuple(self.pattern.split("*"))  # runs of stars give empty middle segments: dropped below
        if len(segments) > 2:
            segments = (segments[0], *(s for s in segments[1:-1] if s), segments[-1])
        object.__setattr__(self, "_segments", segments)
        object.__setattr__(self, "_regexes", tuple(_segment_regex(s) for s in segments))

    def fullmatch(self, text: str) -> bool:
        """Whether the whole of ``text`` matches the pattern (``O(len(text) * k)``, no backtracking)."""
        segments = self._segments
        if len(segments) == 1:
            return len(text) == len(segments[0]) and _fits(segments[0], text, 0)
        first, last = segments[0], segments[-1]
        end = len(text) - len(last)
        if end < len(first) or not _fits(first, text, 0) or not _fits(last, text, end):
            return False
        pos = len(first)
        for segment, regex in zip(segments[1:-1], self._regexes[1:-1]):
            if regex is None:
                found = text.find(segment, pos, end)
            else:
                hit = regex.search(text, pos, end)
                found = -1 if hit is None else hit.start()
            if found < 0:
                return False
            pos = found + len(segment)
        return True
