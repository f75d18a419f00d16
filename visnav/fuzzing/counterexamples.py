"""What a supervisor counterexample file holds, written and read with :mod:`analysis.counterexamples`.

A :class:`Counterexample` is a shrunk failing example of one property on one
variant: the measurement sequence (signal and stateful properties) or the
whole scenario (closed-loop properties), with the measurement space, the
violation and the seed.  :func:`counterexample_to_json` writes it in format
:data:`FORMAT`, version :data:`FORMAT_VERSION` (one sample per line, floats
exact, ``inf`` as a string); :func:`counterexample_from_json` reads it back,
checking the presence and type of every field (unknown keys refused), and
builds the embedded scenario through the scenario validator
(:func:`visnav.scenario.scenario_from_mapping`), so a file whose scenario
could not describe a run is refused as malformed rather than run.  The
obstacles are the exception: they are read as typed records (finite centre,
positive radius and height) without the layout hypotheses (2 d+ apart, the
start and goal outside ξ−), because the ``classified_outcome`` property breaks
those on purpose (:func:`visnav.fuzzing.layouts.scenarios`).  The
specification constants of the measurement space (envelopes, supervisor
settings, period) go through the same validator; its per-sample rate bounds
must be finite and > 0.

The keys of a file (all written by :func:`counterexample_to_json`):

``format``, ``version``
    :data:`FORMAT`, :data:`FORMAT_VERSION`.
``property``, ``variant``, ``kind``
    A property of :data:`visnav.fuzzing.registry.PROPERTIES`, a variant of
    :data:`visnav.fuzzing.variants.VARIANTS`, the property's kind.
``violation``
    ``message`` (a string, required), ``sample`` (an integer >= 0 or null),
    ``details`` (an object, free-form).
``seed``
    An integer or null.
``space``
    The :class:`~visnav.fuzzing.space.MeasurementSpace` (an object; keys left
    out take their defaults).
``channels``, ``measurements`` (signal kinds only)
    The channel names (exactly ``space``'s) and a non-empty list of rows of
    that many numbers (``"inf"``, ``"-inf"``, ``"nan"`` as strings).
``scenario`` (scenario kind only)
    The scenario, as :func:`visnav.scenario.scenario_from_mapping` reads it.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from analysis.counterexamples import (
    CounterexampleError,
    CounterexampleFormat,
    check_keys,
    decode_optional_int,
    decode_record,
    decode_rows,
    decode_str,
    json_type,
    show_value,
)

from visnav.fuzzing.registry import PROPERTIES
from visnav.fuzzing.space import MeasurementSpace
from visnav.fuzzing.variants import VARIANTS
from visnav.parameters import Obstacle, Scenario
from visnav.scenario import ScenarioError, load_scenario, scenario_from_mapping, scenario_to_toml

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
        rows = self.measurements
        if rows is not None and not (type(rows) is tuple and set(map(type, rows)) <= {tuple}
                                     and set(map(type, itertools.chain.from_iterable(rows))) <= {float}):
            object.__setattr__(self, "measurements", tuple(tuple(map(float, row)) for row in rows))


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


_ENVELOPE = ("format", "version")
_COMMON = ("property", "variant", "kind", "violation", "space")
_KIND_KEYS = {"signals": ("channels", "measurements"), "stateful": ("channels", "measurements"),
              "scenario": ("scenario",)}
_SPACE_RATES = ("camera_half_width_px", "max_step_d_m", "max_step_d_occ_px", "max_step_d_bord_px",
                "max_step_pan_rad", "max_step_alpha_rad", "max_step_visible")
# Where the scenario validator's keys come from in a measurement space (see _check_space).
_SPACE_KEYS = {"envelopes": "space.envelopes", "supervisor": "space.settings", "sampling_period_s": "space.period_s"}


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


def _validator_problem(err: ScenarioError, source: str) -> str:
    """A :class:`ScenarioError`'s message without its ``scenario 'source': `` prefix."""
    return str(err).removeprefix(f"scenario {source!r}: ")


def _scenario_from_json(data: Any, source: str) -> Scenario:
    """The embedded scenario, validated by :func:`visnav.scenario.scenario_from_mapping` (obstacles aside)."""
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"scenario: expected an object, found {json_type(data)}")
    obstacles = data.get("obstacles", [])
    if not isinstance(obstacles, list):
        raise CounterexampleError(source, f"scenario.obstacles: expected a list, found {json_type(obstacles)}")
    try:
        scenario = scenario_from_mapping({k: v for k, v in data.items() if k != "obstacles"}, source)
    except ScenarioError as err:
        raise CounterexampleError(source, f"scenario: {_validator_problem(err, source)}") from None
    decoded = tuple(_obstacle_from_json(o, f"scenario.obstacles[{i}]", source) for i, o in enumerate(obstacles))
    return dataclasses.replace(scenario, obstacles=decoded)


@functools.cache
def _space_check_template() -> dict[str, Any]:
    """The paper scenario as the validator reads it, without obstacles and requirements (see :func:`_check_space`)."""
    data = tomllib.loads(scenario_to_toml(load_scenario("paper")))
    return {k: v for k, v in data.items() if k not in ("obstacles", "requirements")}


