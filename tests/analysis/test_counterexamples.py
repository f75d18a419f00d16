"""analysis.counterexamples: the file envelope, typed decoding and replay (robot-free: a thermostat's runs)."""

import json
import math
from dataclasses import dataclass, field

import pytest

from analysis.counterexamples import (
    CounterexampleError,
    CounterexampleFormat,
    Replay,
    decode_float,
    decode_int,
    decode_optional_int,
    decode_record,
    decode_rows,
    encode_value,
    replay_counterexample,
)
from analysis.fuzzing import PropertyViolation
from analysis.sequences import run_sequence
from hybrid import HybridAutomaton, Mode, Transition

FMT = CounterexampleFormat(name="thermostat-counterexample", version=3, reader="this thermostat")


@dataclass(frozen=True, kw_only=True, slots=True)
class Band:
    low: float = 19.0
    high: float = 21.0

    def __post_init__(self):
        if not self.low < self.high:
            raise ValueError(f"Band: low = {self.low!r} >= high = {self.high!r}")


@dataclass(frozen=True, kw_only=True, slots=True)
class Setup:
    name: str = "lab"
    band: Band = field(default_factory=Band)
    sensors: int = 1
    offsets: tuple[float, ...] = ()
    corner: tuple[float, float] = (0.0, 0.0)
    heated: bool = True


def thermostat(band):
    heat = Transition(name="heat", source="off", target="on", guard=lambda v, m: band.low - v[0])
    cool = Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - band.high)
    return HybridAutomaton(name="thermostat", modes=(Mode(name="off"), Mode(name="on")), transitions=(heat, cool),
                           variables=("T",), initial_mode="off")


def test_the_text_is_deterministic_one_sample_per_line_and_exact():
    rows = [(20.0,), (0.1 + 0.2,), (math.inf,), (-math.inf,)]
    text = FMT.dumps({"setup": Setup(), "property": "never_on", "seed": None}, rows_key="samples", rows=rows)
    assert text.endswith('"seed": null,\n "setup": {\n  "band": {\n   "high": 21.0,\n   "low": 19.0\n  },\n'
                         '  "corner": [\n   0.0,\n   0.0\n  ],\n  "heated": true,\n  "name": "lab",\n  "offsets": [],\n'
                         '  "sensors": 1\n },\n "version": 3,\n "samples": [\n  [20.0],\n  [0.30000000000000004],\n'
                         '  ["inf"],\n  ["-inf"]\n ]\n}\n')
    assert text.startswith('{\n "format": "thermostat-counterexample",\n "property": "never_on",\n')
    data = FMT.loads(text, "t.json")
    assert decode_rows(data["samples"], 1, "samples", "t.json") == tuple(rows)
    assert decode_record(Setup, data["setup"], "setup", "t.json") == Setup()
    assert FMT.dumps({"a": 1}) == '{\n "a": 1,\n "format": "thermostat-counterexample",\n "version": 3\n}\n'


def test_encode_value_is_the_toolkit_policy_for_files_read_back():
    assert encode_value({"x": (math.nan, 1), "o": object}) == {"x": ["nan", 1], "o": "<class 'object'>"}


@pytest.mark.parametrize("text, message", [
    ("{nope", r"counterexample 'f.json': not valid JSON \(Expecting property name"),
    ("[1]", r"not a counterexample file \(format = 'list', expected 'thermostat-counterexample'\)"),
    ('{"format": "other"}', r"not a counterexample file \(format = 'other'"),
    ('{"format": "thermostat-counterexample", "version": 2}',
     r"format version 2 is not supported \(this thermostat reads version 3\)"),
])
def test_the_envelope_is_checked(text, message):
    with pytest.raises(CounterexampleError, match=message) as info:
        FMT.loads(text, "f.json")
    assert info.value.source == "f.json" and info.value.problem in str(info.value)


