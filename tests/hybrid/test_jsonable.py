"""The one JSON policy (hybrid.jsonable), and the hybrid results that go through it."""

import dataclasses
import enum
import json
import math

import numpy as np
import pytest

from hybrid import Box
from hybrid.diagnostics import ChatterEpisode, ZenoReport
from hybrid.jsonable import NONFINITE, canonical_json, float_from_json, to_jsonable

NONFINITE_VALUES = (math.inf, -math.inf, math.nan)


class Colour(enum.Enum):
    RED = "red"
    BLUE = 2


class Level(enum.IntEnum):
    LOW = 1


@dataclasses.dataclass(frozen=True, kw_only=True, slots=True)
class Inner:
    x: float
    tag: str = "t"


@dataclasses.dataclass(frozen=True, kw_only=True, slots=True)
class Outer:
    name: str
    inner: Inner
    values: tuple[float, ...]
    cache: object = dataclasses.field(default=None, metadata={"json": False})


def exact(value):
    """``value`` with the type of every element, so that ``1 == 1.0 == True`` do not hide a wrong type."""
    if isinstance(value, dict):
        return {k: exact(v) for k, v in value.items()}
    if isinstance(value, list):
        return [exact(v) for v in value]
    return (type(value).__name__, value)


# ---------------------------------------------------------------------------- each type


@pytest.mark.parametrize("value", [None, True, False, "text", "", 0, -7, 2**70, 1.5, -0.0])
def test_json_scalars_are_kept(value):
    assert exact(to_jsonable(value)) == exact(value)


@pytest.mark.parametrize("value, expected", [
    (np.float64(0.25), 0.25),
    (np.float32(0.5), 0.5),
    (np.int64(-3), -3),
    (np.uint8(200), 200),
    (np.bool_(True), True),
    (np.bool_(False), False),
    (Level.LOW, 1),
    (Colour.RED, "red"),
    (Colour.BLUE, 2),
])
def test_numpy_scalars_and_enums_become_plain_values(value, expected):
    assert exact(to_jsonable(value)) == exact(expected)


def test_complex_numbers_become_pairs():
    assert to_jsonable(1 + 2j) == [1.0, 2.0]
    assert to_jsonable(np.complex128(-0.5j)) == [-0.0, -0.5]
    assert to_jsonable(complex(math.inf, 1.0)) == [None, 1.0]
    assert to_jsonable(complex(1.0, -math.inf), nonfinite="string") == [1.0, "-inf"]


def test_containers():
    assert to_jsonable((1, (2.0, "a"), [None])) == [1, [2.0, "a"], [None]]
    assert to_jsonable({1: "a", (2, 3): "b", "c": (4,)}) == {"1": "a", "(2, 3)": "b", "c": [4]}
    assert to_jsonable({3, 1, 2}) == [1, 2, 3]
    assert to_jsonable(frozenset({"b", "a"})) == ["a", "b"]
    assert to_jsonable(np.array([[1.0, 2.0], [3.0, math.nan]])) == [[1.0, 2.0], [3.0, None]]
    assert exact(to_jsonable(np.arange(3))) == exact([0, 1, 2])
    assert to_jsonable(np.array(2.5)) == 2.5


def test_mapping_order_is_kept_unless_sorted():
    data = {"b": 1, "a": {"z": 0, "y": 1}}
    assert list(to_jsonable(data)) == ["b", "a"]
    assert list(to_jsonable(data)["a"]) == ["z", "y"]
    sorted_ = to_jsonable(data, sort_mappings=True)
    assert list(sorted_) == ["a", "b"] and list(sorted_["a"]) == ["y", "z"]


def test_dataclasses_give_their_fields_in_order_without_the_hidden_ones():
    value = Outer(name="o", inner=Inner(x=math.inf), values=(1.0, np.float64(2.0)), cache=object())
    out = to_jsonable(value)
    assert list(out) == ["name", "inner", "values"]
    assert out == {"name": "o", "inner": {"x": None, "tag": "t"}, "values": [1.0, 2.0]}
    assert exact(out["values"]) == exact([1.0, 2.0])


def test_the_output_is_made_of_json_types_only():
    value = {"a": np.float64(1.5), "b": (np.int32(2), Level.LOW), "c": Inner(x=np.float64(3.0))}
    out = to_jsonable(value)
    assert exact(out) == exact({"a": 1.5, "b": [2, 1], "c": {"x": 3.0, "tag": "t"}})
    assert json.loads(json.dumps(out, allow_nan=False)) == out


# ---------------------------------------------------------------------------- non-finite numbers


def test_nonfinite_as_null_by_default():
    assert to_jsonable([*NONFINITE_VALUES, 1.0]) == [None, None, None, 1.0]
    assert to_jsonable(np.array(NONFINITE_VALUES)) == [None, None, None]
    assert to_jsonable({"x": np.float64(math.inf)}) == {"x": None}


