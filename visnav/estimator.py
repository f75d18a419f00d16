"""Reconstruction of image features and depths during an occlusion: equations (13)–(14).

While the target is visible, :class:`FeatureEstimator` records the measured
states ``ψ = ((X_1, Y_1, z_1), ..., (X_N, Y_N, z_N))`` at the sampling
instants and the zero-order-hold (ZOH) inputs of every sampling period.  When
the target becomes hidden, :meth:`FeatureEstimator.start` switches it to
reconstruction: each call of :meth:`FeatureEstimator.advance` then performs one
fixed-step BDF step of (13)::

    ψ_{k+1} = sum_j c_j ψ_{k+1-j} + β h F(ψ_{k+1}),   F = blockdiag(L_i) T_rc

with the camera screw ``T_rc`` chosen by ``EstimatorSettings.screw_model``
(open question 13 of ``docs/supervisor.md``; see ``docs/estimator.md`` for the measured effect).

Newton structure
----------------
``∂F/∂ψ`` is block diagonal (one 3×3 block per point) and inside a block ``X``
feeds neither ``Ẏ`` nor ``ż``.  So every point is corrected on its own, Newton
runs on the 2×2 ``(Y, z)`` system (closed-form solve) and ``X`` follows from the
scalar linear equation ``X (1 - βh (V_z/z + Y Ω_x)) = r_X``.  The predictor is
the extrapolation polynomial through the stored history, so one or two Newton
iterations suffice.  Equation (13) is not written here: the rates and the
Jacobian of the ``(Y, z)`` rows come from :func:`visnav.model.yz_rate_and_jacobian`
(one call per Newton iteration, with the screw scaled by ``βh``), the ``X`` row from
:func:`visnav.model.x_rate_gain` and the start-up's full rate from
:func:`visnav.model.feature_depth_rate`.  The step uses Python floats and :mod:`math`
only (a numpy call costs about 1 µs, more than the whole arithmetic of a point).

Start-up
--------
The buffer is filled while the features are measured (the normal case: reconstruction
then starts from a full, exact history of ``order`` values).  While the history
holds fewer than ``order`` values (reconstruction started early, or shortly after
a previous one stopped), :meth:`FeatureEstimator.advance` computes the step with
classical RK4 on the *exact* ODE of the period instead: under ZOH the joint rates
are constant over ``[t_k, t_k + h]`` and ``ϑ(t) = ϑ_k + ϖ (t - t_k)``, so the
camera screw inside the period is ``J_r(ϑ(t)) q̇_k`` exactly
(:func:`zoh_period_rk4`, :data:`STARTUP_RK4_SUBSTEPS` substeps).  The result is
appended to the history like a BDF value; after ``order - 1`` such steps the BDF
takes over.  ``start(startup="ramp")`` keeps the former low-order ramp (BDF1,
BDF2, ... with the full step; it leaves a permanent error, see
``docs/estimator.md``), ``start(require_full_history=True)`` refuses a short history.

Measurements observed after :meth:`FeatureEstimator.stop` replace the whole
reconstructed history at once (the periods' mean screws, exact inputs, are kept), so a
later :meth:`FeatureEstimator.start` never mixes reconstructed and measured values.

Examples
--------
>>> from visnav.parameters import EstimatorSettings, RobotGeometry
>>> est = FeatureEstimator(RobotGeometry(), EstimatorSettings(order=1, screw_model="end"))
>>> est.observe(((0.1, 0.2, 2.0),))
>>> est.start()
>>> ((x, y, z),) = est.advance(0.0, (0.2, 0.0, 0.0), 0.05)
>>> round(z, 12)  # moving 1 cm forward along the optical axis
1.99
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

from analysis.bdf import bdf_coefficients, extrapolation_weights, histopolation_weights, validate_order
from hybrid.errors import NumericalFailure
from visnav.model import camera_screw, feature_depth_rate, x_rate_gain, yz_rate_and_jacobian
from visnav.parameters import EstimatorSettings, RobotGeometry

__all__ = [
    "SCREW_MODELS",
    "STARTUP_METHODS",
    "STARTUP_RK4_SUBSTEPS",
    "PERIOD_RELATIVE_TOLERANCE",
    "EstimatorSettingsError",
    "EstimatorInputError",
    "EstimatorUsageError",
    "HeldInputs",
    "validate_settings",
    "mean_camera_screw",
    "held_inputs",
    "zoh_period_rk4",
    "bdf_stage_residual",
    "FeatureEstimator",
]

SCREW_MODELS = ("end", "start", "mean", "histopolated")
"""Allowed ``EstimatorSettings.screw_model`` values (see :func:`FeatureEstimator.screw_for_step`)."""

STARTUP_METHODS = ("rk4", "ramp")
"""Start-ups accepted by :meth:`FeatureEstimator.start` while the history is shorter than ``order``."""

STARTUP_RK4_SUBSTEPS = 16
"""Classical RK4 substeps per sampling period in the ``"rk4"`` start-up (:func:`zoh_period_rk4`).

Chosen from the measured error of one 50 ms period against ``solve_ivp(DOP853,
rtol=1e-13)`` with the exact in-period screw.  Bounding case: 4 points at depths
0.5–2 m with ``|X|, |Y|`` up to 0.6 and every joint rate at its stated limit
(0.6 m/s, 1 rad/s, 1.5 rad/s); error per step in ``X, Y`` / relative in ``z``:

=========  ==================  ==================
substeps   ``|ΔX|, |ΔY|``      ``|Δz|/z``
=========  ==================  ==================
4          4.0e-9              1.2e-8
8          2.7e-10             7.5e-10
16         1.7e-11             4.7e-11
=========  ==================  ==================

