"""The paper's closed loop as a sampled-data system around the supervisor automaton.

:class:`ClosedLoop` implements :class:`hybrid.sampled.SampledController`:
at every sample it measures (camera image and proximity sensors, from the
exact geometry), advances the feature/depth estimator over the period that
just ended, and, once the supervisor has jumped, computes the global control
(19) from the risk parameters of the new mode.  The plant is the cart with its
pan-platform, integrated exactly under zero-order hold.

The loop applies the demand (19) as it is (the paper's loop), or, with
``saturate=True``, clipped to the actuator limits of the scenario's
``[limits]`` (:func:`clip_command`, the one place where a command is
clipped): the plant and the estimator then move with the applied command,
and the demand is recorded (:data:`DEMAND_RECORDS`) next to it.

Per-sample cost matters (the paper scenario must run 1000× faster than real
time): everything here works on Python floats and tuples.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from hybrid import HybridSystem, Plant

from visnav.controllers import (
    avoidance_control,
    blend,
    occlusion_avoidance,
    pan_tracking,
    path_following,
    visual_servoing,
)
from visnav import model
from visnav.estimator import FeatureEstimator
from visnav.geometry import (
    ImageMeasurement,
    camera_pose,
    choose_bypass_side,
    image_measurement,
    project_points,
    propagate_pose,
    proximity,
    wrap_angle,
)
from visnav.parameters import ActuatorLimits, Scenario
from visnav.supervisor import SupervisorModel, build_supervisor, split_mode

__all__ = ["ClosedLoop", "LoopState", "Observation", "robot_plant", "desired_features", "record_names",
           "clip_command", "DEMAND_RECORDS"]

Point = tuple[float, float, float]

DEMAND_RECORDS = ("v_demand_mps", "omega_demand_radps", "pan_rate_demand_radps")
"""Records of a saturating loop (:attr:`ClosedLoop.saturate`): the demand (19) ``(v, ω, ϖ)`` before clipping
[m/s, rad/s, rad/s] (the trace's inputs are the applied, clipped command)."""


def clip_command(u: Sequence[float], limits: ActuatorLimits) -> tuple[float, float, float]:
    """The command ``(v, ω, ϖ)`` each clipped to ``[-max, max]`` of its actuator limit.

    Parameters
    ----------
    u : (v, ω, ϖ)
        Demanded linear velocity [m/s], angular velocity of the base [rad/s] and pan rate [rad/s].
    limits : ActuatorLimits
        ``v_max_mps``, ``omega_max_radps``, ``pan_rate_max_radps`` (positive).

    Returns
    -------
    (v, ω, ϖ)
        The applied command: each component independently saturated (the actuators are
        independent); a NaN stays NaN (the executor reports it).
    """
    out = []
    for value, bound in zip(u, (limits.v_max_mps, limits.omega_max_radps, limits.pan_rate_max_radps)):
        value = float(value)
        out.append(-bound if value < -bound else (bound if value > bound else value))
    return out[0], out[1], out[2]


def robot_plant() -> Plant:
    """The cart with pan-platform: state ``(x, y, theta, pan)``, input ``(v, omega, pan_rate)``."""

    def derivative(x: Sequence[float], u: Sequence[float]) -> tuple[float, float, float, float]:
        return model.pose_rates(x[2], u[0], u[1], u[2])

    def exact(x: Sequence[float], u: Sequence[float], dt: float) -> tuple[float, float, float, float]:
        return propagate_pose((x[0], x[1], x[2], x[3]), u[0], u[1], u[2], dt)

    return Plant(
        state_names=("x_m", "y_m", "theta_rad", "pan_rad"),
        input_names=("v_mps", "omega_radps", "pan_rate_radps"),
        derivative=derivative,
        exact_flow=exact,
    )


def desired_features(scenario: Scenario) -> tuple[Point, ...]:
    """Features ``(X*, Y*, z*)`` of the target seen from the goal pose."""
    goal = scenario.goal
    cam = camera_pose(goal.x_m, goal.y_m, goal.theta_rad, goal.pan_rad, scenario.robot)
    return project_points(*cam, scenario.robot.camera_height_m, scenario.target.points_m)


def record_names(n_points: int, saturate: bool = False) -> tuple[str, ...]:
    """Names of the values :meth:`ClosedLoop.control` records each sample for ``n_points`` points.

    A saturating loop (``saturate``) records the demand (:data:`DEMAND_RECORDS`) last.
    """
    names = ["mu_coll", "mu_occ"]
    names += [f"{c}{i}" for i in range(n_points) for c in ("X", "Y")]
    names += [f"{c}{i}_est" for i in range(n_points) for c in ("X", "Y")]
    names += [f"z{i}" for i in range(n_points)]
    names += [f"z{i}_est" for i in range(n_points)]
    names += ["n_hidden", "n_occluded", "reconstructing", "clearance_m", "feature_error_px"]
    names += ["occluder_y_minus", "occluder_y_plus"]
    if saturate:
        names += DEMAND_RECORDS
    return tuple(names)


@dataclass(frozen=True, kw_only=True, slots=True)
class Observation:
    """What the sensors give at one state.

    Attributes
    ----------
    features : tuple of (X, Y, z)
        True image features of the target points.
    image : ImageMeasurement
        Visibility, occluder, d_occ, d_bord.
    clearance : float
        Distance to the nearest obstacle surface [m].
    feature_error_px : float
        ‖s − s*‖ in pixels.
    signals : tuple of float
        The supervisor's signals (:data:`visnav.supervisor.SIGNALS` + one distance per obstacle).
    """

    features: tuple[Point, ...]
    image: ImageMeasurement
    clearance: float
    feature_error_px: float
    signals: tuple[float, ...]


@dataclass(kw_only=True, slots=True)
class LoopState:
    """Controller-side state carried from sample to sample (owned by one run)."""

    estimator: FeatureEstimator
    reconstructing: bool = False
    samples: int = 0
    last_input: tuple[float, float, float] = (0.0, 0.0, 0.0)
    last_pan: float = 0.0
    true_features: tuple[Point, ...] = ()
    estimated: tuple[Point, ...] = ()
    image: ImageMeasurement | None = None
    clearance: float = math.inf
    feature_error_px: float = math.inf


@dataclass(frozen=True, kw_only=True, slots=True)
class ClosedLoop:
    """Measurement, supervision and control of the paper's robot.

    Attributes
    ----------
    scenario : Scenario
    supervisor : SupervisorModel
    desired : tuple of (X*, Y*, z*)
        Image of the target at the goal pose.
    saturate : bool
        Clip the applied command to ``scenario.limits`` (:func:`clip_command`); the demand (19)
        is recorded as :data:`DEMAND_RECORDS`.  Default ``False``: the paper's loop, which
        applies the demand as it is.
    """

    scenario: Scenario
    saturate: bool = False
    supervisor: SupervisorModel = field(init=False)
    desired: tuple[Point, ...] = field(init=False)
    record_names: tuple[str, ...] = field(init=False)
    _desired_xy: tuple[tuple[float, float], ...] = field(init=False, repr=False)
    _y_gc_desired: float = field(init=False, repr=False)
    _occluding: tuple[bool, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        s = self.scenario
        object.__setattr__(self, "supervisor", build_supervisor(s.envelopes, s.supervisor, len(s.obstacles)))
        desired = desired_features(s)
        object.__setattr__(self, "desired", desired)
        object.__setattr__(self, "_desired_xy", tuple((p[0], p[1]) for p in desired))
        object.__setattr__(self, "_y_gc_desired", sum(p[1] for p in desired) / len(desired))
        object.__setattr__(
            self, "_occluding", tuple(o.occludes(s.robot.camera_height_m) for o in s.obstacles)
        )
        object.__setattr__(self, "record_names", record_names(len(s.target.points_m), self.saturate))

    # ------------------------------------------------------------------ protocol
    def initial_state(self, t: float, x: Sequence[float]) -> LoopState:
        """A fresh estimator, not reconstructing."""
        s = self.scenario
        return LoopState(
            estimator=FeatureEstimator(s.robot, s.estimator),
            last_pan=float(x[3]),
        )

    def observe(self, x: Sequence[float]) -> Observation:
        """Camera image and proximity measurements at the state ``x`` (pure)."""
        s = self.scenario
        px, py, theta, pan = x
        cam = camera_pose(px, py, theta, pan, s.robot)
        true = project_points(*cam, s.robot.camera_height_m, s.target.points_m)
        image = image_measurement(
            cam, s.robot.camera_height_m, true, s.target.points_m, s.obstacles, s.camera, self._occluding,
        )
        distances = []
        nearest, d_nearest = -1, math.inf
        for i, obstacle in enumerate(s.obstacles):
            ox, oy = obstacle.center_m
            d = math.hypot(px - ox, py - oy) - obstacle.radius_m
            distances.append(d)
            if d < d_nearest:
                nearest, d_nearest = i, d
        side = choose_bypass_side(px, py, theta, s.obstacles[nearest]) if nearest >= 0 else 0
        f = s.camera.focal_px
        feature_error = f * math.sqrt(
            sum((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 for a, b in zip(true, self.desired))
        )
        signals = (
            d_nearest,
            float(max(nearest, 0)),
            float(side),
            image.d_occ_px,
            image.d_bord_px,
            wrap_angle(pan),
            *distances,
        )
        return Observation(
            features=true, image=image, clearance=d_nearest, feature_error_px=feature_error, signals=signals
        )

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        """Image and proximity measurements at a sample; advances the estimator."""
        s = self.scenario
        obs = self.observe(x)
        true = obs.features
        if c.reconstructing:
            estimated = c.estimator.advance(c.last_pan, c.last_input, s.sampling_period_s)
        else:
            if c.samples:
                c.estimator.observe(true, c.last_pan, c.last_input, s.sampling_period_s)
            else:
                c.estimator.observe(true)
            estimated = true
        c.samples += 1
        c.true_features = true
        c.estimated = estimated
        c.image = obs.image
        c.clearance = obs.clearance
        c.feature_error_px = obs.feature_error_px
        return obs.signals, c

    def control(
        self,
        t: float,
        x: Sequence[float],
        c: LoopState,
        v: Sequence[float],
        mode: str,
        memory: Mapping[str, float],
    ) -> tuple[tuple[float, float, float], LoopState, tuple[float, ...]]:
        """Global control (19) in ``mode``, applied through :meth:`actuate`; starts/stops the reconstruction.

        The reconstruction runs while µ_occ > 0.

        Returns the applied command (what the plant integrates and the estimator's screw
        reads), the state and the row of :attr:`record_names` (with the demand last when
        :attr:`saturate`).
        """
        px, py, theta, pan = x
        collision, occlusion = split_mode(mode)
        mu_coll = self.supervisor.mu_coll(collision, v, memory)
        mu_occ = self.supervisor.mu_occ(occlusion, v, memory)
        # Open question 11: reconstruction runs exactly while mu_occ > 0; it starts
        # from the measured history (the current sample is already in it).
        if mu_occ > 0.0 and not c.reconstructing:
            c.estimator.start()
            c.reconstructing = True
        elif mu_occ == 0.0 and c.reconstructing:
            c.estimator.stop()
            c.reconstructing = False
            c.estimated = c.true_features
        image = c.image
        assert image is not None
        demand = self.command(x, v, image, _merge(c.true_features, c.estimated, image.visible), c.estimated, mode,
                              memory, risk=(mu_coll, mu_occ))
        u = self.actuate(demand)
        c.last_input = u
        c.last_pan = pan
        n_hidden = sum(1 for vis in image.visible if not vis)
        n_occluded = sum(1 for occ in image.occluded if occ)
        row = [mu_coll, mu_occ]
        for p in c.true_features:
            row += (p[0], p[1])
        for p in c.estimated:
            row += (p[0], p[1])
        row += [p[2] for p in c.true_features]
        row += [p[2] for p in c.estimated]
        row += [float(n_hidden), float(n_occluded), float(c.reconstructing), c.clearance, c.feature_error_px]
        row += [image.y_o_minus, image.y_o_plus]
        if self.saturate:
            row += demand
        return u, c, tuple(row)

    def actuate(self, demand: tuple[float, float, float]) -> tuple[float, float, float]:
        """The command the robot applies for ``demand`` (v, ω, ϖ): clipped to the limits when :attr:`saturate`."""
        return clip_command(demand, self.scenario.limits) if self.saturate else demand

    def command(
        self,
        x: Sequence[float],
        v: Sequence[float],
        image: ImageMeasurement,
        features: tuple[Point, ...],
        estimated: tuple[Point, ...],
        mode: str,
        memory: Mapping[str, float],
        *,
        risk: tuple[float, float] | None = None,
    ) -> tuple[float, float, float]:
        """The global control (19) ``(v, ω, ϖ)`` in ``mode`` (pure).

        Parameters
        ----------
        x : (x, y, θ, ϑ)
            Robot pose and pan angle [m, m, rad, rad].
        v : sequence of float
            Supervisor signals at ``x``.
        image : ImageMeasurement
            Visibility and occluder of the current image.
        features : tuple of (X, Y, z)
            Features used by the image-based tasks: measured where visible,
            reconstructed elsewhere.
        estimated : tuple of (X, Y, z)
            Reconstructed features (pan tracking on the reconstructed target).
        risk : (µ_coll, µ_occ) or None
            The mode's risk parameters at ``v`` when the caller has them already.
        """
        s = self.scenario
        g = s.gains
        px, py, theta, pan = x
        mu_coll, mu_occ = self.supervisor.risk(mode, v, memory) if risk is None else risk
        w_vs = (1.0 - mu_occ) * (1.0 - mu_coll)
        w_occ = (1.0 - mu_coll) * mu_occ
        q_vs = (
            visual_servoing(features, self._desired_xy, pan, s.robot, g.lambda_vs, self.desired)
            if w_vs > 0.0
            else None
        )
        q_occ = None
        if w_occ > 0.0:
            if image.occluder_index >= 0 and math.isfinite(image.d_occ_px):
                q_occ = occlusion_avoidance(
                    features, self._desired_xy, image, pan, s.robot, s.camera, s.envelopes, g.lambda_occ, g.beta_occ
                )
            else:  # no occluder in front any more: the occlusion task is void
                q_occ = visual_servoing(features, self._desired_xy, pan, s.robot, g.lambda_vs, self.desired)
        q_coll = None
        if mu_coll > 0.0:
            obstacle = s.obstacles[int(memory["obstacle"])]
            prox = proximity(px, py, theta, obstacle, int(memory["side"]))
            v_coll, omega_coll = path_following(prox, s.envelopes.d_zero_m, g.v_coll_mps, g.k_path)
            pan_real = (
                pan_tracking(features, pan, v_coll, omega_coll, s.robot, g.lambda_gc, self._y_gc_desired)
                if mu_occ < 1.0
                else None
            )
            pan_rec = (
                pan_tracking(estimated, pan, v_coll, omega_coll, s.robot, g.lambda_gc, self._y_gc_desired)
                if mu_occ > 0.0
                else None
            )
            q_coll = avoidance_control(v_coll, omega_coll, pan_real, pan_rec, mu_occ)
        return blend(mu_coll, mu_occ, q_vs, q_occ, q_coll)

    def continuous_system(self) -> HybridSystem:
        """The loop with the controller evaluated continuously (no sampling, no hold).

        The command is :meth:`actuate` of (19) (clipped when :attr:`saturate`).  State ``(x, y, θ, ϑ)``; the
        output is the supervisor's signals of
        :meth:`observe`; every mode's flow is the cart kinematics under the
        control (19) of that mode.  The feature/depth estimator is ideal: in
        continuous time, integrating (13) exactly from the last measured image
        gives the true features, so the reconstructed features *are* the true
        ones (the T → 0 limit of the sampled estimator, whose error is
        measured in ``docs/estimator.md``).  No jump maps: the supervisor only
        resets its memory.
        """

        def flow_of(mode: str) -> Callable[[float, Sequence[float], Mapping[str, float]], tuple[float, ...]]:
            def flow(t: float, x: Sequence[float], memory: Mapping[str, float]) -> tuple[float, ...]:
                obs = self.observe(x)
                u = self.actuate(self.command(x, obs.signals, obs.image, obs.features, obs.features, mode, memory))
                return model.pose_rates(x[2], u[0], u[1], u[2])

            return flow

        automaton = self.supervisor.automaton
        return HybridSystem(
            automaton=automaton,
            state_names=robot_plant().state_names,
            flows={mode: flow_of(mode) for mode in automaton.mode_names},
            output=lambda t, x: self.observe(x).signals,
        )

    def continuous_stops(self) -> dict[str, Callable[[float, Sequence[float], str, Mapping[str, float]], float]]:
        """Stop functions of :meth:`continuous_system`: ``collision`` and ``success`` (as :meth:`stop`)."""
        tolerance = self.scenario.success_tolerance_px

        def collision(t: float, x: Sequence[float], mode: str, memory: Mapping[str, float]) -> float:
            return -self.observe(x).clearance

        def success(t: float, x: Sequence[float], mode: str, memory: Mapping[str, float]) -> float:
            if mode != "FAR|CLEAR":
                return -math.inf
            return tolerance - self.observe(x).feature_error_px

        return {"collision": collision, "success": success}

    def stop(
        self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str, memory: Mapping[str, float]
    ) -> str | None:
        """Termination: ``"collision"``, ``"success"`` or ``None`` to go on."""
        if c.clearance <= 0.0:
            return "collision"
        if c.feature_error_px <= self.scenario.success_tolerance_px and mode == "FAR|CLEAR":
            return "success"
        return None


def _merge(true: tuple[Point, ...], estimated: tuple[Point, ...], visible: tuple[bool, ...]) -> tuple[Point, ...]:
    """Measured features where visible, reconstructed ones elsewhere."""
    return tuple(t if vis else e for t, e, vis in zip(true, estimated, visible))

