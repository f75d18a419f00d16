"""Closed-loop checks of visnav.controllers on the exact geometry.

Each controller is applied as a constant input over a short exact step of
visnav.geometry.propagate_pose, the task error is recomputed from the true
geometry, and its central-difference derivative is compared to the decay the
controller promises.  Tolerances: step H = 1e-5 gives truncation ~H² |e'''| and
rounding ~eps |e| / H, both below 1e-9 relative here; 1e-6 relative leaves
margin while a wrong sign or a missing term is off by O(1).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hybrid.errors import NumericalFailure
from visnav import controllers as c
from visnav import geometry as g
from visnav import model
from visnav.parameters import CameraModel, Envelopes, Obstacle, RobotGeometry

ROBOT = RobotGeometry()
CAMERA = CameraModel()
ENVELOPES = Envelopes()
H = 1e-5
REL = 1e-6

TARGET = ((4.0, -0.1, 0.4), (4.0, 0.1, 0.4), (4.0, 0.1, 0.6), (4.0, -0.1, 0.6))
GOAL = (2.8, 0.0, 0.0, 0.0)
TALL = Obstacle(name="tall", center_m=(2.0, 0.45), radius_m=0.2, height_m=1.0)


def features_at(pose, robot=ROBOT, world=TARGET):
    return g.project_points(*g.camera_pose(*pose, robot), robot.camera_height_m, world)


DESIRED = tuple((x, y) for x, y, _ in features_at(GOAL))


def central_difference(fun, pose, qdot, h=H):
    plus = np.asarray(fun(g.propagate_pose(pose, *qdot, h)), dtype=float)
    minus = np.asarray(fun(g.propagate_pose(pose, *qdot, -h)), dtype=float)
    return (plus - minus) / (2 * h)


def assert_close(got, expected, tol) -> None:
    """Elementwise ``|got - expected| <= tol`` (``tol`` may be an array)."""
    got, expected = np.asarray(got, dtype=float), np.asarray(expected, dtype=float)
    excess = np.abs(got - expected) - np.asarray(tol)
    assert np.all(excess <= 0), f"got {got}, expected {expected}, tolerance {tol}"


def interaction_matrix(features) -> np.ndarray:
    rows = []
    for x, y, z in features:
        rows.append(model.interaction_x_row(x, y, z))
        rows.append(model.interaction_y_row(y, z))
    return np.array(rows)


def stacked(features) -> np.ndarray:
    return np.array([v for x, y, _ in features for v in (x, y)])


# --------------------------------------------------------------------------- visual servoing

VS_POSES = [(0.0, 0.0, 0.0, 0.0), (0.5, -0.6, 0.3, -0.2), (1.0, 0.8, -0.25, 0.1), (2.6, 0.05, 0.02, -0.03)]


@pytest.mark.parametrize("pose", VS_POSES)
def test_visual_servoing_error_is_the_least_squares_screw(pose) -> None:
    feats = features_at(pose)
    ell = interaction_matrix(feats)
    expected = np.linalg.lstsq(ell, stacked(feats) - np.ravel(DESIRED), rcond=None)[0]
    # The normal equations lose cond(L)² eps (cond(L) ~ 1e2-1e3 for a small, distant target:
    # the V_y and Omega_x columns are nearly parallel); lstsq (SVD) loses cond(L) eps.
    cond = np.linalg.cond(ell)
    assert 10 < cond < 1e4
    got = np.array(c.visual_servoing_error(feats, DESIRED))
    assert np.linalg.norm(got - expected) <= 10 * cond**2 * np.finfo(float).eps * np.linalg.norm(expected)


@pytest.mark.parametrize("pose", VS_POSES)
def test_visual_servoing_decreases_e_vs_at_rate_lambda(pose) -> None:
    """With C frozen at the sample (C = L^+ of the current L): d/dt e_VS = -lambda e_VS exactly."""
    lam = 0.7
    feats = features_at(pose)
    qdot = c.visual_servoing(feats, DESIRED, pose[3], ROBOT, lam)
    e = np.array(c.visual_servoing_error(feats, DESIRED))
    s_dot = central_difference(lambda p: stacked(features_at(p)), pose, qdot)
    e_dot = np.linalg.pinv(interaction_matrix(feats)) @ s_dot
    np.testing.assert_allclose(e_dot, -lam * e, rtol=0, atol=REL * lam * np.linalg.norm(e))
    # and the norm of the full error (C varying too) decreases
    norm = lambda p: np.linalg.norm(c.visual_servoing_error(features_at(p), DESIRED))  # noqa: E731
    assert central_difference(norm, pose, qdot) < 0


def test_visual_servoing_full_derivative_near_the_goal() -> None:
    """With the current C, e' = -lambda e + C'(s - s*): the deviation is second order in the error."""
    lam = 1.0
    deviations = []
    for offset in (1e-3, 2e-3, 4e-3):
        pose = (GOAL[0] - offset, GOAL[1] + offset, GOAL[2] + offset, GOAL[3] - offset)
        feats = features_at(pose)
        qdot = c.visual_servoing(feats, DESIRED, pose[3], ROBOT, lam)
        e = np.array(c.visual_servoing_error(feats, DESIRED))
        e_dot = central_difference(lambda p: c.visual_servoing_error(features_at(p), DESIRED), pose, qdot)
        deviations.append(np.linalg.norm(e_dot + lam * e) / np.linalg.norm(lam * e))
    # relative deviation proportional to the error: doubles with the offset, and small
    assert deviations[0] < 1e-2
    assert deviations[1] / deviations[0] == pytest.approx(2.0, rel=0.05)
    assert deviations[2] / deviations[1] == pytest.approx(2.0, rel=0.05)


def test_visual_servoing_at_goal_is_zero() -> None:
    feats = features_at(GOAL)
    np.testing.assert_allclose(c.visual_servoing(feats, DESIRED, 0.0, ROBOT, 0.5), 0.0, atol=1e-15)


@pytest.mark.parametrize(
    "features",
    [
        ((0.1, 0.2, 3.0),) * 4,  # all points at the same image location
        ((0.1, 0.2, 3.0),),  # a single point: L^T L has rank 2
    ],
)
def test_visual_servoing_degenerate_target_raises(features) -> None:
    desired = ((0.0, 0.0),) * len(features)
    with pytest.raises(NumericalFailure, match=r"visual_servoing: L\^T L is singular .*degenerate"):
        c.visual_servoing(features, desired, 0.0, ROBOT, 0.5)


def test_visual_servoing_nan_raises() -> None:
    feats = list(features_at(VS_POSES[0]))
    feats[2] = (math.nan, 0.0, 3.0)
    with pytest.raises(NumericalFailure, match="singular"):
        c.visual_servoing(tuple(feats), DESIRED, 0.0, ROBOT, 0.5)


# --------------------------------------------------------------------------- path following

PATH_CASES = [
    # pose (x, y, theta), side
    ((1.2, 0.2, 0.0), 1),
    ((1.4, 0.9, 0.8), 1),
    ((2.0, 1.3, 2.9), 1),
    ((1.2, 0.7, 0.0), -1),
    ((2.9, 0.3, -1.2), -1),
]


@pytest.mark.parametrize(("pose", "side"), PATH_CASES)
def test_path_following_closed_loop_matches_the_model(pose, side) -> None:
    d0, v_coll, k = 0.5, 0.2, 2.0
    prox = g.proximity(*pose, TALL, side)
    v, omega = c.path_following(prox, d0, v_coll, k)
    assert v == v_coll
    full = (*pose, 0.0)

    def path_state(p):
        q = g.proximity(*p[:3], TALL, side)
        return (q.d_coll - d0, q.alpha)

    delta_dot, alpha_dot = central_difference(path_state, full, (v, omega, 0.0))
    delta, alpha = prox.d_coll - d0, prox.alpha
    assert delta_dot == pytest.approx(v_coll * math.sin(alpha), abs=1e-9)
    assert alpha_dot == pytest.approx(-v_coll * (k * delta + alpha + 2 * k * math.sin(alpha)), abs=1e-9)


def test_path_following_on_the_envelope_follows_the_circle() -> None:
    """delta = alpha = 0: omega is the circle's rate side v / rho and the robot stays on it."""
    d0, v_coll = 0.5, 0.2
    rho = TALL.radius_m + d0
    side = 1
    pose = (TALL.center_m[0] + rho, TALL.center_m[1], math.pi / 2, 0.0)  # counter-clockwise
    prox = g.proximity(*pose[:3], TALL, side)
    v, omega = c.path_following(prox, d0, v_coll, 2.0)
    assert omega == pytest.approx(v_coll / rho, rel=1e-14)
    end = g.propagate_pose(pose, v, omega, 0.0, 3.0)
    assert math.hypot(end[0] - TALL.center_m[0], end[1] - TALL.center_m[1]) == pytest.approx(rho, rel=1e-13)


