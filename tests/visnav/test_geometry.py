"""Checks of visnav.geometry: exact flow, projection, proximity, occlusion measurements."""

from __future__ import annotations

import dataclasses
import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from hybrid.errors import NumericalFailure
from visnav import geometry as g
from visnav.parameters import CameraModel, Obstacle, RobotGeometry

ROBOT = RobotGeometry()
CAMERA = CameraModel()
H = 1e-5  # central-difference step (see the tolerance notes in test_model.py)

# --------------------------------------------------------------------------- wrap_angle


@pytest.mark.parametrize(
    ("angle", "expected"),
    [(0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi), (-0.5, -0.5), (7.0, 7.0 - 2 * math.pi)],
)
def test_wrap_angle(angle: float, expected: float) -> None:
    assert g.wrap_angle(angle) == pytest.approx(expected, abs=1e-15)


@given(st.floats(min_value=-1e3, max_value=1e3))
def test_wrap_angle_range_and_congruence(angle: float) -> None:
    w = g.wrap_angle(angle)
    assert -math.pi < w <= math.pi
    # congruent modulo 2 pi (rounding of 2 pi times up to 160 turns)
    turns = (angle - w) / (2 * math.pi)
    assert turns == pytest.approx(round(turns), abs=1e-12)


# --------------------------------------------------------------------------- propagate_pose


def unicycle(_t: float, state: np.ndarray, v: float, omega: float, pan_rate: float) -> list[float]:
    return [v * math.cos(state[2]), v * math.sin(state[2]), omega, pan_rate]


@pytest.mark.parametrize("omega", [0.0, 1e-12, -1e-9, 1e-6, 1e-4, 1e-3, 0.5, -2.0, 10.0])
@pytest.mark.parametrize("dt", [0.05, 1.3])
def test_propagate_pose_matches_solve_ivp(omega: float, dt: float) -> None:
    pose = (0.4, -1.2, 2.3, -0.6)
    v, pan_rate = 0.7, 0.9
    ref = solve_ivp(unicycle, (0.0, dt), pose, method="DOP853", rtol=1e-12, atol=1e-14, args=(v, omega, pan_rate))
    # DOP853 at rtol 1e-12 over <= 13 rad of heading change: global error ~1e-11.
    np.testing.assert_allclose(g.propagate_pose(pose, v, omega, pan_rate, dt), ref.y[:, -1], rtol=0, atol=1e-10)


getcontext().prec = 50


def _dsin(x: Decimal) -> Decimal:
    term, total, k = x, x, 1
    while abs(term) > Decimal(10) ** -45:
        term = -term * x * x / ((2 * k) * (2 * k + 1))
        total += term
        k += 1
    return total


def _dcos(x: Decimal) -> Decimal:
    term, total, k = Decimal(1), Decimal(1), 1
    while abs(term) > Decimal(10) ** -45:
        term = -term * x * x / ((2 * k - 1) * (2 * k))
        total += term
        k += 1
    return total


@pytest.mark.parametrize("omega", [1e-15, 3e-9, 2e-5, 1.999e-3, 2.001e-3, 0.3, 7.0])
def test_propagate_pose_is_accurate_to_machine_precision(omega: float) -> None:
    """Against the closed form evaluated in 50-digit decimal arithmetic (no cancellation there).

    ``omega dt / 2`` straddles SINC_SERIES_THRESHOLD (1e-4 at dt = 0.1) to check both branches.
    """
    x0, y0, th0, v, dt = 0.25, -0.5, 1.1, 0.8, 0.1
    x, y, th, _ = g.propagate_pose((x0, y0, th0, 0.0), v, omega, 0.0, dt)
    d_om, d_th, d_dt, d_v = (Decimal(repr(q)) for q in (omega, th0, dt, v))
    th1 = d_th + d_om * d_dt
    x_ref = Decimal(repr(x0)) + d_v * (_dsin(th1) - _dsin(d_th)) / d_om
    y_ref = Decimal(repr(y0)) - d_v * (_dcos(th1) - _dcos(d_th)) / d_om
    # The displacement (0.08 m) is computed to a few ulps of itself; adding x0 costs one ulp of x0.
    assert abs(x - float(x_ref)) <= 4 * math.ulp(0.5)
    assert abs(y - float(y_ref)) <= 4 * math.ulp(0.5)
    assert th == th0 + omega * dt


