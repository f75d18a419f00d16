"""Frozen parameter records of the robot, the camera, the environment and the controllers.

All lengths are in metres, angles in radians, image distances in pixels,
times in seconds.  These records carry values only; validation of user input
(with messages that name the key) lives in :mod:`visnav.scenario`, and the
dataclasses re-check the invariants that the numerics rely on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from analysis.verify.requirements import Requirement

__all__ = [
    "K_PATH_RANGE",
    "PATH_CLEARANCE_M",
    "RobotGeometry",
    "CameraModel",
    "Envelopes",
    "Gains",
    "ActuatorLimits",
    "EstimatorSettings",
    "SupervisorSettings",
    "Obstacle",
    "Target",
    "Pose",
    "Scenario",
]


K_PATH_RANGE = (1e-3, 1e3)
"""Certified range ``[low, high]`` of the path-following gain ``k`` of (11) [1/m].

The interval the Lyapunov certificate of the path-following law covers and the
admissible-gain search scans (:mod:`visnav.studies.path_following`,
:mod:`visnav.studies.loop_analysis`).  :mod:`visnav.scenario` refuses a
``gains.k_path`` outside it, so that every command accepts the same scenarios."""

PATH_CLEARANCE_M = 0.1
"""Clearance [m] the admissible path-following gains of ``visnav analyse`` and ``visnav report``
must guarantee by default (the value of :data:`visnav.studies.loop_analysis.DEFAULT_CLEARANCE_M`).

