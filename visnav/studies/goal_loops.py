"""Stability of the loops around the goal: visual servoing (7), the pan task (16), the full closed loop.

One symbolic source: every expression is composed in CasADi from the
functions of :mod:`visnav.model` that the simulation evaluates with floats —
the camera pose and the pinhole projection of the target points, the
interaction rows (5), the reduced Jacobian (1) and its inverse, the cart
kinematics — so the Jacobians below are automatic derivatives of the code
that runs, not of a re-derivation.  A test evaluates these models against
:mod:`visnav.controllers` on random poses.

Visual servoing (7) around the goal pose ``p* = (x*, y*, θ*, ϑ*)``:
``e_VS(p) = C (s(p) − s*)`` with the constant ``C = L*⁺`` and
``q̇ = −λ_VS J_r(ϑ)⁻¹ e_VS``.  With ``E = ∂e_VS/∂p`` and ``G`` the cart
kinematics (``ṗ = G q̇``), ``E G = C L* J_r = J_r`` at the goal (the AD of the
projection reproduces the analytic interaction matrix), so

* the task ``e_VS`` obeys ``ė = −λ_VS e`` to first order: three eigenvalues
  ``−λ_VS`` (closed form);
* the full 4-state loop in ``p`` has ``A = −λ_VS G J_r⁻¹ E``, whose nonzero
  eigenvalues are those of ``−λ_VS E G J_r⁻¹ = −λ_VS I`` (``AB`` and ``BA``
  share them) and whose fourth eigenvalue is **0**: the features depend on
  the camera pose ``(c_x, c_y, φ)`` only (3 numbers) while the robot pose has 4,
  so the poses with the camera at its goal pose form a curve of equilibria
  (the base turned about the camera, the pan counter-turned).  The loop is
  exponentially stable in the image and in the camera pose, not in the base
  pose: it converges to a point of that curve.  The zero eigenvector lies in
  the kernel of ``∂(c_x, c_y, φ)/∂p`` (checked).

The pan task (16): ``e_gc = mean(Y_i) − Y*_gc`` and
``ϖ = −(λ_gc e_gc + L̄_Y T_base)/(L̄_Y J_ϖ)`` with ``L̄_Y`` the mean of the
``L_Y`` rows; because ``L̄_Y`` is the exact derivative of the mean,
``ė_gc = −λ_gc e_gc`` holds identically for every pose and every base motion
``(v, ω)`` (checked symbolically below and numerically in the tests); with
the base at rest at the goal, the pan loop in ``ϑ`` has the eigenvalue
``−λ_gc``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from analysis.linearise import Linearisation, linearise
from hybrid.jsonable import to_jsonable

from visnav import model
from visnav.parameters import Scenario

__all__ = [
    "VisualServoingModel",
    "visual_servoing_model",
    "PanTaskModel",
    "pan_task_model",
    "GoalLoopFindings",
    "goal_loop_findings",
]

_POSE_NAMES = ("x_m", "y_m", "theta_rad", "pan_rad")


def _pose_symbol() -> Any:
    return ca.SX.sym("pose", 4)


def _projections(scenario: Scenario, pose: Any) -> tuple[tuple[Any, Any, Any], ...]:
    """``(X_i, Y_i, z_i)`` of every target point as CasADi expressions of the pose."""
    robot = scenario.robot
    cam = model.camera_centre(pose[0], pose[1], pose[2], pose[3], robot.pan_offset_m, robot.camera_forward_m,
                              robot.camera_lateral_m, ops=ca)
    return tuple(model.project_world_point(*cam, robot.camera_height_m, wx, wy, wh, ops=ca)
                 for wx, wy, wh in scenario.target.points_m)


def _goal_pose(scenario: Scenario) -> tuple[float, float, float, float]:
    g = scenario.goal
    return (g.x_m, g.y_m, g.theta_rad, g.pan_rad)


def _numeric(function: ca.Function, *args: Any) -> np.ndarray:
    return np.array(function(*args).full(), dtype=float)


def _validate_gain(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} = {value!r}; expected a finite gain > 0 [1/s] (the scenario's [gains] table)")
    return float(value)


@dataclass(frozen=True, kw_only=True, slots=True)
class VisualServoingModel:
    """Visual servoing (7) at the goal, symbolic in the robot pose.

    Attributes
    ----------
    lambda_vs : float
        Gain λ_VS [1/s].
    goal : tuple of 4 float
        Goal pose ``(x, y, θ, ϑ)`` [m, m, rad, rad]: the equilibrium.
    desired : tuple of (X*, Y*, z*)
        Features at the goal (from the float code path).
    task_matrix : ndarray, shape (3, 8)
        ``C = (L*ᵀ L*)⁻¹ L*ᵀ``, columns ``(X_0, Y_0, X_1, ...)``.
    pose : casadi.SX, shape (4, 1)
    features, error, joint_rates, rates : casadi.SX
        ``s(p)`` (2n), ``e_VS(p)`` (3), ``q̇(p)`` by (7) (3), ``ṗ(p)`` (4).
    camera : casadi.SX, shape (3, 1)
        Camera pose ``(c_x, c_y, φ)`` of the pose.
    function : casadi.Function
        ``F(p) -> ṗ``, the full closed loop.
    offsets : tuple of 3 float
        ``(Dx, a, b)`` of the robot [m].
    error_function, joint_rate_function : casadi.Function
        ``p -> e_VS`` and ``p -> q̇``, built once (evaluated in loops by the checks).
    """

    lambda_vs: float
    goal: tuple[float, float, float, float]
    desired: tuple[tuple[float, float, float], ...]
    task_matrix: np.ndarray
    pose: Any
    features: Any
    error: Any
    joint_rates: Any
    rates: Any
    camera: Any
    function: Any
    offsets: tuple[float, float, float]
    error_function: Any
    joint_rate_function: Any

    def error_at(self, pose: Sequence[float]) -> np.ndarray:
        """``e_VS`` at a pose, shape (3,)."""
        return _numeric(self.error_function, pose).ravel()

    def joint_rates_at(self, pose: Sequence[float]) -> np.ndarray:
        """``(v, ω, ϖ)`` of (7) at a pose, shape (3,) [m/s, rad/s, rad/s]."""
        return _numeric(self.joint_rate_function, pose).ravel()

    def error_jacobian(self) -> np.ndarray:
        """``E = ∂e_VS/∂p`` at the goal, shape (3, 4), by AD."""
        return _numeric(ca.Function("E", [self.pose], [ca.jacobian(self.error, self.pose)]), self.goal)

    def input_matrix(self) -> np.ndarray:
        """``E G = ∂ė_VS/∂q̇`` at the goal, shape (3, 3): the task rate per joint rate (= ``J_r(ϑ*)``)."""
        q = ca.SX.sym("q", 3)
        rates = ca.vertcat(*model.pose_rates(self.pose[2], q[0], q[1], q[2], ops=ca))
        g = ca.jacobian(rates, q)
        f = ca.Function("EG", [self.pose], [ca.mtimes(ca.jacobian(self.error, self.pose), g)])
        return _numeric(f, self.goal)

    def task_linearisation(self) -> Linearisation:
        """The task ``ė_VS = (E G) q̇(e_VS)`` under (7), linearised at ``e_VS = 0``.

        ``q̇(e) = −λ_VS J_r(ϑ*)⁻¹ e`` composed symbolically from
        :func:`visnav.model.joint_rates_from_screw`; closed form ``−λ_VS I``.
        """
        e = ca.SX.sym("e_vs", 3)
        robot_pan = self.goal[3]
        q = self._joint_rates_of_error(e, robot_pan)
        f = ca.Function("task_vs", [e], [ca.mtimes(ca.DM(self.input_matrix()), ca.vertcat(*q))])
        return linearise(f, (0.0, 0.0, 0.0), state_names=("e_Vy", "e_Vz", "e_Wx"), name="visual servoing task (7)")

    def closed_loop_linearisation(self) -> Linearisation:
        """The full closed loop ``ṗ = F(p)`` linearised at the goal pose (4 states)."""
        return linearise(self.function, self.goal, state_names=_POSE_NAMES, name="closed loop at the goal (7)")

    def camera_jacobian(self) -> np.ndarray:
        """``∂(c_x, c_y, φ)/∂p`` at the goal, shape (3, 4)."""
        return _numeric(ca.Function("Jc", [self.pose], [ca.jacobian(self.camera, self.pose)]), self.goal)

    def _joint_rates_of_error(self, e: Any, pan: Any) -> tuple[Any, Any, Any]:
        return model.joint_rates_from_screw(
            pan, -self.lambda_vs * e[0], -self.lambda_vs * e[1], -self.lambda_vs * e[2],
            *self.offsets, ops=ca,
        )


def visual_servoing_model(scenario: Scenario, *, lambda_vs: float | None = None) -> VisualServoingModel:
    """Compose visual servoing (7) at the scenario's goal (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
    lambda_vs : float, optional
        Gain [1/s]; default the scenario's ``lambda_vs``.

    Raises
    ------
    ValueError
        A gain that is not a finite positive number.
    """
    lam = _validate_gain("lambda_vs", scenario.gains.lambda_vs if lambda_vs is None else lambda_vs)
    robot = scenario.robot
    goal = _goal_pose(scenario)
    pose = _pose_symbol()
    projections = _projections(scenario, pose)
    desired_f = ca.Function("s_goal", [pose], [ca.vertcat(*[c for x, y, z in projections for c in (x, y, z)])])
    flat = _numeric(desired_f, goal).ravel()
    desired = tuple((float(flat[3 * i]), float(flat[3 * i + 1]), float(flat[3 * i + 2]))
                    for i in range(len(projections)))
    rows = []
    for x, y, z in desired:
        rows.append(model.interaction_x_row(x, y, z))
        rows.append(model.interaction_y_row(y, z))
    interaction = np.array(rows, dtype=float)
    task_matrix = np.linalg.solve(interaction.T @ interaction, interaction.T)
    features = ca.vertcat(*[c for x, y, _ in projections for c in (x, y)])
    s_star = ca.DM([c for x, y, _ in desired for c in (x, y)])
    error = ca.mtimes(ca.DM(task_matrix), features - s_star)
    offsets = (robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    q = model.joint_rates_from_screw(pose[3], -lam * error[0], -lam * error[1], -lam * error[2], *offsets, ops=ca)
    joint_rates = ca.vertcat(*q)
    rates = ca.vertcat(*model.pose_rates(pose[2], q[0], q[1], q[2], ops=ca))
    camera = ca.vertcat(*model.camera_centre(pose[0], pose[1], pose[2], pose[3], *offsets, ops=ca))
    return VisualServoingModel(
        lambda_vs=lam, goal=goal, desired=desired, task_matrix=task_matrix, pose=pose, features=features,
        error=error, joint_rates=joint_rates, rates=rates, camera=camera,
        function=ca.Function("closed_loop_vs", [pose], [rates]), offsets=offsets,
        error_function=ca.Function("e_vs", [pose], [error]),
        joint_rate_function=ca.Function("q_vs", [pose], [joint_rates]),
    )


@dataclass(frozen=True, kw_only=True, slots=True)
class PanTaskModel:
    """The pan-platform task (16), symbolic in the pose and the base inputs ``(v, ω)``.

    Attributes
    ----------
    lambda_gc : float
        Gain λ_gc [1/s].
    y_gc_desired : float
        ``Y*_gc``, mean of the desired ``Y`` [-].
    pose : casadi.SX, shape (4, 1)
    base : casadi.SX, shape (2, 1)
        ``(v, ω)`` [m/s, rad/s].
    error : casadi.SX
        ``e_gc(p)``.
    pan_rate : casadi.SX
        ``ϖ(p, v, ω)`` by (16).
    error_rate : casadi.SX
        ``ė_gc = ∂e_gc/∂p · ṗ(p, v, ω, ϖ)`` by AD.
    goal : tuple of 4 float
    pan_rate_function, closure_function : casadi.Function
        ``(p, (v, ω)) -> ϖ`` and ``-> ė_gc + λ_gc e_gc``, built once.
    """

    lambda_gc: float
    y_gc_desired: float
    pose: Any
    base: Any
    error: Any
    pan_rate: Any
    error_rate: Any
    goal: tuple[float, float, float, float]
    pan_rate_function: Any
    closure_function: Any

    def pan_rate_at(self, pose: Sequence[float], v: float, omega: float) -> float:
        """``ϖ`` of (16) [rad/s]."""
        return float(_numeric(self.pan_rate_function, pose, [v, omega])[0, 0])

    def closure_residual(self, pose: Sequence[float], v: float, omega: float) -> float:
        """``ė_gc + λ_gc e_gc`` at a pose and base motion (0 when (16) decouples the task exactly)."""
        return float(_numeric(self.closure_function, pose, [v, omega])[0, 0])

    def pan_linearisation(self) -> Linearisation:
        """The pan loop ``ϑ̇ = ϖ(ϑ)`` with the base at rest at the goal (1 state); closed form ``−λ_gc``."""
        pan = ca.SX.sym("pan")
        x, y, theta, _ = self.goal
        f = ca.Function("pan_loop", [pan], [ca.substitute(self.pan_rate, ca.vertcat(self.pose, self.base),
                                                          ca.vertcat(x, y, theta, pan, 0.0, 0.0))])
        return linearise(f, (self.goal[3],), state_names=("pan_rad",), name="pan task (16) at the goal")

    def loop_gains(self) -> tuple[float, float]:
        """``(c, K)``: ``∂e_gc/∂ϑ`` and ``−∂ϖ/∂e_gc`` at the goal (base at rest); loop ``L = K c / s``."""
        wrt = ca.vertcat(self.pose, self.base)
        at = ca.DM([*self.goal, 0.0, 0.0])
        c = float(_numeric(ca.Function("c", [wrt], [ca.jacobian(self.error, self.pose[3])]), at)[0, 0])
        dpan = float(_numeric(ca.Function("dp", [wrt], [ca.jacobian(self.pan_rate, self.pose[3])]), at)[0, 0])
        return c, -dpan / c


def pan_task_model(scenario: Scenario, *, lambda_gc: float | None = None) -> PanTaskModel:
    """Compose the pan task (16) (see the module docstring).

    Raises
    ------
    ValueError
        A gain that is not a finite positive number.
    """
    lam = _validate_gain("lambda_gc", scenario.gains.lambda_gc if lambda_gc is None else lambda_gc)
    robot = scenario.robot
    goal = _goal_pose(scenario)
    pose, base = _pose_symbol(), ca.SX.sym("base", 2)
    projections = _projections(scenario, pose)
    n = len(projections)
    y_goal = ca.Function("ygc", [pose], [sum(y for _, y, _ in projections) / n])
    y_gc_desired = float(_numeric(y_goal, goal)[0, 0])
    error = sum(y for _, y, _ in projections) / n - y_gc_desired
    rows = [model.interaction_y_row(y, z) for _, y, z in projections]
    mean_row = [sum(r[i] for r in rows) / n for i in range(3)]
    offsets = (robot.pan_offset_m, robot.camera_forward_m, robot.camera_lateral_m)
    screw = model.camera_screw(pose[3], base[0], base[1], 0.0, *offsets, ops=ca)
    column = model.pan_column(robot.camera_forward_m, robot.camera_lateral_m)
    gain = sum(m * j for m, j in zip(mean_row, column))
    pan_rate = -(lam * error + sum(m * t for m, t in zip(mean_row, screw))) / gain
    rates = ca.vertcat(*model.pose_rates(pose[2], base[0], base[1], pan_rate, ops=ca))
    error_rate = ca.mtimes(ca.jacobian(error, pose), rates)
    return PanTaskModel(lambda_gc=lam, y_gc_desired=y_gc_desired, pose=pose, base=base, error=error,
                        pan_rate=pan_rate, error_rate=error_rate, goal=goal,
                        pan_rate_function=ca.Function("pan", [pose, base], [pan_rate]),
                        closure_function=ca.Function("closure", [pose, base], [error_rate + lam * error]))


@dataclass(frozen=True, kw_only=True, slots=True)
class GoalLoopFindings:
    """What the goal models say (see :func:`goal_loop_findings`).

    Attributes
    ----------
    task : Linearisation
        The visual-servoing task ``e_VS`` under (7).
    task_closed_form : float
        ``−λ_VS`` (three times).
    closed_loop : Linearisation
        The full 4-state loop at the goal (not Hurwitz: one zero eigenvalue).
    zero_mode : tuple of float or None
        Unit eigenvector of the eigenvalue closest to 0 (sign fixed: largest
        entry positive), ``None`` if the loop is Hurwitz.
    zero_mode_camera_motion : float or None
        ``‖∂(c_x, c_y, φ)/∂p · v0‖``: 0 when the zero mode moves the base but not the camera.
    input_matrix : ndarray, shape (3, 3)
        ``E G`` by AD.
    input_matrix_error : float
        ``max |E G − J_r(ϑ*)|``: the AD of the projection against the analytic interaction matrix.
    pan : Linearisation
        The pan loop at the goal.
    pan_closed_form : float
        ``−λ_gc``.
    pan_closure_residual : float
        ``max |ė_gc + λ_gc e_gc|`` over poses along the straight line from the
        start to the goal and ``(v, ω)`` in a grid (the exact decoupling of (16)).
    explanation : str
    """

    task: Linearisation
    task_closed_form: float
    closed_loop: Linearisation
    zero_mode: tuple[float, ...] | None
    zero_mode_camera_motion: float | None
    input_matrix: np.ndarray
    input_matrix_error: float
    pan: Linearisation
    pan_closed_form: float
    pan_closure_residual: float
    explanation: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: each linearisation (:meth:`Linearisation.as_dict`) with its closed form and
        claim under the report's keys, the input matrix and the explanation."""
        return to_jsonable({
            "visual_servoing_task": {**self.task.as_dict(), "closed_form": [self.task_closed_form] * 3,
                                     "claim": "computed"},
            "closed_loop": {**self.closed_loop.as_dict(), "zero_mode": self.zero_mode,
                            "zero_mode_camera_motion": self.zero_mode_camera_motion, "claim": "computed"},
            "input_matrix": self.input_matrix,
            "input_matrix_error_vs_reduced_jacobian": self.input_matrix_error,
            "pan_task": {**self.pan.as_dict(), "closed_form": [self.pan_closed_form],
                         "closure_residual": self.pan_closure_residual, "claim": "computed"},
            "explanation": self.explanation,
        })


