"""The paper's controllers (7), (9), (11)-(12), (16)-(19), on floats and tuples.

Each controller is a small pure function on Python floats (the closed loop
evaluates them every 50 ms sample, 1000 times faster than real time, so a
whole sample must cost less than 50 µs).  Small linear algebra (3×3 normal
equations, a 2×3 pseudo-inverse) is written out with scalar arithmetic.  The
kinematic matrices come from :mod:`visnav.model`, the single source of truth.

All joint-rate results are tuples ``(v, omega, pan_rate)`` [m/s, rad/s, rad/s].
Design choices are documented in ``docs/model.md``.
"""

from __future__ import annotations

import math

from hybrid.errors import NumericalFailure
from visnav import model
from visnav.geometry import ImageMeasurement, Proximity
from visnav.parameters import CameraModel, Envelopes, RobotGeometry

__all__ = [
    "RELATIVE_SINGULARITY_TOLERANCE",
    "PAN_SINGULARITY_TOLERANCE",
    "D_OCC_FLOOR_PX",
    "visual_servoing_error",
    "visual_servoing",
    "path_following",
    "pan_tracking",
    "occlusion_task",
    "occlusion_avoidance",
    "avoidance_control",
    "blend",
]

#: A Gram matrix ``G`` counts as singular when ``det G / prod(diag G)`` (the
#: determinant of its correlation matrix, 1 for orthogonal columns, 0 for
#: dependent ones, invariant to the units of the columns) is below this.
RELATIVE_SINGULARITY_TOLERANCE = 1e-10

#: ``|L_Ygc J_pan|`` below which the pan cannot move the gravity centre.
PAN_SINGULARITY_TOLERANCE = 1e-9

#: Lower clamp of ``d_occ`` inside ``cot((pi/2) d_occ / D+)`` [px]: avoids the pole at 0.
D_OCC_FLOOR_PX = 0.5

Joint = tuple[float, float, float]


def _solve_sym3(
    a11: float, a12: float, a13: float, a22: float, a23: float, a33: float, b1: float, b2: float, b3: float, what: str
) -> tuple[float, float, float]:
    """Solve the symmetric positive semi-definite system ``A u = b`` by cofactors."""
    c11 = a22 * a33 - a23 * a23
    c12 = a13 * a23 - a12 * a33
    c13 = a12 * a23 - a13 * a22
    det = a11 * c11 + a12 * c12 + a13 * c13
    scale = a11 * a22 * a33
    if not (scale > 0.0 and det > RELATIVE_SINGULARITY_TOLERANCE * scale):
        raise NumericalFailure(
            f"{what}: L^T L is singular (det = {det:.3g}, det/prod(diag) = "
            f"{(det / scale) if scale else math.nan:.3g}, expected > {RELATIVE_SINGULARITY_TOLERANCE:g}); "
            "the image points are degenerate (coincident or too few), check the target and the depths"
        )
    c22 = a11 * a33 - a13 * a13
    c23 = a12 * a13 - a11 * a23
    c33 = a11 * a22 - a12 * a12
    inv = 1.0 / det
    return (
        (c11 * b1 + c12 * b2 + c13 * b3) * inv,
        (c12 * b1 + c22 * b2 + c23 * b3) * inv,
        (c13 * b1 + c23 * b2 + c33 * b3) * inv,
    )