16 keeps even the 5 start-up steps of BDF6 at this extreme below 1e-9 in total
(8 would give up to 3.7e-9).  On the test motion of ``docs/estimator.md``
(depths 2.6–5.6 m) a single RK4 step is already within 3e-11 and 16 substeps
reach round-off (6e-16).  The tests check the step against DOP853 (rtol 1e-12).
Cost: about 0.13 ms per start-up step (4 points) when measured, 1.5–2× that since
:func:`visnav.model.feature_depth_rate` is assembled from the single definition of (13);
paid at most ``order - 1`` times per reconstruction.
"""

PERIOD_RELATIVE_TOLERANCE = 1e-9
"""Relative tolerance within which two sampling periods count as equal (fixed-step BDF)."""

_BDF_NAMES = {q: f"bdf{q}" for q in range(1, 7)}
_SINC_SERIES_BOUND = 1e-3  # below |x| this, sin(x)/x = 1 - x²/6 + x⁴/120 to 1e-22

_State = tuple[tuple[float, float, float], ...]
"""One ``ψ``: an ``(X, Y, z)`` triple per point [-, -, m]."""

_HistoryTerms = list[tuple[float, float, float, float, float]]
"""Per point ``(r_X, r_Y, r_z, p_Y, p_z)``: BDF history term and predictor (:func:`_history_combiner`)."""


class EstimatorSettingsError(ValueError):
    """Invalid :class:`~visnav.parameters.EstimatorSettings` (tolerance, iteration limit, screw model)."""


class EstimatorInputError(ValueError):
    """A malformed measurement, joint-rate record or step size given to the estimator."""


class EstimatorUsageError(RuntimeError):
    """A method called in the wrong phase (e.g. ``advance`` while tracking measurements)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class HeldInputs:
    """Zero-order-hold record of one sampling period ``[t_k, t_k + h]``.

    Attributes
    ----------
    pan_start : float
        Pan angle ϑ_k at the start of the period [rad].
    v, omega, pan_rate : float
        Joint rates held over the period [m/s, rad/s, rad/s].
    period : float
        Period length ``h`` [s].
    mean_screw : tuple of 3 float
        Exact mean of ``J_r(ϑ(t)) q̇_k`` over the period (:func:`mean_camera_screw`).
    """

    pan_start: float
    v: float
    omega: float
    pan_rate: float
    period: float
    mean_screw: tuple[float, float, float]


MIN_NEWTON_TOL = 1e-15
"""Smallest Newton tolerance accepted: a few ulps of a relative update (a smaller one cannot be met)."""
MAX_NEWTON_ITER = 100
"""Most Newton iterations per step accepted (a bound on the work of one step)."""


def validate_settings(settings: EstimatorSettings) -> None:
    """Check ``settings`` (order 1–6, known screw model, tolerance > 0, maxiter >= 1).

    Raises
    ------
    analysis.bdf.BdfOrderError
        Order outside 1..6.
    EstimatorSettingsError
        Any other invalid field; the message names it, the value and the fix.
    """
    validate_order(settings.order, name="EstimatorSettings.order")
    if settings.screw_model not in SCREW_MODELS:
        raise EstimatorSettingsError(
            f"EstimatorSettings.screw_model = {settings.screw_model!r}: expected one of "
            f"{', '.join(map(repr, SCREW_MODELS))} (default 'histopolated', see docs/estimator.md)"
        )
    tol = settings.newton_tol
    if (isinstance(tol, bool) or not isinstance(tol, (int, float))
            or not (MIN_NEWTON_TOL <= tol < 1.0 and math.isfinite(tol))):
        raise EstimatorSettingsError(
            f"EstimatorSettings.newton_tol = {tol!r}: expected a relative tolerance in [{MIN_NEWTON_TOL:g}, 1) "
            "(below that, double precision cannot meet it and every step would fail), e.g. 1e-12"
        )
    maxiter = settings.newton_maxiter
    if isinstance(maxiter, bool) or not isinstance(maxiter, int) or not 1 <= maxiter <= MAX_NEWTON_ITER:
        raise EstimatorSettingsError(
            f"EstimatorSettings.newton_maxiter = {maxiter!r}: expected an integer in [1, {MAX_NEWTON_ITER}] "
            "(Newton converges in a few iterations or not at all), e.g. 8"
        )


def _sinc(x: float) -> float:
    """``sin(x)/x`` with its series near 0."""
    if abs(x) < _SINC_SERIES_BOUND:
        x2 = x * x
        return 1.0 - x2 / 6.0 * (1.0 - x2 / 20.0)
    return math.sin(x) / x


def mean_camera_screw(
    pan_start: float, v: float, omega: float, pan_rate: float, h: float, geometry: RobotGeometry
) -> tuple[float, float, float]:
    """Exact mean of ``T_rc(t) = J_r(ϑ_k + ϖ (t - t_k)) q̇`` over ``[t_k, t_k + h]`` (ZOH ``q̇``).

    Only ``sin ϑ`` and ``cos ϑ`` vary in ``J_r``; their means are
    ``sinc(ϖh/2) · (sin, cos)(ϑ_mid)`` with ``ϑ_mid = ϑ_k + ϖh/2`` (the ``sinc``
    uses its series when ``ϖh → 0``).  So the mean is :func:`visnav.model.camera_screw`
    at ``ϑ_mid`` with ``v, ω`` scaled by the ``sinc`` factor and the heading rate
    ``ω + ϖ`` unchanged.
    """
    half = 0.5 * pan_rate * h
    k = _sinc(half)
    return camera_screw(
        pan_start + half,
        k * v,
        k * omega,
        omega + pan_rate - k * omega,
        geometry.pan_offset_m,
        geometry.camera_forward_m,
        geometry.camera_lateral_m,
    )


