"""analysis.counterexamples: the file envelope, typed decoding and replay (robot-free: a thermostat's runs)."""

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np
import pytest

from analysis.counterexamples import (
    MAX_DEPTH,
    MAX_FILE_BYTES,
    MAX_INT_DIGITS,
    CounterexampleError,
    CounterexampleFormat,
    Replay,
    check_keys,
    decode_float,
    decode_int,
    decode_optional_int,
    decode_record,
    decode_rows,
    encode_value,
    parse_json,
    read_counterexample_text,
    replay_counterexample,
    show_value,
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
    ("[1]", r"not a counterexample file: the top level is an array, expected an object with "
            r"format = 'thermostat-counterexample'"),
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
    ({"band": 3}, r"setup.band: expected an object, found an integer"),
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


# ---- reading a file: strict JSON, bounded ------------------------------------------------------------------

_OK = '{"format": "thermostat-counterexample", "version": 3, "x": %s}'


@pytest.mark.parametrize("text, message", [
    ("", r"'f.json': malformed counterexample file: the file is empty; expected a JSON object"),
    (" \n\t", r"malformed counterexample file: the file is empty"),
    ("\ufeff" + _OK % 1, r"malformed counterexample file: it starts with a byte-order mark \(U\+FEFF\)"),
    (_OK % "[1.0, NaN]", r"malformed counterexample file: x\[1\]: NaN is not a JSON number .*the strings \"nan\""),
    (_OK % '{"t": Infinity}', r"malformed counterexample file: x\.t: Infinity is not a JSON number"),
    (_OK % "-Infinity", r"malformed counterexample file: x: -Infinity is not a JSON number"),
    (_OK % "[[1.0, 1e999]]", r"x\[0\]\[1\]: a number too large for a float \(it reads as infinity\)"),
    (_OK % ("1" * 400 + ".5"), r"x: a number too large for a float"),
    (_OK % ("7" * 5000), r"x: an integer of 5000 digits \(at most 300 are read\)"),
    (_OK % ("-" + "7" * 301), r"x: an integer of 301 digits"),
    ('{"format": "thermostat-counterexample", "version": 3, "version": 3}',
     r"malformed counterexample file: the top-level object: duplicate key 'version'"),
    (_OK % '[{"a": 1, "b": 2, "a": 3}]', r"x\[0\]: duplicate key 'a' \(each key may occur once per object\)"),
    (_OK % '"\\udc00"', r"x: string '\\udc00' has an unpaired surrogate"),
    (_OK % '{"\\ud800": 1}', r"x: key '\\ud800' has an unpaired surrogate"),
    ("[" * 5000 + "]" * 5000, rf"malformed counterexample file: line 1, column {MAX_DEPTH + 1}: nested more than "
                              rf"{MAX_DEPTH} levels deep"),
    ('{"a": \n' + '{"a": ' * 5000 + "1" + "}" * 5001, r"line 2, column 379: nested more than 64 levels deep"),
    (_OK % ("[" * 100 + "]" * 100), r"x\[0\]\[0\].*: nested more than 64 levels deep"),
    ("null", r"not a counterexample file: the top level is null, expected an object"),
    ('"thermostat-counterexample"', r"the top level is a string"),
    ('{"version": 3}', r"not a counterexample file: no 'format' key \(expected format = 'thermostat-counterexample'\)"),
    ('{"format": ["thermostat-counterexample"]}', r"not a counterexample file \(format = \['thermostat-counterexample'\]"),
    ('{"format": "thermostat-counterexample"}', r"no 'version' key \(expected version = 3: this thermostat reads"),
    ('{"format": "thermostat-counterexample", "version": true}', r"version = True: expected the integer 3, found a bool"),
    ('{"format": "thermostat-counterexample", "version": 3.0}', r"version = 3\.0: expected the integer 3, found a number"),
    ('{"format": "thermostat-counterexample", "version": "3"}', r"version = '3': expected the integer 3, found a string"),
    ('{"format": "thermostat-counterexample", "version": 3} []', r"not valid JSON \(Extra data at line 1, column 55\)"),
])
def test_reading_is_strict_json_and_says_what_and_where(text, message):
    with pytest.raises(CounterexampleError, match=message) as info:
        FMT.loads(text, "f.json")
    assert info.value.source == "f.json" and str(info.value).startswith("counterexample 'f.json': ")


def test_strict_reading_keeps_what_the_writer_writes():
    """Big finite values, ints in float rows, the non-finite strings, nesting up to MAX_DEPTH: read as before."""
    rows = [(1e308, 1e308), (2, -0.0), (math.inf, 5e-324), (math.nan, 1.5)]
    text = FMT.dumps({"deep": [[[]]], "big": 10 ** (MAX_INT_DIGITS - 1)}, rows_key="samples", rows=rows)
    data = FMT.loads(text, "t.json")
    assert data["big"] == 10 ** (MAX_INT_DIGITS - 1) and data["deep"] == [[[]]]
    back = decode_rows(data["samples"], 2, "samples", "t.json")
    assert back[:3] == ((1e308, 1e308), (2.0, -0.0), (math.inf, 5e-324)) and type(back[1][0]) is float
    assert math.isnan(back[3][0]) and back[3][1] == 1.5
    nested = "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1)
    assert parse_json(f'{{"x": {nested}}}', "t.json")["x"] == json.loads(nested)


def test_a_file_is_read_only_when_it_is_a_regular_utf8_file_of_bounded_size(tmp_path):
    good = tmp_path / "good.json"
    good.write_text('{"a": "é"}', encoding="utf-8")
    assert read_counterexample_text(good) == '{"a": "é"}'
    with pytest.raises(CounterexampleError, match=r"'.*missing.json': no such file") as info:
        read_counterexample_text(tmp_path / "missing.json")
    assert info.value.source == str(tmp_path / "missing.json")
    with pytest.raises(CounterexampleError, match=r"is a folder, not a file"):
        read_counterexample_text(tmp_path)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)  # reading it would block: refused before opening
    with pytest.raises(CounterexampleError, match=r"is not a regular file \(a device, FIFO or socket\)"):
        read_counterexample_text(fifo)
    with pytest.raises(CounterexampleError, match=r"the file is 11 bytes, more than the 10 bytes a counterexample"):
        read_counterexample_text(good, max_bytes=10)
    assert MAX_FILE_BYTES == 50_000_000
    latin = tmp_path / "latin.json"
    latin.write_bytes(b'{\n "a": "\xe9t\xe9"}')
    with pytest.raises(CounterexampleError, match=r"not UTF-8 text: byte 0xe9 at line 2, column 8 \(invalid "
                                                  r"continuation byte\)"):
        read_counterexample_text(latin)