def visual_servoing_error(
    features: tuple[tuple[float, float, float], ...],
    desired: tuple[tuple[float, float], ...],
    interaction_at: tuple[tuple[float, float, float], ...] | None = None,
) -> tuple[float, float, float]:
    """``e_VS = C (s - s*)``, ``C = (L^T L)^{-1} L^T``.

    ``L`` stacks the rows ``L_X, L_Y`` of every point evaluated at
    ``interaction_at`` (``(X, Y, z)`` per point): the current features by
    default, or e.g. the desired ones ``(X*, Y*, z*)`` for the classical
    constant ``C = L*^+``.  The result lives in screw space ``(V_y, V_z, Omega_x)``.

    Raises
    ------
    NumericalFailure
        If ``L^T L`` is singular relative to its scale (coincident points,
        fewer than two points) or not finite.
    """
    if len(features) != len(desired):
        raise ValueError(f"visual_servoing: {len(features)} features but {len(desired)} desired points")
    a11 = a12 = a13 = a22 = a23 = a33 = b1 = b2 = b3 = 0.0
    x_row, y_row = model.interaction_x_row, model.interaction_y_row
    at = features if interaction_at is None else interaction_at
    if len(at) != len(features):
        raise ValueError(f"visual_servoing: {len(features)} features but {len(at)} interaction points")
    for (x, y, _), (xd, yd), (xl, yl, zl) in zip(features, desired, at):
        _, lx2, lx3 = x_row(xl, yl, zl)  # first entry is 0
        ly1, ly2, ly3 = y_row(yl, zl)
        ex, ey = x - xd, y - yd
        a11 += ly1 * ly1
        a12 += ly1 * ly2
        a13 += ly1 * ly3
        a22 += lx2 * lx2 + ly2 * ly2
        a23 += lx2 * lx3 + ly2 * ly3
        a33 += lx3 * lx3 + ly3 * ly3
        b1 += ly1 * ey
        b2 += lx2 * ex + ly2 * ey
        b3 += lx3 * ex + ly3 * ey
    return _solve_sym3(a11, a12, a13, a22, a23, a33, b1, b2, b3, "visual_servoing")


def visual_servoing(
    features: tuple[tuple[float, float, float], ...],
    desired: tuple[tuple[float, float], ...],
    pan: float,
    robot: RobotGeometry,
    lambda_vs: float,
    interaction_at: tuple[tuple[float, float, float], ...] | None = None,
) -> Joint:
    """Nominal visual servoing (7): ``q̇_VS = -lambda_vs J_r^{-1} e_VS``.

    ``interaction_at`` selects where ``L`` (hence ``C``) is evaluated, see
    :func:`visual_servoing_error`; the closed loop uses the desired features.

    Parameters
    ----------
    features : tuple of (X, Y, z)
        Current normalised image coordinates and depths [-, -, m].
    desired : tuple of (X*, Y*)
        Desired image coordinates.
    pan : float
        Pan angle [rad].
    robot : RobotGeometry
    lambda_vs : float
        Gain [1/s].
    """
    e1, e2, e3 = visual_servoing_error(features, desired, interaction_at)
    return model.joint_rates_from_screw(
        pan,
        -lambda_vs * e1,
        -lambda_vs * e2,
        -lambda_vs * e3,
        robot.pan_offset_m,
        robot.camera_forward_m,
        robot.camera_lateral_m,
    )


def path_following(prox: Proximity, d_zero: float, v_coll: float, k: float) -> tuple[float, float]:
    """Base avoidance controller (11)-(12) in the path frame of :func:`visnav.geometry.proximity`.

    ``delta = d_coll - d0``; ``omega = side v (k delta + alpha + 2k sin alpha + cos(alpha)/rho)``,
    i.e. (11) with the exact curvature term ``chi = -1/rho`` and ``omega_path = -side omega``.
    In closed loop ``delta' = v sin alpha`` and ``alpha' = -v (k delta + alpha + 2k sin alpha)``.

    Returns
    -------
    (v, omega) : tuple of float
    """
    omega = model.path_following_omega(prox.d_coll - d_zero, prox.alpha, 1.0 / prox.rho, prox.side, v_coll, k)
    return (v_coll, omega)