# --------------------------------------------------------------------------- pan tracking


@pytest.mark.parametrize(
    ("pose", "base"),
    [((0.0, 0.0, 0.0, 0.0), (0.2, 0.3)), ((1.0, -0.5, 0.4, -0.3), (0.2, -0.5)), ((2.0, 0.4, -0.2, 0.1), (0.0, 0.8))],
)
def test_pan_tracking_decreases_e_gc_at_rate_lambda(pose, base) -> None:
    lam, y_star = 2.0, 0.05
    v, omega = base
    feats = features_at(pose)
    pan_rate = c.pan_tracking(feats, pose[3], v, omega, ROBOT, lam, y_star)
    e_gc = np.mean([y for _, y, _ in feats]) - y_star
    e_dot = central_difference(lambda p: np.mean([y for _, y, _ in features_at(p)]) - y_star, pose, (v, omega, pan_rate))
    assert e_dot == pytest.approx(-lam * e_gc, abs=REL * lam * abs(e_gc))


def test_pan_tracking_singular_raises() -> None:
    # L_Ygc J_pan = -a/z - b Y/z - 1 - Y² vanishes for a = -z, b = 0, Y = 0
    robot = RobotGeometry(camera_forward_m=-2.0, camera_lateral_m=0.0)
    with pytest.raises(NumericalFailure, match=r"L_Ygc J_pan = 0, .*cannot move the gravity centre"):
        c.pan_tracking(((0.0, 0.0, 2.0),), 0.0, 0.2, 0.0, robot, 1.0, 0.0)


