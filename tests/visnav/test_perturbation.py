"""visnav.perturbation: one declaration of the moves, one application, draws from numpy or hypothesis."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.closed_loop import desired_features
from visnav.perturbation import (
    Move,
    Perturbation,
    PerturbationError,
    Symmetric,
    Uniform,
    apply_perturbation,
)
from visnav.scenario import ScenarioError, load_scenario, target_square


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


def move(field, change="offset", draw=None):
    return Move(field=field, change=change, draw=draw or Symmetric(half_width=0.1))


# ---------------------------------------------------------------------------------------------
# Distributions
# ---------------------------------------------------------------------------------------------


def test_distribution_formulas_and_bounds():
    assert Symmetric(half_width=0.2).at(0.0) == -0.2 and Symmetric(half_width=0.2).at(1.0) == 0.2
    assert Symmetric(half_width=0.2).bounds == (-0.2, 0.2) and Symmetric(half_width=0).at(0.3) == -0.0
    assert Uniform(low=1.0, high=3.0).at(0.25) == 1.5 and Uniform(low=1.0, high=3.0).bounds == (1.0, 3.0)
    assert Uniform(low=0.5, high=0.5).at(0.9) == 0.5


def test_uniform_is_numpys_uniform_bit_for_bit():
    """Uniform(lo, hi).at(u) is Generator.uniform(lo, hi) for the same unit draw: the stiffness study's draws."""
    for seed in range(20):
        for lo, hi in ((-0.3, 0.3), (0.85, 1.25), (0.15, 0.3), (0.75, 1.5), (-0.1, 0.1)):
            expected = np.random.default_rng(seed).uniform(lo, hi, size=7)
            u = np.random.default_rng(seed).random(7)
            assert [Uniform(low=lo, high=hi).at(x) for x in u] == expected.tolist()


@pytest.mark.parametrize("build, message", [
    (lambda: Uniform(low=2.0, high=1.0), r"^Uniform = \(2.0, 1.0\): expected low <= high; fix: swap"),
    (lambda: Uniform(low=math.inf, high=1.0), r"^Uniform.low = inf: expected a finite number"),
    (lambda: Symmetric(half_width=-0.1), r"^Symmetric.half_width = -0.1: expected a half-width >= 0; fix: use 0"),
    (lambda: Symmetric(half_width=True), r"^Symmetric.half_width = True: expected a finite number"),
])
def test_distribution_validation(build, message):
    with pytest.raises(PerturbationError, match=message):
        build()


# ---------------------------------------------------------------------------------------------
# Declarations
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("field, change, label", [
    ("start.x_m", "offset", "start.dx_m"),
    ("start.theta_rad", "offset", "start.dtheta_rad"),
    ("obstacles[1].radius_m", "offset", "obstacles[1].dradius_m"),
    ("target.heading_rad", "offset", "target.dheading_rad"),
    ("gains.k_path", "factor", "gains.k_path"),
    ("gains.v_coll_mps", "value", "gains.v_coll_mps"),
    ("duration_s", "offset", "dduration_s"),
    ("estimator.newton_tol", "factor", "estimator.newton_tol"),
])
def test_fields_and_labels(field, change, label):
    assert move(field, change).label == label


@pytest.mark.parametrize("build, message", [
    (lambda: move("start.z_m"), r"^Move.field = 'start.z_m': expected a field of one of the forms"),
    (lambda: move("obstacles[0].name"), r"^Move.field = 'obstacles\[0\].name': expected obstacles\[j\]"),
    (lambda: move("estimator.order"), r"^Move.field = 'estimator.order'"),  # an integer field
    (lambda: move("start.x_m", "scale"), r"^Move.change = 'scale': expected one of offset, factor, value"),
    (lambda: move("target.x_m", "value"), r"^Move.change = 'value': expected 'offset' for target.x_m"),
    (lambda: Move(field="start.x_m", change="offset", draw=(0, 1)), r"^Move.draw = \(0, 1\): expected a Uniform"),
    (lambda: Perturbation(moves=(move("start.x_m"), move("start.x_m", "factor"))),
     r"^Perturbation.moves = 'start.x_m': expected each field moved once"),
    (lambda: Perturbation(moves=[move("start.x_m")]), r"^Perturbation.moves = .*expected a tuple of Move"),
])
def test_declaration_validation(build, message):
    with pytest.raises(PerturbationError, match=message):
        build()