def pan_tracking(
    features: tuple[tuple[float, float, float], ...],
    pan: float,
    v: float,
    omega: float,
    robot: RobotGeometry,
    lambda_gc: float,
    y_gc_desired: float,
) -> float:
    """Pan-platform control (16) (or (17) with reconstructed features): the pan rate.

    ``e_gc = Y_gc - Y*_gc`` with ``Y_gc`` the mean of the points' ``Y``;
    ``L_Ygc`` is the mean of the points' ``L_Y`` rows, the exact derivative of
    the mean (the paper evaluates ``L_Y`` at the centroid instead), so that in
    closed loop ``e_gc' = -lambda_gc e_gc`` exactly.

    Raises
    ------
    NumericalFailure
        If the pan cannot move ``Y_gc`` (``|L_Ygc J_pan| < PAN_SINGULARITY_TOLERANCE``).
    """
    n = len(features)
    if n == 0:
        raise NumericalFailure("pan_tracking: no feature given (expected at least one point)")
    sy = s_inv_z = s_y_z = s_yy = 0.0
    for _, y, z in features:
        inv_z = 1.0 / z
        sy += y
        s_inv_z += inv_z
        s_y_z += y * inv_z
        s_yy += y * y
    inv_n = 1.0 / n
    # mean of L_Y rows (-1/z, Y/z, 1 + Y^2), see model.interaction_y_row
    l1, l2, l3 = -s_inv_z * inv_n, s_y_z * inv_n, 1.0 + s_yy * inv_n
    a, b, dx = robot.camera_forward_m, robot.camera_lateral_m, robot.pan_offset_m
    t1, t2, t3 = model.camera_screw(pan, v, omega, 0.0, dx, a, b)
    j1, j2, j3 = model.pan_column(a, b)
    gain = l1 * j1 + l2 * j2 + l3 * j3
    if not abs(gain) >= PAN_SINGULARITY_TOLERANCE:
        raise NumericalFailure(
            f"pan_tracking: L_Ygc J_pan = {gain:.3g}, expected |.| >= {PAN_SINGULARITY_TOLERANCE:g}: "
            "the pan rate cannot move the gravity centre (check depths and camera offsets)"
        )
    e_gc = sy * inv_n - y_gc_desired
    return -(lambda_gc * e_gc + l1 * t1 + l2 * t2 + l3 * t3) / gain


def occlusion_task(
    features: tuple[tuple[float, float, float], ...],
    meas: ImageMeasurement,
    pan: float,
    robot: RobotGeometry,
    camera: CameraModel,
    envelopes: Envelopes,
) -> tuple[tuple[float, float], tuple[tuple[float, float, float], tuple[float, float, float]]]:
    """Primary occlusion task ``e_O`` of (9) and its Jacobian ``W_O = ∂e_O/∂q`` (2×3).

    ``e_O = (cot((pi/2) d̄/D+), d_bord)`` with ``d̄ = clamp(d_occ, D_OCC_FLOOR_PX, D+)``.
    ``W_O`` is the chain rule through ``d_occ = occ_sign f (Y_j - Y_occ)`` and
    ``d_bord = ±f (Y_border ± Y_max)``, with the image motion of the silhouette
    borders equal to that of their tangent points (envelope theorem).  The
    derivative of the cotangent is taken at the clamped argument (the clamp
    acts on the value only), and that of ``d_bord`` ignores its floor at 0, so
    ``W_O`` keeps full rank at the clamps.

    Raises
    ------
    NumericalFailure
        Without occluder in front or without feature to protect.
    """
    if meas.occluder_index < 0:
        raise NumericalFailure(
            "occlusion_avoidance: no occluder in front of the camera (meas.occluder_index = -1); "
            "the occlusion task is undefined, do not call it when mu_occ = 0"
        )
    j = meas.nearest_feature
    if j < 0:
        raise NumericalFailure(
            f"occlusion_avoidance: no visible or hidden feature near occluder {meas.occluder_index} "
            f"(d_occ = {meas.d_occ_px!r} px); the occlusion task is undefined"
        )
    f, d_plus = camera.focal_px, envelopes.D_plus_px
    # e_O
    d_bar = min(max(meas.d_occ_px, D_OCC_FLOOR_PX), d_plus)
    arg = 0.5 * math.pi * d_bar / d_plus
    sin_arg = math.sin(arg)
    e1 = math.cos(arg) / sin_arg
    e2 = meas.d_bord_px
    dcot = -0.5 * math.pi / (d_plus * sin_arg * sin_arg)  # d e1 / d d_occ
    # rows in screw space
    _, yj, zj = features[j]
    if meas.occ_border > 0:
        y_occ, z_occ = meas.y_o_plus, meas.z_o_plus
    else:
        y_occ, z_occ = meas.y_o_minus, meas.z_o_minus
    lf = model.interaction_y_row(yj, zj)
    lo = model.interaction_y_row(y_occ, z_occ)
    k1 = dcot * meas.occ_sign * f
    r1 = (k1 * (lf[0] - lo[0]), k1 * (lf[1] - lo[1]), k1 * (lf[2] - lo[2]))
    if meas.feature_side > 0:
        lb = model.interaction_y_row(meas.y_o_plus, meas.z_o_plus)
        k2 = f
    else:
        lb = model.interaction_y_row(meas.y_o_minus, meas.z_o_minus)
        k2 = -f
    r2 = (k2 * lb[0], k2 * lb[1], k2 * lb[2])
    (j11, j12, j13), (j21, j22, j23), (j31, j32, j33) = model.reduced_jacobian(
        pan, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m
    )
    w1 = (
        r1[0] * j11 + r1[1] * j21 + r1[2] * j31,
        r1[0] * j12 + r1[1] * j22 + r1[2] * j32,
        r1[0] * j13 + r1[1] * j23 + r1[2] * j33,
    )
    w2 = (
        r2[0] * j11 + r2[1] * j21 + r2[2] * j31,
        r2[0] * j12 + r2[1] * j22 + r2[2] * j32,
        r2[0] * j13 + r2[1] * j23 + r2[2] * j33,
    )
    return (e1, e2), (w1, w2)