@pytest.mark.parametrize("data, message", [
    ({"band": {"low": 22.0}}, r"setup.band: Band: low = 22.0 >= high = 21.0"),
    ({"band": {"low": "warm"}}, r"setup.band.low = 'warm': expected a number or one of 'inf', '-inf', 'nan'"),
    ({"band": {"low": True}}, r"setup.band.low = True: expected a number .*not a boolean"),
    ({"band": 3}, r"setup.band: expected an object, found int"),
    ({"sensors": 1.0}, r"setup.sensors = 1.0: expected an integer"),
    ({"name": 7}, r"setup.name = 7: expected a string"),
    ({"heated": 1}, r"setup.heated = 1: expected true or false"),
    ({"offsets": 0.5}, r"setup.offsets = 0.5: expected a list"),
    ({"offsets": [0.5, "x"]}, r"setup.offsets\[1\] = 'x': expected a number"),
    ({"corner": [1.0]}, r"setup.corner: expected a list of 2 values, found 1"),
    ({"colour": "red"}, r"setup: unknown key\(s\) \['colour'\]; expected some of \['name', 'band'"),
])
def test_records_are_type_checked_field_by_field(data, message):
    with pytest.raises(CounterexampleError, match=message):
        decode_record(Setup, data, "setup", "f.json")


def test_records_take_defaults_and_read_nonfinite_strings():
    setup = decode_record(Setup, {"band": {"high": "inf"}, "offsets": [1, "-inf"], "corner": [1, 2]}, "s", "f")
    assert setup == Setup(band=Band(high=math.inf), offsets=(1.0, -math.inf), corner=(1.0, 2.0))


def test_scalar_and_row_decoders_name_the_field():
    assert decode_float("nan", "x", "f") != decode_float("nan", "x", "f")
    assert decode_int(3, "n", "f") == 3 and decode_optional_int(None, "seed", "f") is None
    with pytest.raises(CounterexampleError, match=r"seed = 1.5: expected an integer or null"):
        decode_optional_int(1.5, "seed", "f")
    with pytest.raises(CounterexampleError, match=r"n = True: expected an integer"):
        decode_int(True, "n", "f")
    with pytest.raises(CounterexampleError, match=r"samples: expected a non-empty list of rows"):
        decode_rows([], 1, "samples", "f")
    with pytest.raises(CounterexampleError, match=r"samples\[1\]: expected a list of 2 numbers \(T, H\)"):
        decode_rows([[1, 2], [3]], 2, "samples", "f", ("T", "H"))


def _never_on(example, record):
    """The property "the heater never switches on", re-run on a saved temperature sequence."""
    for step in run_sequence(thermostat(example["band"]), example["samples"]):
        record({"k": step.index, "T": step.signals[0], "mode": step.mode})
        if step.mode == "on":
            raise PropertyViolation("never_on", f"the heater is on at T = {step.signals[0]}", sample=step.index)


def test_replay_reports_a_violation_with_the_trace_so_far():
    saved = FMT.dumps({"band": Band()}, rows_key="samples", rows=[(20.0,), (18.0,), (17.0,)])
    data = FMT.loads(saved, "cx.json")
    example = {"band": decode_record(Band, data["band"], "band", "cx.json"),
               "samples": decode_rows(data["samples"], 1, "samples", "cx.json")}
    result = replay_counterexample(example, _never_on)
    assert isinstance(result, Replay) and result.counterexample is example
    assert (result.violated, result.message, result.sample) == (True, "the heater is on at T = 18.0", 1)
    assert [dict(r) for r in result.trace] == [{"k": 0, "T": 20.0, "mode": "off"}, {"k": 1, "T": 18.0, "mode": "on"}]
    with pytest.raises(TypeError):
        result.trace[0]["mode"] = "x"  # read-only rows


def test_replay_of_a_fixed_example_holds_and_any_exception_is_a_failure():
    held = replay_counterexample({"band": Band(low=10.0), "samples": [(18.0,)]}, _never_on)
    assert (held.violated, held.message, held.sample, len(held.trace)) == (False, "holds", None, 1)
    broken = replay_counterexample({"band": Band(), "samples": [(1.0, 2.0)]}, _never_on)
    assert broken.violated and broken.sample is None and broken.trace == ()
    assert broken.message.startswith("ValueError: automaton 'thermostat': sample 0 has 2 values")


def test_counterexample_error_is_a_value_error_naming_the_file():
    err = CounterexampleError("a.json", "broken")
    assert isinstance(err, ValueError) and str(err) == "counterexample 'a.json': broken"
    assert json.loads(FMT.dumps({})) == {"format": "thermostat-counterexample", "version": 3}