def test_propagate_pose_is_a_flow() -> None:
    pose = (1.0, 2.0, -0.3, 0.2)
    q = (0.3, -0.8, 0.4)
    once = g.propagate_pose(pose, *q, 0.7)
    twice = g.propagate_pose(g.propagate_pose(pose, *q, 0.3), *q, 0.4)
    np.testing.assert_allclose(once, twice, rtol=0, atol=1e-15)
    back = g.propagate_pose(once, *q, -0.7)
    np.testing.assert_allclose(back, pose, rtol=0, atol=1e-15)


def test_propagate_pose_does_not_wrap_angles() -> None:
    _, _, theta, pan = g.propagate_pose((0.0, 0.0, 3.0, 3.0), 0.0, 1.0, 1.0, 1.0)
    assert theta == 4.0 and pan == 4.0


# --------------------------------------------------------------------------- camera and projection


def test_camera_pose_offsets() -> None:
    robot = RobotGeometry(pan_offset_m=0.1, camera_forward_m=0.05, camera_lateral_m=0.03)
    cx, cy, phi = g.camera_pose(1.0, 2.0, 0.0, math.pi / 2, robot)
    # P = (1.1, 2); pan frame forward = +y, left = -x
    assert phi == pytest.approx(math.pi / 2)
    assert (cx, cy) == pytest.approx((1.1 - 0.03, 2.0 + 0.05), abs=1e-15)


def test_project_point_conventions() -> None:
    # camera at origin looking along +x: a point ahead-left and below the camera
    x_img, y_img, z = g.project_point(0.0, 0.0, 0.0, 0.5, 2.0, 0.4, 0.1)
    assert z == 2.0
    assert y_img == pytest.approx(0.2)  # left is +Y
    assert x_img == pytest.approx(0.2)  # below is +X (x_C points down)
    # looking along +y, the same construction
    x_img, y_img, z = g.project_point(1.0, 1.0, math.pi / 2, 0.5, 0.6, 3.0, 0.9)
    assert (x_img, y_img, z) == pytest.approx((-0.2, 0.2, 2.0))


def test_project_points_agrees_with_project_point() -> None:
    pts = ((2.0, 0.4, 0.1), (3.0, -1.0, 0.7))
    cam = (0.1, -0.2, 0.3)
    assert g.project_points(*cam, 0.5, pts) == tuple(g.project_point(*cam, 0.5, *p) for p in pts)


def test_points_behind_the_camera_raise() -> None:
    with pytest.raises(NumericalFailure, match=r"point 1 at \(-2, 0, 0\.3\) has depth z = -2 m"):
        g.project_points(0.0, 0.0, 0.0, 0.5, ((1.0, 0.0, 0.3), (-2.0, 0.0, 0.3)))
    with pytest.raises(NumericalFailure, match=r"depth z = 0 m: expected z > 0"):
        g.project_point(0.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.3)


# --------------------------------------------------------------------------- proximity

OBSTACLE = Obstacle(name="pillar", center_m=(2.0, 0.5), radius_m=0.3, height_m=1.0)
LOW = Obstacle(name="box", center_m=(2.0, 0.5), radius_m=0.3, height_m=0.2)


def test_nearest_obstacle() -> None:
    obstacles = (OBSTACLE, Obstacle(name="b", center_m=(0.0, -1.0), radius_m=0.2, height_m=1.0))
    index, d = g.nearest_obstacle(0.0, 0.0, obstacles)
    assert index == 1 and d == pytest.approx(0.8)
    assert g.nearest_obstacle(0.0, 0.0, ()) == (-1, math.inf)
    index, d = g.nearest_obstacle(2.0, 0.6, obstacles)
    assert index == 0 and d == pytest.approx(-0.2)  # inside: negative


@pytest.mark.parametrize(("center", "expected"), [((2.0, 0.3), 1), ((2.0, -0.3), -1), ((2.0, 0.0), 1)])
def test_choose_bypass_side(center: tuple[float, float], expected: int) -> None:
    obstacle = dataclasses.replace(OBSTACLE, center_m=center)
    assert g.choose_bypass_side(0.0, 0.0, 0.0, obstacle) == expected