def held_inputs(
    pan_start: float, joint_rates: Sequence[float], h: float, geometry: RobotGeometry
) -> HeldInputs:
    """Validated :class:`HeldInputs` of one period (computes the exact mean screw)."""
    pan, v, omega, pan_rate, period = _validated_period(pan_start, joint_rates, h)
    return HeldInputs(
        pan_start=pan,
        v=v,
        omega=omega,
        pan_rate=pan_rate,
        period=period,
        mean_screw=mean_camera_screw(pan, v, omega, pan_rate, period, geometry),
    )


def _validated_period(
    pan_start: float, joint_rates: Sequence[float], h: float
) -> tuple[float, float, float, float, float]:
    """``(pan_start, v, omega, pan_rate, h)`` of one ZOH period as finite floats, ``h > 0``.

    Raises
    ------
    EstimatorInputError
        A value that is not a number, not finite, or ``h <= 0``.
    """
    try:
        v, omega, pan_rate = joint_rates
        v, omega, pan_rate = float(v), float(omega), float(pan_rate)
        pan = float(pan_start)
        period = float(h)
    except (TypeError, ValueError) as err:
        raise EstimatorInputError(
            f"joint_rates = {joint_rates!r}, pan_start = {pan_start!r}, h = {h!r}: expected three joint "
            f"rates (v, omega, pan_rate), a pan angle and a period, all numbers"
        ) from err
    if not (period > 0.0 and math.isfinite(period)):
        raise EstimatorInputError(f"h = {h!r}: expected a positive finite sampling period [s]")
    if not (math.isfinite(v) and math.isfinite(omega) and math.isfinite(pan_rate) and math.isfinite(pan)):
        raise EstimatorInputError(
            f"pan_start = {pan_start!r}, joint_rates = {joint_rates!r}: expected finite values"
        )
    return (pan, v, omega, pan_rate, period)


def zoh_period_rk4(
    psi: Sequence[tuple[float, float, float]],
    record: HeldInputs,
    geometry: RobotGeometry,
    substeps: int = STARTUP_RK4_SUBSTEPS,
) -> tuple[tuple[float, float, float], ...]:
    """``ψ(t_k + h)`` by classical RK4 on the exact ODE of one ZOH period.

    Over ``[t_k, t_k + h]`` the joint rates ``q̇_k = (v, ω, ϖ)`` of ``record`` are
    constant and ``ϑ(t) = ϑ_k + ϖ (t - t_k)``, so the camera screw is exactly
    ``T(t) = J_r(ϑ(t)) q̇_k`` (:func:`visnav.model.camera_screw`) and every point
    follows ``ψ_i' = F(ψ_i, T(t))`` (:func:`visnav.model.feature_depth_rate`).
    ``substeps`` equal RK4 substeps; the screw is evaluated at the substep ends
    and midpoints (``τ = j h / (2 substeps)``, no accumulated time).

    Parameters
    ----------
    psi : sequence of (X, Y, z)
        State at ``t_k`` (depths > 0).
    record : HeldInputs
        The period: ``pan_start``, the held ``v, omega, pan_rate`` and ``period``
        (:func:`held_inputs`).
    geometry : RobotGeometry
        ``Dx, a, b`` of ``J_r``.
    substeps : int
        RK4 substeps over the period (default :data:`STARTUP_RK4_SUBSTEPS`).

    Raises
    ------
    hybrid.errors.NumericalFailure
        A stage or substep depth ``<= 0``, or a non-finite value: the point
        passed behind the camera or the motion is too fast for the step.
    """
    dx, a, b = geometry.pan_offset_m, geometry.camera_forward_m, geometry.camera_lateral_m
    pan0, v, omega, pan_rate = record.pan_start, record.v, record.omega, record.pan_rate
    dt = record.period / substeps
    half = 0.5 * dt
    sixth = dt / 6.0
    screws = [
        camera_screw(pan0 + pan_rate * (j * half), v, omega, pan_rate, dx, a, b) for j in range(2 * substeps + 1)
    ]
    f = feature_depth_rate
    out = []
    for i, (x, y, z) in enumerate(psi):
        for n in range(substeps):
            t0, tm, t1 = screws[2 * n], screws[2 * n + 1], screws[2 * n + 2]
            k1x, k1y, k1z = f(x, y, z, *t0)
            z2 = z + half * k1z
            if not z2 > 0.0:
                raise _rk4_depth_failure(i, z2, n, substeps, record.period)
            k2x, k2y, k2z = f(x + half * k1x, y + half * k1y, z2, *tm)
            z3 = z + half * k2z
            if not z3 > 0.0:
                raise _rk4_depth_failure(i, z3, n, substeps, record.period)
            k3x, k3y, k3z = f(x + half * k2x, y + half * k2y, z3, *tm)
            z4 = z + dt * k3z
            if not z4 > 0.0:
                raise _rk4_depth_failure(i, z4, n, substeps, record.period)
            k4x, k4y, k4z = f(x + dt * k3x, y + dt * k3y, z4, *t1)
            x += sixth * (k1x + 2.0 * (k2x + k3x) + k4x)
            y += sixth * (k1y + 2.0 * (k2y + k3y) + k4y)
            z += sixth * (k1z + 2.0 * (k2z + k3z) + k4z)
            if not (z > 0.0 and math.isfinite(z) and math.isfinite(x) and math.isfinite(y)):
                raise _rk4_depth_failure(i, z, n, substeps, record.period, (x, y))
        out.append((x, y, z))
    return tuple(out)


