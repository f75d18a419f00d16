"""Random scenarios: one declaration of what moves, one function that applies the draws.

A :class:`Perturbation` is a tuple of :class:`Move`: each names a field of a
scenario (:data:`FIELDS`), how a drawn quantity changes it (:data:`CHANGES`:
added to the base value, multiplying it, or replacing it) and the distribution
of that quantity (:class:`Symmetric` or :class:`Uniform`).
:func:`apply_perturbation` applies one value per move to a base scenario and
validates the result with the rules of :mod:`visnav.scenario`.

The values are drawn by the caller, so every random study shares the mechanism
whatever its source of randomness:

* numpy: unit draws mapped by each distribution,
  ``perturbation.from_unit(rng.random(perturbation.size))``;
* hypothesis: one float per move within its bounds,
  ``[draw(st.floats(lo, hi)) for lo, hi in perturbation.bounds]``.

The two distributions differ in their formula only, and both are kept because
existing studies depend on their exact floating-point values:
``Symmetric(w).at(u) = w (2u - 1)`` (the Monte-Carlo campaign) and
``Uniform(lo, hi).at(u) = lo + (hi - lo) u``, which is what
``numpy.random.Generator.uniform(lo, hi)`` computes from the same unit draw
(the stiffness study, gain factors).

Fields
------
``start.<f>``, ``goal.<f>`` with ``f`` a :class:`~visnav.parameters.Pose` field
    ``x_m``, ``y_m``, ``theta_rad``, ``pan_rad``.
``<record>.<f>``
    A float field of ``robot``, ``camera``, ``envelopes``, ``gains``, ``limits``,
    ``estimator``, ``supervisor``; also the top-level ``sampling_period_s``,
    ``duration_s``, ``success_tolerance_px``.
``obstacles[j].<f>``
    ``x_m``, ``y_m`` (the centre), ``radius_m``, ``height_m`` of obstacle ``j``.
``target.x_m``, ``target.y_m``, ``target.heading_rad`` (``offset`` only)
    A rigid motion of the target *and the goal*: rotation by ``heading_rad``
    about the target's centroid, then a shift; the desired image ``s*`` is unchanged.
``target.normal_rad`` (``offset`` only)
    A rotation of the target alone about its centroid (the goal stays: ``s*`` changes).

Each move's drawn value is recorded under a label: ``<prefix>.d<name>`` for an
offset (``start.dx_m``, ``obstacles[0].dradius_m``, ``target.dheading_rad``),
the field path with the resulting value for a factor or a value
(``gains.k_path``).

Examples
--------
>>> from visnav.scenario import load_scenario
>>> base = load_scenario("paper")
>>> p = Perturbation(moves=(Move(field="start.y_m", change="offset", draw=Symmetric(half_width=0.2)),
...                         Move(field="gains.k_path", change="factor", draw=Uniform(low=0.5, high=1.5))))
>>> p.bounds
((-0.2, 0.2), (0.5, 1.5))
>>> drawn = apply_perturbation(base, p, p.from_unit([1.0, 0.5]))
>>> drawn.scenario.start.y_m, drawn.scenario.gains.k_path, drawn.parameters
(0.2, 4.0, (('gains.k_path', 4.0), ('start.dy_m', 0.2)))
"""

from __future__ import annotations

import dataclasses
import math
import re
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from hybrid.errors import ParameterError

from visnav.parameters import (
    ActuatorLimits,
    CameraModel,
    Envelopes,
    EstimatorSettings,
    Gains,
    Obstacle,
    Pose,
    RobotGeometry,
    Scenario,
    SupervisorSettings,
)

__all__ = [
    "CHANGES",
    "FIELDS",
    "PerturbationError",
    "Symmetric",
    "Uniform",
    "Move",
    "Perturbation",
    "PerturbedScenario",
    "apply_perturbation",
]

CHANGES = ("offset", "factor", "value")
"""How a move's drawn quantity changes its field: added, multiplied, or replacing the base value."""