def test_size_bounds_unit_draws_and_description():
    p = Perturbation(moves=(move("start.x_m", draw=Symmetric(half_width=0.2)),
                            move("gains.k_path", "factor", Uniform(low=0.5, high=1.5))))
    assert p.size == 2 and p.bounds == ((-0.2, 0.2), (0.5, 1.5))
    assert p.from_unit([0.75, 0.5]) == (0.2 * (2 * 0.75 - 1), 1.0)
    with pytest.raises(PerturbationError, match=r"^u = 3: expected 2 unit draws"):
        p.from_unit([0.1, 0.2, 0.3])
    assert p.as_dict() == [
        {"field": "start.x_m", "change": "offset", "draw": {"Symmetric": {"half_width": 0.2}}},
        {"field": "gains.k_path", "change": "factor", "draw": {"Uniform": {"low": 0.5, "high": 1.5}}},
    ]


# ---------------------------------------------------------------------------------------------
# Application
# ---------------------------------------------------------------------------------------------


def test_offsets_factors_and_values_change_only_their_fields(paper):
    p = Perturbation(moves=(move("start.y_m"), move("gains.k_path", "factor"), move("gains.v_coll_mps", "value"),
                            move("obstacles[1].x_m"), move("obstacles[0].height_m"), move("limits.v_max_mps", "value"),
                            move("duration_s", "value")))
    drawn = apply_perturbation(paper, p, [0.05, 1.25, 0.25, -0.1, 0.02, 0.5, 100.0])
    s = drawn.scenario
    assert drawn.valid and drawn.error is None and s == drawn.candidate
    assert s.start == dataclasses.replace(paper.start, y_m=paper.start.y_m + 0.05)
    assert s.gains == dataclasses.replace(paper.gains, k_path=paper.gains.k_path * 1.25, v_coll_mps=0.25)
    assert s.obstacles[1] == dataclasses.replace(paper.obstacles[1], center_m=(paper.obstacles[1].center_m[0] - 0.1,
                                                                               paper.obstacles[1].center_m[1]))
    assert s.obstacles[0].height_m == paper.obstacles[0].height_m + 0.02 and s.limits.v_max_mps == 0.5
    assert s.duration_s == 100.0 and s.goal == paper.goal and s.target == paper.target and s.camera == paper.camera
    assert dict(drawn.parameters) == {"start.dy_m": 0.05, "gains.k_path": paper.gains.k_path * 1.25,
                                      "gains.v_coll_mps": 0.25, "obstacles[1].dx_m": -0.1,
                                      "obstacles[0].dheight_m": 0.02, "limits.v_max_mps": 0.5, "duration_s": 100.0}
    assert [k for k, _ in drawn.parameters] == sorted(k for k, _ in drawn.parameters)


def test_rigid_target_motion_carries_the_goal_and_keeps_the_desired_image(paper):
    p = Perturbation(moves=(move("target.x_m"), move("target.y_m"), move("target.heading_rad")))
    drawn = apply_perturbation(paper, p, [0.3, -0.2, 0.1])
    assert drawn.valid and drawn.scenario.goal.theta_rad == paper.goal.theta_rad + 0.1
    assert drawn.scenario.goal.x_m != paper.goal.x_m and drawn.scenario.target != paper.target
    assert np.allclose(desired_features(drawn.scenario), desired_features(paper), rtol=0, atol=1e-12)


def test_normal_rotates_the_target_alone(paper):
    p = Perturbation(moves=(move("target.normal_rad"),))
    drawn = apply_perturbation(paper, p, [0.15])
    assert drawn.scenario.goal == paper.goal
    assert np.allclose(drawn.scenario.target.points_m, target_square((9.0, 0.0, 0.5), math.pi + 0.15, 0.3),
                       rtol=0, atol=1e-12)