# --------------------------------------------------------------------------- occlusion avoidance

OCC_POSES = [(0.0, 0.0, 0.0, 0.0), (0.2, 0.05, 0.03, -0.02), (-0.3, -0.1, -0.05, 0.08)]


def occlusion_error(pose):
    cam = g.camera_pose(*pose, ROBOT)
    feats = features_at(pose)
    meas = g.image_measurement(cam, ROBOT.camera_height_m, feats, TARGET, (TALL,), CAMERA)
    return feats, meas


def e_o(pose):
    feats, meas = occlusion_error(pose)
    return c.occlusion_task(feats, meas, pose[3], ROBOT, CAMERA, ENVELOPES)[0]


@pytest.mark.parametrize("pose", OCC_POSES)
def test_occlusion_geometry_is_inside_the_envelope(pose) -> None:
    _, meas = occlusion_error(pose)
    assert meas.occluder_index == 0 and 0.5 < meas.d_occ_px < ENVELOPES.D_plus_px and meas.d_bord_px > 0


@pytest.mark.parametrize("pose", OCC_POSES)
def test_w_o_equals_finite_differences_of_e_o(pose) -> None:
    feats, meas = occlusion_error(pose)
    _, w = c.occlusion_task(feats, meas, pose[3], ROBOT, CAMERA, ENVELOPES)
    w = np.array(w)
    for k in range(3):
        unit = tuple(1.0 if i == k else 0.0 for i in range(3))
        column = central_difference(e_o, pose, unit)
        assert_close(column, w[:, k], REL * np.abs(w).max(axis=1))


@pytest.mark.parametrize("pose", OCC_POSES)
@pytest.mark.parametrize("beta", [0.0, 0.5, 3.0])
def test_occlusion_avoidance_decreases_e_o_at_rate_lambda(pose, beta) -> None:
    lam = 0.4
    feats, meas = occlusion_error(pose)
    qdot = c.occlusion_avoidance(feats, DESIRED, meas, pose[3], ROBOT, CAMERA, ENVELOPES, lam, beta)
    e = np.array(e_o(pose))
    e_dot = central_difference(e_o, pose, qdot)
    assert_close(e_dot, -lam * e, REL * lam * np.abs(e))


@pytest.mark.parametrize("pose", OCC_POSES)
def test_occlusion_secondary_task_is_the_projected_gradient(pose) -> None:
    """q(beta) - q(0) = -lambda beta (I - W^+ W) grad_q (|s - s*|²/2), gradient by finite differences."""
    lam, beta = 0.4, 1.5
    feats, meas = occlusion_error(pose)
    args = (feats, DESIRED, meas, pose[3], ROBOT, CAMERA, ENVELOPES, lam)
    diff = np.array(c.occlusion_avoidance(*args, beta)) - np.array(c.occlusion_avoidance(*args, 0.0))

    def cost(p):
        return 0.5 * float(np.sum((stacked(features_at(p)) - np.ravel(DESIRED)) ** 2))

    grad = np.array([central_difference(cost, pose, tuple(float(i == k) for i in range(3))) for k in range(3)])
    w = np.array(c.occlusion_task(feats, meas, pose[3], ROBOT, CAMERA, ENVELOPES)[1])
    projector = np.eye(3) - np.linalg.pinv(w) @ w
    expected = -lam * beta * projector @ grad
    np.testing.assert_allclose(diff, expected, rtol=0, atol=1e-6 * np.linalg.norm(expected))