def test_bypass_side_turns_away_from_the_obstacle() -> None:
    """Ahead-left obstacle: side +1, and the travel tangent points to the right of the heading."""
    side = g.choose_bypass_side(0.0, 0.0, 0.0, OBSTACLE)
    prox = g.proximity(0.0, 0.0, 0.0, OBSTACLE, side)
    # alpha = -side wrap(theta - theta_t) < 0: the robot heads towards the obstacle side of the tangent
    assert side == 1 and prox.alpha < 0
    # aligned with the tangent and kept on the left: the centre is on the left of the heading
    theta_t = side * prox.alpha  # alpha = -side (theta - theta_t) with theta = 0
    assert math.cos(theta_t) * 0.5 - math.sin(theta_t) * 2.0 > 0


def test_proximity_values() -> None:
    # M on the +x side of the centre, heading +y: counter-clockwise motion, obstacle on the left
    prox = g.proximity(3.0, 0.5, math.pi / 2, OBSTACLE, 1)
    assert prox.d_coll == pytest.approx(0.7) and prox.rho == pytest.approx(1.0)
    assert prox.alpha == pytest.approx(0.0, abs=1e-15) and prox.curvature == pytest.approx(1 / 0.3)
    # the same heading with side -1 is backwards along the clockwise tangent
    assert abs(g.proximity(3.0, 0.5, math.pi / 2, OBSTACLE, -1).alpha) == pytest.approx(math.pi)
    # heading straight away from the obstacle: alpha = +pi/2 (d_coll increases at rate v)
    assert g.proximity(3.0, 0.5, 0.0, OBSTACLE, 1).alpha == pytest.approx(math.pi / 2)
    assert g.proximity(3.0, 0.5, 0.0, OBSTACLE, -1).alpha == pytest.approx(math.pi / 2)


def test_proximity_at_centre_raises() -> None:
    with pytest.raises(NumericalFailure, match="centre of obstacle 'pillar'.*rho = 0.0"):
        g.proximity(2.0, 0.5, 0.0, OBSTACLE, 1)


@given(
    x=st.floats(-1.5, 5.0),
    y=st.floats(-2.0, 3.0),
    theta=st.floats(-7.0, 7.0),
    v=st.floats(-0.5, 0.5),
    omega=st.floats(-1.5, 1.5),
    side=st.sampled_from([1, -1]),
)
@settings(deadline=None)
def test_proximity_derivatives_by_finite_differences(
    x: float, y: float, theta: float, v: float, omega: float, side: int
) -> None:
    prox = g.proximity(x, y, theta, OBSTACLE, side)
    if prox.rho < 0.2 or abs(prox.alpha) > 3.0:
        return  # too close to the centre, or at the wrap of alpha (heading opposite to the tangent)
    pose = (x, y, theta, 0.0)
    plus = g.propagate_pose(pose, v, omega, 0.0, H)
    minus = g.propagate_pose(pose, v, omega, 0.0, -H)
    p_plus, p_minus = g.proximity(*plus[:3], OBSTACLE, side), g.proximity(*minus[:3], OBSTACLE, side)
    d_dot = (p_plus.d_coll - p_minus.d_coll) / (2 * H)
    a_dot = (p_plus.alpha - p_minus.alpha) / (2 * H)
    # second derivatives are <= v²/rho² + ... ~ 10, so truncation <= 2e-10
    assert d_dot == pytest.approx(v * math.sin(prox.alpha), abs=1e-8)
    assert a_dot == pytest.approx(-side * omega + v * math.cos(prox.alpha) / prox.rho, abs=1e-8)


# --------------------------------------------------------------------------- occluder interval


def tangent_checks(cam: tuple[float, float, float], obstacle: Obstacle) -> None:
    cx, cy, phi = cam
    y_minus, y_plus, z_minus, z_plus = g.occluder_interval(cx, cy, phi, obstacle)
    assert y_minus < y_plus
    ox, oy = obstacle.center_m
    zc = (math.cos(phi), math.sin(phi))
    yc = (-math.sin(phi), math.cos(phi))
    for y_img, z in ((y_minus, z_minus), (y_plus, z_plus)):
        # ray direction in the world and the tangent point at depth z on it
        d = (zc[0] + y_img * yc[0], zc[1] + y_img * yc[1])
        norm = math.hypot(*d)
        dist_line = abs(d[0] * (oy - cy) - d[1] * (ox - cx)) / norm
        assert dist_line == pytest.approx(obstacle.radius_m, rel=1e-12)
        point = (cx + z * d[0], cy + z * d[1])
        assert math.hypot(point[0] - ox, point[1] - oy) == pytest.approx(obstacle.radius_m, rel=1e-12)
    # the trigonometric definition: tan(beta_c +- asin(R / dist))
    beta_c = math.atan2(-(ox - cx) * math.sin(phi) + (oy - cy) * math.cos(phi),
                        (ox - cx) * math.cos(phi) + (oy - cy) * math.sin(phi))
    half = math.asin(obstacle.radius_m / math.hypot(ox - cx, oy - cy))
    assert y_minus == pytest.approx(math.tan(beta_c - half), rel=1e-12, abs=1e-14)
    assert y_plus == pytest.approx(math.tan(beta_c + half), rel=1e-12, abs=1e-14)


