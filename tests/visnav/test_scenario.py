"""Tests of visnav.scenario: loading, validation messages, canonical TOML and geometry."""

from __future__ import annotations

import copy
import dataclasses
import importlib.resources
import math
import pickle
import re
import tomllib

import pytest

from visnav import model
from visnav.geometry import camera_pose
from visnav.parameters import Pose, RobotGeometry, Scenario
from visnav.scenario import (
    ScenarioError,
    builtin_scenario_names,
    load_scenario,
    point_in_camera,
    scenario_digest,
    scenario_from_mapping,
    scenario_from_toml,
    scenario_to_toml,
    target_square,
)

SOURCE = "test.toml"


@pytest.fixture
def paper() -> dict:
    """The built-in paper scenario with a fixed reference layout, as a fresh mutable mapping.

    The validation tests below compute their expected figures from this layout
    ("low" at (3.2, 0.15), r = 0.6; "tall" at (5.6, -0.75), r = 0.2, f = 500 px),
    so it is pinned here rather than read from the tunable built-in file.
    """
    text = importlib.resources.files("visnav").joinpath("scenarios", "paper.toml").read_text(encoding="utf-8")
    data = copy.deepcopy(tomllib.loads(text))
    data["camera"]["focal_px"] = 500.0
    data["obstacles"] = [
        {"name": "low", "center_m": [3.2, 0.15], "radius_m": 0.6, "height_m": 0.3},
        {"name": "tall", "center_m": [5.6, -0.75], "radius_m": 0.2, "height_m": 1.5},
    ]
    return data


def rejects(data: dict, key: str, fix: str, expected: str = "") -> ScenarioError:
    """Assert that validation fails naming ``key`` (and ``expected``) with ``fix``; return the error."""
    pattern = rf"^scenario '{re.escape(SOURCE)}': {re.escape(key)}( = | is missing).*expected .*"
    if expected:
        pattern += re.escape(expected) + ".*"
    pattern += rf"; fix: .*{re.escape(fix)}"
    with pytest.raises(ScenarioError, match=pattern) as info:
        scenario_from_mapping(data, SOURCE)
    assert info.value.key == key
    assert info.value.source == SOURCE
    assert fix in info.value.fix
    return info.value


# ---------------------------------------------------------------------------------------------
# Built-ins, loading, round trip
# ---------------------------------------------------------------------------------------------


def test_paper_is_builtin():
    assert "paper" in builtin_scenario_names()


@pytest.mark.parametrize("name", builtin_scenario_names())
def test_every_builtin_loads(name):
    scenario = load_scenario(name)
    assert isinstance(scenario, Scenario)
    assert scenario.name == name


def test_paper_published_values():
    s = load_scenario("paper")
    env = s.envelopes
    assert (env.d_minus_m, env.d_zero_m, env.d_plus_m) == (0.3, 0.5, 0.6)
    assert (env.D_minus_px, env.D_zero_px, env.D_plus_px) == (40.0, 60.0, 80.0)
    assert s.sampling_period_s == 0.05
    assert s.gains.v_coll_mps == 0.2
    assert s.estimator.order == 4
    assert len(s.target.points_m) == 4
    assert [o.name for o in s.obstacles] == ["low", "tall"]
    low, tall = s.obstacles
    assert not low.occludes(s.robot.camera_height_m)
    assert tall.occludes(s.robot.camera_height_m)
    gap = math.dist(low.center_m, tall.center_m) - low.radius_m - tall.radius_m
    assert gap >= 2 * env.d_plus_m


@pytest.mark.parametrize("name", builtin_scenario_names())
def test_round_trip_through_file(name, tmp_path):
    scenario = load_scenario(name)
    text = scenario_to_toml(scenario)
    path = tmp_path / "copy.toml"
    path.write_text(text, encoding="utf-8")
    again = load_scenario(str(path))
    assert again == scenario
    assert scenario_digest(again) == scenario_digest(scenario)
    assert scenario_to_toml(again) == text


def test_round_trip_awkward_values(paper):
    paper["description"] = 'quote " backslash \\ tab \t newline \n unicode é \x7f'
    paper["robot"]["camera_lateral_m"] = -0.0
    paper["estimator"]["newton_tol"] = 1.0000000000000002e-13
    paper["start"]["theta_rad"] = 0.1 + 0.2
    scenario = scenario_from_mapping(paper, SOURCE)
    again = scenario_from_toml(scenario_to_toml(scenario), "copy")
    assert again == scenario
    assert math.copysign(1.0, again.robot.camera_lateral_m) == -1.0


