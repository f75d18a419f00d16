"""What a supervisor counterexample file holds, written and read with :mod:`analysis.counterexamples`.

A :class:`Counterexample` is a shrunk failing example of one property on one
variant: the measurement sequence (signal and stateful properties) or the
whole scenario (closed-loop properties), with the measurement space, the
violation and the seed.  :func:`counterexample_to_json` writes it in format
:data:`FORMAT`, version :data:`FORMAT_VERSION` (one sample per line, floats
exact, ``inf`` as a string); :func:`counterexample_from_json` reads it back,
type-checking every field, and builds the embedded scenario through the
scenario validator (:func:`visnav.scenario.scenario_from_mapping`), so a file
whose scenario could not describe a run is refused as malformed rather than
run.  The obstacles are the exception: they are read as typed records
(finite centre, positive radius and height) without the layout hypotheses
(2 d+ apart, the start and goal outside ξ−), because the ``classified_outcome``
property breaks those on purpose (:func:`visnav.fuzzing.layouts.scenarios`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from analysis.counterexamples import (
    CounterexampleError,
    CounterexampleFormat,
    decode_optional_int,
    decode_record,
    decode_rows,
)

from visnav.fuzzing.registry import PROPERTIES
from visnav.fuzzing.space import MeasurementSpace
from visnav.fuzzing.variants import VARIANTS
from visnav.parameters import Obstacle, Scenario
from visnav.scenario import ScenarioError, scenario_from_mapping

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "COUNTEREXAMPLE_FORMAT",
    "Counterexample",
    "CounterexampleError",
    "counterexample_to_json",
    "counterexample_from_json",
]

FORMAT = "visnav-fuzz-counterexample"
"""Value of the ``format`` key of a counterexample file."""
FORMAT_VERSION = 1
"""Version of the counterexample file format (:func:`counterexample_from_json` accepts only this one)."""

COUNTEREXAMPLE_FORMAT = CounterexampleFormat(name=FORMAT, version=FORMAT_VERSION, reader="this visnav")
"""The envelope of the files (:class:`analysis.counterexamples.CounterexampleFormat`)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class Counterexample:
    """A shrunk failing example, replayable.

    Attributes
    ----------
    property, variant : str
    kind : str
        ``"signals"``, ``"stateful"`` or ``"scenario"``.
    message : str
        The violation found by the fuzzer.
    sample : int or None
        Sample of the violation (signal kinds).
    details : Mapping[str, Any]
    space : MeasurementSpace
        Envelopes, settings, rates (signal kinds; the scenario's own otherwise).
    measurements : tuple of rows or None
        Signal kinds: the measurement sequence.
    scenario : Scenario or None
        Scenario kind: the full scenario.
    seed : int or None
        Seed of the run that found it (``None``: derandomised).
    """

    property: str
    variant: str
    kind: str
    message: str
    sample: int | None = None
    details: Mapping[str, Any] = field(default_factory=dict)
    space: MeasurementSpace = field(default_factory=MeasurementSpace)
    measurements: tuple[tuple[float, ...], ...] | None = None
    scenario: Scenario | None = None
    seed: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))
        if self.measurements is not None:
            object.__setattr__(self, "measurements", tuple(tuple(float(x) for x in row) for row in self.measurements))


def counterexample_to_json(cx: Counterexample) -> str:
    """Deterministic JSON text of a counterexample (floats exact, ``inf`` as a string, one sample per line)."""
    fields: dict[str, Any] = {
        "property": cx.property,
        "variant": cx.variant,
        "kind": cx.kind,
        "violation": {"message": cx.message, "sample": cx.sample, "details": cx.details},
        "seed": cx.seed,
        "space": cx.space,
    }
    if cx.scenario is not None:
        fields["scenario"] = cx.scenario
    if cx.measurements is None:
        return COUNTEREXAMPLE_FORMAT.dumps(fields)
    fields["channels"] = list(cx.space.names)
    return COUNTEREXAMPLE_FORMAT.dumps(fields, rows_key="measurements", rows=cx.measurements)