def _check_space(space: MeasurementSpace, source: str) -> None:
    """The space's specification constants through the scenario validator; its rate bounds finite and > 0.

    The validator reads whole scenarios only, so the envelopes, the supervisor
    settings and the period are put into the obstacle-free paper scenario
    (lasting 1 s: the properties count samples in 1 s windows, so the
    validator's bound on the samples of a run applies to one second) and the
    keys of its message are renamed back (``envelopes.d_minus_m`` ->
    ``space.envelopes.d_minus_m``).
    """
    for name in _SPACE_RATES:
        value = getattr(space, name)
        if not (math.isfinite(value) and value > 0.0):
            raise CounterexampleError(source, f"space.{name} = {value!r}: expected a finite value > 0")
    period = space.period_s
    data = {**_space_check_template(), "envelopes": dataclasses.asdict(space.envelopes),
            "supervisor": dataclasses.asdict(space.settings), "sampling_period_s": period,
            "duration_s": max(1.0, period) if math.isfinite(period) else 1.0}
    try:
        scenario_from_mapping(data, source)
    except ScenarioError as err:
        key = err.key or ""
        table = key.split(".", 1)[0]
        if table in _SPACE_KEYS:
            where = f"{_SPACE_KEYS[table]}{key[len(table):]} = {show_value(err.value)}"
        elif key == "duration_s":  # the one-second run the period was checked with
            where = f"space.period_s = {period!r} (checked as the sampling period of a 1 s run)"
        else:  # pragma: no cover - the template's other tables are the paper scenario's, valid
            raise CounterexampleError(source, f"space: {_validator_problem(err, source)}") from None
        raise CounterexampleError(source, f"{where}: expected {err.expected}; fix: {err.fix}") from None


def _name(data: Mapping[str, Any], key: str, known: Mapping[str, Any], source: str) -> str:
    """``data[key]``: present, a string, among ``known``."""
    if key not in data:
        raise CounterexampleError(source, f"missing key {key!r}; expected a {key} name, one of: {', '.join(known)}")
    value = data[key]
    if not isinstance(value, str):
        raise CounterexampleError(source, f"{key} = {show_value(value)}: expected a string, one of: "
                                          f"{', '.join(known)}; found {json_type(value)}")
    if value not in known:
        raise CounterexampleError(source, f"unknown {key} {show_value(value)}; known: {', '.join(known)}")
    return value


def _checked_names(data: Mapping[str, Any], source: str) -> tuple[str, str, str]:
    """Property, variant and kind of a file, each present, known and consistent."""
    prop = _name(data, "property", PROPERTIES, source)
    variant = _name(data, "variant", VARIANTS, source)
    kind = PROPERTIES[prop].kind
    if "kind" not in data:
        raise CounterexampleError(source, f"missing key 'kind'; expected {kind!r} (the kind of property {prop!r})")
    if data["kind"] != kind:
        raise CounterexampleError(source, f"kind {show_value(data['kind'])} does not match property {prop!r} "
                                          f"({kind!r})")
    return prop, variant, kind


def _violation(data: Any, source: str) -> tuple[str, int | None, Mapping[str, Any]]:
    """The violation's message, sample and details."""
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"violation: expected an object with a 'message' string, "
                                          f"found {json_type(data)}")
    check_keys(data, "violation", source, ("message",), ("sample", "details"))
    message = decode_str(data["message"], "violation.message", source)
    sample = decode_optional_int(data.get("sample"), "violation.sample", source)
    if sample is not None and sample < 0:
        raise CounterexampleError(source, f"violation.sample = {sample}: expected an integer >= 0 or null")
    details = data.get("details", {})
    if not isinstance(details, Mapping):
        raise CounterexampleError(source, f"violation.details = {show_value(details)}: expected an object, "
                                          f"found {json_type(details)}")
    return message, sample, details


def _channels(data: Any, space: MeasurementSpace, source: str) -> tuple[str, ...]:
    """The channel names of a signal file: exactly the space's (the columns of ``measurements``)."""
    if not isinstance(data, list) or not all(isinstance(c, str) for c in data):
        raise CounterexampleError(source, f"channels = {show_value(data)}: expected a list of channel names")
    # space.names has n_obstacles + 6 entries: compare the counts before building it (n_obstacles may be huge)
    if len(data) != space.n_obstacles + 6:
        raise CounterexampleError(
            source, f"channels: {len(data)} names for a space of space.n_obstacles = {show_value(space.n_obstacles)} "
                    "obstacle(s); expected n_obstacles + 6 names (d_coll_<i>_m per obstacle, then side, "
                    "d_occ_px, d_bord_px, pan_rad, alpha_rad, visible)"
        )
    names = space.names
    if tuple(data) != names:
        i = next(i for i, (a, b) in enumerate(zip(data, names)) if a != b)
        raise CounterexampleError(source, f"channels[{i}] = {show_value(data[i])}: expected {names[i]!r} "
                                          f"(the channels are {', '.join(names)})")
    return names


def counterexample_from_json(text: str, source: str = "<string>") -> Counterexample:
    """Parse and validate a counterexample file's text (the keys: the module docstring).

    Raises
    ------
    CounterexampleError
        Not strict JSON, not a counterexample, another format version, a
        missing or unknown key, an unknown property or variant, or malformed
        data, including a scenario or measurement space the scenario
        validator refuses (the message names the source, the field, the value
        and what was expected).
    """
    data = COUNTEREXAMPLE_FORMAT.loads(text, source)
    prop, variant, kind = _checked_names(data, source)
    check_keys(data, "", source, (*_ENVELOPE, *_COMMON, *_KIND_KEYS[kind]), ("seed",))
    message, sample, details = _violation(data["violation"], source)
    space = decode_record(MeasurementSpace, data["space"], "space", source)
    _check_space(space, source)
    measurements = scenario = None
    if kind == "scenario":
        scenario = _scenario_from_json(data["scenario"], source)
    else:
        names = _channels(data["channels"], space, source)
        measurements = decode_rows(data["measurements"], len(names), "measurements", source, names)
    seed = decode_optional_int(data.get("seed"), "seed", source)
    return Counterexample(
        property=prop, variant=variant, kind=kind, message=message, sample=sample, details=details,
        space=space, measurements=measurements, scenario=scenario, seed=seed,
    )