def test_check_keys_names_the_missing_and_the_unknown_ones():
    check_keys({"a": 1, "b": 2}, "top", "f", ("a",), ("b", "c"))
    with pytest.raises(CounterexampleError, match=r"'f': top: missing key 'a' \(required: a\)"):
        check_keys({"b": 1}, "top", "f", ("a",))
    with pytest.raises(CounterexampleError, match=r"'f': unknown keys 'z', 'y'; the known keys are a, b \(remove"):
        check_keys({"a": 1, "z": 2, "y": 3}, "", "f", ("a",), ("b",))


def test_show_value_bounds_what_a_message_repeats():
    assert show_value("abc") == "'abc'" and show_value([1, 2]) == "[1, 2]"
    assert show_value("x" * 10_000) == "'" + "x" * 79 + "... (a string of 10,000 characters)"
    assert show_value(list(range(5000))).endswith("... (an array of 5,000 entries)")
    assert len(show_value(10 ** 200)) == 83


# ---- bounded traces (stored_sample_indices) ----------------------------------------------------------


def test_a_short_trace_is_stored_whole():
    from analysis.counterexamples import stored_sample_indices

    indices, every_change = stored_sample_indices(np.linspace(0.0, 1.0, 50), instants=(0.5,),
                                                  changes=[np.arange(50) % 3], max_rows=50)
    assert indices.tolist() == list(range(50)) and every_change


def test_a_long_trace_keeps_its_ends_the_instants_and_both_samples_of_every_change():
    from analysis.counterexamples import stored_sample_indices

    n, budget = 100_000, 1_000
    t = np.linspace(0.0, 10.0, n)
    jumps = np.searchsorted([1.0, 3.3, 3.30004, 9.99], t, side="right")  # 4 jumps, two of them 1 sample apart
    mode = np.where(t < 5.0, "a", "b")
    indices, every_change = stored_sample_indices(t, instants=(6.54321, 10.0), changes=[jumps, mode],
                                                  max_rows=budget)
    kept = set(indices.tolist())
    assert every_change and len(indices) <= budget and indices.tolist() == sorted(kept)
    assert {0, n - 1} <= kept
    for instant in (6.54321,):  # the samples on both sides of the instant (found by a scan, not a bisection)
        before = max(k for k in range(n) if t[k] < instant)
        assert {before, before + 1} <= kept
    for values in (jumps, mode):
        for k in range(1, n):
            if values[k] != values[k - 1]:
                assert {k - 1, k} <= kept, k
    gaps = np.diff(indices)
    assert gaps.max() <= 2 * n / (budget - 20)  # the rest evenly spread: no stretch left without samples


def test_more_changes_than_the_budget_are_thinned_and_said_so():
    from analysis.counterexamples import stored_sample_indices

    n = 10_000
    chatter = np.arange(n) % 2  # a change at every sample
    indices, every_change = stored_sample_indices(np.arange(n, dtype=float), instants=(4321.0,),
                                                  changes=[chatter], max_rows=100)
    assert not every_change and len(indices) <= 100 and {0, n - 1, 4320, 4321} <= set(indices.tolist())