FIELDS = (
    "start.<pose field>",
    "goal.<pose field>",
    "<record>.<float field>",
    "<top-level float>",
    "obstacles[j].x_m|y_m|radius_m|height_m",
    "target.x_m|y_m|heading_rad|normal_rad",
)
"""The forms of a move's field (module docstring)."""

_POSE_FIELDS = ("x_m", "y_m", "theta_rad", "pan_rad")
_RECORD_CLASSES: dict[str, type] = {
    "robot": RobotGeometry,
    "camera": CameraModel,
    "envelopes": Envelopes,
    "gains": Gains,
    "limits": ActuatorLimits,
    "estimator": EstimatorSettings,
    "supervisor": SupervisorSettings,
}
_RECORDS = tuple(_RECORD_CLASSES)
_TOP_FLOATS = ("sampling_period_s", "duration_s", "success_tolerance_px")
_OBSTACLE_FIELDS = ("x_m", "y_m", "radius_m", "height_m")
_TARGET_FIELDS = ("x_m", "y_m", "heading_rad", "normal_rad")
_OBSTACLE = re.compile(r"^obstacles\[(\d+)\]\.(\w+)$")


class PerturbationError(ParameterError):
    """An invalid distribution, move or perturbation, or values that do not fit it.

    ``parameter``, ``value``, ``expected`` and ``fix`` as in :class:`hybrid.errors.ParameterError`.
    """