@pytest.mark.parametrize(
    "cam", [(0.0, 0.0, 0.0), (0.5, 1.0, -0.3), (1.0, -0.5, 1.2), (4.0, 0.5, math.pi), (1.4, 0.5, 0.0)]
)
def test_occluder_interval_rays_are_tangent(cam: tuple[float, float, float]) -> None:
    tangent_checks(cam, OBSTACLE)


@pytest.mark.parametrize(
    ("cam", "why"),
    [
        ((2.0, 0.6, 0.0), "camera inside"),
        ((2.3, 0.5, 0.0), "camera on the circle"),
        ((3.0, 0.5, 0.0), "obstacle behind"),
        ((2.0, -0.2, 0.0), "obstacle beside: a tangent bearing beyond 90 degrees"),
    ],
)
def test_occluder_interval_none(cam: tuple[float, float, float], why: str) -> None:
    assert g.occluder_interval(*cam, OBSTACLE) is None, why


# --------------------------------------------------------------------------- point_hidden


def brute_force_min_distance(c: tuple[float, float], w: tuple[float, float], o: tuple[float, float]) -> float:
    t = np.linspace(0.0, 1.0, 20001)
    px = c[0] + t * (w[0] - c[0])
    py = c[1] + t * (w[1] - c[1])
    return float(np.min(np.hypot(px - o[0], py - o[1])))


def test_point_hidden_against_sampling() -> None:
    rng = np.random.default_rng(3)
    checked = hidden_count = 0
    for _ in range(400):
        c = tuple(rng.uniform(-2, 2, size=2))
        w = tuple(rng.uniform(-2, 2, size=2))
        r = rng.uniform(0.1, 0.8)
        o = tuple(rng.uniform(-2, 2, size=2))
        obstacle = Obstacle(name="o", center_m=o, radius_m=r, height_m=1.0)
        d = brute_force_min_distance(c, w, o)
        # segments <= 5.7 m long sampled every 2.9e-4 m: the sampled minimum exceeds the
        # true one by < 1.1e-4 m, so decide only outside a 1e-3 m band around the circle.
        if abs(d - r) < 1e-3:
            continue
        checked += 1
        hidden = g.point_hidden(c[0], c[1], w[0], w[1], obstacle)
        hidden_count += hidden
        assert hidden == (d < r), (c, w, o, r, d)
    assert checked > 350 and 50 < hidden_count < checked - 50  # both outcomes exercised


def test_point_hidden_edge_cases() -> None:
    # C inside the disc hides everything, W inside the disc is hidden, the disc beyond W does not hide it
    assert g.point_hidden(2.0, 0.5, 5.0, 5.0, OBSTACLE)
    assert g.point_hidden(0.0, 0.0, 2.1, 0.5, OBSTACLE)
    assert not g.point_hidden(0.0, 0.5, 1.5, 0.5, OBSTACLE)
    quarter = dataclasses.replace(OBSTACLE, radius_m=0.25)  # exact binary fractions below
    assert g.point_hidden(0.0, 0.5, 1.75, 0.5, quarter)  # W exactly on the circle: closed disc
    assert not g.point_hidden(0.0, 0.5, 1.75 - 2**-40, 0.5, quarter)
    assert not g.point_hidden(0.0, 0.81, 4.0, 0.81, OBSTACLE)


# --------------------------------------------------------------------------- image measurements

TARGET = ((4.0, -0.1, 0.4), (4.0, 0.1, 0.4), (4.0, 0.1, 0.6), (4.0, -0.1, 0.6))
TALL = Obstacle(name="tall", center_m=(2.0, 0.45), radius_m=0.2, height_m=1.0)