def test_digest_is_sha256_and_changes_with_values(paper):
    a = scenario_from_mapping(paper, SOURCE)
    b = dataclasses.replace(a, duration_s=121.0)
    assert re.fullmatch(r"[0-9a-f]{64}", scenario_digest(a))
    assert scenario_digest(a) != scenario_digest(b)
    assert scenario_digest(a) == scenario_digest(scenario_from_mapping(copy.deepcopy(paper), "elsewhere"))


def test_defaults_fill_missing_tables():
    data = {
        "name": "minimal",
        "start": {},
        "goal": {"x_m": 7.9},
        "target": {"center_m": [9.0, 0.0, 0.5], "normal_rad": math.pi, "side_m": 0.3},
    }
    scenario = scenario_from_mapping(data, SOURCE)
    assert scenario.start == Pose()
    assert scenario.obstacles == ()
    assert scenario.robot == RobotGeometry()
    assert scenario.duration_s == 120.0


def test_ints_accepted_for_floats_and_converted(paper):
    paper["duration_s"] = 90
    paper["obstacles"][0]["radius_m"] = 1
    scenario = scenario_from_mapping(paper, SOURCE)
    assert scenario.duration_s == 90.0 and type(scenario.duration_s) is float
    assert type(scenario.obstacles[0].radius_m) is float


def test_unknown_name_lists_builtins():
    pattern = r"scenario 'nope': .*one of: .*paper.*; fix: use one of the built-in names"
    with pytest.raises(ScenarioError, match=pattern):
        load_scenario("nope")


def test_missing_file_lists_builtins(tmp_path):
    path = tmp_path / "absent.toml"
    with pytest.raises(ScenarioError, match=r"an existing scenario file .*absent\.toml.*; fix: .*paper"):
        load_scenario(str(path))


def test_toml_syntax_error_has_position(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('name = "x"\n\n[robot]\npan_offset_m = = 0.1\n', encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"line 4, column \d+.*; fix: correct the TOML syntax at line 4") as info:
        load_scenario(str(path))
    assert info.value.line == 4
    assert info.value.column is not None
    assert isinstance(info.value.__cause__, tomllib.TOMLDecodeError)


def test_error_message_format_and_attributes(paper):
    paper["envelopes"]["d_zero_m"] = 0.7
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(paper, "FILE")
    error = info.value
    assert str(error) == (
        "scenario 'FILE': envelopes.d_zero_m = 0.7: expected d_minus_m < d_zero_m < d_plus_m "
        "(0.3 < 0.7 < 0.6 is false); fix: choose d_zero_m between d_minus_m and d_plus_m"
    )
    assert isinstance(error, ValueError)
    assert (error.key, error.value) == ("envelopes.d_zero_m", 0.7)
    assert error.fix == "choose d_zero_m between d_minus_m and d_plus_m"
    clone = pickle.loads(pickle.dumps(error))
    assert str(clone) == str(error) and clone.key == error.key


# ---------------------------------------------------------------------------------------------
# Structure: required keys, unknown keys, types
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["name", "target", "start", "goal"])
def test_required_keys(paper, key):
    del paper[key]
    error = rejects(paper, key, "add")
    assert error.value is None


@pytest.mark.parametrize(
    ("where", "bad", "good"),
    [
        ((), "duration", "duration_s"),
        (("envelopes",), "d_zero", "d_zero_m"),
        (("gains",), "lamda_vs", "lambda_vs"),
        (("obstacles", 1), "radius", "radius_m"),
        (("target",), "side", "side_m"),
    ],
)
def test_unknown_key_suggests_closest(paper, where, bad, good):
    table = paper
    for step in where:
        table = table[step]
    table[bad] = 1.0
    prefix = ".".join(f"[{s}]" if isinstance(s, int) else s for s in where).replace(".[", "[")
    key = f"{prefix}.{bad}" if prefix else bad
    rejects(paper, key, f"rename {bad!r} to {good!r}")


def test_unknown_key_without_close_match_lists_valid_keys(paper):
    paper["camera"]["zzz"] = 1
    rejects(paper, "camera.zzz", "remove 'zzz' (valid keys: focal_px, half_width_px, half_height_px)")


def test_unknown_top_level_table(paper):
    paper["obstacle"] = [{"name": "x"}]
    rejects(paper, "obstacle", "rename 'obstacle' to 'obstacles'")


@pytest.mark.parametrize(
    ("section", "field", "value", "fix"),
    [
        ("gains", "lambda_vs", True, "true/false are not numbers"),
        ("camera", "focal_px", "500", "without quotes"),
        ("robot", "pan_offset_m", [0.1], "single number"),
        ("estimator", "order", 4.0, "whole number without a decimal point (e.g. 4)"),
        ("estimator", "order", "4", "without quotes"),
        ("estimator", "screw_model", 1, "double quotes"),
    ],
)
def test_wrong_scalar_type(paper, section, field, value, fix):
    paper[section][field] = value
    rejects(paper, f"{section}.{field}", fix)