def test_nonfinite_as_strings():
    assert to_jsonable([*NONFINITE_VALUES, 1.0], nonfinite="string") == ["inf", "-inf", "nan", 1.0]
    assert to_jsonable(np.array([math.inf]), nonfinite="string") == ["inf"]
    assert to_jsonable({"x": np.float32(-math.inf)}, nonfinite="string") == {"x": "-inf"}


@pytest.mark.parametrize("value", [*NONFINITE_VALUES, 0.0, -0.0, 1e-310, 1.7976931348623157e308, 0.1, -2.5])
def test_string_encoding_round_trips_through_json(value):
    text = json.dumps(to_jsonable({"v": value}, nonfinite="string"), allow_nan=False)
    back = float_from_json(json.loads(text)["v"], where="v")
    if math.isnan(value):
        assert math.isnan(back)
    else:
        assert back == value and math.copysign(1.0, back) == math.copysign(1.0, value)


def test_float_from_json_reads_numbers():
    assert float_from_json(3, where="x") == 3.0 and isinstance(float_from_json(3, where="x"), float)
    assert float_from_json(-0.5, where="x") == -0.5


@pytest.mark.parametrize("value", [True, False, None, "Infinity", "NaN", "1.0", [1.0], {"x": 1}])
def test_float_from_json_refuses_other_values_by_name(value):
    with pytest.raises(ValueError, match=r"^speed = "):
        float_from_json(value, where="speed")


def test_float_from_json_names_booleans():
    with pytest.raises(ValueError, match="not a boolean"):
        float_from_json(True, where="x")


# ---------------------------------------------------------------------------- other objects and errors


def test_other_objects_raise_unless_repr_is_asked_for():
    def f():
        return 0

    with pytest.raises(TypeError, match="cannot encode a function"):
        to_jsonable({"f": f})
    text = to_jsonable({"f": f}, fallback="repr")["f"]
    assert text.startswith("<function") and "0x" not in text
    assert to_jsonable(object(), fallback="repr") == "<object object>"


def test_a_dataclass_class_is_not_an_instance():
    with pytest.raises(TypeError, match="cannot encode a type"):
        to_jsonable(Inner)


@pytest.mark.parametrize("kwargs, match", [
    (dict(nonfinite="none"), "nonfinite = 'none'"),
    (dict(nonfinite="repr"), "nonfinite = 'repr'"),
    (dict(fallback="str"), "fallback = 'str'"),
])
def test_unknown_options_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        to_jsonable(1.0, **kwargs)


def test_the_two_encodings_are_named():
    assert NONFINITE == ("null", "string")


def test_canonical_json_is_compact_sorted_and_strict():
    text = canonical_json({"b": (1, 0.1), "a": math.inf, "c": Inner(x=2.0)})
    assert text == '{"a":null,"b":[1,0.1],"c":{"tag":"t","x":2.0}}'
    assert canonical_json({"b": 1, "a": 2}) == canonical_json({"a": 2, "b": 1})


# ---------------------------------------------------------------------------- hybrid results that use it


def test_box_as_dict():
    box = Box(bounds={"h": (0.0, 10), "v": (-2.5, 3.0)}, choices={"s": (1, -1.0)}, memory={"m": 2.0, "k": (0, 1)})
    data = box.as_dict()
    assert data == {
        "bounds": {"h": [0.0, 10.0], "v": [-2.5, 3.0]},
        "choices": {"s": [1.0, -1.0]},
        "memory": {"m": [2.0, 2.0], "k": [0.0, 1.0]},
    }
    assert exact(data) == exact(json.loads(json.dumps(data, allow_nan=False)))


def test_zeno_report_as_dict_writes_nonfinite_as_null():
    report = ZenoReport(kind="instantaneous", zeno_time=1.5, ratio=math.nan, jumps=3, modes=("a", "b"),
                        transitions=("t",), last_times=(1.0, math.inf, 1.5), message="m")
    assert list(report.as_dict().items()) == [
        ("kind", "instantaneous"), ("zeno_time", 1.5), ("ratio", None), ("jumps", 3), ("modes", ["a", "b"]),
        ("transitions", ["t"]), ("last_times", [1.0, None, 1.5]), ("message", "m"),
    ]


@pytest.mark.parametrize("end, rate", [(2.0, 4.0), (1.0, None)])
def test_chatter_episode_as_dict_adds_the_rate(end, rate):
    episode = ChatterEpisode(transitions=("a", "b"), modes=("p", "q"), start=1.0, end=end, switches=5,
                             shortest_dwell=0.1)
    assert list(episode.as_dict().items()) == [
        ("transitions", ["a", "b"]), ("modes", ["p", "q"]), ("start", 1.0), ("end", end), ("switches", 5),
        ("shortest_dwell", 0.1), ("rate_per_s", rate),
    ]
