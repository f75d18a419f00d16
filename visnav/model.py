"""The paper's kinematic and image equations, written once for every backend.

Every function here uses only arithmetic operators and the ``sin``/``cos``
functions of the ``ops`` namespace it is given.  With the default ``ops=math``
the functions take and return Python floats (the fast path used by the
closed-loop simulation, where a numpy call per scalar would cost more than the
arithmetic); with ``ops=casadi`` and ``casadi.SX`` arguments they build the
symbolic expressions from which ``analysis`` and the tests derive Jacobians by
automatic differentiation.  This module is the single source of truth for
equations (1), (5), the depth row and (13) of Folio & Cadenat, of the camera
pose and the pinhole projection, and of the path-frame equations (10)–(11).

Conventions (see ``docs/model.md``)
-----------------------------------
* Robot reference point ``M = (x, y)`` [m], heading ``theta`` [rad], pan angle
  ``pan`` (the paper's ϑ) [rad] relative to the base.
* Inputs ``q̇ = (v, omega, pan_rate)`` [m/s, rad/s, rad/s].
* Reduced camera screw ``T_rc = (V_y, V_z, Omega_x)`` in the camera frame:
  ``z_C`` is the optical axis (forward), ``y_C`` points left, ``x_C`` points
  down.  Image coordinates are normalised (``X = x/z`` vertical, ``Y = y/z``
  horizontal, positive to the left).
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

__all__ = [
    "reduced_jacobian",
    "reduced_jacobian_inverse",
    "camera_screw",
    "joint_rates_from_screw",
    "interaction_x_row",
    "interaction_y_row",
    "depth_row",
    "yz_rate_and_jacobian",
    "x_rate_gain",
    "feature_depth_rate",
    "feature_depth_rate_jacobian",
    "pan_column",
    "path_error_rates",
    "camera_centre",
    "pose_rates",
    "project_world_point",
    "path_following_omega",
]

Scalar = Any  # float, or casadi.SX/MX when ops=casadi


def reduced_jacobian(
    pan: Scalar, pan_offset: float, cam_forward: float, cam_lateral: float, ops: ModuleType = math
) -> tuple[tuple[Scalar, Scalar, Scalar], ...]:
    """Reduced robot Jacobian ``J_r(ϑ)`` of equation (1), ``T_rc = J_r q̇``.

    Parameters
    ----------
    pan : float
        Pan angle ϑ [rad].
    pan_offset : float
        ``Dx``, distance from M to the pan centre P [m].
    cam_forward, cam_lateral : float
        Camera offset ``(a, b)`` in the pan frame [m].
    ops : module
        ``math`` (floats) or ``casadi`` (symbolic).

    Returns
    -------
    tuple of 3 rows of 3 entries
        Rows ``(V_y, V_z, Omega_x)``, columns ``(v, omega, pan_rate)``.
        ``det J_r = +Dx`` for every ϑ.
    """
    s, c = ops.sin(pan), ops.cos(pan)
    a, b = cam_forward, cam_lateral
    return (
        (-s, pan_offset * c + a, a),
        (c, pan_offset * s - b, -b),
        (0.0, -1.0, -1.0),
    )


def pan_column(cam_forward: float, cam_lateral: float) -> tuple[float, float, float]:
    """Third column ``J_ϖ = (a, -b, -1)`` of ``J_r``: the screw per unit pan rate."""
    return (cam_forward, -cam_lateral, -1.0)


def camera_screw(
    pan: Scalar,
    v: Scalar,
    omega: Scalar,
    pan_rate: Scalar,
    pan_offset: float,
    cam_forward: float,
    cam_lateral: float,
    ops: ModuleType = math,
) -> tuple[Scalar, Scalar, Scalar]:
    """Reduced camera screw ``T_rc = J_r(ϑ) q̇`` [m/s, m/s, rad/s]."""
    s, c = ops.sin(pan), ops.cos(pan)
    a, b = cam_forward, cam_lateral
    heading_rate = omega + pan_rate
    return (
        -s * v + pan_offset * c * omega + a * heading_rate,
        c * v + pan_offset * s * omega - b * heading_rate,
        -heading_rate,
    )


def joint_rates_from_screw(
    pan: Scalar,
    v_y: Scalar,
    v_z: Scalar,
    omega_x: Scalar,
    pan_offset: float,
    cam_forward: float,
    cam_lateral: float,
    ops: ModuleType = math,
) -> tuple[Scalar, Scalar, Scalar]:
    """Closed-form ``J_r(ϑ)^{-1} T_rc``: the joint rates ``(v, omega, pan_rate)``.

    ``J_r`` is invertible for every ϑ because ``det J_r = Dx > 0``.
    """
    s, c = ops.sin(pan), ops.cos(pan)
    lateral = v_y + cam_forward * omega_x
    forward = v_z - cam_lateral * omega_x
    v = -s * lateral + c * forward
    omega = (c * lateral + s * forward) / pan_offset
    return (v, omega, -omega_x - omega)


def reduced_jacobian_inverse(
    pan: Scalar, pan_offset: float, cam_forward: float, cam_lateral: float, ops: ModuleType = math
) -> tuple[tuple[Scalar, Scalar, Scalar], ...]:
    """``J_r(ϑ)^{-1}`` in closed form (rows ``v, omega, pan_rate``)."""
    s, c = ops.sin(pan), ops.cos(pan)
    a, b, dx = cam_forward, cam_lateral, pan_offset
    # columns: d/dV_y, d/dV_z, d/dOmega_x of joint_rates_from_screw
    v_row = (-s, c, -s * a - c * b)
    w_row = (c / dx, s / dx, (c * a - s * b) / dx)
    p_row = (-c / dx, -s / dx, -1.0 - (c * a - s * b) / dx)
    return (v_row, w_row, p_row)


def interaction_x_row(x_img: Scalar, y_img: Scalar, depth: Scalar) -> tuple[Scalar, Scalar, Scalar]:
    """Row ``L_X = (0, X/z, X Y)`` of equation (5) (columns ``V_y, V_z, Omega_x``)."""
    return (0.0, x_img / depth, x_img * y_img)


def interaction_y_row(y_img: Scalar, depth: Scalar) -> tuple[Scalar, Scalar, Scalar]:
    """Row ``L_Y = (-1/z, Y/z, 1 + Y²)`` of equation (5)."""
    return (-1.0 / depth, y_img / depth, 1.0 + y_img * y_img)


def depth_row(y_img: Scalar, depth: Scalar) -> tuple[Scalar, Scalar, Scalar]:
    """Depth row ``L_z = (0, -1, -z Y)``: ``ż = L_z T_rc`` for a fixed world point."""
    return (0.0, -1.0, -depth * y_img)


def yz_rate_and_jacobian(
    y_img: Scalar, depth: Scalar, v_y: Scalar, v_z: Scalar, omega_x: Scalar
) -> tuple[Scalar, Scalar, Scalar, Scalar, Scalar, Scalar, Scalar, Scalar, Scalar]:
    """The ``(Y, z)`` rows of equation (13) and their Jacobian ``∂(Ẏ, ż)/∂(Y, z)``.

    The rows do not involve ``X``: the ``(Y, z)`` subsystem of a point is closed (``X``
    follows from :func:`x_rate_gain`).  They are returned split into their translational
    part (from ``V_y, V_z``) and their rotational part (from ``Ω_x``):

    * ``Ẏ = Ẏ_v + Ẏ_ω`` with ``Ẏ_v = (Y V_z − V_y)/z`` and ``Ẏ_ω = (1 + Y²) Ω_x``;
    * ``ż = ż_v + ż_ω`` with ``ż_v = −V_z`` and ``ż_ω = −z Y Ω_x``;
    * ``∂Ẏ/∂Y = V_z/z + 2 Y Ω_x`` (the same two parts), ``∂Ẏ/∂z = −(Y V_z − V_y)/z²``,
      ``∂ż/∂Y = −z Ω_x`` and ``∂ż/∂z = −Y Ω_x``.

    This function is the only place where these rows and their derivatives are written:
    :func:`feature_depth_rate`, :func:`feature_depth_rate_jacobian` and the Newton iteration of
    the estimator's BDF stage (:class:`visnav.estimator.FeatureEstimator`) all call it.  One
    call gives the Newton iteration its residual and its Jacobian (it solves for ``(Y, z)``
    of each point).  Everything is linear in the screw, so the estimator passes ``βh T_rc``
    and gets ``βh`` times the rates and derivatives.  The parts are kept apart so that the
    BDF residual subtracts them one after the other, ``(Y − Ẏ_v) − Ẏ_ω``: the estimator's
    results then stay identical, to the last bit, to those of its former inline arithmetic.

    Parameters
    ----------
    y_img : float
        Normalised horizontal image coordinate ``Y`` [-].
    depth : float
        Depth ``z`` along the optical axis [m], nonzero (positive in use).
    v_y, v_z, omega_x : float
        Reduced camera screw ``T_rc`` [m/s, m/s, rad/s], or a multiple of it.

    Returns
    -------
    tuple of 9 float
        ``(Ẏ_v, ż_v, Ẏ_ω, ż_ω)`` [1/s, m/s, 1/s, m/s], then
        ``(∂Ẏ_v/∂Y, ∂Ẏ_ω/∂Y, ∂Ẏ/∂z, ∂ż/∂Y, ∂ż/∂z)`` [1/s, 1/s, 1/(m s), m/s, 1/s],
        all times the scale of the screw.
    """
    inv_z = 1.0 / depth
    y_v = (y_img * v_z - v_y) * inv_z
    minus_omega = -omega_x
    return (
        y_v,
        -v_z,
        (1.0 + y_img * y_img) * omega_x,
        depth * y_img * minus_omega,
        v_z * inv_z,
        2.0 * y_img * omega_x,
        -y_v * inv_z,
        depth * minus_omega,
        y_img * minus_omega,
    )


def x_rate_gain(y_img: Scalar, depth: Scalar, v_z: Scalar, omega_x: Scalar) -> tuple[Scalar, Scalar]:
    """The ``X`` row of equation (13), which is linear in ``X``: ``Ẋ = X (k_v + k_ω)``.

    ``k_v = V_z/z`` (translation) and ``k_ω = Y Ω_x`` (rotation); ``k_v + k_ω = ∂Ẋ/∂X``.
    The estimator solves its BDF stage for ``X`` from ``X (1 − βh k) = r_X`` once ``(Y, z)``
    has converged (parts subtracted one after the other, as in :func:`yz_rate_and_jacobian`;
    ``k_v`` is a true division, as in the estimator's former inline arithmetic, so that the
    results are the same to the last bit).

    Parameters
    ----------
    y_img, depth, v_z, omega_x : float
        As for :func:`yz_rate_and_jacobian` [-, m, m/s, rad/s].

    Returns
    -------
    tuple of 2 float
        ``(k_v, k_ω)`` [1/s] (times the scale of the screw).
    """
    return (v_z / depth, y_img * omega_x)


def feature_depth_rate(
    x_img: Scalar, y_img: Scalar, depth: Scalar, v_y: Scalar, v_z: Scalar, omega_x: Scalar
) -> tuple[Scalar, Scalar, Scalar]:
    """One point's block of equation (13): ``(Ẋ, Ẏ, ż) = (L_X; L_Y; L_z) T_rc``.

    Assembled from :func:`x_rate_gain` and :func:`yz_rate_and_jacobian` (the definition of the
    rows): ``Ẋ = X (V_z/z + Y Ω_x)``, ``Ẏ = (Y V_z − V_y)/z + (1 + Y²) Ω_x``,
    ``ż = −V_z − z Y Ω_x``.

    Parameters
    ----------
    x_img, y_img : float
        Normalised image coordinates ``X, Y`` [-].
    depth : float
        Depth ``z`` along the optical axis [m], must be positive.
    v_y, v_z, omega_x : float
        Reduced camera screw [m/s, m/s, rad/s].

    Returns
    -------
    tuple of 3 float
        ``(Ẋ, Ẏ, ż)`` [1/s, 1/s, m/s].
    """
    k_v, k_w = x_rate_gain(y_img, depth, v_z, omega_x)
    y_v, z_v, y_w, z_w, _, _, _, _, _ = yz_rate_and_jacobian(y_img, depth, v_y, v_z, omega_x)
    return (x_img * (k_v + k_w), y_v + y_w, z_v + z_w)


def feature_depth_rate_jacobian(
    x_img: Scalar, y_img: Scalar, depth: Scalar, v_y: Scalar, v_z: Scalar, omega_x: Scalar
) -> tuple[tuple[Scalar, Scalar, Scalar], ...]:
    """``∂(Ẋ, Ẏ, ż)/∂(X, Y, z)`` of :func:`feature_depth_rate` (one 3×3 block).

    The full Jacobian of (13) is block diagonal with one such block per point.
    It is lower block-triangular inside the block: ``X`` feeds neither ``Ẏ``
    nor ``ż``.  The ``(Y, z)`` block comes from :func:`yz_rate_and_jacobian`, ``∂Ẋ/∂X``
    is the gain of :func:`x_rate_gain`; the ``X`` row adds ``∂Ẋ/∂Y = X Ω_x`` and
    ``∂Ẋ/∂z = −X V_z/z²``.  Checked against CasADi's automatic differentiation of
    :func:`feature_depth_rate` in the tests.

    Parameters
    ----------
    x_img, y_img, depth, v_y, v_z, omega_x : float
        As for :func:`feature_depth_rate` [-, -, m, m/s, m/s, rad/s].

    Returns
    -------
    tuple of 3 rows of 3 float
        Rows ``(Ẋ, Ẏ, ż)``, columns ``(X, Y, z)``.
    """
    k_v, k_w = x_rate_gain(y_img, depth, v_z, omega_x)
    _, _, _, _, dyy_v, dyy_w, dyz, dzy, dzz = yz_rate_and_jacobian(y_img, depth, v_y, v_z, omega_x)
    return (
        (k_v + k_w, x_img * omega_x, -x_img * k_v / depth),
        (0.0, dyy_v + dyy_w, dyz),
        (0.0, dzy, dzz),
    )


def path_error_rates(
    v: Scalar, omega: Scalar, alpha: Scalar, curvature: Scalar, side: float, ops: ModuleType = math
) -> tuple[Scalar, Scalar]:
    """Rates ``(δ̇, α̇)`` of the path-frame errors, equation (10) in our conventions.

    ``δ = d_coll − d0``, ``α`` the heading relative to the travel tangent of
    the circle of radius ``ρ = |M − c|`` through M (see
    :func:`visnav.geometry.proximity`), ``curvature = 1/ρ``:
    ``δ̇ = v sin α`` and ``α̇ = −side ω + v cos α · curvature`` (the paper's
    ``χ`` is ``−1/ρ``).  The curvature is an argument (not ``ρ``) so that a
    symbolic analysis can keep it as an independent symbol.
    """
    return (v * ops.sin(alpha), -side * omega + v * ops.cos(alpha) * curvature)


def path_following_omega(
    delta: Scalar, alpha: Scalar, curvature: Scalar, side: float, v: Scalar, k: Scalar, ops: ModuleType = math
) -> Scalar:
    """Angular velocity (11) of the path-following law with the exact curvature term.

    ``ω = side v (k δ + α + 2k sin α + cos α · curvature)``, ``curvature = 1/ρ``; with
    :func:`path_error_rates` it gives the closed loop ``δ̇ = v sin α``,
    ``α̇ = −v (k δ + α + 2k sin α)`` whatever the curvature.
    """
    return side * v * (k * delta + alpha + 2.0 * k * ops.sin(alpha) + ops.cos(alpha) * curvature)


def camera_centre(
    x: Scalar, y: Scalar, theta: Scalar, pan: Scalar, pan_offset: float, cam_forward: float, cam_lateral: float,
    ops: ModuleType = math,
) -> tuple[Scalar, Scalar, Scalar]:
    """Optical centre ``(cx, cy)`` [m] and camera heading ``phi = theta + pan`` [rad].

    The pan centre P is ``pan_offset`` ahead of M on the base axis; the optical
    centre is ``(cam_forward, cam_lateral)`` from P in the pan frame.
    """
    phi = theta + pan
    c, s = ops.cos(phi), ops.sin(phi)
    a, b, dx = cam_forward, cam_lateral, pan_offset
    return (
        x + dx * ops.cos(theta) + a * c - b * s,
        y + dx * ops.sin(theta) + a * s + b * c,
        phi,
    )


def project_world_point(
    cx: Scalar, cy: Scalar, phi: Scalar, camera_height: float, wx: float, wy: float, wh: float,
    ops: ModuleType = math,
) -> tuple[Scalar, Scalar, Scalar]:
    """Pinhole projection: normalised image coordinates and depth ``(X, Y, z)`` of a world point.

    ``z = (W − C)·(cos phi, sin phi)`` along the optical axis, ``X = (h_c − h_w)/z``
    (down), ``Y = ((W − C)·(−sin phi, cos phi))/z`` (left).  Valid for ``z > 0``;
    the caller checks (:func:`visnav.geometry.project_point` raises).

    Parameters
    ----------
    cx, cy, phi : float
        Camera pose from :func:`camera_centre` [m, m, rad].
    camera_height : float
        Height of the optical centre [m].
    wx, wy, wh : float
        World point: position and height [m].
    """
    c, s = ops.cos(phi), ops.sin(phi)
    dx, dy = wx - cx, wy - cy
    z = dx * c + dy * s
    inv_z = 1.0 / z
    return ((camera_height - wh) * inv_z, (dy * c - dx * s) * inv_z, z)


def pose_rates(
    theta: Scalar, v: Scalar, omega: Scalar, pan_rate: Scalar, ops: ModuleType = math
) -> tuple[Scalar, Scalar, Scalar, Scalar]:
    """Kinematics of the cart and pan platform: ``(ẋ, ẏ, θ̇, ϑ̇) = (v cos θ, v sin θ, ω, ϖ)``."""
    return (v * ops.cos(theta), v * ops.sin(theta), omega, pan_rate)
