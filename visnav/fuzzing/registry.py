"""The named properties: what ``visnav fuzz`` runs, on which inputs, with which budget.

Every property is a named, documented check in :data:`PROPERTIES` (``visnav
fuzz --property NAME``; the checks' docstrings are the specification): the
signal-sequence properties of :mod:`visnav.fuzzing.properties`, the state
machine of :mod:`visnav.fuzzing.machine` (replayed as a sequence by
``check_stateful``) and the closed-loop properties of
:mod:`visnav.fuzzing.scenario_properties` (and the two closed-loop checks of
:mod:`visnav.fuzzing.loop_properties` written against slips,
``reconstruction_bounded`` and ``blend_weights``).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from hypothesis import strategies as st

from visnav.fuzzing.layouts import scenarios
from visnav.fuzzing.loop_properties import check_blend_weights, check_reconstruction_bounded
from visnav.fuzzing.properties import (
    check_control_continuity,
    check_determinism,
    check_differential,
    check_flag_consistency,
    check_leave_release,
    check_leave_timing,
    check_mu_continuity,
    check_mu_range,
    check_no_chatter,
    check_occlu_timing,
    check_release_band,
    check_side_latched,
    check_stateful,
)
from visnav.fuzzing.scenario_properties import (
    check_classified_outcome,
    check_closed_loop_continuity,
    check_no_collision,
)
from visnav.fuzzing.space import MeasurementSpace, signal_runs
from visnav.parameters import Scenario

__all__ = [
    "Property",
    "PROPERTIES",
    "property_names",
    "budget",
    "RESPECTING",
    "signal_strategy",
    "scenario_strategy",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class Property:
    """A named, documented property.

    Attributes
    ----------
    name : str
    kind : str
        ``"signals"`` (measurement sequences), ``"stateful"`` (a rule-based
        state machine, replayed as a sequence) or ``"scenario"`` (closed-loop runs).
    inputs : str
        What the examples are: ``"bounded"``, ``"adversarial-respecting"``,
        ``"adversarial"``, ``"machine"``, ``"scenarios-respecting"``, ``"scenarios-any"``.
    check : callable
        The check (its docstring is the specification).
    ci_examples : int
        Examples in the CI budget.
    """

    name: str
    kind: str
    inputs: str
    check: Callable[..., Any]
    ci_examples: int

    @property
    def doc(self) -> str:
        """The check's docstring, dedented."""
        return inspect.cleandoc(self.check.__doc__ or "")

    @property
    def summary(self) -> str:
        """First line of :attr:`doc`."""
        return self.doc.splitlines()[0] if self.doc else ""


PROPERTIES: Mapping[str, Property] = MappingProxyType({
    p.name: p for p in (
        Property(name="mu_range", kind="signals", inputs="adversarial", check=check_mu_range, ci_examples=120),
        Property(name="mu_continuity", kind="signals", inputs="adversarial-respecting", check=check_mu_continuity,
                 ci_examples=150),
        Property(name="determinism", kind="signals", inputs="adversarial", check=check_determinism, ci_examples=120),
        Property(name="no_chatter", kind="signals", inputs="bounded", check=check_no_chatter, ci_examples=150),
        Property(name="flag_consistency", kind="signals", inputs="adversarial", check=check_flag_consistency,
                 ci_examples=120),
        Property(name="control_continuity", kind="signals", inputs="bounded", check=check_control_continuity,
                 ci_examples=120),
        Property(name="leave_timing", kind="signals", inputs="bounded", check=check_leave_timing, ci_examples=150),
        Property(name="leave_release", kind="signals", inputs="bounded", check=check_leave_release, ci_examples=150),
        Property(name="differential", kind="signals", inputs="adversarial", check=check_differential,
                 ci_examples=120),
        Property(name="occlu_timing", kind="signals", inputs="adversarial", check=check_occlu_timing,
                 ci_examples=120),
        Property(name="release_band", kind="signals", inputs="bounded", check=check_release_band, ci_examples=150),
        Property(name="side_latched", kind="signals", inputs="adversarial-respecting", check=check_side_latched,
                 ci_examples=120),
        Property(name="stateful", kind="stateful", inputs="machine", check=check_stateful, ci_examples=40),
        Property(name="no_collision", kind="scenario", inputs="scenarios-respecting", check=check_no_collision,
                 ci_examples=20),
        Property(name="classified_outcome", kind="scenario", inputs="scenarios-any", check=check_classified_outcome,
                 ci_examples=20),
        Property(name="closed_loop_continuity", kind="scenario", inputs="scenarios-respecting",
                 check=check_closed_loop_continuity, ci_examples=15),
        Property(name="reconstruction_bounded", kind="scenario", inputs="scenarios-respecting",
                 check=check_reconstruction_bounded, ci_examples=15),
        Property(name="blend_weights", kind="scenario", inputs="scenarios-respecting", check=check_blend_weights,
                 ci_examples=15),
    )
})
"""Every property, in the order ``visnav fuzz`` runs them."""


def property_names(kind: str | None = None) -> tuple[str, ...]:
    """Names of the properties (of one kind)."""
    return tuple(name for name, p in PROPERTIES.items() if kind is None or p.kind == kind)


def budget(name: str, profile: str = "ci") -> int:
    """Examples of property ``name`` in a budget: ``"ci"`` (the registry's) or ``"dev"`` (a fifth, >= 5)."""
    examples = PROPERTIES[name].ci_examples
    if profile == "ci":
        return examples
    if profile == "dev":
        return max(5, examples // 5)
    raise ValueError(f"budget profile {profile!r}: expected 'ci' or 'dev'")


RESPECTING = ("bounded", "adversarial-respecting", "machine")
"""Signal inputs that keep the paper's hypotheses (H1 by projection, H2 by
:func:`~visnav.fuzzing.properties.hypotheses_prefix`)."""


def signal_strategy(inputs: str, space: MeasurementSpace) -> st.SearchStrategy[Any]:
    """The measurement sequences of a signal property's ``inputs`` (see :class:`Property`)."""
    if inputs == "bounded":
        return signal_runs(space, bounded=True, respect=True)
    if inputs == "adversarial-respecting":
        return signal_runs(space, bounded=False, respect=True)
    if inputs == "adversarial":
        return signal_runs(space, bounded=False, respect=False)
    raise ValueError(f"unknown signal inputs {inputs!r}")  # pragma: no cover


def scenario_strategy(inputs: str) -> st.SearchStrategy[Scenario]:
    """The scenarios of a closed-loop property's ``inputs`` (see :class:`Property`)."""
    if inputs == "scenarios-respecting":
        return scenarios(respect=True)
    return st.one_of(scenarios(respect=True), scenarios(respect=False))