def occlusion_avoidance(
    features: tuple[tuple[float, float, float], ...],
    desired: tuple[tuple[float, float], ...],
    meas: ImageMeasurement,
    pan: float,
    robot: RobotGeometry,
    camera: CameraModel,
    envelopes: Envelopes,
    lambda_occ: float,
    beta_occ: float,
) -> Joint:
    """Occlusion avoidance (8)-(9): ``q̇_occ = -lambda_occ (W_O^+ e_O + beta_occ (I - W_O^+ W_O) g_s)``.

    ``g_s = ((s - s*)^T L J_r)^T`` over the visible features (the gradient of
    ``|s - s*|²/2``); ``W_O^+ = W_O^T (W_O W_O^T)^{-1}``.

    Raises
    ------
    NumericalFailure
        Without occluder (``meas.occluder_index < 0``) or if ``W_O W_O^T`` is singular.
    """
    (e1, e2), (w1, w2) = occlusion_task(features, meas, pan, robot, camera, envelopes)
    g11 = w1[0] * w1[0] + w1[1] * w1[1] + w1[2] * w1[2]
    g12 = w1[0] * w2[0] + w1[1] * w2[1] + w1[2] * w2[2]
    g22 = w2[0] * w2[0] + w2[1] * w2[1] + w2[2] * w2[2]
    det = g11 * g22 - g12 * g12
    scale = g11 * g22
    if not (scale > 0.0 and det > RELATIVE_SINGULARITY_TOLERANCE * scale):
        raise NumericalFailure(
            f"occlusion_avoidance: W_O W_O^T is singular (det = {det:.3g}, rows {w1!r}, {w2!r}); "
            "the rows of d_occ and d_bord are dependent, W_O has no pseudo-inverse"
        )
    inv = 1.0 / det
    # (W W^T)^{-1} = [[g22, -g12], [-g12, g11]] / det ; W^+ x = W^T (W W^T)^{-1} x
    def pinv(x1: float, x2: float) -> tuple[float, float, float]:
        y1 = (g22 * x1 - g12 * x2) * inv
        y2 = (g11 * x2 - g12 * x1) * inv
        return (w1[0] * y1 + w2[0] * y2, w1[1] * y1 + w2[1] * y2, w1[2] * y1 + w2[2] * y2)

    # g_s = J_r^T L^T (s - s*) over the visible features
    u1 = u2 = u3 = 0.0
    visible = meas.visible
    for i, ((x, y, z), (xd, yd)) in enumerate(zip(features, desired)):
        if not visible[i]:
            continue
        ex, ey = x - xd, y - yd
        _, lx2, lx3 = model.interaction_x_row(x, y, z)
        ly1, ly2, ly3 = model.interaction_y_row(y, z)
        u1 += ly1 * ey
        u2 += lx2 * ex + ly2 * ey
        u3 += lx3 * ex + ly3 * ey
    (j11, j12, j13), (j21, j22, j23), (j31, j32, j33) = model.reduced_jacobian(
        pan, robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m
    )
    g = (
        j11 * u1 + j21 * u2 + j31 * u3,
        j12 * u1 + j22 * u2 + j32 * u3,
        j13 * u1 + j23 * u2 + j33 * u3,
    )
    p = pinv(w1[0] * g[0] + w1[1] * g[1] + w1[2] * g[2], w2[0] * g[0] + w2[1] * g[1] + w2[2] * g[2])
    primary = pinv(e1, e2)
    return (
        -lambda_occ * (primary[0] + beta_occ * (g[0] - p[0])),
        -lambda_occ * (primary[1] + beta_occ * (g[1] - p[1])),
        -lambda_occ * (primary[2] + beta_occ * (g[2] - p[2])),
    )