def bdf_stage_residual(
    y_img: float, depth: float, r_y: float, r_z: float, s_y: float, s_z: float, s_w: float
) -> tuple[float, float]:
    """Residual of one point's implicit BDF stage in ``(Y, z)``: ``G = (Y, z) − βh (Ẏ, ż) − (r_Y, r_z)``.

    ``(Ẏ, ż)`` are the ``(Y, z)`` rows of equation (13), :func:`visnav.model.yz_rate_and_jacobian`;
    they are linear in the screw, so ``βh (Ẏ, ż)`` is that function of the scaled screw
    ``S = βh T_rc``.  The translational and rotational parts are subtracted one after the
    other.  The Newton iteration of :meth:`FeatureEstimator.advance` computes this residual
    from the same call that gives it the Jacobian, so it writes these two subtractions out
    (one call per iteration instead of two); ``tests/visnav/test_estimator.py`` checks that
    a Newton iteration on this function reproduces the estimator's steps bit for bit, and
    :meth:`FeatureEstimator.advance` reports it when Newton does not converge.

    Parameters
    ----------
    y_img, depth : float
        The iterate ``(Y, z)`` [-, m], ``z > 0``.
    r_y, r_z : float
        BDF history term ``sum_j c_j (Y, z)_{k+1-j}`` [-, m].
    s_y, s_z, s_w : float
        Scaled screw ``βh (V_y, V_z, Ω_x)`` [m, m, rad] (``β`` of the BDF order, ``h`` the step [s]).

    Returns
    -------
    tuple of 2 float
        ``(G_Y, G_z)`` [-, m]; zero at the solution of the stage.
    """
    f_yv, f_zv, f_yw, f_zw = yz_rate_and_jacobian(y_img, depth, s_y, s_z, s_w)[:4]
    return (y_img - f_yv - f_yw - r_y, depth - f_zv - f_zw - r_z)


def _rk4_depth_failure(
    point: int, z: float, substep: int, substeps: int, h: float, xy: tuple[float, float] | None = None
) -> NumericalFailure:
    state = f"depth z = {z:.6g} m" if xy is None else f"state (X, Y, z) = ({xy[0]:.6g}, {xy[1]:.6g}, {z:.6g})"
    return NumericalFailure(
        f"RK4 over the ZOH period (h = {h:g} s, substep {substep + 1} of {substeps}): point {point} reached "
        f"{state} (the depth must stay finite and > 0): the point passed behind the camera or the motion "
        f"is too fast for the step"
    )