def measure(pose, world=TARGET, obstacles=(TALL,), camera=CAMERA):
    cam = g.camera_pose(*pose, ROBOT)
    feats = g.project_points(*cam, ROBOT.camera_height_m, world)
    return g.image_measurement(cam, ROBOT.camera_height_m, feats, world, obstacles, camera), cam, feats


def test_image_measurement_basic_values() -> None:
    meas, cam, feats = measure((0.0, 0.0, 0.0, 0.0))
    y_minus, y_plus, z_minus, z_plus = g.occluder_interval(*cam, TALL)
    assert meas.occluder_index == 0
    assert (meas.y_o_minus, meas.y_o_plus, meas.z_o_minus, meas.z_o_plus) == (y_minus, y_plus, z_minus, z_plus)
    assert meas.in_view == meas.visible == (True,) * 4 and meas.occluded == (False,) * 4
    # the silhouette is left of the target: features on its - side, nearest border Y-
    assert meas.feature_side == -1 and meas.occ_border == -1 and meas.occ_sign == -1
    f = CAMERA.focal_px
    expected = f * min(abs(ft[1] - b) for ft in feats for b in (y_minus, y_plus))
    assert meas.d_occ_px == pytest.approx(expected, rel=1e-15)
    assert meas.nearest_feature in (1, 2)  # the two left points share Y
    assert meas.d_bord_px == pytest.approx(f * (CAMERA.y_limit - y_minus), rel=1e-15)


def test_image_measurement_is_a_frozen_dataclass() -> None:
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0))
    rebuilt = g.ImageMeasurement(**{f.name: getattr(meas, f.name) for f in dataclasses.fields(meas)})
    assert rebuilt == meas
    with pytest.raises(dataclasses.FrozenInstanceError):
        meas.d_occ_px = 0.0  # type: ignore[misc]
    prox = g.proximity(0.0, 0.0, 0.0, TALL, 1)
    assert prox == g.Proximity(d_coll=prox.d_coll, alpha=prox.alpha, rho=prox.rho, curvature=5.0, side=1)


def test_occluded_flags_agree_with_point_hidden() -> None:
    rng = np.random.default_rng(11)
    obstacles = (TALL, Obstacle(name="t2", center_m=(3.0, -0.3), radius_m=0.15, height_m=2.0), LOW)
    for _ in range(200):
        pose = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))
        meas, cam, _ = measure(pose, obstacles=obstacles)
        expected = tuple(
            any(g.point_hidden(cam[0], cam[1], w[0], w[1], o) for o in obstacles[:2]) for w in TARGET
        )
        assert meas.occluded == expected
        assert meas.visible == tuple(a and not b for a, b in zip(meas.in_view, meas.occluded))


def test_low_obstacles_never_occlude() -> None:
    # camera at y = 0.45 behind the low obstacle: every sight line crosses its disc
    world = ((4.0, 0.4, 0.4), (4.0, 0.5, 0.4), (4.0, 0.5, 0.6), (4.0, 0.4, 0.6))
    low = dataclasses.replace(LOW, center_m=(2.0, 0.45))
    meas, cam, _ = measure((0.0, 0.45 - ROBOT.camera_lateral_m, 0.0, 0.0), world=world, obstacles=(low,))
    assert all(g.point_hidden(cam[0], cam[1], w[0], w[1], low) for w in world)
    assert meas.occluded == (False,) * 4 and meas.occluder_index == -1
    assert meas.d_occ_px == math.inf and meas.d_bord_px == math.inf and meas.feature_side == 0
    assert all(math.isnan(v) for v in (meas.y_o_minus, meas.y_o_plus, meas.z_o_minus, meas.z_o_plus))
    # the same obstacle made tall hides all four points and gives d_occ = 0
    meas, _, _ = measure((0.0, 0.45 - ROBOT.camera_lateral_m, 0.0, 0.0), world=world,
                         obstacles=(dataclasses.replace(low, height_m=0.5),))
    assert meas.occluded == (True,) * 4 and meas.d_occ_px == 0.0 and meas.occluder_index == 0


def test_in_view_limits() -> None:
    # the camera is at x = Dx = 0.1, so the points are at depth 4
    world = ((4.1, 0.0, 0.5), (4.1, 4.0 * 0.65, 0.5), (4.1, 0.0, 0.5 - 4.0 * 0.47), (4.1, -2.0, 0.5))
    meas, _, feats = measure((0.0, -ROBOT.camera_lateral_m, 0.0, 0.0), world=world, obstacles=())
    # Y_max = 0.64, X_max = 0.48
    assert meas.in_view == (True, False, True, True)
    assert feats[2][0] == pytest.approx(0.47)


