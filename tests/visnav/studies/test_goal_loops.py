"""The symbolic goal models against the float code, and their eigenvalues against closed forms."""

import json
import math

import numpy as np
import pytest

from visnav import controllers, model
from visnav.closed_loop import desired_features
from visnav.geometry import camera_pose, project_points
from visnav.studies.goal_loops import goal_loop_findings, pan_task_model, visual_servoing_model
from visnav.scenario import load_scenario

# Round-off of one evaluation of the projection + 3x3 solve is ~1e-15 relative; the symbolic and the
# float paths order their operations differently, so allow 1e-11 relative to the largest entry.
AGREE = 1e-11


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


def _poses(paper, count=12, seed=3):
    """Poses scattered around the straight line from the start to the goal (target in view)."""
    rng = np.random.default_rng(seed)
    g, s = paper.goal, paper.start
    out = []
    for u in np.linspace(0.3, 1.0, count):
        pose = np.array([s.x_m + u * (g.x_m - s.x_m), s.y_m + u * (g.y_m - s.y_m),
                         s.theta_rad + u * (g.theta_rad - s.theta_rad), s.pan_rad + u * (g.pan_rad - s.pan_rad)])
        out.append(pose + rng.normal(scale=(0.05, 0.05, 0.03, 0.03)))
    return out


def test_visual_servoing_model_agrees_with_the_controller(paper):
    vs = visual_servoing_model(paper)
    desired = desired_features(paper)
    assert np.allclose(vs.desired, desired, rtol=0, atol=1e-15)
    desired_xy = tuple((x, y) for x, y, _ in desired)
    for pose in _poses(paper):
        features = project_points(*camera_pose(*pose, paper.robot), paper.robot.camera_height_m,
                                  paper.target.points_m)
        e_float = np.array(controllers.visual_servoing_error(features, desired_xy, desired))
        q_float = np.array(controllers.visual_servoing(features, desired_xy, pose[3], paper.robot,
                                                       paper.gains.lambda_vs, desired))
        e_sym, q_sym = vs.error_at(pose), vs.joint_rates_at(pose)
        assert np.max(np.abs(e_sym - e_float)) <= AGREE * max(1e-3, np.max(np.abs(e_float)))
        assert np.max(np.abs(q_sym - q_float)) <= AGREE * max(1e-3, np.max(np.abs(q_float)))


def test_pan_task_model_agrees_with_the_controller(paper):
    pan = pan_task_model(paper)
    desired = desired_features(paper)
    assert pan.y_gc_desired == pytest.approx(sum(p[1] for p in desired) / len(desired), abs=1e-15)
    for i, pose in enumerate(_poses(paper)):
        v, w = 0.2 * (i % 3), 0.4 * ((i % 5) - 2)
        features = project_points(*camera_pose(*pose, paper.robot), paper.robot.camera_height_m,
                                  paper.target.points_m)
        want = controllers.pan_tracking(features, pose[3], v, w, paper.robot, paper.gains.lambda_gc,
                                        pan.y_gc_desired)
        assert pan.pan_rate_at(pose, v, w) == pytest.approx(want, rel=AGREE, abs=1e-14)


def test_ad_of_the_projection_reproduces_the_interaction_matrix(paper):
    """E G = C L* J_r = J_r at the goal: AD of camera pose + projection vs the analytic rows (5) and (1)."""
    vs = visual_servoing_model(paper)
    robot = paper.robot
    jr = np.array(model.reduced_jacobian(vs.goal[3], robot.pan_offset_m, robot.camera_forward_m,
                                         robot.camera_lateral_m))
    np.testing.assert_allclose(vs.input_matrix(), jr, rtol=0, atol=1e-12)


def test_goal_eigenvalues_match_the_closed_forms(paper):
    f = goal_loop_findings(paper)
    lam_vs, lam_gc = paper.gains.lambda_vs, paper.gains.lambda_gc
    for e in f.task.eigenvalues:
        assert abs(e - (-lam_vs)) <= 1e-12  # three-fold eigenvalue: ~1e-14 seen
    eig = sorted(f.closed_loop.eigenvalues, key=lambda z: z.real)
    for e in eig[:3]:
        assert abs(e - (-lam_vs)) <= 1e-12
    assert abs(eig[3]) <= 1e-12
    assert not f.closed_loop.hurwitz
    assert "on the imaginary axis" in f.closed_loop.finding
    # the zero mode moves the base, not the camera: a curve of equilibria, invisible in the image
    assert f.zero_mode_camera_motion <= 1e-12
    assert abs(np.linalg.norm(f.zero_mode) - 1.0) <= 1e-12
    assert f.pan.eigenvalues[0] == pytest.approx(-lam_gc, abs=1e-12)
    assert f.pan_closure_residual <= 1e-12
    assert f.input_matrix_error <= 1e-12


def test_goal_findings_as_dict_keeps_the_report_keys(paper):
    f = goal_loop_findings(paper)
    data = f.as_dict()
    assert list(data) == ["visual_servoing_task", "closed_loop", "input_matrix",
                          "input_matrix_error_vs_reduced_jacobian", "pan_task", "explanation"]
    task = data["visual_servoing_task"]
    assert list(task) == list(f.task.as_dict()) + ["closed_form", "claim"]
    assert task["closed_form"] == [-paper.gains.lambda_vs] * 3 and task["claim"] == "computed"
    loop = data["closed_loop"]
    assert loop["zero_mode"] == list(f.zero_mode) and loop["zero_mode_camera_motion"] == f.zero_mode_camera_motion
    assert data["input_matrix"] == f.input_matrix.tolist()
    assert data["pan_task"]["closed_form"] == [-paper.gains.lambda_gc]
    assert data["pan_task"]["closure_residual"] == f.pan_closure_residual
    assert json.loads(json.dumps(data, allow_nan=False)) == data


def test_zero_mode_is_a_curve_of_equilibria(paper):
    """Moving along the zero eigenvector (camera fixed to first order) changes e_VS only to second order."""
    vs = visual_servoing_model(paper)
    f = goal_loop_findings(paper)
    goal = np.array(vs.goal)
    for h in (1e-2, 1e-3):
        moved = np.linalg.norm(vs.error_at(goal + h * np.array(f.zero_mode)))
        other = np.linalg.norm(vs.error_at(goal + h * np.array([1.0, 0.0, 0.0, 0.0])))
        assert moved <= 10 * h * h  # second order
        assert other >= 0.1 * h  # a generic direction is first order


def test_pan_loop_gains_give_lambda_over_s(paper):
    c, gain = pan_task_model(paper).loop_gains()
    assert c * gain == pytest.approx(paper.gains.lambda_gc, rel=1e-12)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, "2"])
def test_bad_gains_are_refused_by_name(paper, bad):
    with pytest.raises(ValueError, match=r"lambda_vs = .*expected a finite gain > 0"):
        visual_servoing_model(paper, lambda_vs=bad)
    with pytest.raises(ValueError, match=r"lambda_gc = .*expected a finite gain > 0"):
        pan_task_model(paper, lambda_gc=bad)
