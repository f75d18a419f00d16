"""Named requirements: an STL formula with a name and a sentence, checked against declared signals.

A :class:`Requirement` is what a user writes (in Python or in a TOML table);
:func:`parse_requirements` parses every formula once against the signals and
labels a verification problem declares and its horizon, so that a typo is an
error before any simulation runs.

Examples
--------
>>> r = Requirement(name="safe", formula="always[0, 10] (x > 0)", description="x stays positive")
>>> parsed = parse_requirements((r,), signals=("x",), labels={}, horizon=10.0)
>>> parsed[0].formula.horizon
10.0
"""

from __future__ import annotations

import re
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

from hybrid.errors import ParameterError

from analysis.stl import Formula, FormulaError, parse_formula

__all__ = ["Requirement", "ParsedRequirement", "RequirementError", "parse_requirements", "requirement_from_mapping",
           "min_dwell"]

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*\Z")


class RequirementError(ParameterError):
    """A requirement that cannot be used: bad name, duplicate, or a formula that does not parse."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Requirement:
    """One requirement: a name, an STL formula (``docs/stl.md``) and what it means.

    Attributes
    ----------
    name : str
        Identifier (letters, digits, ``_ . -``), unique within a problem.
    formula : str
        The STL text; robustness at the first sample is the requirement's robustness.
    description : str
        One sentence: the claim in words (and its source, e.g. a paper's equation).
    """

    name: str
    formula: str
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise RequirementError(
                "requirement.name", self.name, "an identifier of letters, digits, '_', '.', '-'",
                "rename the requirement, e.g. 'no_collision'",
            )
        if not isinstance(self.formula, str) or not self.formula.strip():
            raise RequirementError(
                f"requirement {self.name!r}: formula", self.formula, "a non-empty STL formula (docs/stl.md)",
                "write e.g. formula = \"always[0, 10] (x > 0)\"",
            )
        if not isinstance(self.description, str):
            raise RequirementError(
                f"requirement {self.name!r}: description", self.description, "a string", "give one sentence"
            )


@dataclass(frozen=True, kw_only=True, slots=True)
class ParsedRequirement:
    """A requirement with its parsed formula."""

    requirement: Requirement
    formula: Formula

    @property
    def name(self) -> str:
        return self.requirement.name


def parse_requirements(
    requirements: Iterable[Requirement],
    *,
    signals: Collection[str],
    labels: Mapping[str, Collection[str]],
    horizon: float | None,
) -> tuple[ParsedRequirement, ...]:
    """Parse every formula against the declared signals, labels and horizon.

    Raises
    ------
    RequirementError
        A duplicate name, an object that is not a :class:`Requirement`, or a
        formula error (the message carries the line, column and caret of
        :class:`analysis.stl.FormulaError`).
    """
    seen: set[str] = set()
    out = []
    for r in requirements:
        if not isinstance(r, Requirement):
            raise RequirementError(
                "requirements", r, "analysis.verify.requirements.Requirement objects",
                "write Requirement(name=..., formula=..., description=...)",
            )
        if r.name in seen:
            raise RequirementError("requirement.name", r.name, "a name used once", "rename one of the two")
        seen.add(r.name)
        try:
            formula = parse_formula(r.formula, signals=signals, labels=labels, horizon=horizon)
        except FormulaError as error:
            raise RequirementError(
                f"requirement {r.name!r}: formula", r.formula, "a valid STL formula (docs/stl.md)", f"\n{error}"
            ) from None
        out.append(ParsedRequirement(requirement=r, formula=formula))
    return tuple(out)


def requirement_from_mapping(data: object, where: str) -> Requirement:
    """A :class:`Requirement` from a TOML/JSON table ``{name, formula, description}``.

    Parameters
    ----------
    where : str
        Where the table comes from (``"paper.toml: requirements[3]"``), named in errors.
    """
    if not isinstance(data, Mapping):
        raise RequirementError(where, data, "a table with keys name, formula, description", "write [[requirements]]")
    unknown = sorted(set(data) - {"name", "formula", "description"})
    if unknown:
        raise RequirementError(
            where, unknown, "only the keys name, formula, description", f"remove {', '.join(map(repr, unknown))}"
        )
    for key in ("name", "formula"):
        if key not in data:
            raise RequirementError(where, dict(data), f"a key {key!r}", f"add {key} = \"...\"")
    return Requirement(name=data["name"], formula=data["formula"], description=data.get("description", ""))


def min_dwell(name: str, seconds: float, modes: Collection[str], horizon: float, *, label: str = "mode",
              description: str = "") -> Requirement:
    """No chatter: after every switch into a mode the run stays in it for at least ``seconds``.

    One clause per mode, written out: ``always[0, H - seconds] ((jumps > prev(jumps) and mode == "m")
    implies always[0, seconds] (mode == "m"))`` for each of ``modes``, joined by ``and``.  A run that ends
    within ``seconds`` of a switch is judged on what it has (an early end leaves it undecided).

    Parameters
    ----------
    name : str
    seconds : float
        The minimum dwell [s], ``0 < seconds < horizon``.
    modes : collection of str
        The label's values (the problem's ``labels["mode"]``).
    horizon : float
        The problem's horizon [s].
    label : str
        The label holding the mode.

    Raises
    ------
    RequirementError
        A non-positive or too long dwell, no modes, or a mode name with a quote.
    """
    import math

    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not (
            math.isfinite(seconds) and 0 < seconds < horizon):
        raise RequirementError("min_dwell: seconds", seconds, f"a time in (0, {horizon:g}) s (below the horizon)",
                               "give the relay's or actuator's minimum dwell, e.g. 0.25")
    modes = tuple(modes)
    if not modes or any(not isinstance(m, str) or '"' in m or "\\" in m for m in modes):
        raise RequirementError("min_dwell: modes", modes, "mode names without quotes or backslashes",
                               "pass the problem's labels['mode']")
    clauses = [f'((jumps > prev(jumps) and {label} == "{m}") implies always[0, {seconds!r}] ({label} == "{m}"))'
               for m in modes]
    formula = f"always[0, {horizon - seconds!r}] (\n    " + "\n    and ".join(clauses) + ")"
    return Requirement(name=name, formula=formula,
                       description=description or f"every mode is kept at least {seconds:g} s after a switch into it")