def goal_loop_findings(scenario: Scenario, *, vs: VisualServoingModel | None = None,
                       pan: PanTaskModel | None = None) -> GoalLoopFindings:
    """Linearise the goal loops and explain the zero eigenvalue of the full loop.

    ``vs`` and ``pan`` are the scenario's models when the caller has built them already
    (default: built here with the scenario's gains).
    """
    vs = vs or visual_servoing_model(scenario)
    task = vs.task_linearisation()
    full = vs.closed_loop_linearisation()
    zero_mode = motion = None
    if not full.hurwitz:
        values, vectors = np.linalg.eig(full.jacobian)
        i = int(np.argmin(np.abs(values)))
        v0 = np.real(vectors[:, i])
        v0 = v0 / np.linalg.norm(v0)
        v0 = v0 if v0[int(np.argmax(np.abs(v0)))] > 0 else -v0
        zero_mode = tuple(float(c) for c in v0)
        motion = float(np.linalg.norm(vs.camera_jacobian() @ v0))
    robot = scenario.robot
    jr = np.array(model.reduced_jacobian(vs.goal[3], robot.pan_offset_m, robot.camera_forward_m,
                                        robot.camera_lateral_m), dtype=float)
    eg = vs.input_matrix()
    pan = pan or pan_task_model(scenario)
    start = scenario.start
    residual = 0.0
    for s in np.linspace(0.0, 1.0, 5):
        pose = [start.x_m + s * (vs.goal[0] - start.x_m), start.y_m + s * (vs.goal[1] - start.y_m),
                start.theta_rad + s * (vs.goal[2] - start.theta_rad), start.pan_rad + s * (vs.goal[3] - start.pan_rad)]
        for v in (0.0, 0.2, 0.5):
            for w in (-1.0, 0.0, 0.7):
                residual = max(residual, abs(pan.closure_residual(pose, v, w)))
    explanation = (
        "visual servoing (7): the task e_VS has three eigenvalues -lambda_VS (E G = J_r at the goal, AD of the "
        "projection against the analytic interaction matrix); the full closed loop in the robot pose has one more "
        "eigenvalue, 0: the image depends on the camera pose (3 numbers) only, so the robot poses with the camera "
        "at its goal pose form a curve of equilibria (base turned about the camera, pan counter-turned); the loop "
        "converges exponentially in the image and the camera pose, to some point of that curve in the base pose. "
        "Pan task (16): e_gc' = -lambda_gc e_gc exactly for every pose and base motion."
    )
    return GoalLoopFindings(
        task=task, task_closed_form=-vs.lambda_vs, closed_loop=full, zero_mode=zero_mode,
        zero_mode_camera_motion=motion, input_matrix=eg, input_matrix_error=float(np.max(np.abs(eg - jr))),
        pan=pan.pan_linearisation(), pan_closed_form=-pan.lambda_gc, pan_closure_residual=residual,
        explanation=explanation,
    )
