"""visnav.fuzzing.counterexamples: the file format, exact round trips, malformed files refused."""

from __future__ import annotations

import dataclasses
import json

import pytest
from hypothesis import find, settings

from visnav.fuzzing.counterexamples import (
    FORMAT,
    FORMAT_VERSION,
    Counterexample,
    CounterexampleError,
    counterexample_from_json,
    counterexample_to_json,
)
from visnav.fuzzing.layouts import scenarios
from visnav.fuzzing.replay import replay
from visnav.fuzzing.run import fuzz_property
from visnav.fuzzing.space import MeasurementSpace
from visnav.scenario import load_scenario


def row(d0, d1=1.6, side=1.0, d_occ=160.0, d_bord=320.0, pan=0.0, alpha=0.0, visible=1.0):
    return (d0, d1, side, d_occ, d_bord, pan, alpha, visible)


def test_counterexample_round_trip_is_exact_and_replays():
    result = fuzz_property("determinism", variant="equal_priority", shrink=False)
    cx = result.counterexample
    text = counterexample_to_json(cx)
    data = json.loads(text)
    assert (data["format"], data["version"], data["property"], data["variant"]) == (
        FORMAT, FORMAT_VERSION, "determinism", "equal_priority")
    back = counterexample_from_json(text, "file.json")
    assert back == cx
    again = replay(back)
    assert again.violated and again.message == cx.message and again.sample == cx.sample
    assert "ARMED->LEAVE@CLEAR" in again.trace[cx.sample]["jumps"]


def test_scenario_counterexample_round_trip():
    scenario = find(scenarios(respect=False), lambda s: len(s.obstacles) >= 2,
                    settings=settings(database=None, derandomize=True))
    cx = Counterexample(property="no_collision", variant="resolved", kind="scenario", message="m",
                        scenario=scenario, space=MeasurementSpace(n_obstacles=len(scenario.obstacles)))
    assert counterexample_from_json(counterexample_to_json(cx), "s.json") == cx


def _valid_text():
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="m",
                        measurements=(row(1.0),))
    return json.loads(counterexample_to_json(cx))


@pytest.mark.parametrize("mutate, message", [
    (lambda d: "{not json", r"counterexample 'f.json': not valid JSON"),
    (lambda d: {**d, "format": "other"}, r"not a counterexample file \(format = 'other'"),
    (lambda d: {**d, "version": 2}, r"format version 2 is not supported \(this visnav reads version 1\)"),
    (lambda d: {**d, "property": "nope"}, r"unknown property 'nope'; known: mu_range, mu_continuity"),
    (lambda d: {**d, "variant": "nope"}, r"unknown variant 'nope'; known: resolved, paper"),
    (lambda d: {**d, "kind": "scenario"}, r"kind 'scenario' does not match property 'mu_range' \('signals'\)"),
    (lambda d: {**d, "measurements": [[1.0, 2.0]]}, r"measurements\[0\]: expected a list of 8 numbers"),
    (lambda d: {**d, "measurements": [[1.0] * 7 + ["x"]]}, r"measurements\[0\] = 'x': expected a number"),
    (lambda d: {**d, "space": {"n_obstacles": 1.5}}, r"space.n_obstacles = 1.5: expected an integer"),
])
def test_bad_counterexample_files_are_reported(mutate, message):
    data = mutate(_valid_text())
    text = data if isinstance(data, str) else json.dumps(data)
    with pytest.raises(CounterexampleError, match=message):
        counterexample_from_json(text, "f.json")


def _scenario_text(**changes):
    scenario = dataclasses.replace(load_scenario("paper"), **changes)
    cx = Counterexample(property="no_collision", variant="resolved", kind="scenario", message="m", scenario=scenario,
                        space=MeasurementSpace(n_obstacles=max(1, len(scenario.obstacles))))
    return cx, json.loads(counterexample_to_json(cx))