def avoidance_control(
    v_coll: float,
    omega_coll: float,
    pan_rate_real: float | None,
    pan_rate_reconstructed: float | None,
    mu_occ: float,
) -> Joint:
    """Collision-avoidance controller (18): ``(v_coll, omega_coll, (1-mu) ϖ + mu ϖ~)``.

    A pan rate may be ``None`` when its weight is exactly 0 (``mu_occ = 1``
    for the real one, ``mu_occ = 0`` for the reconstructed one).
    """
    return (v_coll, omega_coll, _mix2(1.0 - mu_occ, pan_rate_real, mu_occ, pan_rate_reconstructed, "pan rate"))


def _mix2(w1: float, x1: float | None, w2: float, x2: float | None, what: str) -> float:
    total = 0.0
    for w, x, name in ((w1, x1, "first"), (w2, x2, "second")):
        if w == 0.0:
            continue
        if x is None:
            raise ValueError(f"avoidance_control: the {name} {what} is None but its weight is {w!r} (expected 0)")
        total += w * x
    return total


def blend(
    mu_coll: float, mu_occ: float, q_vs: Joint | None, q_occ: Joint | None, q_coll: Joint | None
) -> Joint:
    """Global controller (19): ``(1-mu_occ)(1-mu_coll) q_VS + (1-mu_coll) mu_occ q_occ + mu_coll q_coll``.

    A controller may be ``None`` when its weight is exactly 0; terms of zero
    weight are skipped, so the corners of Table I return the pure controllers
    bit for bit.

    Raises
    ------
    ValueError
        If a controller of non-zero weight is ``None``.
    """
    weights = ((1.0 - mu_occ) * (1.0 - mu_coll), (1.0 - mu_coll) * mu_occ, mu_coll)
    v = omega = pan_rate = 0.0
    for w, q, name in zip(weights, (q_vs, q_occ, q_coll), ("q_vs", "q_occ", "q_coll")):
        if w == 0.0:
            continue
        if q is None:
            raise ValueError(
                f"blend: {name} is None but its weight is {w!r} (mu_coll = {mu_coll!r}, mu_occ = {mu_occ!r}); "
                "compute that controller or pass weights that exclude it"
            )
        v += w * q[0]
        omega += w * q[1]
        pan_rate += w * q[2]
    return (v, omega, pan_rate)