def test_occlusion_cotangent_is_clamped() -> None:
    feats, meas = occlusion_error(OCC_POSES[0])
    hidden = dataclasses.replace(meas, d_occ_px=0.0)
    far = dataclasses.replace(meas, d_occ_px=math.inf)
    (e_hidden, _), w_hidden = c.occlusion_task(feats, hidden, 0.0, ROBOT, CAMERA, ENVELOPES)
    (e_far, _), w_far = c.occlusion_task(feats, far, 0.0, ROBOT, CAMERA, ENVELOPES)
    assert e_hidden == pytest.approx(1.0 / math.tan(0.5 * math.pi * c.D_OCC_FLOOR_PX / ENVELOPES.D_plus_px))
    assert e_far == pytest.approx(0.0, abs=1e-15)
    # the derivative is taken at the clamped argument, never zeroed: W_O keeps its rank
    assert np.linalg.matrix_rank(np.array(w_hidden)) == 2 and np.linalg.matrix_rank(np.array(w_far)) == 2


def test_occlusion_avoidance_without_occluder_raises() -> None:
    feats = features_at(OCC_POSES[0])
    cam = g.camera_pose(*OCC_POSES[0], ROBOT)
    meas = g.image_measurement(cam, ROBOT.camera_height_m, feats, TARGET, (), CAMERA)
    with pytest.raises(NumericalFailure, match=r"no occluder in front .*occluder_index = -1"):
        c.occlusion_avoidance(feats, DESIRED, meas, 0.0, ROBOT, CAMERA, ENVELOPES, 0.3, 0.5)


def test_occlusion_avoidance_singular_w_o_raises() -> None:
    feats, meas = occlusion_error(OCC_POSES[0])
    j = meas.nearest_feature
    # put the nearest feature exactly on the border it is measured from: the d_occ row vanishes
    moved = list(feats)
    moved[j] = (feats[j][0], meas.y_o_minus, meas.z_o_minus)
    with pytest.raises(NumericalFailure, match="W_O W_O\\^T is singular"):
        c.occlusion_avoidance(tuple(moved), DESIRED, meas, 0.0, ROBOT, CAMERA, ENVELOPES, 0.3, 0.5)


# --------------------------------------------------------------------------- switching (18), (19)

Q_VS, Q_OCC, Q_COLL = (0.1, 0.2, 0.3), (-0.4, 0.5, -0.6), (0.2, -0.7, 0.9)


@pytest.mark.parametrize(
    ("mu_coll", "mu_occ", "expected"),
    [(0.0, 0.0, Q_VS), (0.0, 1.0, Q_OCC), (1.0, 0.0, Q_COLL), (1.0, 1.0, Q_COLL)],
)
def test_blend_corners_of_table_one(mu_coll, mu_occ, expected) -> None:
    assert c.blend(mu_coll, mu_occ, Q_VS, Q_OCC, Q_COLL) == expected  # bit for bit
    # the controllers of zero weight may be missing
    args = {"q_vs": Q_VS, "q_occ": Q_OCC, "q_coll": Q_COLL}
    needed = {Q_VS: "q_vs", Q_OCC: "q_occ", Q_COLL: "q_coll"}[expected]
    only = {name: (q if name == needed else None) for name, q in args.items()}
    assert c.blend(mu_coll, mu_occ, **only) == expected


def test_blend_interior_is_equation_19() -> None:
    mu_coll, mu_occ = 0.3, 0.6
    expected = (
        (1 - mu_occ) * (1 - mu_coll) * np.array(Q_VS)
        + (1 - mu_coll) * mu_occ * np.array(Q_OCC)
        + mu_coll * np.array(Q_COLL)
    )
    np.testing.assert_allclose(c.blend(mu_coll, mu_occ, Q_VS, Q_OCC, Q_COLL), expected, rtol=1e-15, atol=1e-16)


def test_blend_missing_controller_with_weight_raises() -> None:
    with pytest.raises(ValueError, match=r"blend: q_occ is None but its weight is 0\.2"):
        c.blend(0.0, 0.2, Q_VS, None, Q_COLL)


def test_avoidance_control_equation_18() -> None:
    assert c.avoidance_control(0.2, -0.3, 0.7, None, 0.0) == (0.2, -0.3, 0.7)
    assert c.avoidance_control(0.2, -0.3, None, -0.5, 1.0) == (0.2, -0.3, -0.5)
    assert c.avoidance_control(0.2, -0.3, 0.7, -0.5, 0.25) == pytest.approx((0.2, -0.3, 0.75 * 0.7 - 0.25 * 0.5))
    with pytest.raises(ValueError, match="second pan rate is None but its weight is 0.5"):
        c.avoidance_control(0.2, -0.3, 0.7, None, 0.5)