@pytest.mark.parametrize("table, key, value, message", [
    ("envelopes", "d_minus_m", 0.9, r"'f\.json': scenario: envelopes\.d_minus_m = 0\.9: expected d_minus_m < d_zero_m"),
    (None, "duration_s", "nan", r"'f\.json': scenario: duration_s = 'nan': expected a number \[s\]"),
    (None, "sampling_period_s", -0.05, r"scenario: sampling_period_s = -0\.05: expected a value > 0"),
    ("supervisor", "detection_hysteresis_m", 0.0, r"scenario: supervisor\.detection_hysteresis_m = 0"),
    ("gains", "lamda", 1.0, r"scenario: gains\.lamda = 1(\.0)?: expected one of the keys"),
])
def test_an_invalid_scenario_is_refused_by_the_scenario_validator(table, key, value, message):
    _, data = _scenario_text()
    (data["scenario"][table] if table else data["scenario"])[key] = value
    with pytest.raises(CounterexampleError, match=message):
        counterexample_from_json(json.dumps(data), "f.json")


def test_a_layout_breaking_the_hypotheses_is_kept():
    """classified_outcome's inputs break the layout hypotheses on purpose: such files must replay."""
    paper = load_scenario("paper")
    (tall,) = [o for o in paper.obstacles if o.name == "tall"] or paper.obstacles[:1]
    close = dataclasses.replace(tall, name="close", center_m=(tall.center_m[0] + tall.radius_m, tall.center_m[1]))
    at_start = dataclasses.replace(tall, name="at-start", center_m=(0.2 + tall.radius_m, 0.0))
    cx, data = _scenario_text(obstacles=(*paper.obstacles, close, at_start))
    assert counterexample_from_json(json.dumps(data), "f.json") == cx


@pytest.mark.parametrize("field, value, message", [
    ("radius_m", -1.0, r"scenario\.obstacles\[0\]\.radius_m = -1\.0: expected a finite value > 0"),
    ("height_m", "inf", r"scenario\.obstacles\[0\]\.height_m = inf: expected a finite value > 0"),
    ("center_m", [1.0], r"scenario\.obstacles\[0\]\.center_m: expected a list of 2 values, found 1"),
    ("name", 3, r"scenario\.obstacles\[0\]\.name = 3: expected a string"),
    ("colour", "red", r"scenario\.obstacles\[0\]: unknown key\(s\) \['colour'\]"),
])
def test_obstacles_are_typed_records(field, value, message):
    _, data = _scenario_text()
    data["scenario"]["obstacles"][0][field] = value
    with pytest.raises(CounterexampleError, match=message):
        counterexample_from_json(json.dumps(data), "f.json")


def test_the_file_text_is_stable():
    """The format, byte for byte: sorted keys, indent 1, one sample per line, inf as a string."""
    cx = Counterexample(property="mu_range", variant="resolved", kind="signals", message="m", sample=1,
                        details={"mu": [float("inf"), 0.5]}, measurements=(row(1.0), row(0.5, d_occ=float("inf"))))
    text = counterexample_to_json(cx)
    assert text.startswith('{\n "channels": [\n  "d_coll_0_m",\n') and text.endswith(
        '  [1.0, 1.6, 1.0, 160.0, 320.0, 0.0, 0.0, 1.0],\n  [0.5, 1.6, 1.0, "inf", 320.0, 0.0, 0.0, 1.0]\n ]\n}\n')
    assert '"details": {\n   "mu": [\n    "inf",\n    0.5\n   ]\n  },' in text
    back = counterexample_from_json(text, "t.json")
    assert back.measurements == cx.measurements and back.sample == 1
    assert dict(back.details) == {"mu": ["inf", 0.5]}  # details are free-form JSON, read back as written


def _without(key):
    return lambda d: {k: v for k, v in d.items() if k != key}


def _set(path, value):
    """A mutation setting ``d[path[0]][path[1]]... = value`` (missing objects created)."""
    def mutate(d):
        d = json.loads(json.dumps(d))
        target = d
        for key in path[:-1]:
            target = target[key] if isinstance(target, list) else target.setdefault(key, {})
        target[path[-1]] = value
        return d
    return mutate