def moving_point_measurements(us: np.ndarray) -> list[tuple[float, bool]]:
    """A target whose point 0 slides left behind TALL; the other three stay clear on the right."""
    out = []
    for u in us:
        world = ((4.0, u, 0.5), (4.0, -0.6, 0.4), (4.0, -0.4, 0.4), (4.0, -0.5, 0.6))
        meas, _, _ = measure((0.0, 0.0, 0.0, 0.0), world=world)
        out.append((meas.d_occ_px, meas.occluded[0]))
    return out


def test_d_occ_is_continuous_when_a_point_enters_the_silhouette() -> None:
    us = np.linspace(0.0, 0.6, 6001)  # du = 1e-4 m
    values = moving_point_measurements(us)
    d_occ = np.array([d for d, _ in values])
    hidden = np.array([h for _, h in values])
    first_hidden = int(np.argmax(hidden))
    assert 0 < first_hidden and hidden[first_hidden:].all()
    assert (d_occ[first_hidden:] == 0.0).all()
    # Y = (u - cy)/z with z ~ 4: d_occ moves by f du / z ~ 0.0125 px per step before and through the entry
    jumps = np.abs(np.diff(d_occ[: first_hidden + 1]))
    assert jumps.max() < 0.02
    assert d_occ[first_hidden - 1] < 0.02
    # and the point approached the silhouette border from the right: nearest border Y-
    assert (np.diff(d_occ[first_hidden - 200 : first_hidden]) < 0).all()


def test_d_occ_without_visible_feature_is_infinite() -> None:
    # all points outside the image (far left), the occluder in front but hiding none
    world = ((4.0, 3.5, 0.5), (4.0, 3.6, 0.5), (4.0, 3.7, 0.5), (4.0, 3.8, 0.5))
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0), world=world)
    assert meas.occluder_index == 0 and meas.visible == (False,) * 4
    assert meas.d_occ_px == math.inf and meas.nearest_feature == -1


def test_d_bord_definition_cases() -> None:
    f, y_lim = CAMERA.focal_px, CAMERA.y_limit
    # features on the + (left) side: distance from Y+ to the right image side -y_lim
    right = dataclasses.replace(TALL, center_m=(2.0, -0.45))
    meas, cam, _ = measure((0.0, 0.0, 0.0, 0.0), obstacles=(right,))
    assert meas.feature_side == 1 and meas.occ_border == 1
    assert meas.d_bord_px == pytest.approx(f * (meas.y_o_plus + y_lim), rel=1e-15)
    # the occluder beyond the right image side (entirely out of the image): d_bord = 0
    far_right = dataclasses.replace(TALL, center_m=(1.0, -1.2), radius_m=0.1)
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0), obstacles=(far_right,))
    assert meas.occluder_index == 0 and meas.y_o_plus < -y_lim
    assert meas.feature_side == 1 and meas.d_bord_px == 0.0
    # features on the - side: distance from Y- to the left image side +y_lim
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0))
    assert meas.feature_side == -1
    assert meas.d_bord_px == pytest.approx(f * (y_lim - meas.y_o_minus), rel=1e-15)
    far_left = dataclasses.replace(TALL, center_m=(1.0, 1.2), radius_m=0.1)
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0), obstacles=(far_left,))
    assert meas.feature_side == -1 and meas.y_o_minus > y_lim and meas.d_bord_px == 0.0


def test_occluder_is_the_obstacle_with_smallest_d_occ() -> None:
    near_target = dataclasses.replace(TALL, name="close", center_m=(2.0, -0.35))
    meas, _, _ = measure((0.0, 0.0, 0.0, 0.0), obstacles=(TALL, near_target))
    alone = [measure((0.0, 0.0, 0.0, 0.0), obstacles=(o,))[0].d_occ_px for o in (TALL, near_target)]
    assert meas.occluder_index == int(np.argmin(alone)) == 1
    assert meas.d_occ_px == min(alone)


def test_image_measurement_argument_errors() -> None:
    with pytest.raises(ValueError, match="4 features and 3 world points"):
        g.image_measurement((0.0, 0.0, 0.0), 0.5, ((0.0, 0.0, 1.0),) * 4, TARGET[:3], (), CAMERA)