The analysis needs it inside the avoidance envelope, ``clearance < d0``, so
:mod:`visnav.scenario` refuses ``envelopes.d_zero_m <= PATH_CLEARANCE_M``: a scenario that
``visnav simulate`` accepts is then analysed by ``visnav analyse`` and ``visnav report`` too."""


@dataclass(frozen=True, kw_only=True, slots=True)
class RobotGeometry:
    """Cart and pan-platform geometry.

    Attributes
    ----------
    pan_offset_m : float
        ``Dx``: distance from the reference point M to the pan centre P [m].
    camera_forward_m, camera_lateral_m : float
        ``(a, b)``: camera offset in the pan frame [m].
    camera_height_m : float
        Height of the optical centre above the floor [m].
    """

    pan_offset_m: float = 0.1
    camera_forward_m: float = 0.0
    camera_lateral_m: float = 0.03
    camera_height_m: float = 0.5


@dataclass(frozen=True, kw_only=True, slots=True)
class CameraModel:
    """Pinhole camera: focal length and image half-sizes, all in pixels."""

    focal_px: float = 500.0
    half_width_px: float = 320.0
    half_height_px: float = 240.0

    @property
    def y_limit(self) -> float:
        """Normalised half-width ``Y_max = half_width / f`` (horizontal image bound)."""
        return self.half_width_px / self.focal_px

    @property
    def x_limit(self) -> float:
        """Normalised half-height ``X_max = half_height / f`` (vertical image bound)."""
        return self.half_height_px / self.focal_px


@dataclass(frozen=True, kw_only=True, slots=True)
class Envelopes:
    """Collision envelopes ``d- < d0 < d+`` [m] and occlusion envelopes ``D- < D0 < D+`` [px]."""

    d_minus_m: float = 0.3
    d_zero_m: float = 0.5
    d_plus_m: float = 0.6
    D_minus_px: float = 40.0
    D_zero_px: float = 60.0
    D_plus_px: float = 80.0


@dataclass(frozen=True, kw_only=True, slots=True)
class Gains:
    """Controller gains.

    Attributes
    ----------
    lambda_vs : float
        Visual-servoing gain λ_VS of (7) [1/s].
    lambda_occ : float
        Occlusion-avoidance gain λ_occ of (9) [1/s].
    beta_occ : float
        Weight β_occ of the secondary (tracking) criterion in (8) [-].
    lambda_gc : float
        Pan-platform centring gain λ_gc of (16)–(17) [1/s].
    k_path : float
        Path-following gain k of (11) [1/m].
    v_coll_mps : float
        Constant linear velocity during avoidance v_coll [m/s].
    """

    lambda_vs: float = 0.3
    lambda_occ: float = 0.3
    beta_occ: float = 0.5
    lambda_gc: float = 2.0
    k_path: float = 2.0
    v_coll_mps: float = 0.2


@dataclass(frozen=True, kw_only=True, slots=True)
class ActuatorLimits:
    """Stated actuator limits; the paper's loop reports (never clips) any excess, a saturated loop clips to them
    (:func:`visnav.closed_loop.clip_command`)."""

    v_max_mps: float = 0.6
    omega_max_radps: float = 1.0
    pan_rate_max_radps: float = 1.5


@dataclass(frozen=True, kw_only=True, slots=True)
class EstimatorSettings:
    """Feature/depth reconstruction settings (see :mod:`visnav.estimator`).

    Attributes
    ----------
    order : int
        BDF order, 1–6 (4 as in the paper).
    screw_model : str
        How the camera screw entering the implicit step is taken over a
        sampling period under zero-order hold (see ``docs/estimator.md``).
    newton_tol : float
        Newton corrector tolerance on the update (max norm) [-, m].
    newton_maxiter : int
        Newton iteration limit; exceeding it raises an error naming the residual.
    """

    order: int = 4
    screw_model: str = "histopolated"
    newton_tol: float = 1e-12
    newton_maxiter: int = 8


@dataclass(frozen=True, kw_only=True, slots=True)
class SupervisorSettings:
    """Design choices of the supervisor automaton that the paper leaves open.

    Attributes
    ----------
    arm_angle_rad : float
        |ϑ| the pan angle must exceed during avoidance before a return of ϑ
        to zero counts as "obstacle overcome" (arming of the LEAVE condition).
    detection_hysteresis_m : float
        Hysteresis beyond d+ before an approached obstacle is forgotten.
    """

    arm_angle_rad: float = 0.2
    detection_hysteresis_m: float = 0.02


@dataclass(frozen=True, kw_only=True, slots=True)
class Obstacle:
    """A vertical circular cylinder standing on the floor.

    Obstacles lower than the camera are a collision risk only; taller ones
    also occlude (they are treated as unbounded upwards in the image).
    """

    name: str
    center_m: tuple[float, float]
    radius_m: float
    height_m: float

    def occludes(self, camera_height_m: float) -> bool:
        """Whether the obstacle is tall enough to hide features from the camera."""
        return self.height_m >= camera_height_m


@dataclass(frozen=True, kw_only=True, slots=True)
class Target:
    """A planar target of points in the world frame, each ``(x, y, height)`` [m]."""

    points_m: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True, kw_only=True, slots=True)
class Pose:
    """Robot configuration ``(x, y, theta, pan)`` [m, m, rad, rad]."""

    x_m: float = 0.0
    y_m: float = 0.0
    theta_rad: float = 0.0
    pan_rad: float = 0.0

    def as_tuple(self) -> tuple[float, float, float, float]:
        """``(x, y, theta, pan)``."""
        return (self.x_m, self.y_m, self.theta_rad, self.pan_rad)


@dataclass(frozen=True, kw_only=True, slots=True)
class Scenario:
    """Everything one closed-loop run needs.

    Attributes
    ----------
    goal : Pose
        The robot configuration whose image of the target defines ``s*``.
    sampling_period_s : float
        ``T_e``, also the estimator's integration step ``h`` [s].
    duration_s : float
        Simulated time limit [s].
    success_tolerance_px : float
        The task succeeds when ``max_i |s_i - s*_i|·f`` falls below this.
    requirements : tuple of analysis.verify.requirements.Requirement
        STL requirements on the run's signals (``docs/requirements.md``), checked
        against :func:`visnav.requirements.signal_catalogue` when the scenario is loaded.
    """

    name: str
    description: str = ""
    robot: RobotGeometry = field(default_factory=RobotGeometry)
    camera: CameraModel = field(default_factory=CameraModel)
    envelopes: Envelopes = field(default_factory=Envelopes)
    gains: Gains = field(default_factory=Gains)
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    estimator: EstimatorSettings = field(default_factory=EstimatorSettings)
    supervisor: SupervisorSettings = field(default_factory=SupervisorSettings)
    obstacles: tuple[Obstacle, ...] = ()
    target: Target
    start: Pose
    goal: Pose
    sampling_period_s: float = 0.05
    duration_s: float = 120.0
    success_tolerance_px: float = 1.0
    requirements: tuple[Requirement, ...] = ()

    def __post_init__(self) -> None:
        if not (self.sampling_period_s > 0 and math.isfinite(self.sampling_period_s)):
            raise ValueError(
                f"Scenario.sampling_period_s = {self.sampling_period_s!r}: expected a positive finite period [s]"
            )