def test_a_draw_breaking_a_rule_is_reported_not_raised(paper):
    p = Perturbation(moves=(move("obstacles[0].x_m"),))
    drawn = apply_perturbation(paper, p, [-2.5], source="paper#3")
    assert not drawn.valid and drawn.scenario is None
    assert isinstance(drawn.error, ScenarioError) and str(drawn.error).startswith("scenario 'paper#3': obstacles[0]")
    assert drawn.candidate.obstacles[0].center_m[0] == paper.obstacles[0].center_m[0] - 2.5
    assert dict(drawn.parameters) == {"obstacles[0].dx_m": -2.5}
    unchecked = apply_perturbation(paper, p, [-2.5], validate=False, name="adversarial")
    assert unchecked.valid and unchecked.scenario is unchecked.candidate and unchecked.scenario.name == "adversarial"


def test_the_gain_rules_apply_to_perturbed_scenarios(paper):
    p = Perturbation(moves=(move("gains.k_path", "value"),))
    assert "gains.k_path = 5000.0" in str(apply_perturbation(paper, p, [5e3]).error)


@pytest.mark.parametrize("values, message", [
    ([0.1, 0.2], r"^values = 2: expected 1 values \(one per move\)"),
    ([math.nan], r"^values\[0\] = nan: expected a finite number for start.x_m"),
])
def test_values_are_checked(paper, values, message):
    with pytest.raises(PerturbationError, match=message):
        apply_perturbation(paper, Perturbation(moves=(move("start.x_m"),)), values)


def test_a_move_of_a_missing_obstacle(paper):
    with pytest.raises(PerturbationError, match=r"^Move.field = 'obstacles\[5\].x_m': expected an obstacle index below 2"):
        apply_perturbation(paper, Perturbation(moves=(move("obstacles[5].x_m"),)), [0.0])


# ---------------------------------------------------------------------------------------------
# Draws from hypothesis: the layout moves of the fuzz strategy (visnav.fuzzing.layouts)
# ---------------------------------------------------------------------------------------------


def _fuzz_base():
    """The fuzz's base scenario without obstacles: ``_layouts`` places its own after the moves."""
    return dataclasses.replace(load_scenario("paper"), duration_s=90.0, obstacles=())


#: The scalar draws of ``visnav.fuzzing.layouts._layouts`` as moves of the paper scenario: goal (and target
#: with it) at x in [4, 8] m, y in [-1, 1] m; start heading in [-0.3, 0.3] rad; target normal pi +- 0.2 rad.
FUZZ_LAYOUT = Perturbation(moves=(
    Move(field="target.x_m", change="offset", draw=Uniform(low=4.0 - 7.9, high=8.0 - 7.9)),
    Move(field="target.y_m", change="offset", draw=Uniform(low=-1.0, high=1.0)),
    Move(field="start.theta_rad", change="value", draw=Uniform(low=-0.3, high=0.3)),
    Move(field="target.normal_rad", change="offset", draw=Uniform(low=-0.2, high=0.2)),
))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st.tuples(*(st.floats(lo, hi) for lo, hi in FUZZ_LAYOUT.bounds)))
def test_hypothesis_draws_within_the_bounds_give_the_fuzz_layouts(values):
    base = _fuzz_base()
    drawn = apply_perturbation(base, FUZZ_LAYOUT, values, name="random-respecting")
    assert drawn.valid, drawn.error  # target ahead and in view at the goal, whatever the draw
    s = drawn.scenario
    goal_x, goal_y = 7.9 + values[0], values[1]
    assert s.goal.x_m == pytest.approx(goal_x, abs=1e-12) and s.goal.y_m == values[1] and s.goal.theta_rad == 0.0
    assert s.start.theta_rad == values[2] and s.name == "random-respecting"
    square = target_square((goal_x + base.robot.pan_offset_m + 1.0, goal_y, base.robot.camera_height_m),
                           math.pi + values[3], 0.3)
    assert np.allclose(s.target.points_m, square, rtol=0, atol=1e-12)