@pytest.mark.parametrize("mutate, message", [
    # the tester's file: a list where the property name goes
    (lambda d: {"format": FORMAT, "version": 1, "property": ["x"]},
     r"property = \['x'\]: expected a string, one of: mu_range, .*; found an array"),
    (_without("property"), r"missing key 'property'; expected a property name, one of: mu_range, "),
    (_set(["variant"], 3), r"variant = 3: expected a string, one of: resolved, paper, .*; found an integer"),
    (_without("kind"), r"missing key 'kind'; expected 'signals' \(the kind of property 'mu_range'\)"),
    (_set(["extra"], 1), r"unknown key 'extra'; the known keys are channels, format, kind, measurements, property, "
                         r"seed, space, variant, version, violation \(remove the others\)"),
    (_set(["scenario"], {}), r"unknown key 'scenario'; the known keys are channels"),
    (_without("channels"), r"missing key 'channels' \(required: format, version, property, variant, kind, violation, "
                           r"space, channels, measurements\)"),
    (_without("space"), r"missing key 'space'"),
    (_without("violation"), r"missing key 'violation'"),
    (_set(["violation"], "boom"), r"violation: expected an object with a 'message' string, found a string"),
    (_set(["violation", "message"], None), r"violation.message = None: expected a string"),
    (_set(["violation", "when"], 0), r"violation: unknown key 'when'; the known keys are details, message, sample"),
    (_set(["violation", "sample"], -1), r"violation.sample = -1: expected an integer >= 0 or null"),
    (_set(["violation", "sample"], 1.0), r"violation.sample = 1.0: expected an integer or null"),
    (_set(["violation", "details"], [1]), r"violation.details = \[1\]: expected an object, found an array"),
    (_set(["seed"], "7"), r"seed = '7': expected an integer or null"),
    (_set(["channels"], "d_coll_0_m"), r"channels = 'd_coll_0_m': expected a list of channel names"),
    (_set(["channels", 1], "d_coll_7_m"), r"channels\[1\] = 'd_coll_7_m': expected 'd_coll_1_m' \(the channels are "
                                          r"d_coll_0_m, d_coll_1_m, side"),
    (_set(["space", "n_obstacles"], 10 ** 200), r"channels: 8 names for a space of space.n_obstacles = 1000.*\.\.\. "
                                                r"obstacle\(s\); expected n_obstacles \+ 6 names"),
    (_set(["space", "n_obstacles"], 0), r"space: MeasurementSpace.n_obstacles = 0: expected an integer >= 1"),
    (_set(["space", "envelopes", "d_minus_m"], 0.9),
     r"space\.envelopes\.d_minus_m = 0\.9: expected d_minus_m < d_zero_m < d_plus_m"),
    (_set(["space", "settings", "detection_hysteresis_m"], 0.0),
     r"space\.settings\.detection_hysteresis_m = 0\.0: expected a value > 0 \[m\]"),
    (_set(["space", "period_s"], "nan"), r"space\.period_s = nan: expected a finite number \[s\]"),
    (_set(["space", "period_s"], 5e-324), r"space\.period_s = 5e-324 \(checked as the sampling period of a 1 s run\)"),
    (_set(["space", "max_step_d_m"], -0.01), r"space\.max_step_d_m = -0\.01: expected a finite value > 0"),
    (_set(["space", "camera_half_width_px"], "inf"), r"space\.camera_half_width_px = inf: expected a finite value"),
    (_set(["measurements", 0, 0], True), r"measurements\[0\] = True: expected a number"),
])
def test_every_field_is_present_and_typed(mutate, message):
    with pytest.raises(CounterexampleError, match=message) as info:
        counterexample_from_json(json.dumps(mutate(_valid_text())), "f.json")
    assert info.value.source == "f.json"


@pytest.mark.parametrize("table, key, value, message", [
    (None, "sampling_period_s", 5e-324, r"'f\.json': scenario: duration_s = 120\.0: expected a run of at most"),
    (None, "bogus", 1, r"scenario: bogus = 1: expected one of the keys name, description"),
    ("envelopes", "D_plus_px", "inf", r"scenario: envelopes\.D_plus_px = 'inf': expected a number"),
])
def test_the_scenario_validator_decides_as_for_simulate(table, key, value, message):
    """The same validator as ``visnav simulate`` (its run bound included): refused, not run."""
    _, data = _scenario_text()
    (data["scenario"][table] if table else data["scenario"])[key] = value
    with pytest.raises(CounterexampleError, match=message):
        counterexample_from_json(json.dumps(data), "f.json")


def test_a_scenario_file_has_no_channels_and_an_optional_seed():
    cx, data = _scenario_text()
    with pytest.raises(CounterexampleError, match=r"unknown keys 'channels', 'measurements'; the known keys are "
                                                  r"format, kind, property, scenario, seed, space"):
        counterexample_from_json(json.dumps({**data, "channels": [], "measurements": []}), "f.json")
    assert counterexample_from_json(json.dumps(_without("seed")(data)), "f.json") == cx  # seed: null by default