def test_top_level_wrong_types(paper):
    paper["name"] = 3
    rejects(paper, "name", "double quotes")


def test_table_expected(paper):
    paper["robot"] = 0.1
    rejects(paper, "robot", "[robot] header")


def test_obstacles_must_be_array_of_tables(paper):
    paper["obstacles"] = {"name": "x"}
    rejects(paper, "obstacles", "[[obstacles]]")


@pytest.mark.parametrize(
    ("value", "found"), [([1.0, 2.0, 3.0], "an array of 3"), ([1.0], "an array of 1"), (1.0, "a float")]
)
def test_obstacle_center_wrong_length(paper, value, found):
    paper["obstacles"][0]["center_m"] = value
    rejects(paper, "obstacles[0].center_m", "write center_m = [x, y]", found)


def test_target_center_wrong_length(paper):
    paper["target"]["center_m"] = [9.0, 0.0]
    rejects(paper, "target.center_m", "write center_m = [x, y, h]")


def test_target_point_wrong_length(paper):
    del paper["target"]
    paper["target"] = {"points_m": [[9.0, 0.1, 0.6], [9.0, -0.1, 0.6], [9.0, 0.0]]}
    rejects(paper, "target.points_m[2]", "write points_m[2] = [x, y, h]")


def test_array_entry_wrong_type(paper):
    paper["obstacles"][1]["center_m"] = [5.6, "-0.75"]
    rejects(paper, "obstacles[1].center_m[1]", "without quotes")


def test_obstacle_missing_key(paper):
    del paper["obstacles"][1]["height_m"]
    rejects(paper, "obstacles[1].height_m", "add height_m to the obstacle")


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_non_finite_numbers(paper, value):
    paper["start"]["y_m"] = value
    rejects(paper, "start.y_m", "replace inf/nan by a finite value", "a finite number")


def test_non_finite_in_array(paper):
    paper["target"]["center_m"] = [9.0, math.nan, 0.5]
    rejects(paper, "target.center_m[1]", "replace inf/nan")


# ---------------------------------------------------------------------------------------------
# Value rules
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("values", "key", "fix"),
    [
        ((0.3, 0.7, 0.6), "envelopes.d_zero_m", "choose d_zero_m between d_minus_m and d_plus_m"),
        ((0.55, 0.5, 0.6), "envelopes.d_zero_m", "choose d_zero_m between d_minus_m and d_plus_m"),
        ((0.7, 0.5, 0.6), "envelopes.d_minus_m", "choose d_minus_m below d_plus_m"),
        ((0.3, 0.5, 0.5), "envelopes.d_zero_m", "choose d_zero_m between"),
    ],
)
def test_collision_envelopes_out_of_order(paper, values, key, fix):
    for name, value in zip(("d_minus_m", "d_zero_m", "d_plus_m"), values):
        paper["envelopes"][name] = value
    rejects(paper, key, fix, "d_minus_m < d_zero_m < d_plus_m")


@pytest.mark.parametrize(
    ("values", "key", "fix"),
    [
        ((40.0, 90.0, 80.0), "envelopes.D_zero_px", "choose D_zero_px between D_minus_px and D_plus_px"),
        ((85.0, 60.0, 80.0), "envelopes.D_minus_px", "choose D_minus_px below D_plus_px"),
    ],
)
def test_occlusion_envelopes_out_of_order(paper, values, key, fix):
    for name, value in zip(("D_minus_px", "D_zero_px", "D_plus_px"), values):
        paper["envelopes"][name] = value
    rejects(paper, key, fix, "D_minus_px < D_zero_px < D_plus_px")


@pytest.mark.parametrize("name", ["d_minus_m", "D_minus_px"])
@pytest.mark.parametrize("value", [0.0, -0.1])
def test_envelopes_positive(paper, name, value):
    paper["envelopes"][name] = value
    rejects(paper, f"envelopes.{name}", f"set {name} to a positive value", "> 0")