def _obstacle_from_json(data: Any, where: str, source: str) -> Obstacle:
    """One obstacle as a typed record with a finite centre and a positive radius and height."""
    obstacle = decode_record(Obstacle, data, where, source)
    if not all(math.isfinite(c) for c in obstacle.center_m):
        raise CounterexampleError(source, f"{where}.center_m = {list(obstacle.center_m)!r}: expected finite numbers")
    for name in ("radius_m", "height_m"):
        value = getattr(obstacle, name)
        if not (math.isfinite(value) and value > 0.0):
            raise CounterexampleError(source, f"{where}.{name} = {value!r}: expected a finite value > 0 [m]")
    return obstacle


def _scenario_from_json(data: Any, source: str) -> Scenario:
    """The embedded scenario, validated by :func:`visnav.scenario.scenario_from_mapping` (obstacles aside)."""
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"scenario: expected an object, found {type(data).__name__}")
    obstacles = data.get("obstacles", [])
    if not isinstance(obstacles, list):
        raise CounterexampleError(source, f"scenario.obstacles: expected a list, found {type(obstacles).__name__}")
    try:
        scenario = scenario_from_mapping({k: v for k, v in data.items() if k != "obstacles"}, source)
    except ScenarioError as err:
        problem = str(err).removeprefix(f"scenario {source!r}: ")
        raise CounterexampleError(source, f"scenario: {problem}") from None
    decoded = tuple(_obstacle_from_json(o, f"scenario.obstacles[{i}]", source) for i, o in enumerate(obstacles))
    return dataclasses.replace(scenario, obstacles=decoded)


def _checked_names(data: Mapping[str, Any], source: str) -> tuple[str, str, str]:
    """Property, variant and kind of a file, each known and consistent."""
    prop = data.get("property")
    if prop not in PROPERTIES:
        raise CounterexampleError(source, f"unknown property {prop!r}; known: {', '.join(PROPERTIES)}")
    variant = data.get("variant")
    if variant not in VARIANTS:
        raise CounterexampleError(source, f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    kind = PROPERTIES[prop].kind
    if data.get("kind") != kind:
        raise CounterexampleError(source, f"kind {data.get('kind')!r} does not match property {prop!r} ({kind!r})")
    return prop, variant, kind


def counterexample_from_json(text: str, source: str = "<string>") -> Counterexample:
    """Parse and validate a counterexample file's text.

    Raises
    ------
    CounterexampleError
        Not JSON, not a counterexample, another format version, an unknown
        property or variant, or malformed data, including a scenario the
        scenario validator refuses (the message names the source and what is
        wrong).
    """
    data = COUNTEREXAMPLE_FORMAT.loads(text, source)
    prop, variant, kind = _checked_names(data, source)
    violation = data.get("violation")
    if not isinstance(violation, Mapping) or not isinstance(violation.get("message"), str):
        raise CounterexampleError(source, "violation: expected an object with a 'message' string")
    sample = decode_optional_int(violation.get("sample"), "violation.sample", source)
    space = decode_record(MeasurementSpace, data.get("space", {}), "space", source)
    measurements = scenario = None
    if kind in ("signals", "stateful"):
        measurements = decode_rows(data.get("measurements"), len(space.names), "measurements", source, space.names)
    else:
        scenario = _scenario_from_json(data.get("scenario"), source)
    seed = decode_optional_int(data.get("seed"), "seed", source)
    details = violation.get("details") or {}
    return Counterexample(
        property=prop, variant=variant, kind=kind, message=violation["message"], sample=sample,
        details=MappingProxyType(dict(details)) if isinstance(details, Mapping) else MappingProxyType({}),
        space=space, measurements=measurements, scenario=scenario, seed=seed,
    )