def _finite(parameter: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise PerturbationError(parameter, value, "a finite number", "give a finite float")


@dataclass(frozen=True, kw_only=True, slots=True)
class Uniform:
    """The uniform distribution on ``[low, high]`` (``low == high``: a fixed value).

    Parameters
    ----------
    low, high : float
        Finite bounds, ``low <= high`` (in the unit of the quantity: m, rad, a factor, ...).
    """

    low: float
    high: float

    def __post_init__(self) -> None:
        _finite("Uniform.low", self.low)
        _finite("Uniform.high", self.high)
        if not self.low <= self.high:
            raise PerturbationError("Uniform", (self.low, self.high), "low <= high", "swap the bounds or make them equal")

    @property
    def bounds(self) -> tuple[float, float]:
        """``(low, high)``."""
        return (float(self.low), float(self.high))

    def at(self, u: float) -> float:
        """The quantity at the unit coordinate ``u``: ``low + (high - low) u``.

        Bit for bit what ``numpy.random.Generator.uniform(low, high)`` returns for the
        unit draw ``u`` of ``Generator.random()``.
        """
        return float(self.low + (self.high - self.low) * u)

    def as_dict(self) -> dict[str, float]:
        """``{"low": ..., "high": ...}``."""
        return {"low": float(self.low), "high": float(self.high)}


@dataclass(frozen=True, kw_only=True, slots=True)
class Symmetric:
    """The uniform distribution on ``[-half_width, half_width]`` (0: no change).

    Parameters
    ----------
    half_width : float
        Finite, ``>= 0`` (in the unit of the quantity).
    """

    half_width: float

    def __post_init__(self) -> None:
        _finite("Symmetric.half_width", self.half_width)
        if not self.half_width >= 0:
            raise PerturbationError("Symmetric.half_width", self.half_width, "a half-width >= 0",
                                    "use 0 to disable the move")

    @property
    def bounds(self) -> tuple[float, float]:
        """``(-half_width, half_width)``."""
        return (-float(self.half_width), float(self.half_width))

    def at(self, u: float) -> float:
        """The quantity at the unit coordinate ``u``: ``half_width (2u - 1)``."""
        return self.half_width * (2.0 * float(u) - 1.0)

    def as_dict(self) -> dict[str, float]:
        """``{"half_width": ...}``."""
        return {"half_width": float(self.half_width)}


Distribution = Uniform | Symmetric


@dataclass(frozen=True, kw_only=True, slots=True)
class Move:
    """One field of a scenario, how it changes, and the distribution of the change.

    Parameters
    ----------
    field : str
        The field path (:data:`FIELDS`), e.g. ``"obstacles[1].radius_m"``.
    change : str
        One of :data:`CHANGES`.
    draw : Uniform or Symmetric
        Distribution of the quantity: the offset, the factor or the new value.
    """

    field: str
    change: str
    draw: Distribution

    def __post_init__(self) -> None:
        if self.change not in CHANGES:
            raise PerturbationError("Move.change", self.change, f"one of {', '.join(CHANGES)}",
                                    "offset adds the draw, factor multiplies by it, value replaces the field")
        if not isinstance(self.draw, (Uniform, Symmetric)):
            raise PerturbationError("Move.draw", self.draw, "a Uniform or a Symmetric distribution",
                                    "e.g. Symmetric(half_width=0.1)")
        _parse(self.field)
        if self.field.startswith("target.") and self.change != "offset":
            raise PerturbationError("Move.change", self.change, f"'offset' for {self.field} (a rigid motion)",
                                    "use change='offset'")

    @property
    def label(self) -> str:
        """Name of the recorded value: ``<prefix>.d<name>`` for an offset, else the field path."""
        if self.change != "offset":
            return self.field
        prefix, _, name = self.field.rpartition(".")
        return f"{prefix}.d{name}" if prefix else f"d{name}"


def _parse(field: str) -> tuple[str, int | None, str]:
    """``(kind, obstacle index or None, name)`` of a field path; :class:`PerturbationError` otherwise."""
    if not isinstance(field, str):
        raise PerturbationError("Move.field", field, "a field path string", "e.g. 'start.x_m'")
    found = _OBSTACLE.match(field)
    if found:
        if found[2] not in _OBSTACLE_FIELDS:
            raise PerturbationError("Move.field", field, f"obstacles[j].{{{', '.join(_OBSTACLE_FIELDS)}}}",
                                    "move the centre with x_m/y_m, or radius_m/height_m")
        return ("obstacle", int(found[1]), found[2])
    if field in _TOP_FLOATS:
        return ("top", None, field)
    head, _, name = field.partition(".")
    if head in ("start", "goal") and name in _POSE_FIELDS:
        return (head, None, name)
    if head == "target" and name in _TARGET_FIELDS:
        return ("target", None, name)
    if head in _RECORDS and typing.get_type_hints(_RECORD_CLASSES[head]).get(name) is float:
        return ("record", None, field)
    raise PerturbationError("Move.field", field, f"a field of one of the forms {'; '.join(FIELDS)}",
                            "see the list of fields in visnav.perturbation")


@dataclass(frozen=True, kw_only=True, slots=True)
class Perturbation:
    """What a random study moves: one :class:`Move` per drawn value, in draw order.

    Parameters
    ----------
    moves : tuple of Move
        Distinct fields; the values passed to :func:`apply_perturbation` follow this order.
    """

    moves: tuple[Move, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.moves, tuple) or not all(isinstance(m, Move) for m in self.moves):
            raise PerturbationError("Perturbation.moves", self.moves, "a tuple of Move", "wrap the moves in a tuple")
        seen: set[str] = set()
        for move in self.moves:
            if move.field in seen:
                raise PerturbationError("Perturbation.moves", move.field, "each field moved once",
                                        "merge the two moves of this field into one")
            seen.add(move.field)

    @property
    def size(self) -> int:
        """Number of values a draw needs (one per move)."""
        return len(self.moves)

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """``(low, high)`` of each move's quantity, in order (e.g. for ``hypothesis.strategies.floats``)."""
        return tuple(m.draw.bounds for m in self.moves)

    def from_unit(self, u: Sequence[float]) -> tuple[float, ...]:
        """The quantities for the unit draws ``u`` (one in ``[0, 1)`` per move), by each distribution's formula."""
        if len(u) != self.size:
            raise PerturbationError("u", len(u), f"{self.size} unit draws (one per move)",
                                    "draw perturbation.size values, e.g. rng.random(perturbation.size)")
        return tuple(m.draw.at(float(x)) for m, x in zip(self.moves, u))

    def as_dict(self) -> list[dict[str, Any]]:
        """JSON-ready description: per move its field, change and distribution."""
        return [{"field": m.field, "change": m.change, "draw": {type(m.draw).__name__: m.draw.as_dict()}}
                for m in self.moves]


@dataclass(frozen=True, kw_only=True, slots=True)
class PerturbedScenario:
    """A base scenario with drawn values applied.

    Attributes
    ----------
    candidate : Scenario
        The perturbed scenario, before validation.
    scenario : Scenario or None
        The validated scenario (``candidate`` itself when validation was not asked
        for); ``None`` when the candidate breaks a scenario rule.
    parameters : tuple of (str, float)
        The recorded values (:attr:`Move.label`), sorted by label.
    error : visnav.scenario.ScenarioError or None
        The rule the candidate breaks.
    """

    candidate: Scenario
    scenario: Scenario | None
    parameters: tuple[tuple[str, float], ...]
    error: Exception | None

    @property
    def valid(self) -> bool:
        """Whether the candidate passed validation (or was not validated)."""
        return self.scenario is not None


def apply_perturbation(
    base: Scenario,
    perturbation: Perturbation,
    values: Sequence[float],
    *,
    name: str | None = None,
    source: str | None = None,
    validate: bool = True,
) -> PerturbedScenario:
    """Apply one drawn value per move to ``base`` and validate the result.

    Parameters
    ----------
    base : Scenario
        The scenario perturbed (every move is relative to its values).
    perturbation : Perturbation
        The moves.
    values : sequence of float
        One quantity per move, in order: an offset [field unit], a factor [-] or a
        value [field unit] (``perturbation.from_unit(u)``, or hypothesis draws within
        ``perturbation.bounds``).
    name : str, optional
        Name of the perturbed scenario (default: the base's).
    source : str, optional
        Label of validation errors (default: the scenario's name).
    validate : bool
        Apply :func:`visnav.scenario.validate_scenario`; ``False`` keeps a candidate that
        may break the paper's hypotheses (adversarial inputs).

    Returns
    -------
    PerturbedScenario
        With ``scenario=None`` and the error when the candidate breaks a rule.

    Raises
    ------
    PerturbationError
        ``values`` of the wrong length or not finite, or a move naming a missing obstacle.
    """
    from visnav.scenario import ScenarioError, validate_scenario

    if not isinstance(perturbation, Perturbation):
        raise PerturbationError("perturbation", perturbation, "a Perturbation", "build one from Move records")
    if len(values) != perturbation.size:
        raise PerturbationError("values", len(values), f"{perturbation.size} values (one per move)",
                                "pass one drawn quantity per move, in order")
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise PerturbationError(f"values[{i}]", value, f"a finite number for {perturbation.moves[i].field}",
                                    "draw within perturbation.bounds")
    candidate, parameters = _perturbed(base, perturbation, [float(v) for v in values])
    if name is not None:
        candidate = dataclasses.replace(candidate, name=name)
    if not validate:
        return PerturbedScenario(candidate=candidate, scenario=candidate, parameters=parameters, error=None)
    try:
        scenario = validate_scenario(candidate, source)
    except ScenarioError as err:
        return PerturbedScenario(candidate=candidate, scenario=None, parameters=parameters, error=err)
    return PerturbedScenario(candidate=candidate, scenario=scenario, parameters=parameters, error=None)


def _changed(base_value: float, change: str, quantity: float) -> float:
    if change == "offset":
        return base_value + quantity
    if change == "factor":
        return base_value * quantity
    return quantity


def _perturbed(base: Scenario, perturbation: Perturbation,
               values: list[float]) -> tuple[Scenario, tuple[tuple[str, float], ...]]:
    """The candidate and its recorded values (in the order: poses, records, obstacles, target)."""
    params: dict[str, float] = {}
    poses: dict[str, dict[str, float]] = {"start": {}, "goal": {}}
    records: dict[str, dict[str, float]] = {}
    top: dict[str, float] = {}
    obstacles: dict[int, dict[str, float]] = {}
    target: dict[str, float] = {}
    for move, quantity in zip(perturbation.moves, values):
        kind, index, field = _parse(move.field)
        if kind in ("start", "goal"):
            new = _changed(getattr(getattr(base, kind), field), move.change, quantity)
            poses[kind][field] = new
        elif kind == "record":
            section, _, attribute = field.partition(".")
            new = _changed(getattr(getattr(base, section), attribute), move.change, quantity)
            records.setdefault(section, {})[attribute] = new
        elif kind == "top":
            new = _changed(getattr(base, field), move.change, quantity)
            top[field] = new
        elif kind == "obstacle":
            assert index is not None
            if index >= len(base.obstacles):
                raise PerturbationError("Move.field", move.field,
                                        f"an obstacle index below {len(base.obstacles)} (obstacles of {base.name!r})",
                                        "declare the moves for the base scenario's obstacles")
            o = base.obstacles[index]
            current = {"x_m": o.center_m[0], "y_m": o.center_m[1], "radius_m": o.radius_m, "height_m": o.height_m}
            new = _changed(current[field], move.change, quantity)
            obstacles.setdefault(index, {})[field] = new
        else:
            new = quantity
            target[field] = quantity
        params[move.label] = quantity if move.change == "offset" else new
    changes: dict[str, Any] = dict(top)
    for kind, fields in poses.items():
        if fields:
            changes[kind] = dataclasses.replace(getattr(base, kind), **fields)
    for section, fields in records.items():
        changes[section] = dataclasses.replace(getattr(base, section), **fields)
    if obstacles:
        changes["obstacles"] = tuple(_moved_obstacle(o, obstacles.get(j, {})) for j, o in enumerate(base.obstacles))
    if target:
        goal = changes.get("goal", base.goal)
        changes["target"], changes["goal"] = _rigid_target(base, goal, target)
    return dataclasses.replace(base, **changes), tuple(sorted(params.items()))


def _moved_obstacle(o: Obstacle, fields: dict[str, float]) -> Obstacle:
    if not fields:
        return o
    x, y = fields.get("x_m", o.center_m[0]), fields.get("y_m", o.center_m[1])
    return dataclasses.replace(o, center_m=(x, y), radius_m=fields.get("radius_m", o.radius_m),
                               height_m=fields.get("height_m", o.height_m))


def _rigid_target(base: Scenario, goal: Pose, moves: dict[str, float]) -> tuple[Any, Pose]:
    """The target after ``target.*`` moves, and the goal carried by the rigid part (shift and heading)."""
    points = base.target.points_m
    cx = sum(p[0] for p in points) / len(points)
    cy = sum(p[1] for p in points) / len(points)
    tx, ty = moves.get("x_m", 0.0), moves.get("y_m", 0.0)
    heading = moves.get("heading_rad")
    normal = moves.get("normal_rad")

    def carry(x: float, y: float, angle: float | None) -> tuple[float, float]:
        # rotate about the target centroid, then shift
        if angle is None:
            return (x + tx, y + ty)
        c, s = math.cos(angle), math.sin(angle)
        return (cx + c * (x - cx) - s * (y - cy) + tx, cy + s * (x - cx) + c * (y - cy) + ty)

    point_angle = heading if normal is None else (normal if heading is None else heading + normal)
    target = dataclasses.replace(base.target, points_m=tuple((*carry(p[0], p[1], point_angle), p[2]) for p in points))
    if heading is None and "x_m" not in moves and "y_m" not in moves:
        return target, goal
    gx, gy = carry(goal.x_m, goal.y_m, heading)
    theta = goal.theta_rad if heading is None else goal.theta_rad + heading
    return target, dataclasses.replace(goal, x_m=gx, y_m=gy, theta_rad=theta)