@pytest.mark.parametrize("name", ["lambda_vs", "lambda_occ", "beta_occ", "lambda_gc", "k_path", "v_coll_mps"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_gains_positive(paper, name, value):
    paper["gains"][name] = value
    rejects(paper, f"gains.{name}", f"set {name} to a positive value", "> 0")


@pytest.mark.parametrize(
    ("section", "name"),
    [
        (None, "sampling_period_s"),
        (None, "duration_s"),
        (None, "success_tolerance_px"),
        ("camera", "focal_px"),
        ("camera", "half_width_px"),
        ("camera", "half_height_px"),
        ("robot", "camera_height_m"),
        ("limits", "v_max_mps"),
        ("limits", "omega_max_radps"),
        ("limits", "pan_rate_max_radps"),
    ],
)
@pytest.mark.parametrize("value", [0.0, -2.0])
def test_positive_parameters(paper, section, name, value):
    table = paper if section is None else paper[section]
    table[name] = value
    key = name if section is None else f"{section}.{name}"
    rejects(paper, key, f"set {name} to a positive value", "> 0")


@pytest.mark.parametrize("value", [0.0, -0.1])
def test_pan_offset_positive_explains_singularity(paper, value):
    paper["robot"]["pan_offset_m"] = value
    rejects(paper, "robot.pan_offset_m", "set pan_offset_m to a positive value", "J_r is singular otherwise")


@pytest.mark.parametrize("order", [0, 7, -1])
def test_estimator_order(paper, order):
    paper["estimator"]["order"] = order
    rejects(paper, "estimator.order", "use 4, as in the paper", "a BDF order in 1..6")


@pytest.mark.parametrize("value", [0.0, -2.0, 5e-324, 1e-16, 1.0])
def test_newton_tol(paper, value):
    paper["estimator"]["newton_tol"] = value
    rejects(paper, "estimator.newton_tol", "set newton_tol to a relative tolerance in [1e-15, 1)",
            "a relative tolerance in [1e-15, 1)")


@pytest.mark.parametrize(("key", "value"), [("order", 9), ("screw_model", "trapezoid"), ("newton_tol", -1.0),
                                            ("newton_maxiter", 0)])
def test_estimator_settings_are_checked_by_the_estimators_own_rule(paper, key, value):
    """One rule: visnav.estimator.validate_settings; its expectation is quoted, the key is the scenario's."""
    from analysis.bdf import BdfOrderError
    from visnav.estimator import EstimatorSettingsError, validate_settings
    from visnav.parameters import EstimatorSettings

    paper["estimator"][key] = value
    with pytest.raises((BdfOrderError, EstimatorSettingsError)) as own:
        validate_settings(EstimatorSettings(**{key: value}))
    err = rejects(paper, f"estimator.{key}", "")
    assert err.value == value and err.expected in str(own.value)


@pytest.mark.parametrize("order", [1, 6])
def test_estimator_order_bounds_accepted(paper, order):
    paper["estimator"]["order"] = order
    assert scenario_from_mapping(paper, SOURCE).estimator.order == order


def test_screw_model(paper):
    paper["estimator"]["screw_model"] = "histopolate"
    rejects(paper, "estimator.screw_model", "did you mean 'histopolated'?", "'end', 'start', 'mean', 'histopolated'")


@pytest.mark.parametrize("model_name", ["end", "start", "mean", "histopolated"])
def test_screw_models_accepted(paper, model_name):
    paper["estimator"]["screw_model"] = model_name
    assert scenario_from_mapping(paper, SOURCE).estimator.screw_model == model_name


@pytest.mark.parametrize("value", [0, 101, 10 ** 12])
def test_newton_maxiter(paper, value):
    paper["estimator"]["newton_maxiter"] = value
    rejects(paper, "estimator.newton_maxiter", "use 8 (at most 100)", "an integer in [1, 100]")


@pytest.mark.parametrize("value", [0.0, -0.2, math.pi / 2, 2.0])
def test_arm_angle(paper, value):
    paper["supervisor"]["arm_angle_rad"] = value
    rejects(paper, "supervisor.arm_angle_rad", "choose an angle such as 0.2 rad", "0 < arm_angle_rad < pi/2")


@pytest.mark.parametrize("value", [-0.01, 0.0])
def test_detection_hysteresis(paper, value):
    """0 is refused too: FAR -> APPROACH and back would both be enabled at d = d+ (finding R2)."""
    paper["supervisor"]["detection_hysteresis_m"] = value
    rejects(paper, "supervisor.detection_hysteresis_m", "use 0.02", "> 0")


def test_empty_name(paper):
    paper["name"] = "  "
    rejects(paper, "name", "short name")


# -- obstacles


@pytest.mark.parametrize("field", ["radius_m", "height_m"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_obstacle_size_positive(paper, field, value):
    paper["obstacles"][1][field] = value
    rejects(paper, f"obstacles[1].{field}", f"set {field} to a positive value", "> 0")


def test_obstacle_duplicate_names(paper):
    paper["obstacles"][1]["name"] = "low"
    rejects(paper, "obstacles[1].name", "rename one of the obstacles", "obstacles[0] is also 'low'")


def test_obstacle_empty_name(paper):
    paper["obstacles"][0]["name"] = ""
    rejects(paper, "obstacles[0].name", "name the obstacle")


def test_obstacles_separation_is_the_papers_hypothesis(paper):
    paper["obstacles"][1]["center_m"] = [3.5, -1.2]  # 0.58 m from "low", surface to surface
    fix = "move 'tall' at least 0.618 m further from 'low'"
    error = rejects(paper, "obstacles[1].center_m", fix, "2*d_plus_m = 1.2 m")
    assert "paper's hypothesis" in str(error)


def test_obstacles_separation_boundary(paper):
    # exactly 2*d+ surface to surface along x is accepted
    paper["obstacles"][1]["center_m"] = [3.2 + 0.6 + 1.2 + 0.2 + 1e-9, 0.15]
    scenario_from_mapping(paper, SOURCE)


def test_obstacle_overlapping_start(paper):
    paper["obstacles"][0]["center_m"] = [0.5, 0.0]  # 0.5 m < 0.6 + 0.3
    error = rejects(paper, "obstacles[0].center_m", "move 'low' or the start pose at least 0.4 m further apart")
    assert "the robot would start inside the critical envelope" in str(error)


def test_obstacle_overlapping_goal(paper):
    paper["obstacles"][1]["center_m"] = [7.9, 0.4]  # 0.4 m < 0.2 + 0.3
    error = rejects(paper, "obstacles[1].center_m", "move 'tall' or the goal pose")
    assert "the robot would end inside the critical envelope" in str(error)


# -- target


def test_target_behind_camera_at_goal(paper):
    paper["goal"]["theta_rad"] = math.pi
    error = rejects(paper, "target.points_m[0]", "place the target ahead of the goal pose", "at the goal pose (depth")
    assert "depth -1.2 m" in str(error)


def test_target_behind_camera_at_start(paper):
    paper["start"]["pan_rad"] = 2.0
    rejects(paper, "target.points_m[0]", "place the target ahead of the start pose", "at the start pose (depth")


def test_target_outside_image_horizontally(paper):
    paper["camera"]["half_width_px"] = 80.0  # point 1 is 0.18 m right of the camera at 1 m: 90 px
    error = rejects(paper, "target.points_m[1]", "move the goal pose further from the target", "s* is unobservable")
    assert "|Y|*f = 90 px > half_width_px = 80" in str(error)


def test_target_outside_image_vertically(paper):
    paper["camera"]["half_height_px"] = 50.0  # 0.15 m above the camera at 1 m: 75 px
    error = rejects(paper, "target.points_m[0]", "shrink the target", "s* is unobservable")
    assert "|X|*f = 75 px > half_height_px = 50" in str(error)


def test_target_outside_image_only_checked_at_goal(paper):
    paper["start"]["pan_rad"] = 1.2  # target out of view at the start, but in front of the camera
    scenario_from_mapping(paper, SOURCE)


def test_too_few_target_points(paper):
    paper["target"] = {"points_m": [[9.0, 0.1, 0.6], [9.0, -0.1, 0.6]]}
    rejects(paper, "target.points_m", "add points", "at least 3 points")


def test_three_target_points_accepted(paper):
    paper["target"] = {"points_m": [[9.0, 0.1, 0.6], [9.0, -0.1, 0.6], [9.0, 0.0, 0.4]]}
    assert len(scenario_from_mapping(paper, SOURCE).target.points_m) == 3


def test_target_points_and_square_exclusive(paper):
    paper["target"]["points_m"] = [[9.0, 0.1, 0.6], [9.0, -0.1, 0.6], [9.0, 0.0, 0.4]]
    rejects(paper, "target.center_m", "remove center_m or remove points_m")


def test_target_square_incomplete(paper):
    del paper["target"]["side_m"]
    rejects(paper, "target.side_m", "add target.side_m (or give points_m)")


def test_target_square_side_positive(paper):
    paper["target"]["side_m"] = 0.0
    rejects(paper, "target.side_m", "set side_m to a positive value")


def test_target_square_n_points(paper):
    paper["target"]["n_points"] = 5
    rejects(paper, "target.n_points", "use n_points = 4, or list the points in points_m")


# ---------------------------------------------------------------------------------------------
# Geometry
# ---------------------------------------------------------------------------------------------


def test_target_square_paper_order():
    points = target_square((9.0, 0.0, 0.5), math.pi, 0.3)
    assert points == ((9.0, 0.15, 0.65), (9.0, -0.15, 0.65), (9.0, -0.15, 0.35), (9.0, 0.15, 0.35))


@pytest.mark.parametrize("normal", [0.0, 0.7, math.pi / 2, -2.5])
def test_target_square_geometry(normal):
    center, side = (1.0, -2.0, 0.4), 0.5
    points = target_square(center, normal, side)
    n = (math.cos(normal), math.sin(normal))
    for p in points:
        # in the vertical plane through the centre, perpendicular to the normal
        assert (p[0] - center[0]) * n[0] + (p[1] - center[1]) * n[1] == pytest.approx(0.0, abs=1e-12)
        assert math.dist(p, center) == pytest.approx(side / math.sqrt(2))
    for a, b in zip(points, points[1:] + points[:1]):
        assert math.dist(a, b) == pytest.approx(side)
    # seen from a camera facing the target (2 m along the normal): TL, TR, BR, BL
    robot = RobotGeometry(pan_offset_m=0.1, camera_forward_m=0.0, camera_lateral_m=0.0, camera_height_m=0.4)
    # heading -n; M = C - Dx * heading = centre + 2.1 n
    pose = Pose(x_m=center[0] + 2.1 * n[0], y_m=center[1] + 2.1 * n[1], theta_rad=normal + math.pi)
    image = [point_in_camera(p, pose, robot) for p in points]
    signs = [(math.copysign(1, x), math.copysign(1, y)) for x, y, _ in image]  # (down, left)
    assert signs == [(-1, 1), (-1, -1), (1, -1), (1, 1)]
    assert all(z == pytest.approx(2.0) for _, _, z in image)


@pytest.mark.parametrize("pan", [0.0, 0.4, -1.3])
def test_camera_pose_velocity_matches_reduced_jacobian(pan):
    """dC/dt and dphi/dt of camera_pose agree with the screw T_rc = J_r q̇ of visnav.model."""
    robot = RobotGeometry(pan_offset_m=0.12, camera_forward_m=0.04, camera_lateral_m=0.03, camera_height_m=0.5)
    theta, v, omega, pan_rate, h = 0.3, 0.5, -0.7, 0.9, 1e-6

    def at(t: float) -> tuple[float, float, float]:
        th = theta + omega * t
        # straight-line motion of M to first order: enough for a central difference at t = 0
        x, y = 1.0 + v * math.cos(theta) * t, 2.0 + v * math.sin(theta) * t
        pose = Pose(x_m=x, y_m=y, theta_rad=th, pan_rad=pan + pan_rate * t)
        return camera_pose(pose.x_m, pose.y_m, pose.theta_rad, pose.pan_rad, robot)

    (x1, y1, p1), (x0, y0, p0) = at(h), at(-h)
    vx, vy, phi_rate = (x1 - x0) / (2 * h), (y1 - y0) / (2 * h), (p1 - p0) / (2 * h)
    phi = theta + pan
    lateral = -math.sin(phi) * vx + math.cos(phi) * vy
    forward = math.cos(phi) * vx + math.sin(phi) * vy
    screw = model.camera_screw(
        pan, v, omega, pan_rate, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m
    )
    assert (lateral, forward, -phi_rate) == pytest.approx(screw, abs=1e-8)


def test_point_in_camera_at_paper_goal():
    s = load_scenario("paper")
    x_c, y_c, z = point_in_camera(s.target.points_m[0], s.goal, s.robot)
    # camera at (8.0, 0.03), height 0.5; point (9.0, 0.15, 0.65)
    assert (x_c, y_c, z) == pytest.approx((-0.15, 0.12, 1.0))


def test_docs_example_loads():
    """The TOML example of docs/scenarios.md is a valid scenario (docs stay in step with the code)."""
    from pathlib import Path

    docs = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"
    assert docs.is_file(), f"{docs} is part of the repository and documents the format"
    block = re.search(r"```toml\n(.*?)```", docs.read_text(encoding="utf-8"), re.S)
    assert block is not None
    scenario = scenario_from_toml(block[1], "docs example")
    assert scenario.target.points_m == target_square((9.0, 0.0, 0.5), math.pi, 0.3)
    assert scenario.robot.camera_lateral_m == RobotGeometry().camera_lateral_m


def test_canonical_text_ignores_int_versus_float(paper):
    """A Scenario built in Python with ints in float fields has the same text and digest."""
    a = scenario_from_mapping(paper, SOURCE)
    b = dataclasses.replace(a, duration_s=120, start=Pose(x_m=0, y_m=0))
    assert scenario_to_toml(b) == scenario_to_toml(a)
    assert "order = 4\n" in scenario_to_toml(a)


def test_load_accepts_path_objects(tmp_path):
    path = tmp_path / "paper"  # no suffix: a PathLike is always a path, never a built-in name
    path.write_text(scenario_to_toml(load_scenario("paper")), encoding="utf-8")
    assert load_scenario(path) == load_scenario("paper")


# ---------------------------------------------------------------------------------------------
# Gains: the certified range of k, v_coll within v_max (one rule for every command)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", [5e3, 1e-4])
def test_k_path_outside_the_certified_range(paper, value):
    from visnav.parameters import K_PATH_RANGE

    paper["gains"]["k_path"] = value
    err = rejects(paper, "gains.k_path", "choose k_path between 0.001 and 1000", "a gain in [0.001, 1000] 1/m")
    assert K_PATH_RANGE == (1e-3, 1e3) and "K_PATH_RANGE" in err.expected


@pytest.mark.parametrize("value", [1e-3, 1e3])
def test_k_path_range_is_closed(paper, value):
    paper["gains"]["k_path"] = value
    assert scenario_from_mapping(paper, SOURCE).gains.k_path == value


def test_v_coll_above_v_max(paper):
    paper["gains"]["v_coll_mps"] = 0.61
    rejects(paper, "gains.v_coll_mps", "lower gains.v_coll_mps or raise limits.v_max_mps",
            "at most limits.v_max_mps = 0.6 m/s")
    paper["gains"]["v_coll_mps"] = 0.6
    assert scenario_from_mapping(paper, SOURCE).gains.v_coll_mps == 0.6  # equal is accepted


def test_validate_gains_is_the_same_rule_for_records_built_in_python():
    from visnav.scenario import validate_gains

    scenario = load_scenario("paper")
    validate_gains(scenario.gains, scenario.limits, source="paper")
    stiff = dataclasses.replace(scenario.gains, k_path=5e3)
    with pytest.raises(ScenarioError, match=r"^scenario 'hand-built': gains.k_path = 5000.0: expected a gain in "):
        validate_gains(stiff, scenario.limits, source="hand-built")
    with pytest.raises(ScenarioError, match=r"gains.v_coll_mps = 0.2: expected at most limits.v_max_mps = 0.1 m/s"):
        validate_gains(scenario.gains, dataclasses.replace(scenario.limits, v_max_mps=0.1))


def test_validate_scenario_applies_every_rule():
    from visnav.scenario import validate_scenario

    scenario = load_scenario("paper")
    assert validate_scenario(scenario) == scenario
    moved = dataclasses.replace(scenario, obstacles=(dataclasses.replace(scenario.obstacles[0], center_m=(0.5, 0.0)),
                                                     scenario.obstacles[1]))
    with pytest.raises(ScenarioError, match=r"^scenario 'label': obstacles\[0\].center_m = .*critical envelope"):
        validate_scenario(moved, "label")
    infinite = dataclasses.replace(scenario, duration_s=math.inf)
    with pytest.raises(ScenarioError, match=r"^scenario 'paper': expected finite numbers and strings only"):
        validate_scenario(infinite)


def test_the_paper_scenario_is_inside_every_range():
    from visnav.parameters import K_PATH_RANGE

    scenario = load_scenario("paper")
    assert K_PATH_RANGE[0] <= scenario.gains.k_path <= K_PATH_RANGE[1]
    assert scenario.gains.v_coll_mps <= scenario.limits.v_max_mps


@pytest.mark.parametrize(("old", "new", "message"), [
    ("k_path = 4.0", "k_path = 5e3", "gains.k_path = 5000.0: expected a gain in [0.001, 1000] 1/m"),
    ("v_coll_mps = 0.2", "v_coll_mps = 0.9", "gains.v_coll_mps = 0.9: expected at most limits.v_max_mps = 0.6 m/s"),
])
def test_every_command_refuses_the_same_scenario_with_the_same_message(tmp_path, old, new, message):
    """A scenario ``visnav simulate`` refuses is refused by ``analyse`` and ``report`` alike: exit 2, one message."""
    import subprocess
    import sys

    text = importlib.resources.files("visnav").joinpath("scenarios", "paper.toml").read_text(encoding="utf-8")
    assert text.count(old) == 1
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new))
    errors = []
    for command in (["simulate", "--no-figures"], ["analyse"], ["report", "--quick", "--out", str(tmp_path / "r")]):
        proc = subprocess.run([sys.executable, "-m", "visnav.app.cli", *command, "--scenario", str(bad)],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, (command, proc.stderr)
        assert "Traceback" not in proc.stderr and proc.stdout == ""
        errors.append(proc.stderr)
    assert errors[0] == errors[1] == errors[2]
    assert errors[0].startswith(f"visnav: error: scenario {str(bad)!r}: {message}") and "; fix: " in errors[0]
    assert not (tmp_path / "r").exists()  # refused before any output


# ---------------------------------------------------------------------------------------------
# [[requirements]]: STL formulas over the signal catalogue, parsed at load (rule 24)
# ---------------------------------------------------------------------------------------------


def _with_requirements(paper: dict, *tables: dict) -> dict:
    paper["requirements"] = [dict(t) for t in tables]
    return paper


def _formula_error(data: dict, index: int) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        scenario_from_mapping(data, SOURCE)
    err = info.value
    assert err.key == f"requirements[{index}].formula" and err.source == SOURCE
    assert str(err).startswith(f"scenario {SOURCE!r}: requirements[{index}].formula = ")
    return err


def test_the_paper_requirements_load_and_round_trip():
    from analysis.verify.requirements import Requirement

    scenario = load_scenario("paper")
    assert scenario.requirements and all(isinstance(r, Requirement) for r in scenario.requirements)
    assert len({r.name for r in scenario.requirements}) == len(scenario.requirements)
    text = scenario_to_toml(scenario)
    assert text.count("[[requirements]]") == len(scenario.requirements)
    assert scenario_from_toml(text, "copy") == scenario
    # multi-line formulas with quotes and comments survive the canonical text
    assert any("\n" in r.formula and '"' in r.formula for r in scenario.requirements)


def test_a_scenario_without_requirements_writes_none(paper):
    del paper["requirements"]
    scenario = scenario_from_mapping(paper, SOURCE)
    assert scenario.requirements == () and "requirements" not in scenario_to_toml(scenario)
    assert scenario_from_toml(scenario_to_toml(scenario), "copy") == scenario


def test_requirements_change_the_digest(paper):
    a = scenario_from_mapping(paper, SOURCE)
    b = dataclasses.replace(a, requirements=a.requirements[:1])
    assert scenario_digest(a) != scenario_digest(b)


def test_requirement_with_an_unknown_signal(paper):
    data = _with_requirements(paper, {"name": "safe", "formula": "always[0, 10] (clearence_m > 0)"})
    err = _formula_error(data, 0)
    assert "unknown signal 'clearence_m' (did you mean 'clearance_m'?)" in str(err)
    assert err.value == "always[0, 10] (clearence_m > 0)"
    # the caret stands under the name, on the line after the formula
    lines = str(err).splitlines()
    assert lines[-2].strip() == "always[0, 10] (clearence_m > 0)"
    assert lines[-1].index("^") == lines[-2].index("clearence_m")


def test_requirement_with_a_syntax_error_shows_the_caret(paper):
    ok = {"name": "safe", "formula": "always[0, 10] (clearance_m > 0)"}
    data = _with_requirements(paper, ok, {"name": "broken", "formula": "always[0, 10] (clearance_m > 0"})
    err = _formula_error(data, 1)
    assert "formula error at line 1, column " in str(err) and "expected ')'" in str(err)
    assert str(err).splitlines()[-1].strip() == "^"
    assert "correct the formula of 'broken'" in err.fix


def test_requirement_with_a_duplicate_name(paper):
    table = {"name": "safe", "formula": "always[0, 10] (clearance_m > 0)"}
    data = _with_requirements(paper, table, {**table, "formula": "always[0, 10] (mu_coll <= 1)"})
    rejects(data, "requirements[1].name", "rename one of the requirements", "a unique name (requirements[0] is also")


def test_requirement_window_longer_than_the_duration(paper):
    paper["duration_s"] = 60.0
    data = _with_requirements(paper, {"name": "late", "formula": "always[0, 50] eventually[0, 20] (mu_coll <= 1)"})
    err = _formula_error(data, 0)
    assert "70 s ahead, more than the horizon 60 s" in str(err)
    assert "no window beyond duration_s = 60.0 s" in err.expected
    paper["duration_s"] = 70.0  # exactly the horizon is accepted
    assert scenario_from_mapping(data, SOURCE).requirements[0].name == "late"


def test_requirement_with_an_unknown_mode_pattern(paper):
    data = _with_requirements(paper, {"name": "m", "formula": 'always[0, 1] (mode == "AVIOD|*" implies mu_coll > 0)'})
    err = _formula_error(data, 0)
    assert 'label pattern "AVIOD|*" matches no value' in str(err)


@pytest.mark.parametrize(("table", "key", "fix"), [
    ({"name": "x", "formula": "time >= 0", "descripton": ""}, "requirements[0].descripton", "did you mean 'description'?"),
    ({"name": "x"}, "requirements[0].formula", 'add formula = "..."'),
    ({"formula": "time >= 0"}, "requirements[0].name", 'add name = "..."'),
    ({"name": "x", "formula": 3}, "requirements[0].formula", "write the text in double quotes"),
    ({"name": "no spaces allowed", "formula": "time >= 0"}, "requirements[0].name", "rename the requirement"),
    ({"name": "x", "formula": "   "}, "requirements[0].formula", "write e.g. formula ="),
])
def test_requirement_table_errors(paper, table, key, fix):
    rejects(_with_requirements(paper, table), key, fix)


def test_requirements_must_be_an_array_of_tables(paper):
    paper["requirements"] = {"name": "x", "formula": "time >= 0"}
    rejects(paper, "requirements", "write each requirement under its own [[requirements]] header")