def _combine_1(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 1: BDF coefficients ``c``, predictor weights ``e`` (1 each)."""
    (c0,), (e0,) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [(c0 * x0, c0 * y0, c0 * z0, e0 * y0, e0 * z0) for ((x0, y0, z0),) in zip(*states)]

    return combine


def _combine_2(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 2: BDF coefficients ``c``, predictor weights ``e`` (2 each)."""
    (c0, c1), (e0, e1) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [
            (c0 * x0 + c1 * x1, c0 * y0 + c1 * y1, c0 * z0 + c1 * z1, e0 * y0 + e1 * y1, e0 * z0 + e1 * z1)
            for (x0, y0, z0), (x1, y1, z1) in zip(*states)
        ]

    return combine


def _combine_3(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 3: BDF coefficients ``c``, predictor weights ``e`` (3 each)."""
    (c0, c1, c2), (e0, e1, e2) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [
            (
                c0 * x0 + c1 * x1 + c2 * x2,
                c0 * y0 + c1 * y1 + c2 * y2,
                c0 * z0 + c1 * z1 + c2 * z2,
                e0 * y0 + e1 * y1 + e2 * y2,
                e0 * z0 + e1 * z1 + e2 * z2,
            )
            for (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) in zip(*states)
        ]

    return combine


def _combine_4(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 4: BDF coefficients ``c``, predictor weights ``e`` (4 each)."""
    (c0, c1, c2, c3), (e0, e1, e2, e3) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [
            (
                c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3,
                c0 * y0 + c1 * y1 + c2 * y2 + c3 * y3,
                c0 * z0 + c1 * z1 + c2 * z2 + c3 * z3,
                e0 * y0 + e1 * y1 + e2 * y2 + e3 * y3,
                e0 * z0 + e1 * z1 + e2 * z2 + e3 * z3,
            )
            for (x0, y0, z0), (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) in zip(*states)
        ]

    return combine


def _combine_5(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 5: BDF coefficients ``c``, predictor weights ``e`` (5 each)."""
    (c0, c1, c2, c3, c4), (e0, e1, e2, e3, e4) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [
            (
                c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3 + c4 * x4,
                c0 * y0 + c1 * y1 + c2 * y2 + c3 * y3 + c4 * y4,
                c0 * z0 + c1 * z1 + c2 * z2 + c3 * z3 + c4 * z4,
                e0 * y0 + e1 * y1 + e2 * y2 + e3 * y3 + e4 * y4,
                e0 * z0 + e1 * z1 + e2 * z2 + e3 * z3 + e4 * z4,
            )
            for (x0, y0, z0), (x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (x4, y4, z4) in zip(*states)
        ]

    return combine


def _combine_6(c: Sequence[float], e: Sequence[float]) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """:func:`_history_combiner` for order 6: BDF coefficients ``c``, predictor weights ``e`` (6 each)."""
    (c0, c1, c2, c3, c4, c5), (e0, e1, e2, e3, e4, e5) = c, e

    def combine(states: Sequence[_State]) -> _HistoryTerms:
        return [
            (
                c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3 + c4 * x4 + c5 * x5,
                c0 * y0 + c1 * y1 + c2 * y2 + c3 * y3 + c4 * y4 + c5 * y5,
                c0 * z0 + c1 * z1 + c2 * z2 + c3 * z3 + c4 * z4 + c5 * z5,
                e0 * y0 + e1 * y1 + e2 * y2 + e3 * y3 + e4 * y4 + e5 * y5,
                e0 * z0 + e1 * z1 + e2 * z2 + e3 * z3 + e4 * z4 + e5 * z5,
            )
            for (x0, y0, z0), (x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (x4, y4, z4), (x5, y5, z5) in zip(*states)
        ]

    return combine


_COMBINERS = (_combine_1, _combine_2, _combine_3, _combine_4, _combine_5, _combine_6)


@lru_cache(maxsize=None)
def _history_combiner(order: int) -> Callable[[Sequence[_State]], _HistoryTerms]:
    """``states -> [(r_X, r_Y, r_z, p_Y, p_z) per point]`` for ``order`` past states (1–6).

    ``r = sum_j c_j ψ_{k+1-j}`` (BDF history term, :func:`analysis.bdf.bdf_coefficients`) and
    ``p = sum_j e_j ψ_{k+1-j}`` (extrapolation predictor, :func:`analysis.bdf.extrapolation_weights`;
    only ``Y, z`` need one).  ``states`` is ``[ψ_k, ψ_{k-1}, ...]`` (``order`` of them, newest first).

    Returns a closure over the coefficient tuples (:func:`_combine_1` ... :func:`_combine_6`)
    with the sums written out for that order: a Python loop over the history costs about
    twice as much (measured 1.6–1.9× for order 4 and 4 points, some 2 µs of the 20 µs step
    budget).  The sums run from the newest state to the oldest; ``tests/visnav/test_estimator.py``
    checks every order bit for bit against a plain loop.

    Raises
    ------
    analysis.bdf.BdfOrderError
        ``order`` outside 1..6.
    """
    validate_order(order)
    return _COMBINERS[order - 1](bdf_coefficients(order).history, extrapolation_weights(order))


def _as_state(psi: object, n_points: int | None) -> tuple[tuple[float, float, float], ...]:
    """Validate a measured ψ and return it as a tuple of float triples."""
    try:
        state = tuple((float(x), float(y), float(z)) for x, y, z in psi)  # type: ignore[union-attr]
    except (TypeError, ValueError) as err:
        raise EstimatorInputError(
            f"psi = {psi!r}: expected a sequence of (X, Y, z) triples, one per point"
        ) from err
    if not state:
        raise EstimatorInputError("psi is empty: expected at least one (X, Y, z) point")
    if n_points is not None and len(state) != n_points:
        raise EstimatorInputError(
            f"psi has {len(state)} points but the stored history has {n_points}; "
            f"call reset() before changing the number of points"
        )
    for i, (x, y, z) in enumerate(state):
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            raise EstimatorInputError(f"psi point {i} = {(x, y, z)!r}: expected finite values")
        if z <= 0.0:
            raise EstimatorInputError(f"psi point {i}: depth z = {z!r} m, expected > 0 (point in front of the camera)")
    return state


class FeatureEstimator:
    """Fixed-step BDF reconstruction of ``ψ`` (features and depths) under ZOH joint rates.

    Parameters
    ----------
    geometry : RobotGeometry
        ``Dx, a, b`` of ``J_r``.
    settings : EstimatorSettings
        Order, screw model and Newton settings (validated here).

    Notes
    -----
    Phases: *tracking* (initial; :meth:`observe` records measurements) and
    *reconstructing* (after :meth:`start`; :meth:`advance` produces estimates;
    :meth:`stop` returns to tracking).  The ring buffer holds the last ``order``
    states (measured or reconstructed, the newest first) and the exact mean screws
    (:func:`mean_camera_screw`) of the last ``order`` periods, the only part of a period
    record that a later step uses; they must share one period ``h`` (fixed-step BDF).
    While it holds fewer than ``order`` states, :meth:`advance` uses the RK4
    start-up (:func:`zoh_period_rk4`) unless ``start(startup="ramp")``.
    After :meth:`stop` the buffer keeps the reconstructed values, so that an
    immediate :meth:`start` resumes on them; the first measurement observed after
    the stop discards them all (it keeps the period means, which are exact
    inputs), so the history never mixes reconstructed and measured values and a
    later :meth:`start` with fewer than ``order`` fresh measurements begins with
    start-up steps.
    """

    __slots__ = (
        "_geometry",
        "_settings",
        "_order",
        "_tol",
        "_maxiter",
        "_model",
        "_states",
        "_period_means",
        "_period",
        "_n_points",
        "_reconstructing",
        "_last_iterations",
        "_last_method",
        "_steps",
        "_rk4_startup",
        "_holds_reconstruction",
        "_combiners",
        "_betas",
        "_hist_weights",
    )

    def __init__(self, geometry: RobotGeometry, settings: EstimatorSettings | None = None) -> None:
        settings = EstimatorSettings() if settings is None else settings
        validate_settings(settings)
        self._geometry = geometry
        self._settings = settings
        self._order = settings.order
        self._tol = float(settings.newton_tol)
        self._maxiter = settings.newton_maxiter
        self._model = settings.screw_model
        self._combiners = {q: _history_combiner(q) for q in range(1, self._order + 1)}
        self._betas = {q: bdf_coefficients(q).beta for q in range(1, self._order + 1)}
        # indexed by the number n of stored period means (0..order): the histopolation weights
        # (w_0, (w_1, ..., w_{p-1})) over p = min(order, n + 1) means
        self._hist_weights = tuple(
            (w[0], w[1:]) for w in (histopolation_weights(min(self._order, n + 1)) for n in range(self._order + 1))
        )
        self._states: deque = deque(maxlen=self._order)
        self._period_means: deque = deque(maxlen=self._order)
        self._period: float | None = None
        self._n_points: int | None = None
        self._reconstructing = False
        self._last_iterations = 0
        self._last_method = ""
        self._steps = 0
        self._rk4_startup = True
        self._holds_reconstruction = False

    # ------------------------------------------------------------------ properties

    @property
    def settings(self) -> EstimatorSettings:
        """The (validated) settings."""
        return self._settings

    @property
    def reconstructing(self) -> bool:
        """``True`` between :meth:`start` and :meth:`stop`."""
        return self._reconstructing

    @property
    def history_length(self) -> int:
        """Number of stored states (at most ``order``)."""
        return len(self._states)

    @property
    def period(self) -> float | None:
        """The sampling period shared by the stored history, or ``None`` before the first period."""
        return self._period

    @property
    def history(self) -> tuple[tuple[tuple[float, float, float], ...], ...]:
        """The stored states, newest first (at most ``order``)."""
        return tuple(self._states)

    @property
    def psi(self) -> tuple[tuple[float, float, float], ...] | None:
        """The newest stored state (measured or reconstructed), or ``None``."""
        return self._states[0] if self._states else None

    @property
    def last_newton_iterations(self) -> int:
        """Newton iterations of the last step (maximum over the points; 0 after an RK4 start-up step)."""
        return self._last_iterations

    @property
    def last_step_method(self) -> str:
        """Method of the last step: ``"rk4"`` (start-up) or ``"bdf<q>"`` (``q`` = order used), ``""`` before any."""
        return self._last_method

    @property
    def reconstruction_steps(self) -> int:
        """Steps (start-up and BDF) performed since the last :meth:`start`."""
        return self._steps

    # ------------------------------------------------------------------ phases

    def reset(self) -> None:
        """Forget the history and return to tracking."""
        self._states.clear()
        self._period_means.clear()
        self._period = None
        self._n_points = None
        self._reconstructing = False
        self._last_iterations = 0
        self._last_method = ""
        self._steps = 0
        self._holds_reconstruction = False

    def observe(
        self,
        psi: Sequence[Sequence[float]],
        pan_start: float | None = None,
        joint_rates: Sequence[float] | None = None,
        h: float | None = None,
    ) -> None:
        """Record a measured ``ψ`` at a sampling instant (tracking phase).

        Parameters
        ----------
        psi : sequence of (X, Y, z)
            Measured features (normalised) and depths [m] of every point.
        pan_start, joint_rates, h : optional
            ZOH record of the period that ended at this sample: pan angle at its
            start, joint rates ``(v, omega, pan_rate)`` held over it, its length.
            Give all three, or none: without them the history restarts from this
            sample (first sample, or after a gap in the measurements).  The first
            measurement after a reconstruction replaces all the reconstructed
            states (the periods' mean screws are kept).

        Raises
        ------
        EstimatorUsageError
            While reconstructing (call :meth:`stop` first).
        EstimatorInputError
            Malformed ``psi`` (depth <= 0, wrong number of points) or record,
            or a period different from the stored history's.
        """
        if self._reconstructing:
            raise EstimatorUsageError(
                "observe() called while reconstructing: call stop() when the features are measured again"
            )
        given = (pan_start is not None, joint_rates is not None, h is not None)
        if any(given) and not all(given):
            raise EstimatorInputError(
                "observe(): give pan_start, joint_rates and h together (the ZOH record of the period "
                "that just ended), or none of them to restart the history from this sample"
            )
        restart = not all(given) or not self._states
        state = _as_state(psi, None if restart else self._n_points)
        if restart:
            self._states.clear()
            self._period_means.clear()
            self._period = None
            self._n_points = len(state)
        if all(given):
            pan, v, omega, pan_rate, period = _validated_period(pan_start, joint_rates, h)  # type: ignore[arg-type]
            self._check_period(period)
            if not restart:
                self._period_means.appendleft(mean_camera_screw(pan, v, omega, pan_rate, period, self._geometry))
        if self._holds_reconstruction:
            # Reconstructed values and measurements do not lie on one trajectory (they differ by the
            # reconstruction error): a BDF history mixing them would differentiate that jump.  Keep
            # only measurements; the period means are exact inputs and stay.
            self._states.clear()
            self._holds_reconstruction = False
        self._states.appendleft(state)

    def start(self, *, require_full_history: bool = False, startup: str = "rk4") -> None:
        """Switch to reconstruction from the stored history.

        Parameters
        ----------
        require_full_history : bool
            If ``True``, refuse to start with fewer than ``order`` stored states
            (no start-up steps).
        startup : {"rk4", "ramp"}
            How :meth:`advance` steps while the history holds fewer than ``order``
            states: ``"rk4"`` (default) integrates the exact ODE of the period
            with classical RK4 (:func:`zoh_period_rk4`, error < 1e-10 per step);
            ``"ramp"`` uses BDF1, BDF2, ... with the full step (kept for
            comparison: its first steps leave a permanent error, 0.5 mm on the
            test motion of ``docs/estimator.md``).

        Raises
        ------
        EstimatorUsageError
            No stored state, already reconstructing, or history too short when
            ``require_full_history``.
        EstimatorInputError
            Unknown ``startup``.
        """
        if startup not in STARTUP_METHODS:
            raise EstimatorInputError(
                f"start(startup={startup!r}): expected one of {', '.join(map(repr, STARTUP_METHODS))}"
            )
        if self._reconstructing:
            raise EstimatorUsageError("start() called while already reconstructing; call stop() first")
        if not self._states:
            raise EstimatorUsageError(
                "start(): no measured state stored; call observe(psi) while the features are visible"
            )
        if require_full_history and len(self._states) < self._order:
            raise EstimatorUsageError(
                f"start(require_full_history=True): {len(self._states)} stored states but order = "
                f"{self._order} needs {self._order}; observe more samples or allow the start-up steps"
            )
        self._reconstructing = True
        self._rk4_startup = startup == "rk4"
        self._steps = 0

    def stop(self) -> None:
        """Return to tracking.

        The history is kept (an immediate :meth:`start` resumes on it); the next
        :meth:`observe` replaces all the reconstructed states at once.
        """
        self._reconstructing = False

    # ------------------------------------------------------------------ screw

    def screw_for_step(
        self, pan_start: float, joint_rates: Sequence[float], h: float
    ) -> tuple[float, float, float]:
        """Camera screw entering the implicit stage at ``t_{k+1}`` for the configured model.

        Does not change the estimator.  With ``q̇_k`` held over ``[t_k, t_{k+1}]``:

        * ``"end"``: ``J_r(ϑ_{k+1}) q̇_k`` (left limit at ``t_{k+1}``);
        * ``"start"``: ``J_r(ϑ_k) q̇_k``;
        * ``"mean"``: the exact period mean ``T̄_k`` (:func:`mean_camera_screw`);
        * ``"histopolated"``: ``sum_i w_i T̄_{k-i}`` over the last ``p = min(order,
          available)`` period means: the value at ``t_{k+1}`` of the polynomial
          whose cell means are the ``T̄`` (:func:`analysis.bdf.histopolation_weights`).
        """
        pan, v, omega, pan_rate, period = _validated_period(pan_start, joint_rates, h)
        mean = mean_camera_screw(pan, v, omega, pan_rate, period, self._geometry)
        return self._screw(pan, v, omega, pan_rate, period, mean)

    def _screw(
        self, pan: float, v: float, omega: float, pan_rate: float, h: float, mean: tuple[float, float, float]
    ) -> tuple[float, float, float]:
        """The screw of the model for the period ``(pan, v, omega, pan_rate, h)`` with mean screw ``mean``."""
        model = self._model
        if model == "histopolated":
            previous = self._period_means
            w0, weights = self._hist_weights[len(previous)]
            vy, vz, wx = mean
            vy, vz, wx = w0 * vy, w0 * vz, w0 * wx
            for w, (py, pz, px) in zip(weights, previous):
                vy += w * py
                vz += w * pz
                wx += w * px
            return (vy, vz, wx)
        if model == "mean":
            return mean
        geometry = self._geometry
        return camera_screw(
            pan + pan_rate * h if model == "end" else pan,
            v,
            omega,
            pan_rate,
            geometry.pan_offset_m,
            geometry.camera_forward_m,
            geometry.camera_lateral_m,
        )

    def _check_period(self, h: float) -> None:
        if self._period is None:
            self._period = h
        elif abs(h - self._period) > PERIOD_RELATIVE_TOLERANCE * self._period:
            raise EstimatorInputError(
                f"h = {h!r} s differs from the period {self._period!r} s of the stored history: the "
                f"fixed-step BDF needs equal periods; call reset() (or observe(psi) without a record "
                f"to restart the history) before changing the period"
            )

    # ------------------------------------------------------------------ steps

    def advance(
        self, pan_start: float, joint_rates: Sequence[float], h: float
    ) -> tuple[tuple[float, float, float], ...]:
        """One step over the period that just ended; returns the reconstructed ``ψ_{k+1}``.

        A BDF step of the configured order once the history holds ``order``
        states; before that (start-up) an RK4 integration of the exact ODE of the
        period (:func:`zoh_period_rk4`), or with ``start(startup="ramp")`` a BDF
        step of the order the history allows.  The result is appended to the
        history in every case.

        Parameters
        ----------
        pan_start : float
            Pan angle at the start of the period [rad].
        joint_rates : (v, omega, pan_rate)
            Joint rates held over the period.
        h : float
            Period length [s] (must equal the history's).

        Raises
        ------
        EstimatorUsageError
            Not reconstructing.
        EstimatorInputError
            Non-positive or changed ``h``, malformed rates.
        hybrid.errors.NumericalFailure
            Newton did not converge, or a depth became <= 0.
        """
        if not self._reconstructing:
            raise EstimatorUsageError("advance() called while tracking measurements: call start() first")
        pan, v, omega, pan_rate, period = _validated_period(pan_start, joint_rates, h)
        if period != self._period:  # the usual case, the same period again, needs no check
            self._check_period(period)
        mean = mean_camera_screw(pan, v, omega, pan_rate, period, self._geometry)
        if self._rk4_startup and len(self._states) < self._order:
            record = HeldInputs(pan_start=pan, v=v, omega=omega, pan_rate=pan_rate, period=period, mean_screw=mean)
            psi = self._startup_step(record)
        else:
            psi = self._bdf_step(self._screw(pan, v, omega, pan_rate, period, mean), period)
        self._period_means.appendleft(mean)
        self._holds_reconstruction = True
        return psi

    def _startup_step(self, record: HeldInputs) -> tuple[tuple[float, float, float], ...]:
        """RK4 on the exact ODE of the period (:func:`zoh_period_rk4`); pushes and returns ψ_{k+1}."""
        try:
            psi = zoh_period_rk4(self._states[0], record, self._geometry)
        except NumericalFailure as err:
            raise NumericalFailure(
                f"feature estimator, start-up step {self._steps + 1} (RK4 on the exact ZOH ODE): {err.cause}"
            ) from err
        self._states.appendleft(psi)
        self._last_iterations = 0
        self._last_method = "rk4"
        self._steps += 1
        return psi

    def advance_with_screw(
        self, screw: Sequence[float], h: float
    ) -> tuple[tuple[float, float, float], ...]:
        """One BDF step with the camera screw at ``t_{k+1}`` given directly (smooth inputs, tests).

        Bypasses the screw model.  The period means are cleared (the inputs of
        this period are unknown), so a later ``"histopolated"`` :meth:`advance`
        restarts its histopolation from one mean.  Only one screw value is
        known, not the ODE over the period, so with a short history this step
        is always a BDF step of the order the history allows (the ramp).
        """
        if not self._reconstructing:
            raise EstimatorUsageError("advance_with_screw() called while tracking: call start() first")
        try:
            v_y, v_z, omega_x = (float(x) for x in screw)
            period = float(h)
        except (TypeError, ValueError) as err:
            raise EstimatorInputError(f"screw = {screw!r}, h = {h!r}: expected (V_y, V_z, Omega_x) and a number") from err
        if not (period > 0.0 and math.isfinite(period)):
            raise EstimatorInputError(f"h = {h!r}: expected a positive finite sampling period [s]")
        self._check_period(period)
        psi = self._bdf_step((v_y, v_z, omega_x), period)
        self._period_means.clear()
        self._holds_reconstruction = True
        return psi

    def _bdf_step(self, screw: tuple[float, float, float], h: float) -> _State:
        """Predictor + per-point 2×2 Newton on (Y, z) + linear X; pushes and returns ψ_{k+1}.

        The stage ``G(Y, z) = (Y, z) − βh (Ẏ, ż) − (r_Y, r_z) = 0`` (:func:`bdf_stage_residual`)
        and its Jacobian ``I − βh ∂(Ẏ, ż)/∂(Y, z)`` both come from one call of
        :func:`visnav.model.yz_rate_and_jacobian` per iteration, with the screw scaled by ``βh``
        (the rates are linear in it).  Then ``X (1 − βh k) = r_X`` with ``βh k`` from
        :func:`visnav.model.x_rate_gain`.
        """
        states = self._states
        q = len(states)
        bh = self._betas[q] * h
        v_y, v_z, omega_x = screw
        s_y, s_z, s_w = bh * v_y, bh * v_z, bh * omega_x
        tol, iterations = self._tol, range(1, self._maxiter + 1)
        rate_and_jacobian, gain = yz_rate_and_jacobian, x_rate_gain
        out = []
        worst = 0
        try:
            for r_x, r_y, r_z, y, z in self._combiners[q](states):  # point len(out)
                for iteration in iterations:
                    if z <= 0.0:
                        raise self._depth_failure(len(out), z, iteration, h)
                    # f = βh (Ẏ_v, ż_v, Ẏ_ω, ż_ω) and j = βh ∂(Ẏ, ż)/∂(Y, z) at (Y, z); G is
                    # bdf_stage_residual(...) written out; A = I − j = [[a11, −j_yz], [−j_zy, a22]];
                    # update d = A⁻¹ G (Cramer).
                    f_yv, f_zv, f_yw, f_zw, j_yy_v, j_yy_w, j_yz, j_zy, j_zz = rate_and_jacobian(
                        y, z, s_y, s_z, s_w
                    )
                    g_y = y - f_yv - f_yw - r_y
                    g_z = z - f_zv - f_zw - r_z
                    a11 = 1.0 - j_yy_v - j_yy_w
                    a22 = 1.0 - j_zz
                    det = a11 * a22 - j_yz * j_zy
                    d_y = (a22 * g_y + j_yz * g_z) / det
                    d_z = (a11 * g_z + j_zy * g_y) / det
                    y -= d_y
                    z -= d_z
                    if abs(d_y) <= tol * (1.0 + abs(y)) and abs(d_z) <= tol * (1.0 + abs(z)):
                        break
                else:
                    raise self._newton_failure(
                        len(out), y, z, r_y, r_z, (s_y, s_z, s_w), max(abs(d_y), abs(d_z)), h
                    )
                if z <= 0.0:
                    raise self._depth_failure(len(out), z, iteration, h)
                if iteration > worst:
                    worst = iteration
                # X (1 − βh k) = r_X: the X row of the block, linear in X.
                k_v, k_w = gain(y, z, s_z, s_w)
                out.append((r_x / (1.0 - k_v - k_w), y, z))
        except ZeroDivisionError as err:
            raise NumericalFailure(
                f"feature estimator, BDF step {self._steps + 1} (h = {h:g} s): singular Newton matrix "
                f"or X equation for point {len(out)} ({err}); reduce h"
            ) from err
        psi = tuple(out)
        states.appendleft(psi)
        self._last_iterations = worst
        self._last_method = _BDF_NAMES[q]
        self._steps += 1
        return psi

    def _depth_failure(self, point: int, z: float, iteration: int, h: float) -> NumericalFailure:
        return NumericalFailure(
            f"feature estimator, BDF step {self._steps + 1} (h = {h:g} s): depth of point {point} became "
            f"z = {z:.6g} m at Newton iteration {iteration} (must be > 0): the point passed behind the camera "
            f"or the step is too large for the motion"
        )

    def _newton_failure(
        self,
        point: int,
        y: float,
        z: float,
        r_y: float,
        r_z: float,
        scaled_screw: tuple[float, float, float],
        update: float,
        h: float,
    ) -> NumericalFailure:
        g_y, g_z = bdf_stage_residual(y, z, r_y, r_z, *scaled_screw)
        return NumericalFailure(
            f"feature estimator, BDF step {self._steps + 1} (h = {h:g} s): Newton for point {point} did not "
            f"converge after {self._maxiter} iterations (last update {update:.3e}, residual "
            f"{max(abs(g_y), abs(g_z)):.3e}, tolerance {self._tol:.1e} relative); reduce h or raise "
            f"EstimatorSettings.newton_maxiter"
        )
