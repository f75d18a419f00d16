"""The pieces of the stiffness study (:mod:`visnav.studies.stiffness`): the occlusion window of a run and its
reconstruction problem, the histopolant screw, the Jacobian spectrum of (13) along a run, random scenarios, the
estimator's replays and the paper's error metrics.

Nothing here prints or writes files; :mod:`visnav.studies.stiffness` re-exports the public names.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from analysis.bdf import MAX_ORDER
from analysis.integrators import FIXED_STEP_SCHEMES, OdeProblem
from analysis.linearise import to_numpy
from analysis.integrator_regions import (
    first_unstable_step,
    max_root_modulus,
    real_stability_interval,
    stability_polynomial,
)
from visnav import model
from visnav.estimator import FeatureEstimator, held_inputs, mean_camera_screw, zoh_period_rk4
from visnav.geometry import camera_pose, project_points, propagate_pose
from visnav.parameters import EstimatorSettings, RobotGeometry, Scenario
from visnav.simulation import SimulationResult

# Helpers shared with visnav.studies.stiffness have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = [
    "StiffnessStudyError",
    "NoOcclusionError",
    "ReconstructionWindow",
    "HistopolantScrew",
    "Spectrum",
    "occlusion_window",
    "histopolant_screw",
    "reconstruction_problem",
    "orbit_problem",
    "jacobian_blocks",
    "spectrum",
    "spectrum_of_run",
    "random_scenarios",
    "replay_estimator",
    "replay_zoh_rk4",
    "paper_metrics",
    "state_error",
    "HISTORY_PERIODS",
    "HISTOPOLANT_DEGREE",
    "ORBIT_RADIUS_M",
    "ORBIT_RATE_RADPS",
    "ORBIT_DURATION_S",
    "WORST_CASE_DEPTHS_M",
    "UNSTABLE_STEP_SEARCH_S",
]


HISTORY_PERIODS = MAX_ORDER
"""Measured periods kept before the occlusion (a full history for BDF6)."""

HISTOPOLANT_DEGREE = 6
"""Degree of the histopolant screw spline (the derivative of a degree-7 interpolant of the primitive)."""

ORBIT_RADIUS_M = 1.0
"""Radius of the verification orbit around the target centre [m] (the goal distance of the paper)."""

ORBIT_RATE_RADPS = 0.5
"""Angular rate of the verification orbit [rad/s] (v = 0.5 m/s, within the paper's limits)."""

ORBIT_DURATION_S = 12.0
"""Duration of the verification problem [s] (a full turn takes 12.6 s)."""

UNSTABLE_STEP_SEARCH_S = 1000.0
"""Largest step searched for the first unstable step [s] (``None`` in the JSON: stable up to it)."""


class StiffnessStudyError(ValueError):
    """The scenario or the settings do not allow the study (no occlusion, short history, bad settings)."""


class NoOcclusionError(StiffnessStudyError):
    """The run has no occlusion window to study (no hidden feature, or too early for the BDF history): the
    study does not apply to that scenario (a report says so instead of failing)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ReconstructionWindow:
    """The longest occlusion of a run, with what a reconstruction needs and the truth.

    Attributes
    ----------
    scenario : str
    start_index : int
        Trace index of the last sample before the occlusion (all features measured).
    times : numpy.ndarray, shape (n + 1,)
        Sample times from that sample to the last hidden one [s].
    psi : numpy.ndarray, shape (n + 1, 3N)
        True ``(X_i, Y_i, z_i)`` at those samples (normalised, m).
    pans : numpy.ndarray, shape (n,)
        Pan angle at the start of each period [rad].
    joint_rates : numpy.ndarray, shape (n, 3)
        ZOH ``(v, ω, ϖ)`` of each period [m/s, rad/s, rad/s].
    hidden : numpy.ndarray of bool, shape (n + 1,)
        At least one feature hidden at the sample.
    history_psi : numpy.ndarray, shape (H + 1, 3N)
        Measured states of the ``H`` = :data:`HISTORY_PERIODS` periods before, ending at ``psi[0]``.
    history_pans, history_rates : numpy.ndarray, shapes (H,), (H, 3)
        ZOH records of those periods.
    period : float
        Sampling period ``T_e`` [s].
    focal_px : float
    geometry : RobotGeometry
    n_points : int
    """

    scenario: str
    start_index: int
    times: np.ndarray
    psi: np.ndarray
    pans: np.ndarray
    joint_rates: np.ndarray
    hidden: np.ndarray
    history_psi: np.ndarray
    history_pans: np.ndarray
    history_rates: np.ndarray
    period: float
    focal_px: float
    geometry: RobotGeometry
    n_points: int

    @property
    def duration(self) -> float:
        """Length of the window [s]."""
        return float(self.times[-1] - self.times[0])


def _readonly(array: np.ndarray) -> np.ndarray:
    out = np.array(array)
    out.flags.writeable = False
    return out


def _true_psi(result: SimulationResult) -> np.ndarray:
    trace = result.trace
    n_points = len(result.scenario.target.points_m)
    cols = [trace.record(f"{c}{i}") for i in range(n_points) for c in ("X", "Y", "z")]
    return np.stack(cols, axis=1)


def occlusion_window(result: SimulationResult) -> ReconstructionWindow:
    """The longest run of samples with a hidden feature, from the sample before it.

    Raises
    ------
    StiffnessStudyError
        No hidden sample, or fewer than :data:`HISTORY_PERIODS` measured
        periods before the occlusion.
    """
    trace = result.trace
    scenario = result.scenario
    hidden = trace.record("n_hidden") > 0
    if not hidden.any():
        raise NoOcclusionError(
            f"scenario {scenario.name!r}: no feature is ever hidden, so there is no occlusion to reconstruct; "
            f"use a scenario whose tall obstacle hides the target (e.g. 'paper')"
        )
    edges = np.flatnonzero(np.diff(np.concatenate([[0], hidden.astype(int), [0]])))
    runs = list(zip(edges[0::2], edges[1::2]))  # [first hidden, one past last hidden)
    first, stop = max(runs, key=lambda r: (r[1] - r[0], -r[0]))
    start = int(first) - 1
    last = int(stop) - 1
    if start < HISTORY_PERIODS:
        raise NoOcclusionError(
            f"scenario {scenario.name!r}: the occlusion starts at sample {first} (t = {trace.times[first]:g} s) but "
            f"the study needs {HISTORY_PERIODS} measured periods before it; start the robot further away"
        )
    psi = _true_psi(result)
    pans = trace.states[:, 3]
    rates = trace.inputs
    h0 = start - HISTORY_PERIODS
    return ReconstructionWindow(
        scenario=scenario.name,
        start_index=start,
        times=_readonly(trace.times[start : last + 1]),
        psi=_readonly(psi[start : last + 1]),
        pans=_readonly(pans[start:last]),
        joint_rates=_readonly(rates[start:last]),
        hidden=_readonly(hidden[start : last + 1]),
        history_psi=_readonly(psi[h0 : start + 1]),
        history_pans=_readonly(pans[h0:start]),
        history_rates=_readonly(rates[h0:start]),
        period=float(trace.period),
        focal_px=float(scenario.camera.focal_px),
        geometry=scenario.robot,
        n_points=len(scenario.target.points_m),
    )


# --------------------------------------------------------------------------- the smooth input


@dataclass(frozen=True, kw_only=True, slots=True)
class HistopolantScrew:
    """The camera screw ``T(t)`` whose mean over every sampling period is the exact ZOH mean.

    Built by :func:`histopolant_screw`: the primitive ``P(t_k) = h Σ_{j<k} T̄_j``
    is interpolated by a degree-7 not-a-knot spline; ``T = P'`` is a C⁵
    piecewise polynomial of degree :data:`HISTOPOLANT_DEGREE` with
    ``∫_{t_k}^{t_{k+1}} T = h T̄_k`` exactly.  It is the continuous-time
    counterpart of the estimator's ``"histopolated"`` screw model, but global
    (it uses the periods after ``t`` too): a smooth surrogate of the ZOH
    input, not an on-line estimate.

    Attributes
    ----------
    breakpoints : tuple of float
        Piecewise-polynomial breakpoints [s].
    coefficients : tuple of tuple of tuple of float
        Per interval, per component ``(V_y, V_z, Ω_x)``, the local
        polynomial coefficients, highest power first (in ``t − breakpoint``).
    knots, spline_coefficients : numpy.ndarray
        The B-spline form (for CasADi).
    """

    breakpoints: tuple[float, ...]
    coefficients: tuple[tuple[tuple[float, ...], ...], ...]
    knots: np.ndarray
    spline_coefficients: np.ndarray

    def __call__(self, t: float) -> tuple[float, float, float]:
        """``(V_y, V_z, Ω_x)`` at ``t`` [m/s, m/s, rad/s] (Python floats, about 3 µs)."""
        x = self.breakpoints
        i = bisect.bisect_right(x, t) - 1
        i = min(max(i, 0), len(self.coefficients) - 1)
        dt = t - x[i]
        out = []
        for poly in self.coefficients[i]:
            value = 0.0
            for c in poly:
                value = value * dt + c
            out.append(value)
        return (out[0], out[1], out[2])

    def casadi(self, t: Any) -> Any:
        """The same spline as a CasADi ``MX`` expression of ``t`` (a 3-vector)."""
        return ca.bspline(
            t, ca.DM(self.spline_coefficients.reshape(-1)), [list(map(float, self.knots))], [HISTOPOLANT_DEGREE], 3, {}
        )


def histopolant_screw(result: SimulationResult) -> HistopolantScrew:
    """The :class:`HistopolantScrew` of a run (every period of the trace)."""
    from scipy.interpolate import BSpline, PPoly, make_interp_spline

    trace = result.trace
    g = result.scenario.robot
    h = float(trace.period)
    means = np.array([
        mean_camera_screw(float(trace.states[k, 3]), *map(float, trace.inputs[k]), h, g)
        for k in range(len(trace.times) - 1)
    ])
    primitive = np.vstack([np.zeros(3), np.cumsum(means * h, axis=0)])
    spline = make_interp_spline(np.asarray(trace.times, dtype=float), primitive, k=HISTOPOLANT_DEGREE + 1)
    derivative = spline.derivative()
    n_coef = len(derivative.t) - derivative.k - 1
    coef = np.array(derivative.c[:n_coef], dtype=float)
    pieces = [PPoly.from_spline(BSpline(derivative.t, coef[:, j], derivative.k)) for j in range(3)]
    x = pieces[0].x
    keep = [i for i in range(len(x) - 1) if x[i + 1] > x[i]]
    coefficients = tuple(
        tuple(tuple(float(c) for c in piece.c[:, i]) for piece in pieces) for i in keep
    )
    return HistopolantScrew(
        breakpoints=tuple(float(x[i]) for i in keep),
        coefficients=coefficients,
        knots=_readonly(derivative.t),
        spline_coefficients=_readonly(coef),
    )


# --------------------------------------------------------------------------- equation (13), one source


@lru_cache(maxsize=None)
def _block_function() -> ca.Function:
    """``∂(Ẋ, Ẏ, ż)/∂(X, Y, z)`` of one point by CasADi AD of :func:`visnav.model.feature_depth_rate`."""
    psi = ca.SX.sym("psi", 3)
    screw = ca.SX.sym("screw", 3)
    rate = ca.vertcat(*model.feature_depth_rate(psi[0], psi[1], psi[2], screw[0], screw[1], screw[2]))
    return ca.Function("dF_dpsi_block", [psi, screw], [ca.jacobian(rate, psi)], ["psi_i", "screw"], ["block"])


@lru_cache(maxsize=32)
def _mapped_blocks(count: int) -> ca.Function:
    return _block_function().map(count)


def jacobian_blocks(psi: np.ndarray, screws: np.ndarray) -> np.ndarray:
    """The 3×3 diagonal blocks of ``∂F/∂ψ`` of (13), by CasADi AD, one call for all samples.

    Parameters
    ----------
    psi : array_like, shape (K, 3N)
        States ``(X_1, Y_1, z_1, …)`` at ``K`` instants.
    screws : array_like, shape (K, 3)
        Camera screws ``(V_y, V_z, Ω_x)`` at the same instants.

    Returns
    -------
    numpy.ndarray, shape (K, N, 3, 3)
        ``∂F/∂ψ`` is block diagonal: its eigenvalues are those of the blocks.
    """
    psi = np.asarray(psi, dtype=float)
    screws = np.asarray(screws, dtype=float).reshape(-1, 3)
    k, width = psi.shape
    n = width // 3
    points = psi.reshape(k * n, 3).T
    repeated = np.repeat(screws, n, axis=0).T
    out = to_numpy(_mapped_blocks(k * n)(points, repeated))  # (3, 3 K N)
    return out.reshape(3, k * n, 3).transpose(1, 0, 2).reshape(k, n, 3, 3)


def _rhs_numpy(screw_at: Callable[[float], Sequence[float]], n_points: int) -> Callable[[float, np.ndarray], np.ndarray]:
    """``F(t, ψ)`` of (13) from :func:`visnav.model.feature_depth_rate` (Python floats per point, then one array)."""
    rate = model.feature_depth_rate

    def f(t: float, y: np.ndarray) -> np.ndarray:
        v_y, v_z, omega_x = screw_at(t)
        values = y.tolist()
        out: list[float] = []
        for i in range(0, 3 * n_points, 3):
            out.extend(rate(values[i], values[i + 1], values[i + 2], v_y, v_z, omega_x))
        return np.array(out)

    return f


def _jac_numpy(screw_at: Callable[[float], Sequence[float]], n_points: int) -> Callable[[float, np.ndarray], np.ndarray]:
    """Block-diagonal ``∂F/∂ψ`` from :func:`visnav.model.feature_depth_rate_jacobian` (fast, for Newton).

    The tests check it against :func:`jacobian_blocks` (CasADi AD of the same source).
    """
    block = model.feature_depth_rate_jacobian

    def jac(t: float, y: np.ndarray) -> np.ndarray:
        v_y, v_z, omega_x = screw_at(t)
        values = y.tolist()
        out = np.zeros((3 * n_points, 3 * n_points))
        for i in range(0, 3 * n_points, 3):
            out[i : i + 3, i : i + 3] = block(values[i], values[i + 1], values[i + 2], v_y, v_z, omega_x)
        return out

    return jac


def _rhs_casadi(screw_expr: Callable[[Any], Any], n_points: int) -> ca.Function:
    t = ca.MX.sym("t")
    y = ca.MX.sym("psi", 3 * n_points)
    screw = screw_expr(t)
    rates = []
    for i in range(n_points):
        rates += list(model.feature_depth_rate(y[3 * i], y[3 * i + 1], y[3 * i + 2], screw[0], screw[1], screw[2]))
    return ca.Function("F", [t, y], [ca.vertcat(*rates)], ["t", "psi"], ["psi_dot"])


def reconstruction_problem(
    window: ReconstructionWindow, screw: HistopolantScrew, *, duration: float | None = None
) -> OdeProblem:
    """Equation (13) over the occlusion, driven by the histopolant screw.

    Parameters
    ----------
    window : ReconstructionWindow
        ``y0`` is the true ``ψ`` at the last unoccluded sample.
    screw : HistopolantScrew
    duration : float, optional
        Integrate over ``[t_a, t_a + duration]`` instead of the whole window [s].
    """
    t0 = float(window.times[0])
    t1 = float(window.times[-1]) if duration is None else t0 + float(duration)
    n = window.n_points
    return OdeProblem(
        f=_rhs_numpy(screw, n), jac=_jac_numpy(screw, n), t0=t0, t1=t1, y0=window.psi[0],
        casadi_rhs=_rhs_casadi(screw.casadi, n), name=f"reconstruction of the {window.scenario} occlusion",
    )


def orbit_problem(scenario: Scenario) -> tuple[OdeProblem, Callable[[float], np.ndarray]]:
    """A verification problem with an exact solution: the camera orbiting the scenario's target.

    The robot drives a circle of radius :data:`ORBIT_RADIUS_M` around the
    target's centre at :data:`ORBIT_RATE_RADPS` with the pan at +90°, so the
    camera keeps facing the centre (joint rates ``(ωR, ω, 0)``, a constant
    camera screw).  It starts on the side of the scenario's goal.  The exact
    ``ψ(t)`` comes from the exact pose flow and the projection
    (:func:`visnav.geometry.propagate_pose`, :func:`~visnav.geometry.project_points`),
    not from an integrator.  The image motion is dominated by the rotation
    (eigenvalues near the imaginary axis), so every scheme reaches its
    asymptotic order at steps where its error is still far above round-off.

    Returns
    -------
    (OdeProblem, exact)
        ``exact(t) -> ψ(t)``, shape (3N,).
    """
    points = scenario.target.points_m
    cx = sum(p[0] for p in points) / len(points)
    cy = sum(p[1] for p in points) / len(points)
    gx, gy = scenario.goal.x_m - cx, scenario.goal.y_m - cy
    norm = math.hypot(gx, gy) or 1.0
    dx, dy = gx / norm, gy / norm
    heading = math.atan2(dy, dx) + 0.5 * math.pi
    pose0 = (cx + ORBIT_RADIUS_M * dx, cy + ORBIT_RADIUS_M * dy, heading, 0.5 * math.pi)
    rates = (ORBIT_RATE_RADPS * ORBIT_RADIUS_M, ORBIT_RATE_RADPS, 0.0)
    g = scenario.robot
    screw = model.camera_screw(pose0[3], *rates, g.pan_offset_m, g.camera_forward_m, g.camera_lateral_m)

    def exact(t: float) -> np.ndarray:
        pose = propagate_pose(pose0, *rates, float(t))
        cam = camera_pose(*pose, g)
        return np.array(project_points(*cam, g.camera_height_m, points), dtype=float).reshape(-1)

    def screw_at(t: float) -> tuple[float, float, float]:
        return screw

    n = len(points)
    problem = OdeProblem(
        f=_rhs_numpy(screw_at, n), jac=_jac_numpy(screw_at, n), t0=0.0, t1=ORBIT_DURATION_S, y0=exact(0.0),
        casadi_rhs=_rhs_casadi(lambda t: ca.DM(screw), n), name="orbit verification problem",
    )
    return problem, exact


# --------------------------------------------------------------------------- error measures


def state_error(y: np.ndarray, reference: np.ndarray) -> float:
    """``max`` over rows and points of ``max(|ΔX|, |ΔY|, |Δz|/z)`` (normalised units, dimensionless)."""
    d = np.abs(np.asarray(y, dtype=float) - np.asarray(reference, dtype=float))
    d[:, 2::3] /= np.abs(np.asarray(reference)[:, 2::3])
    return float(d.max())


def paper_metrics(y: np.ndarray, truth: np.ndarray, hidden: np.ndarray, focal_px: float) -> tuple[float, float]:
    """The paper's metrics: max ``f‖s − s̃‖`` [px] and ``1000‖z − z̃‖`` [mm] over the ``hidden`` rows.

    The same norms as :func:`visnav.simulation.compute_metrics` (all points together).
    """
    d = np.asarray(y, dtype=float) - np.asarray(truth, dtype=float)
    n = d.shape[1] // 3
    s = np.delete(d, np.s_[2::3], axis=1)
    z = d[:, 2::3]
    px = focal_px * np.linalg.norm(s, axis=1)
    mm = 1000.0 * np.linalg.norm(z, axis=1)
    mask = np.asarray(hidden, dtype=bool)
    if not mask.any() or n == 0:
        return 0.0, 0.0
    return float(px[mask].max()), float(mm[mask].max())


def metrics_dict(px_mm: tuple[float, float]) -> dict[str, float]:
    """The ``(px, mm)`` of :func:`paper_metrics` as the study's JSON record."""
    return {"max_error_px": px_mm[0], "max_depth_error_mm": px_mm[1]}


# --------------------------------------------------------------------------- spectra


@dataclass(frozen=True, kw_only=True, slots=True)
class Spectrum:
    """Eigenvalues of ``∂F/∂ψ`` of (13) at ``K`` instants.

    Attributes
    ----------
    times : numpy.ndarray, shape (K,)
    eigenvalues : numpy.ndarray of complex, shape (K, 3N)
        Point ``i`` owns columns ``3i .. 3i + 2`` [1/s].
    depths : numpy.ndarray, shape (K, N)
        True depths [m].
    screws : numpy.ndarray, shape (K, 3)
        ``(V_y, V_z, Ω_x)`` used [m/s, m/s, rad/s].
    period : float
        ``h`` for ``h λ`` [s].
    rate_floor : float
        ``1 / window``: rates below it count as this rate in :attr:`stiffness_ratio` [1/s].
    """

    times: np.ndarray
    eigenvalues: np.ndarray
    depths: np.ndarray
    screws: np.ndarray
    period: float
    rate_floor: float

    @property
    def spectral_radius(self) -> np.ndarray:
        """``max_i |λ_i|`` per instant [1/s], shape (K,)."""
        return np.abs(self.eigenvalues).max(axis=1)

    @property
    def stiffness_ratio(self) -> np.ndarray:
        """``max(max_i |Re λ_i|, r) / max(min_i |Re λ_i|, r)`` per instant, ``r`` = :attr:`rate_floor`, shape (K,).

        Lambert's ratio of the fastest to the slowest time scale, with every
        rate below ``r = 1/window`` counted as ``r``: a mode slower than the
        window sets no time scale inside it.  So the ratio is at least 1, and
        exactly 1 when every mode is slower than the window.  (The raw ratio,
        :attr:`lambert_ratio`, is unbounded whenever an eigenvalue crosses zero.)
        """
        re = np.abs(self.eigenvalues.real)
        floor = self.rate_floor
        return np.maximum(re.max(axis=1), floor) / np.maximum(re.min(axis=1), floor)

    @property
    def lambert_ratio(self) -> np.ndarray:
        """The raw ``max |Re λ| / min |Re λ|`` per instant (``inf`` if some ``Re λ = 0``)."""
        re = np.abs(self.eigenvalues.real)
        with np.errstate(divide="ignore"):
            return re.max(axis=1) / re.min(axis=1)


def spectrum(psi: np.ndarray, screws: np.ndarray, times: np.ndarray, period: float, rate_floor: float) -> Spectrum:
    """:class:`Spectrum` of (13) at states ``psi`` (K, 3N) and screws (K, 3) (CasADi AD, batched eigenvalues)."""
    blocks = jacobian_blocks(psi, screws)
    k, n = blocks.shape[:2]
    eig = np.linalg.eigvals(blocks.reshape(k * n, 3, 3)).reshape(k, 3 * n)
    return Spectrum(
        times=_readonly(np.asarray(times, dtype=float)), eigenvalues=_readonly(eig),
        depths=_readonly(np.asarray(psi, dtype=float)[:, 2::3]), screws=_readonly(np.asarray(screws, dtype=float)),
        period=float(period), rate_floor=float(rate_floor),
    )


def _start_screws(result: SimulationResult, indices: np.ndarray) -> np.ndarray:
    trace = result.trace
    g = result.scenario.robot
    return np.array([
        model.camera_screw(float(trace.states[k, 3]), *map(float, trace.inputs[k]), g.pan_offset_m,
                           g.camera_forward_m, g.camera_lateral_m)
        for k in indices
    ]).reshape(-1, 3)


def spectrum_of_run(result: SimulationResult, *, window_s: float | None = None) -> Spectrum | None:
    """:class:`Spectrum` at every sample where the run's estimator reconstructs (``None`` if it never does).

    At sample ``k``: the true ``ψ(t_k)`` and the screw of the period that
    starts there, ``J_r(ϑ_k) q̇_k``.  ``rate_floor = 1/window_s`` (default: the
    total reconstruction time).
    """
    trace = result.trace
    mask = trace.record("reconstructing") > 0
    mask[-1] = False  # the last sample has no period after it
    indices = np.flatnonzero(mask)
    if indices.size == 0:
        return None
    window = window_s if window_s is not None else indices.size * float(trace.period)
    return spectrum(_true_psi(result)[indices], _start_screws(result, indices), trace.times[indices],
                    float(trace.period), 1.0 / window)


def spectrum_summary(spec: Spectrum, h: float) -> dict[str, Any]:
    """Where (13) is fastest along a spectrum, and how far from stiff."""
    eig = spec.eigenvalues
    rho = spec.spectral_radius
    k = int(np.argmax(rho))
    col = int(np.argmax(np.abs(eig[k])))
    ratio = spec.stiffness_ratio
    kr = int(np.argmax(ratio))
    lambert = spec.lambert_ratio
    re = eig.real
    return {
        "samples": int(eig.shape[0]),
        "max_abs_h_lambda": float(h * rho[k]),
        "max_spectral_radius_per_s": float(rho[k]),
        "where_fastest": {
            "t_s": float(spec.times[k]), "point": col // 3, "depth_m": float(spec.depths[k, col // 3]),
            "eigenvalue": complex(eig[k, col]), "screw": tuple(float(v) for v in spec.screws[k]),
        },
        "max_stiffness_ratio": float(ratio[kr]),
        "where_stiffness_ratio": {"t_s": float(spec.times[kr])},
        "median_stiffness_ratio": float(np.median(ratio)),
        "max_lambert_ratio": float(np.max(lambert)) if np.all(np.isfinite(lambert)) else math.inf,
        "max_real_part_per_s": float(re.max()),
        "min_real_part_per_s": float(re.min()),
        "fraction_positive_real_part": float(np.mean(re > 0.0)),
        "min_depth_m": float(spec.depths.min()),
    }


def scheme_margins(eigenvalues: np.ndarray, h: float, window_steps: int) -> dict[str, dict[str, float]]:
    """Per fixed scheme: ``h λ`` inside the region?, first unstable step, spurious growth over the window."""
    lam = np.asarray(eigenvalues, dtype=complex).reshape(-1)
    damped = lam[lam.real <= 0.0]
    out: dict[str, dict[str, float]] = {}
    for scheme in FIXED_STEP_SCHEMES:
        poly = stability_polynomial(scheme)
        if damped.size:
            modulus = max_root_modulus(poly, h * damped)
            inside = float(np.mean(modulus <= 1.0 + 1e-12))
            # log of the largest root over the exact growth e^{h Re λ}: the spurious amplification per step
            excess = float(np.max(np.log(modulus) - h * damped.real))
        else:
            inside, excess = 1.0, 0.0
        out[scheme] = {
            "fraction_inside": inside,
            "first_unstable_step_s": first_unstable_step(poly, damped, h, UNSTABLE_STEP_SEARCH_S, points=60),
            "searched_up_to_s": UNSTABLE_STEP_SEARCH_S,
            "max_spurious_growth_per_step": excess,
            "spurious_growth_over_window": math.exp(max(excess, 0.0) * window_steps),
        }
    return out

WORST_CASE_DEPTHS_M = tuple(float(d) for d in np.geomspace(1e-4, 10.0, 61))
"""Depth grid of the worst-case analysis [m] (ratio 1.21 between neighbours)."""


def worst_case_depths(scenario: Scenario, h: float) -> dict[str, Any]:
    """How close the motions allowed by the actuator limits bring (13) to stiffness, as a function of depth.

    Eigenvalues do not depend on ``X``; the box spans ``Y`` in ``{−Y_max, 0,
    Y_max}`` (image half-width), each joint rate in ``{−max, 0, +max}`` and the
    pan angle on a 10° grid, at every depth of :data:`WORST_CASE_DEPTHS_M` (one
    batched CasADi call).  ``stiff_below_depth_m`` per explicit scheme: the
    depth below which the fastest decay ``h max(−Re λ)`` leaves the scheme's
    real stability interval (classical stiffness), interpolated linearly in
    ``log z`` between grid depths; the BDFs are stable on the whole negative
    real axis (0).
    """
    lim = scenario.limits
    g = scenario.robot
    y_lim = scenario.camera.y_limit
    screws = []
    for v in (-lim.v_max_mps, 0.0, lim.v_max_mps):
        for w in (-lim.omega_max_radps, 0.0, lim.omega_max_radps):
            for p in (-lim.pan_rate_max_radps, 0.0, lim.pan_rate_max_radps):
                for pan in np.radians(np.arange(0.0, 360.0, 10.0)):
                    screws.append(model.camera_screw(float(pan), v, w, p, g.pan_offset_m, g.camera_forward_m,
                                                     g.camera_lateral_m))
    box = np.unique(np.round(np.array(screws), 12), axis=0)
    ys = np.array([-y_lim, 0.0, y_lim])
    depths = np.array(WORST_CASE_DEPTHS_M)
    s_rep = np.tile(np.repeat(box, ys.size, axis=0), (depths.size, 1))
    y_rep = np.tile(ys, box.shape[0] * depths.size)
    z_rep = np.repeat(depths, box.shape[0] * ys.size)
    psi = np.stack([np.zeros_like(y_rep), y_rep, z_rep], axis=1)
    lam = np.linalg.eigvals(jacobian_blocks(psi, s_rep).reshape(-1, 3, 3)).reshape(depths.size, -1)
    decay = np.max(-lam.real, axis=1)  # fastest decay rate per depth [1/s]
    radius = np.max(np.abs(lam), axis=1)
    out: dict[str, Any] = {
        "max_speed_along_axis_mps": float(np.abs(box[:, 1]).max()),
        "max_abs_omega_x_radps": float(np.abs(box[:, 2]).max()),
        "by_depth_m": {f"{d:.3g}": {"spectral_radius_per_s": float(r), "fastest_decay_per_s": float(c)}
                       for d, r, c in zip(depths, radius, decay) if d >= 0.0099 and math.isclose(
                           math.log10(d), round(math.log10(d)), abs_tol=1e-9)},
        "stiff_below_depth_m": {},
    }
    log_z = np.log(depths)
    for scheme in FIXED_STEP_SCHEMES:
        limit = -real_stability_interval(stability_polynomial(scheme))
        excess = h * decay - limit  # decreasing with depth
        if math.isinf(limit) or excess[0] <= 0.0:
            out["stiff_below_depth_m"][scheme] = 0.0
        elif excess[-1] >= 0.0:
            out["stiff_below_depth_m"][scheme] = math.inf
        else:
            j = int(np.flatnonzero(excess < 0.0)[0])
            frac = excess[j - 1] / (excess[j - 1] - excess[j])
            out["stiff_below_depth_m"][scheme] = float(math.exp(log_z[j - 1] + frac * (log_z[j] - log_z[j - 1])))
    return out


# --------------------------------------------------------------------------- random scenarios


def random_scenarios(base: Scenario, count: int, seed: int) -> tuple[Scenario, ...]:
    """``count`` seeded perturbations of ``base``: occluders, start pose and gains.

    Each occluding obstacle's centre moves by up to ±0.3 m per axis and its
    radius by a factor 0.85–1.25; the start ``y`` by ±0.3 m and heading by
    ±0.1 rad; ``λ_gc`` by a factor 0.75–1.5, ``k`` by 0.75–1.25 and
    ``v_coll`` is drawn in 0.15–0.3 m/s.  Same seed, same scenarios.

    The moves are a :class:`visnav.perturbation.Perturbation` applied by
    :func:`visnav.perturbation.apply_perturbation` to unit draws of
    ``numpy.random.default_rng(seed)``.  The scenarios are *not* validated: they
    probe the estimator's stiffness, and some break the paper's hypotheses
    (e.g. obstacles less than 2 d+ apart after the moves); validating would
    change the study.
    """
    from visnav.perturbation import Move, Perturbation, Uniform, apply_perturbation

    moves: list[Move] = []
    for j, o in enumerate(base.obstacles):
        if o.occludes(base.robot.camera_height_m):
            moves += [Move(field=f"obstacles[{j}].x_m", change="offset", draw=Uniform(low=-0.3, high=0.3)),
                      Move(field=f"obstacles[{j}].y_m", change="offset", draw=Uniform(low=-0.3, high=0.3)),
                      Move(field=f"obstacles[{j}].radius_m", change="factor", draw=Uniform(low=0.85, high=1.25))]
    moves += [
        Move(field="start.y_m", change="offset", draw=Uniform(low=-0.3, high=0.3)),
        Move(field="start.theta_rad", change="offset", draw=Uniform(low=-0.1, high=0.1)),
        Move(field="gains.lambda_gc", change="factor", draw=Uniform(low=0.75, high=1.5)),
        Move(field="gains.k_path", change="factor", draw=Uniform(low=0.75, high=1.25)),
        Move(field="gains.v_coll_mps", change="value", draw=Uniform(low=0.15, high=0.3)),
    ]
    perturbation = Perturbation(moves=tuple(moves))
    rng = np.random.default_rng(seed)
    return tuple(
        apply_perturbation(base, perturbation, perturbation.from_unit(rng.random(perturbation.size)),
                           name=f"{base.name}-random-{seed}-{i}", validate=False).scenario
        for i in range(count)
    )


# --------------------------------------------------------------------------- estimator replays


def replay_estimator(window: ReconstructionWindow, settings: EstimatorSettings) -> np.ndarray:
    """The production estimator over the window, from the measured history.

    Observes the :data:`HISTORY_PERIODS` periods before the occlusion, starts
    with a full history and advances once per period with the ZOH records.

    Returns
    -------
    numpy.ndarray, shape (n + 1, 3N)
        Row 0 is the measured ``ψ(t_a)``.
    """
    n = window.n_points

    def as_points(row: np.ndarray) -> tuple[tuple[float, float, float], ...]:
        return tuple((float(row[3 * i]), float(row[3 * i + 1]), float(row[3 * i + 2])) for i in range(n))

    est = FeatureEstimator(window.geometry, settings)
    est.observe(as_points(window.history_psi[0]))
    for k in range(HISTORY_PERIODS):
        est.observe(as_points(window.history_psi[k + 1]), float(window.history_pans[k]),
                    tuple(map(float, window.history_rates[k])), window.period)
    est.start(require_full_history=True)
    out = [np.array(window.psi[0])]
    for k in range(window.pans.size):
        psi = est.advance(float(window.pans[k]), tuple(map(float, window.joint_rates[k])), window.period)
        out.append(np.array(psi, dtype=float).reshape(-1))
    return np.array(out)


def replay_zoh_rk4(window: ReconstructionWindow, substeps: int) -> np.ndarray:
    """Classical RK4 on the exact ODE of every ZOH period (:func:`visnav.estimator.zoh_period_rk4`).

    ``substeps`` RK4 steps per period, the screw ``J_r(ϑ_k + ϖ τ) q̇_k`` evaluated at
    the stage times: the input model of the period is exact, only RK4's
    truncation remains.  Returns shape ``(n + 1, 3N)`` like :func:`replay_estimator`.
    """
    n = window.n_points
    psi = tuple(tuple(map(float, window.psi[0][3 * i : 3 * i + 3])) for i in range(n))
    out = [np.array(window.psi[0])]
    for k in range(window.pans.size):
        record = held_inputs(float(window.pans[k]), tuple(map(float, window.joint_rates[k])), window.period,
                             window.geometry)
        psi = zoh_period_rk4(psi, record, window.geometry, substeps=substeps)
        out.append(np.array(psi, dtype=float).reshape(-1))
    return np.array(out)

