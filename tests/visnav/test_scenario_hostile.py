"""Hostile scenario files: each is refused at load with a ScenarioError that says what, where and how to fix it.

One test per reproduction of the tester's report (zero obstacles, cross-field rules, resource bounds,
parser limits, citations), then the hostile values of every numeric key and the array bounds.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib.resources
import math
import re
import time
import tomllib
from pathlib import Path

import pytest

from visnav.parameters import PATH_CLEARANCE_M, Scenario
from visnav.scenario import (
    MAX_KEY_PARTS,
    MAX_OBSTACLES,
    MAX_REQUIREMENTS,
    MAX_SCENARIO_BYTES,
    MAX_TARGET_POINTS,
    ScenarioError,
    load_scenario,
    scenario_from_mapping,
    scenario_from_toml,
)

ROOT = Path(__file__).resolve().parents[2]
PAPER_TEXT = importlib.resources.files("visnav").joinpath("scenarios", "paper.toml").read_text(encoding="utf-8")
BASE = PAPER_TEXT.split("\n[[requirements]]", 1)[0]  # the paper scenario without its requirements (fast to load)
NO_OBSTACLES = BASE.split("\n[[obstacles]]", 1)[0]


def refused(tmp_path: Path, text: str | bytes, *words: str, key: str | None = None) -> ScenarioError:
    """Write ``text`` to a file, load it and assert a ScenarioError naming ``key`` whose message has ``words``."""
    path = tmp_path / "hostile.toml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    start = time.perf_counter()
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert time.perf_counter() - start < 5.0
    err = info.value
    message = str(err)
    assert message.startswith(f"scenario {str(path)!r}: ") and "expected " in message and "; fix: " in message
    assert err.key == key, message
    for word in words:
        assert word in message, (word, message)
    assert len(message) < 2000  # a hostile value is abbreviated, never dumped
    return err


def replace_once(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


def cli(tmp_path: Path, path: Path, capsys) -> tuple[int, str]:
    from visnav.app.cli import main

    code = main(["simulate", "--scenario", str(path), "--no-figures", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err
    assert not (tmp_path / "o").exists()  # refused before any output
    return code, err


# --------------------------------------------------------------------------- 1. zero obstacles


def test_zero_obstacles_are_a_valid_scene_the_supervisor_runs(tmp_path):
    from visnav.simulation import simulate

    path = tmp_path / "empty.toml"
    path.write_text(replace_once(NO_OBSTACLES, "success_tolerance_px = 1.0",
                                 "success_tolerance_px = 1.0\nobstacles = []"))
    scenario = load_scenario(path)
    assert scenario.obstacles == ()
    result = simulate(dataclasses.replace(scenario, duration_s=1.0))
    assert len(result.trace.times) == 21
    assert {m.split("|")[0] for m in result.trace.visited_modes} == {"FAR"}  # no collision phase without obstacles
    assert result.trace.record("mu_coll").max() == 0.0
    assert math.isinf(result.metrics.min_clearance_m)


def test_the_supervisor_without_obstacles_is_checked_without_inf_or_nan():
    from hybrid import check
    from hybrid.model import guard_value

    from visnav.parameters import Envelopes, SupervisorSettings
    from visnav.supervisor import (SIGNALS, build_supervisor, measurement_box, measurement_rates, measurement_system,
                                   no_obstacle_distance)

    env = Envelopes()
    model = build_supervisor(env, SupervisorSettings(), n_obstacles=0)
    assert model.automaton.variables == SIGNALS and len(model.automaton.modes) == 18
    system = measurement_system(model)
    v = system.signals(0.0, (1.0, 50.0, 10.0, 0.3))
    assert v[0] == no_obstacle_distance(env) == 16.0 > env.d_plus_m + 1.0  # finite, beyond every threshold
    # every guard is a real number after every reset (the sampled check found NaN: dL = inf in LEAVE)
    initial = model.automaton.initial_memory()
    for reset in [None, *(t.reset for t in model.automaton.transitions if t.reset is not None)]:
        memory = {**initial, **(reset(v, initial) if reset else {})}
        for t in model.automaton.transitions:
            assert math.isfinite(guard_value(t, v, memory)), (t.name, memory)
    collision_from_far = [t for t in model.automaton.transitions if t.name.startswith("FAR->")]
    assert collision_from_far and all(guard_value(t, v, initial) < 0 for t in collision_from_far)
    rates = measurement_rates({"d": 0.03, "d_occ": 4.0, "d_bord": 6.0, "pan": 0.04}, 0.05, 0)
    report = check(system, measurement_box(model, 320.0), samples=5, starts=1, method="smt", max_cycles=3, rates=rates)
    assert report.clean and not report.kinds("error", "warning")


@pytest.mark.parametrize("n", [-1, 1.5, True, "2"])
def test_build_supervisor_refuses_a_count_that_is_not_one(n):
    from visnav.parameters import Envelopes, SupervisorSettings
    from visnav.supervisor import build_supervisor

    with pytest.raises(ValueError, match=r"n_obstacles = .*expected an integer >= 0"):
        build_supervisor(Envelopes(), SupervisorSettings(), n_obstacles=n)


# --------------------------------------------------------------------------- 2. cross-field rules


def test_v_coll_above_v_max_names_both_fields(tmp_path):
    refused(tmp_path, replace_once(BASE, "v_coll_mps = 0.2 ", "v_coll_mps = 0.8 "),
            "gains.v_coll_mps = 0.8", "limits.v_max_mps = 0.6", "lower gains.v_coll_mps or raise limits.v_max_mps",
            key="gains.v_coll_mps")


def test_d_zero_inside_the_analysis_clearance_is_refused_at_load(tmp_path):
    from visnav.studies.loop_analysis import DEFAULT_CLEARANCE_M

    assert PATH_CLEARANCE_M == DEFAULT_CLEARANCE_M  # the value visnav analyse and report use
    text = replace_once(BASE, "d_minus_m = 0.3 ", "d_minus_m = 0.05 ")
    text = replace_once(text, "d_zero_m = 0.5 ", "d_zero_m = 0.08 ")
    text = replace_once(text, "d_plus_m = 0.6 ", "d_plus_m = 0.09 ")
    refused(tmp_path, text, "envelopes.d_zero_m = 0.08", "a value > 0.1 m", "PATH_CLEARANCE_M",
            "choose d_zero_m above 0.1 m", key="envelopes.d_zero_m")


def test_a_duration_shorter_than_one_period_is_refused(tmp_path):
    refused(tmp_path, replace_once(BASE, "sampling_period_s = 0.05 ", "sampling_period_s = 200.0 "),
            "duration_s = 120.0", "at least sampling_period_s = 200.0 s", key="duration_s")


def test_degenerate_target_points_are_refused_at_load(tmp_path):
    square = BASE[BASE.index("[target]"):BASE.index("# Chosen layout")]
    text = BASE.replace(square, "[target]\npoints_m = [[9.0, 0.0, 0.5], [9.0, 0.0, 0.5], [9.0, 0.0, 0.5]]\n\n")
    refused(tmp_path, text, "target.points_m", "L^T L at s* must be invertible", "no two of them coincident",
            key="target.points_m")


# --------------------------------------------------------------------------- 3. resource bounds


@pytest.mark.parametrize(("old", "new", "count"), [
    ("sampling_period_s = 0.05 ", "sampling_period_s = 5e-324 ", "more samples than a float can count"),
    ("sampling_period_s = 0.05 ", "sampling_period_s = 1e-12 ", "gives 1.2e+14 samples"),
    ("duration_s = 120.0 ", "duration_s = 1.7976931348623157e308 ", "more samples than a float can count"),
    ("duration_s = 120.0 ", "duration_s = 1e12 ", "gives 2e+13 samples"),
])
def test_a_run_over_the_sample_bound_is_refused_at_load(tmp_path, old, new, count):
    refused(tmp_path, replace_once(BASE, old, new), count, "at most 1,000,000 samples", "MAX_RUN_SAMPLES",
            "lengthen sampling_period_s or shorten duration_s", key="duration_s")


def test_a_run_over_the_memory_bound_is_refused_at_load(tmp_path):
    from visnav.simulation import MAX_TRACE_BYTES, run_size

    text = replace_once(BASE, "sampling_period_s = 0.05 ", "sampling_period_s = 0.0001 ")
    text = replace_once(text, "duration_s = 120.0 ", "duration_s = 60.0 ")
    refused(tmp_path, text, "600,001 samples of 51 values", "(4 target points, 2 obstacles)", "1,469 MB",
            "at most 500 MB", "MAX_TRACE_BYTES", "at most 204,248 samples fit", key="duration_s")
    fits = run_size(0.05, 0.05 * (204_248 - 1), 4, 2)  # the largest run that fits is accepted
    over = run_size(0.05, 0.05 * 204_248, 4, 2)
    assert fits.samples == 204_248 and fits.trace_bytes <= MAX_TRACE_BYTES < over.trace_bytes
    scenario_from_toml(replace_once(BASE, "duration_s = 120.0 ", f"duration_s = {0.05 * (204_248 - 1)!r} "), "fits")


def test_the_bounds_hold_for_a_scenario_built_in_python_too():
    from hybrid.sampled import SampledArgumentError

    from visnav.simulation import simulate

    scenario = dataclasses.replace(scenario_from_toml(BASE, "base"), duration_s=1e12)  # not validated
    start = time.perf_counter()
    with pytest.raises(SampledArgumentError, match=r"duration = 1000000000000.0; expected at most max_samples = "):
        simulate(scenario)
    assert time.perf_counter() - start < 1.0


def test_the_cli_refuses_a_huge_run_with_exit_2(tmp_path, capsys):
    path = tmp_path / "long.toml"
    path.write_text(replace_once(BASE, "sampling_period_s = 0.05 ", "sampling_period_s = 1e-12 "))
    code, err = cli(tmp_path, path, capsys)
    assert code == 2
    assert err.startswith(f"visnav: error: scenario {str(path)!r}: duration_s = 120.0: expected a run of at most")


# --------------------------------------------------------------------------- 4. the file and its TOML


def test_nesting_too_deep_for_the_parser(tmp_path):
    refused(tmp_path, "a = " + "[" * 5000 + "]" * 5000 + "\n" + BASE, "nested too deep", "line 1 opens 5,000",
            "remove the extra brackets")


def test_an_integer_too_long_for_the_parser(tmp_path):
    line = BASE[:BASE.index("duration_s = 120.0 ")].count("\n") + 1
    refused(tmp_path, replace_once(BASE, "duration_s = 120.0 ", "duration_s = " + "9" * 5000 + " "),
            "an integer has at most 4300 digits", "found an integer of 5000 digits", f"at line {line}",
            "float with an exponent")


def test_an_integer_beyond_the_float_range(tmp_path):
    refused(tmp_path, replace_once(BASE, "duration_s = 120.0 ", "duration_s = " + "9" * 400 + " "),
            "<an integer of 400 digits>", "beyond the float range", key="duration_s")


def test_a_byte_order_mark(tmp_path):
    err = refused(tmp_path, b"\xef\xbb\xbf" + BASE.encode(), "starts with a UTF-8 byte-order mark",
                  "save the file as UTF-8 without BOM")
    assert (err.line, err.column) == (1, 1)


def test_a_non_ascii_bare_key(tmp_path):
    refused(tmp_path, "durée = 1.0\n" + BASE, "a bare key of ASCII letters", "'é'", "'durée' at line 1, column 4",
            'quote the key ("durée" = ...) or spell it in ASCII')


def test_bytes_that_are_not_utf8_are_named_by_offset(tmp_path):
    data = BASE.encode()
    at = data.index(b'"paper"') + 3
    err = refused(tmp_path, data[:at] + b"\xff" + data[at:], f"the byte 0xff at byte offset {at}", "is not valid UTF-8",
                  "save the file as UTF-8")
    assert err.line == BASE[:at].count("\n") + 1


def test_a_directory_is_named_as_such(tmp_path):
    (tmp_path / "inside.toml").write_text(BASE)
    with pytest.raises(ScenarioError, match=r"found a directory at .*inside\.toml.*; fix: give the path of a \.toml"):
        load_scenario(tmp_path)


def test_a_file_over_the_size_bound(tmp_path):
    refused(tmp_path, BASE + "#" * MAX_SCENARIO_BYTES, f"at most {MAX_SCENARIO_BYTES:,} bytes", "MAX_SCENARIO_BYTES")


def test_a_top_level_key_below_a_table_header(tmp_path):
    refused(tmp_path, NO_OBSTACLES + "\nobstacles = []\n", "target.obstacles = []",
            "every key after a [target] header belongs to that table",
            "move the line obstacles = ... above the first [table] header", key="target.obstacles")
    text = BASE + "\nduration_s = 60.0\n"  # after the last [[obstacles]] table
    refused(tmp_path, text, "obstacles[1].duration_s", "after a [[obstacles]] header", key="obstacles[1].duration_s")


def test_keys_and_tables_defined_twice(tmp_path):
    line = BASE[:BASE.index("duration_s = 120.0 ")].count("\n") + 2
    refused(tmp_path, replace_once(BASE, "duration_s = 120.0 ", "duration_s = 120.0\nduration_s = 60.0 "),
            "each key defined once per table", f"'duration_s' at line {line}", "delete one of the two lines duration_s")
    first = BASE[:BASE.index("[robot]")].count("\n") + 1
    refused(tmp_path, BASE + "\n[robot]\npan_offset_m = 0.2\n", "each table defined once", "[robot]",
            f"first at line {first}", "merge the keys")


def test_a_dotted_key_of_too_many_parts_is_refused_before_parsing(tmp_path):
    refused(tmp_path, "a." * 20000 + "b = 1\n" + BASE, f"at most {MAX_KEY_PARTS} parts", "a key of 20,001 parts",
            "shorten the key at line 1")
    refused(tmp_path, "[" + ".".join(["t"] * 5000) + "]\n" + BASE, "a key of 5,000 parts")
    # a dotted text inside a string or a comment is not a key
    scenario_from_toml(replace_once(BASE, 'name = "paper"', 'name = "paper"  # ' + "a." * 100) + "\n", "comment")


def test_the_cli_refuses_a_parser_limit_with_exit_2(tmp_path, capsys):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    code, err = cli(tmp_path, path, capsys)
    assert code == 2 and "nested too deep for the parser" in err


# --------------------------------------------------------------------------- 5. citations inside the repository


@pytest.mark.parametrize("relative", ["docs/stiffness.md", "visnav/scenarios/paper.toml", "docs/scenarios.md"])
def test_the_paper_notes_are_cited_from_the_repository(relative):
    text = (ROOT / relative).read_text(encoding="utf-8")
    assert "shared/paper" not in text and "NOTES.md" not in text
    for cited in set(re.findall(r"docs/[A-Za-z_]+\.md", text)):
        assert (ROOT / cited).is_file(), cited
    if relative != "docs/scenarios.md":
        assert '"What the paper publishes"' in text
    docs = (ROOT / "docs/scenarios.md").read_text(encoding="utf-8")
    section = docs[docs.index("## What the paper publishes"):docs.index("## Why the built-in")]
    for fact in ("`sampling_period_s` = 0.05", "`gains.v_coll_mps` = 0.2", "`estimator.order` = 4", "0.17 px",
                 "1.164 mm", "15 s occlusion", "Adams–Bashforth–Moulton"):
        assert fact in section, fact


# --------------------------------------------------------------------------- hostile values everywhere


def base_mapping() -> dict:
    return copy.deepcopy(tomllib.loads(BASE))


_FLOAT_KEYS = [
    (section, f.name)
    for section in ("robot", "camera", "envelopes", "gains", "limits", "estimator", "supervisor", "start", "goal")
    for f in dataclasses.fields(type(getattr(scenario_from_toml(BASE, "base"), section)))
    if f.type in (float, "float")
] + [("", "sampling_period_s"), ("", "duration_s"), ("", "success_tolerance_px")]


@pytest.mark.parametrize(("section", "name"), _FLOAT_KEYS)
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, True, "0.5", [0.5], {"a": 1.0}])
def test_every_numeric_key_refuses_non_numbers_and_non_finite_values(section, name, value):
    data = base_mapping()
    (data.setdefault(section, {}) if section else data)[name] = value
    key = f"{section}.{name}" if section else name
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(data, "hostile")
    assert info.value.key == key, str(info.value)
    assert re.search(r"expected a (finite )?number", str(info.value))


@pytest.mark.parametrize("name", ["order", "newton_maxiter"])
@pytest.mark.parametrize("value", [4.0, True, "4", math.nan, [4]])
def test_integer_keys_refuse_everything_else(name, value):
    data = base_mapping()
    data["estimator"][name] = value
    with pytest.raises(ScenarioError, match=rf"^scenario 'hostile': estimator\.{name} = .*expected an integer"):
        scenario_from_mapping(data, "hostile")


@pytest.mark.parametrize(("key", "build", "words"), [
    ("obstacles", lambda d: d.update(obstacles=[d["obstacles"][0]] * 10**6),
     f"at most {MAX_OBSTACLES} obstacles (visnav.scenario.MAX_OBSTACLES), found 1,000,000"),
    ("target.points_m", lambda d: d.update(target={"points_m": [[9.0, 0.0, 0.5]] * 10**6}),
     f"at most {MAX_TARGET_POINTS} target points (visnav.scenario.MAX_TARGET_POINTS), found 1,000,000"),
    ("requirements", lambda d: d.update(requirements=[{"name": "a", "formula": "clearance_m > 0"}] * 10**4),
     f"at most {MAX_REQUIREMENTS:,} requirements (visnav.scenario.MAX_REQUIREMENTS), found 10,000"),
    ("obstacles[0].center_m", lambda d: d["obstacles"][0].update(center_m=[1.0] * 10**6),
     "an array of 2 numbers [x, y] [m], found an array of 1000000"),  # noqa: E501
])
def test_huge_arrays_are_refused_quickly_with_a_short_message(key, build, words):
    data = base_mapping()
    build(data)
    start = time.perf_counter()
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(data, "hostile")
    assert time.perf_counter() - start < 2.0  # typically 0.01 s
    assert info.value.key == key and words in str(info.value)
    assert len(str(info.value)) < 1000 and " entries)" in str(info.value)  # the value abbreviated


def test_deeply_nested_tables_give_a_short_message():
    data = base_mapping()
    nested: dict = {"x": 1}
    for _ in range(900):
        nested = {"a": nested}
    data["robot"]["deep"] = nested
    shown = r"robot\.deep = \{a = \{a = \{a = \{a = \{…\}\}\}\}\}: expected one of the keys"  # 4 levels, then …
    with pytest.raises(ScenarioError, match=shown):
        scenario_from_mapping(data, "hostile")


def test_the_period_rule_reads_the_dataclass_defaults_of_missing_keys():
    defaults = {f.name: f.default for f in dataclasses.fields(Scenario)}
    data = base_mapping()
    del data["sampling_period_s"], data["duration_s"]
    scenario = scenario_from_mapping(data, "defaults")
    assert (scenario.sampling_period_s, scenario.duration_s) == (defaults["sampling_period_s"], defaults["duration_s"])
    data["duration_s"] = defaults["sampling_period_s"] / 2
    with pytest.raises(ScenarioError, match=r"^scenario 'defaults': duration_s = 0.025: expected at least "
                                            r"sampling_period_s = 0.05 s"):
        scenario_from_mapping(data, "defaults")
