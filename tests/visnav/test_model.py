"""Checks of visnav.model (equations (1), (5), depth row, (13)) against geometry and AD.

The geometry (camera pose, projection, exact unicycle flow) comes from
visnav.geometry, written independently of the Jacobians: finite differences of
the former must reproduce the latter.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav import model
from visnav.geometry import camera_pose, project_point, propagate_pose
from visnav.parameters import RobotGeometry

GEOMETRIES = [
    RobotGeometry(),
    RobotGeometry(pan_offset_m=0.25, camera_forward_m=0.07, camera_lateral_m=-0.04, camera_height_m=0.8),
    RobotGeometry(pan_offset_m=0.02, camera_forward_m=-0.1, camera_lateral_m=0.15, camera_height_m=0.3),
]

# Central differences with step H: truncation error H²/6 |f'''| ~ 2e-11 for the
# O(1) derivatives here, rounding error eps |f| / H ~ 1e-11; 1e-8 leaves margin
# while a wrong sign, a swapped column or a missing term (all O(1e-2) or more)
# fails by orders of magnitude.
H = 1e-5
FD_TOL = 1e-8

angles = st.floats(min_value=-7.0, max_value=7.0, allow_nan=False)
rates = st.floats(min_value=-2.0, max_value=2.0, allow_nan=False)


def geometry_from(g: tuple[float, float, float]) -> RobotGeometry:
    return RobotGeometry(pan_offset_m=g[0], camera_forward_m=g[1], camera_lateral_m=g[2])


geometries = st.tuples(
    st.floats(min_value=0.02, max_value=1.0),
    st.floats(min_value=-0.3, max_value=0.3),
    st.floats(min_value=-0.3, max_value=0.3),
).map(geometry_from)


def jr(pan: float, robot: RobotGeometry) -> np.ndarray:
    return np.array(
        model.reduced_jacobian(pan, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    )


def jr_inv(pan: float, robot: RobotGeometry) -> np.ndarray:
    return np.array(
        model.reduced_jacobian_inverse(pan, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    )


# --------------------------------------------------------------------------- J_r


@pytest.mark.parametrize("robot", GEOMETRIES)
def test_det_reduced_jacobian_is_dx_for_every_pan(robot: RobotGeometry) -> None:
    # det of a 3x3 matrix with entries <= 1.3 is computed to ~1e-15.
    for pan in np.linspace(-2 * math.pi, 2 * math.pi, 721):
        assert np.linalg.det(jr(pan, robot)) == pytest.approx(robot.pan_offset_m, abs=1e-13)


def test_det_reduced_jacobian_symbolically() -> None:
    pan, dx, a, b = (ca.SX.sym(n) for n in ("pan", "dx", "a", "b"))
    j = ca.vertcat(*(ca.horzcat(*row) for row in model.reduced_jacobian(pan, dx, a, b, ops=ca)))
    det = ca.Function("det", [pan, dx, a, b], [ca.simplify(ca.det(j))])
    for args in [(0.3, 0.1, 0.0, 0.03), (-2.0, 0.4, 0.2, -0.1), (5.0, 0.05, -0.3, 0.3)]:
        assert float(det(*args)) == pytest.approx(args[1], abs=1e-14)


@given(pan=angles, robot=geometries)
@settings(deadline=None)
def test_reduced_jacobian_inverse_is_the_inverse(pan: float, robot: RobotGeometry) -> None:
    # Entries of J_r^{-1} are at most (1 + |a| + |b|)/Dx <= 80; products are exact to ~1e-13.
    np.testing.assert_allclose(jr_inv(pan, robot) @ jr(pan, robot), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(jr(pan, robot) @ jr_inv(pan, robot), np.eye(3), atol=1e-12)


@given(pan=angles, robot=geometries, v=rates, omega=rates, pan_rate=rates)
@settings(deadline=None)
def test_joint_rates_from_screw_inverts_camera_screw(
    pan: float, robot: RobotGeometry, v: float, omega: float, pan_rate: float
) -> None:
    g = (robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    screw = model.camera_screw(pan, v, omega, pan_rate, *g)
    np.testing.assert_allclose(screw, jr(pan, robot) @ np.array([v, omega, pan_rate]), atol=1e-13)
    back = model.joint_rates_from_screw(pan, *screw, *g)
    # Division by Dx >= 0.02 amplifies rounding by <= 50 (screw entries <= 5).
    np.testing.assert_allclose(back, (v, omega, pan_rate), atol=1e-12)


def test_pan_column_is_third_column_of_reduced_jacobian() -> None:
    robot = GEOMETRIES[1]
    col = model.pan_column(robot.camera_forward_m, robot.camera_lateral_m)
    for pan in (-1.0, 0.0, 2.5):
        np.testing.assert_array_equal(jr(pan, robot)[:, 2], col)


def test_camera_screw_matches_casadi_jacobian_of_itself() -> None:
    """J_r is the Jacobian of the screw with respect to q̇ (symbolic check of (1))."""
    pan, v, w, p = (ca.SX.sym(n) for n in ("pan", "v", "w", "p"))
    robot = GEOMETRIES[1]
    g = (robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    screw = ca.vertcat(*model.camera_screw(pan, v, w, p, *g, ops=ca))
    jac = ca.Function("j", [pan], [ca.jacobian(screw, ca.vertcat(v, w, p))])
    for angle in (-3.0, 0.1, 1.2):
        np.testing.assert_allclose(np.array(jac(angle)), jr(angle, robot), atol=1e-15)


# --------------------------------------------------------------------------- screw vs geometry


def camera_state(pose: tuple[float, ...], robot: RobotGeometry) -> tuple[float, float, float]:
    return camera_pose(*pose, robot)


CASES = [
    # pose (x, y, theta, pan), inputs (v, omega, pan_rate)
    ((0.0, 0.0, 0.0, 0.0), (0.3, 0.0, 0.0)),
    ((1.0, -2.0, 0.7, -0.4), (0.2, 0.5, -0.3)),
    ((-0.5, 0.3, -2.9, 1.4), (-0.1, -1.2, 0.8)),
    ((3.0, 1.0, 4.0, -2.5), (0.0, 0.3, 1.1)),
]


@pytest.mark.parametrize("robot", GEOMETRIES)
@pytest.mark.parametrize(("pose", "qdot"), CASES)
def test_camera_screw_equals_finite_differences_of_camera_pose(
    robot: RobotGeometry, pose: tuple[float, ...], qdot: tuple[float, float, float]
) -> None:
    plus = camera_state(propagate_pose(pose, *qdot, H), robot)
    minus = camera_state(propagate_pose(pose, *qdot, -H), robot)
    cx_dot, cy_dot, phi_dot = ((p - m) / (2 * H) for p, m in zip(plus, minus))
    phi = pose[2] + pose[3]
    # velocity of C expressed in the camera frame: z_C = (cos phi, sin phi), y_C = (-sin phi, cos phi),
    # and Omega_x = -phi_dot because x_C points down.
    v_z = cx_dot * math.cos(phi) + cy_dot * math.sin(phi)
    v_y = -cx_dot * math.sin(phi) + cy_dot * math.cos(phi)
    expected = model.camera_screw(
        pose[3], *qdot, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m
    )
    np.testing.assert_allclose((v_y, v_z, -phi_dot), expected, atol=FD_TOL)


# --------------------------------------------------------------------------- interaction rows


WORLD_POINTS = [(4.0, 0.3, 0.2), (2.5, -0.7, 0.9), (6.0, 1.5, 0.5)]


@pytest.mark.parametrize("robot", GEOMETRIES)
@pytest.mark.parametrize(("pose", "qdot"), CASES[:3])
@pytest.mark.parametrize("point", WORLD_POINTS)
def test_interaction_and_depth_rows_equal_finite_differences(
    robot: RobotGeometry,
    pose: tuple[float, ...],
    qdot: tuple[float, float, float],
    point: tuple[float, float, float],
) -> None:
    # Put the point in front of the camera whatever the pose: express it relative to C.
    cx, cy, phi = camera_pose(*pose, robot)
    c, s = math.cos(phi), math.sin(phi)
    fwd, left, height = point
    world = (cx + fwd * c - left * s, cy + fwd * s + left * c, height)

    def image(p: tuple[float, ...]) -> tuple[float, float, float]:
        return project_point(*camera_pose(*p, robot), robot.camera_height_m, *world)

    x_img, y_img, z = image(pose)
    plus, minus = image(propagate_pose(pose, *qdot, H)), image(propagate_pose(pose, *qdot, -H))
    x_dot, y_dot, z_dot = ((p - m) / (2 * H) for p, m in zip(plus, minus))
    screw = np.array(
        model.camera_screw(pose[3], *qdot, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    )
    assert np.dot(model.interaction_x_row(x_img, y_img, z), screw) == pytest.approx(x_dot, abs=FD_TOL)
    assert np.dot(model.interaction_y_row(y_img, z), screw) == pytest.approx(y_dot, abs=FD_TOL)
    assert np.dot(model.depth_row(y_img, z), screw) == pytest.approx(z_dot, abs=FD_TOL)
    # (13): the stacked block is the same thing
    np.testing.assert_allclose(
        model.feature_depth_rate(x_img, y_img, z, *screw), (x_dot, y_dot, z_dot), atol=FD_TOL
    )


def test_interaction_rows_fail_for_a_wrong_model() -> None:
    """The finite-difference check above can fail: a sign error in L_Y is caught."""
    robot = GEOMETRIES[0]
    pose, qdot = CASES[1]
    world = (4.0, -1.0, 0.2)

    def y_of(p: tuple[float, ...]) -> float:
        return project_point(*camera_pose(*p, robot), robot.camera_height_m, *world)[1]

    _, y_img, z = project_point(*camera_pose(*pose, robot), robot.camera_height_m, *world)
    y_dot = (y_of(propagate_pose(pose, *qdot, H)) - y_of(propagate_pose(pose, *qdot, -H))) / (2 * H)
    screw = model.camera_screw(pose[3], *qdot, 0.1, 0.0, 0.03)
    wrong = (1.0 / z, y_img / z, 1.0 + y_img * y_img)
    assert abs(np.dot(wrong, screw) - y_dot) > 1e3 * FD_TOL


# --------------------------------------------------------------------------- Jacobian of (13)


def test_feature_depth_rate_jacobian_equals_casadi_ad() -> None:
    syms = [ca.SX.sym(n) for n in ("X", "Y", "z", "vy", "vz", "wx")]
    psi = ca.vertcat(*syms[:3])
    rate = ca.vertcat(*model.feature_depth_rate(*syms))
    ad = ca.Function("ad", syms, [ca.jacobian(rate, psi)])
    rng = np.random.default_rng(7)
    for _ in range(200):
        x_img, y_img = rng.uniform(-1.0, 1.0, size=2)
        z = rng.uniform(0.2, 10.0)
        screw = rng.uniform(-2.0, 2.0, size=3)
        args = (x_img, y_img, z, *screw)
        expected = np.array(ad(*args))
        got = np.array(model.feature_depth_rate_jacobian(*args))
        # Same arithmetic in a different order: agreement to a few ulps of entries <= ~60.
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_feature_depth_rate_jacobian_structure() -> None:
    """X feeds neither Ẏ nor ż (lower block-triangular in (X, (Y, z)))."""
    jac = model.feature_depth_rate_jacobian(0.3, -0.2, 2.0, 0.1, -0.4, 0.7)
    assert jac[1][0] == 0.0 and jac[2][0] == 0.0


# --------------------------------------------------------------------------- the (Y, z) rows: rate and Jacobian


def _random_points(seed: int, n: int = 200):
    """(Y, z, V_y, V_z, Omega_x) with |Y| <= 1, z in [0.2, 10] m, |screw| <= 2 (the estimator's range and more)."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        y_img = rng.uniform(-1.0, 1.0)
        z = rng.uniform(0.2, 10.0)
        yield (y_img, z, *rng.uniform(-2.0, 2.0, size=3))


def _yz_jacobian(values: tuple[float, ...]) -> np.ndarray:
    """The 2×2 ``∂(Ẏ, ż)/∂(Y, z)`` assembled from the entries of :func:`model.yz_rate_and_jacobian`."""
    dyy_v, dyy_w, dyz, dzy, dzz = values[4:]
    return np.array([[dyy_v + dyy_w, dyz], [dzy, dzz]])


def test_yz_rate_and_jacobian_equals_casadi_ad() -> None:
    """Each part of the Jacobian is the AD of the matching part of the rate (zeros included)."""
    syms = [ca.SX.sym(n) for n in ("Y", "z", "vy", "vz", "wx")]
    yz = ca.vertcat(syms[0], syms[1])
    out = model.yz_rate_and_jacobian(*syms)
    translation, rotation = ca.vertcat(out[0], out[1]), ca.vertcat(out[2], out[3])
    ad = ca.Function("ad", syms, [ca.jacobian(translation, yz), ca.jacobian(rotation, yz)])
    for args in _random_points(11):
        jac_v, jac_w = (np.array(m) for m in ad(*args))
        got = model.yz_rate_and_jacobian(*args)
        dyy_v, dyy_w, dyz, dzy, dzz = got[4:]
        # Same arithmetic in another order: a few ulps of entries up to |V|/z² <= 100 (z >= 0.2 m).
        np.testing.assert_allclose(jac_v, [[dyy_v, dyz], [0.0, 0.0]], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(jac_w, [[dyy_w, 0.0], [dzy, dzz]], rtol=1e-12, atol=1e-12)


def test_yz_jacobian_equals_central_differences() -> None:
    """Independent of CasADi: central differences of the rate (an absolute step in Y, a relative one in z).

    The rates are quadratic in Y, so a step ``h_Y = 1e-5`` has no truncation error, only the
    rounding error ``eps |f| / h_Y`` <= 2.2e-16 × 14 / 1e-5 = 3e-10 (``|f| <= |V|/z + 2 |Ω| <= 14``).
    In z the step is relative, ``h_z = 1e-5 z``: the truncation error ``h_z² |∂³f/∂z³| / 6``, with
    the worst third derivative ``6 |Y V_z − V_y| / z⁴``, is ``1e-10 |Y V_z − V_y| / z² = 1e-10 |∂Ẏ/∂z|``;
    the rounding error ``eps |f| / h_z`` is below 3e-10 / z <= 1.5e-9 (z >= 0.2 m).  So
    ``1e-8 (1 + |entry|)`` bounds both with a wide margin (measured over 20000 draws: 1.2 % of it),
    while halving any one entry moves it by at least 4e-6 (1 + |entry|) in these draws (400 times
    the tolerance).
    """
    for args in _random_points(12):
        y_img, z = args[:2]
        screw = args[2:]

        def rate(y_: float, z_: float) -> np.ndarray:
            y_v, z_v, y_w, z_w = model.yz_rate_and_jacobian(y_, z_, *screw)[:4]
            return np.array([y_v + y_w, z_v + z_w])

        hy, hz = 1e-5, 1e-5 * z
        fd = np.column_stack([
            (rate(y_img + hy, z) - rate(y_img - hy, z)) / (2 * hy),
            (rate(y_img, z + hz) - rate(y_img, z - hz)) / (2 * hz),
        ])
        jac = _yz_jacobian(model.yz_rate_and_jacobian(*args))
        assert np.all(np.abs(fd - jac) <= 1e-8 * (1.0 + np.abs(jac))), (args, fd, jac)


def test_yz_rate_is_equation_13() -> None:
    """The two parts add up to the rows ``L_Y T`` and ``L_z T`` of (5) (written separately in this module)."""
    for y_img, z, *screw in _random_points(13):
        y_v, z_v, y_w, z_w = model.yz_rate_and_jacobian(y_img, z, *screw)[:4]
        assert y_v + y_w == pytest.approx(np.dot(model.interaction_y_row(y_img, z), screw), rel=1e-13, abs=1e-13)
        assert z_v + z_w == pytest.approx(np.dot(model.depth_row(y_img, z), screw), rel=1e-13, abs=1e-13)
        # translation and rotation: the parts are the columns (V_y, V_z) and Omega_x of the rows
        assert y_w == pytest.approx(model.interaction_y_row(y_img, z)[2] * screw[2], rel=1e-15)
        assert z_w == pytest.approx(model.depth_row(y_img, z)[2] * screw[2], rel=1e-15)


def test_x_rate_gain_is_the_x_row() -> None:
    """``Ẋ = X (k_v + k_ω)`` is ``L_X T``, and ``k_v + k_ω`` is the AD of Ẋ with respect to X."""
    x, y, z = ca.SX.sym("X"), ca.SX.sym("Y"), ca.SX.sym("z")
    vz, wx = ca.SX.sym("vz"), ca.SX.sym("wx")
    k_v, k_w = model.x_rate_gain(y, z, vz, wx)
    ad = ca.Function("ad", [x, y, z, vz, wx], [ca.jacobian(x * (k_v + k_w), x)])
    rng = np.random.default_rng(14)
    for y_img, depth, v_y, v_z, omega_x in _random_points(14):
        x_img = rng.uniform(-1.0, 1.0)
        gain = sum(model.x_rate_gain(y_img, depth, v_z, omega_x))
        row = np.dot(model.interaction_x_row(x_img, y_img, depth), (v_y, v_z, omega_x))
        assert x_img * gain == pytest.approx(row, rel=1e-13, abs=1e-13)
        assert float(ad(x_img, y_img, depth, v_z, omega_x)) == pytest.approx(gain, rel=1e-15, abs=1e-16)


def test_feature_depth_rate_is_assembled_from_the_rows() -> None:
    """The 3-point block and its 3×3 Jacobian are the single definitions, not a second copy."""
    for y_img, z, v_y, v_z, omega_x in _random_points(15, 50):
        x_img = 0.5 * y_img - 0.1
        k_v, k_w = model.x_rate_gain(y_img, z, v_z, omega_x)
        y_v, z_v, y_w, z_w, *jac = model.yz_rate_and_jacobian(y_img, z, v_y, v_z, omega_x)
        assert model.feature_depth_rate(x_img, y_img, z, v_y, v_z, omega_x) == (
            x_img * (k_v + k_w), y_v + y_w, z_v + z_w)
        block = np.array(model.feature_depth_rate_jacobian(x_img, y_img, z, v_y, v_z, omega_x))
        np.testing.assert_array_equal(block[1:, 1:], _yz_jacobian((y_v, z_v, y_w, z_w, *jac)))
        assert block[0, 0] == k_v + k_w
