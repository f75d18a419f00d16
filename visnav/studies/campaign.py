"""Monte-Carlo campaigns over scenario and gain distributions.

A :class:`CampaignSpec` names a base scenario, a number of samples, a seed and
the distributions of the perturbations: start pose, obstacle positions, radii
and heights, target pose (moved rigidly with the goal, so that ``s*`` is
unchanged) and relative factors on the gains ``k_path``, ``λ_VS`` and
``v_coll``.  Sample ``i`` is drawn from ``SeedSequence(seed).spawn(...)[i]``
only, so a campaign's results do not depend on the order in which samples run,
on the number of workers or on interruptions.

:func:`run_sample` simulates one sample and never raises for a failed run: it
classifies it (:data:`OUTCOMES`).  :func:`summarise` aggregates results in
index order (success rate with a Wilson interval, quantiles of the clearance
and of the reconstruction error, the failure classes).  :func:`run_campaign`
submits samples to any :class:`concurrent.futures.Executor` (a process pool, a
Dask ``ClientExecutor`` or :class:`InlineExecutor`) and hands each result to a
sink as it arrives; :func:`campaign_executor` builds those executors.

Nothing here prints or writes files: the results file is
:mod:`visnav.app.campaign_store`, the command line :mod:`visnav.app.cli_sweep`.

Examples
--------
>>> from visnav.scenario import load_scenario
>>> spec = CampaignSpec(scenario=load_scenario("paper"), samples=2, seed=7)
>>> sample_scenario(spec, 1) == sample_scenario(spec, 1)
True
"""

from __future__ import annotations

import asyncio
import concurrent.futures as cf
import contextlib
import dataclasses
import hashlib
import json
import logging
import math
import multiprocessing
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.jsonable import jsonable
from visnav.parameters import Scenario

__all__ = [
    "CAMPAIGN_FORMAT",
    "CAMPAIGN_VERSION",
    "OUTCOMES",
    "QUANTILES",
    "WILSON_Z",
    "CampaignSpecError",
    "SchedulerUnavailableError",
    "Uniform",
    "CampaignSpec",
    "SampledScenario",
    "SampleResult",
    "CampaignSummary",
    "CampaignBackend",
    "InlineExecutor",
    "sample_scenario",
    "run_sample",
    "classify",
    "summarise",
    "wilson_interval",
    "run_campaign",
    "campaign_executor",
    "probe_scheduler",
    "process_pool",
    "canonical_json",
]

CAMPAIGN_FORMAT = "visnav-campaign"
"""Name of the campaign file format (header of the results file, spec hash)."""
CAMPAIGN_VERSION = 1
"""Version of the sampling scheme and of the result records; part of the spec hash."""

OUTCOMES = ("success", "collision", "timeout", "diverged", "invalid_scenario", "error")
"""Outcome classes of a sample, in report order.

``success``: the task was achieved without touching an obstacle.  ``collision``: the
exact trajectory reached an obstacle surface (also between samples).  ``timeout``: the
scenario's duration ran out.  ``diverged``: :class:`hybrid.DivergenceError` (the detail
gives time, mode and cause).  ``invalid_scenario``: no draw within ``max_attempts``
satisfied the scenario rules (``docs/scenarios.md``).  ``error``: any other exception
(its type and message are the detail).
"""

QUANTILES = (0.0, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)
"""Quantile levels reported by :func:`summarise` (linear interpolation)."""

WILSON_Z = 1.959963984540054
"""Normal quantile of the 95 % Wilson score interval."""

_METRIC_OUTCOMES = ("success", "collision", "timeout")
_ADDRESS = re.compile(r"^(tcp|tls)://[^\s/:]+:(\d{1,5})$")


class CampaignSpecError(ValueError):
    """An invalid campaign specification or campaign option.

    Attributes
    ----------
    parameter : str
        The offending parameter (``"samples"``, ``"obstacle_height_m"``, ``"--scheduler"``, ...).
    value : object
        The value found.
    expected : str
        What a valid value looks like.
    fix : str
        How to correct it.
    """

    def __init__(self, parameter: str, value: object, expected: str, fix: str) -> None:
        self.parameter = parameter
        self.value = value
        self.expected = expected
        self.fix = fix
        super().__init__(f"{parameter} = {value!r}: expected {expected}; fix: {fix}")

    def __reduce__(self):  # picklable across processes
        return (CampaignSpecError, (self.parameter, self.value, self.expected, self.fix))


class SchedulerUnavailableError(ConnectionError):
    """A Dask scheduler that does not answer, or has no workers, within the connect timeout.

    Attributes
    ----------
    address : str
        The scheduler address tried.
    timeout_s : float
        The connect timeout [s].
    """

    def __init__(self, address: str, timeout_s: float, reason: str, fix: str) -> None:
        self.address = address
        self.timeout_s = timeout_s
        super().__init__(f"--scheduler {address!r}: {reason} within the connect timeout of {timeout_s:g} s; fix: {fix}")


# ---------------------------------------------------------------------------------------------
# Specification
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class Uniform:
    """A uniform distribution on ``[low, high]`` (``low == high`` is a fixed value).

    Parameters
    ----------
    low, high : float
        Finite bounds, ``low <= high``.
    """

    low: float
    high: float

    def __post_init__(self) -> None:
        for name in ("low", "high"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise CampaignSpecError(f"Uniform.{name}", value, "a finite number", "give a finite float")
        if not self.low <= self.high:
            raise CampaignSpecError(
                "Uniform", (self.low, self.high), "low <= high", "swap the bounds or make them equal"
            )

    def at(self, u: float) -> float:
        """The value at the unit-interval coordinate ``u`` (``low + (high - low) u``)."""
        return float(self.low + (self.high - self.low) * u)

    def as_dict(self) -> dict[str, float]:
        """``{"low": ..., "high": ...}``."""
        return {"low": float(self.low), "high": float(self.high)}


_HALF_WIDTHS = (
    "start_offset_m",
    "start_heading_rad",
    "obstacle_offset_m",
    "obstacle_radius_m",
    "obstacle_height_m",
    "target_offset_m",
    "target_heading_rad",
)
_GAIN_FIELDS = {"k_path_scale": "k_path", "lambda_vs_scale": "lambda_vs", "v_coll_scale": "v_coll_mps"}


@dataclass(frozen=True, kw_only=True, slots=True)
class CampaignSpec:
    """What a campaign runs: a base scenario, ``samples`` draws and their distributions.

    Every perturbation is a uniform offset on ``[-w, w]`` added to the base
    value (``w`` the half-width given here, 0 disables it); each gain is the
    base gain times a factor drawn from a :class:`Uniform`.  A draw that breaks
    a scenario rule (obstacles ``2 d+`` apart, start and goal outside the
    critical envelopes, target in view, see ``docs/scenarios.md``) is redrawn,
    up to ``max_attempts`` times; the campaign samples the distribution
    conditioned on the paper's hypotheses.

    Parameters
    ----------
    scenario : Scenario
        The base scenario.
    samples : int
        Number of samples ``N >= 1``.
    seed : int
        Seed ``>= 0``; sample ``i`` depends on ``(seed, i)`` only.
    start_offset_m : float
        Half-width of the offsets of the start point's ``x`` and ``y`` [m].
    start_heading_rad : float
        Half-width of the offset of the start heading ``θ`` [rad].
    obstacle_offset_m : float
        Half-width of the offsets of each obstacle centre's ``x`` and ``y`` [m].
    obstacle_radius_m : float
        Half-width of the offset of each radius [m]; below the smallest radius.
    obstacle_height_m : float
        Half-width of the offset of each height [m]; an obstacle stays on its side
        of the camera height (low obstacles never occlude, tall ones always do).
    target_offset_m : float
        Half-width of the offsets of the target's ``x`` and ``y``; the goal moves
        with the target, so the desired image ``s*`` is unchanged [m].
    target_heading_rad : float
        Half-width of a rotation of target and goal about the target centre [rad].
    k_path_scale, lambda_vs_scale, v_coll_scale : Uniform
        Factors on the path-following gain ``k``, on ``λ_VS`` and on ``v_coll``
        (positive bounds).
    max_attempts : int
        Draws per sample before it is classified ``invalid_scenario``.

    Raises
    ------
    CampaignSpecError
        Naming the parameter, the value, the expectation and the fix.
    """

    scenario: Scenario
    samples: int
    seed: int
    start_offset_m: float = 0.2
    start_heading_rad: float = 0.1
    obstacle_offset_m: float = 0.15
    obstacle_radius_m: float = 0.05
    obstacle_height_m: float = 0.1
    target_offset_m: float = 0.2
    target_heading_rad: float = 0.05
    k_path_scale: Uniform = Uniform(low=0.75, high=1.25)
    lambda_vs_scale: Uniform = Uniform(low=0.8, high=1.2)
    v_coll_scale: Uniform = Uniform(low=0.75, high=1.25)
    max_attempts: int = 20

    def __post_init__(self) -> None:
        if not isinstance(self.scenario, Scenario):
            raise CampaignSpecError(
                "scenario", type(self.scenario).__name__, "a visnav Scenario", "load one with visnav.scenario.load_scenario"
            )
        _check_int("samples", self.samples, 1, "give the number of scenarios to run, e.g. 100")
        _check_int("seed", self.seed, 0, "give a non-negative integer seed, e.g. 0")
        _check_int("max_attempts", self.max_attempts, 1, "use e.g. 20")
        for name in _HALF_WIDTHS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value >= 0):
                raise CampaignSpecError(name, value, "a finite half-width >= 0", "use 0 to disable this perturbation")
        for name in _GAIN_FIELDS:
            value = getattr(self, name)
            if not isinstance(value, Uniform):
                raise CampaignSpecError(name, value, "a Uniform(low=..., high=...) factor", "e.g. Uniform(low=0.8, high=1.2)")
            if not value.low > 0:
                raise CampaignSpecError(
                    name, value.as_dict(), "a factor range with low > 0 (every gain must stay positive)", "raise low above 0"
                )
        obstacles = self.scenario.obstacles
        if obstacles:
            smallest = min(o.radius_m for o in obstacles)
            if not self.obstacle_radius_m < smallest:
                raise CampaignSpecError(
                    "obstacle_radius_m",
                    self.obstacle_radius_m,
                    f"a half-width below the smallest obstacle radius ({smallest:g} m) so that radii stay positive",
                    f"use a value below {smallest:g}",
                )
        camera_h = self.scenario.robot.camera_height_m
        w = self.obstacle_height_m
        for j, o in enumerate(obstacles):
            tall = o.occludes(camera_h)
            low, high = o.height_m - w, o.height_m + w
            keeps = (low >= camera_h) if tall else (low > 0 and high < camera_h)
            if not keeps:
                limit = o.height_m - camera_h if tall else min(o.height_m, camera_h - o.height_m)
                kind = "tall (occluding)" if tall else "low (non-occluding)"
                raise CampaignSpecError(
                    "obstacle_height_m",
                    w,
                    f"heights of obstacles[{j}] {o.name!r} ({o.height_m:g} ± {w:g} m) to stay {kind} with "
                    f"respect to the camera height {camera_h:g} m (the paper's hypothesis on its class)",
                    f"use a half-width below {limit:g} m",
                )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description; the scenario as its canonical TOML text and digest."""
        from visnav.scenario import scenario_digest, scenario_to_toml

        out: dict[str, Any] = {
            "format": CAMPAIGN_FORMAT,
            "version": CAMPAIGN_VERSION,
            "scenario": self.scenario.name,
            "scenario_digest": scenario_digest(self.scenario),
            "scenario_toml": scenario_to_toml(self.scenario),
            "samples": self.samples,
            "seed": self.seed,
            "max_attempts": self.max_attempts,
        }
        for name in _HALF_WIDTHS:
            out[name] = float(getattr(self, name))
        for name in _GAIN_FIELDS:
            out[name] = getattr(self, name).as_dict()
        return out

    def spec_hash(self) -> str:
        """SHA-256 (hex) of the canonical JSON of :meth:`as_dict`: identifies a campaign."""
        return hashlib.sha256(canonical_json(self.as_dict()).encode("utf-8")).hexdigest()


def _check_int(name: str, value: object, minimum: int, fix: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise CampaignSpecError(name, value, f"an integer >= {minimum}", fix)
    if value < minimum:
        raise CampaignSpecError(name, value, f"an integer >= {minimum}", fix)


def canonical_json(value: Any) -> str:
    """Compact JSON with sorted keys (floats as ``repr``): the byte-stable form used for hashes."""
    return json.dumps(jsonable(value), sort_keys=True, separators=(",", ":"), allow_nan=False)


# ---------------------------------------------------------------------------------------------
# Sampling
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class SampledScenario:
    """Sample ``index`` of a campaign: the scenario drawn, or why no valid one was found.

    Attributes
    ----------
    index : int
        The sample index.
    scenario : Scenario or None
        The validated scenario, ``None`` if every attempt broke a scenario rule.
    parameters : tuple of (str, float)
        The values drawn at the last attempt, sorted by name: offsets (``start.dx_m``,
        ``obstacles[0].dheight_m``, ``target.dheading_rad``, ...) and the resulting gains
        (``gains.k_path``, ...).
    attempts : int
        Draws used.
    detail : str
        The scenario rule the last draw broke ("" when valid).
    """

    index: int
    scenario: Scenario | None
    parameters: tuple[tuple[str, float], ...]
    attempts: int
    detail: str


def _slots(n_obstacles: int) -> int:
    return 3 + 4 * n_obstacles + 3 + len(_GAIN_FIELDS)


def _rng(spec: CampaignSpec, index: int) -> np.random.Generator:
    # Identical to np.random.SeedSequence(spec.seed).spawn(index + 1)[index], without the spawn.
    return np.random.default_rng(np.random.SeedSequence(entropy=spec.seed, spawn_key=(index,)))


def _draw(spec: CampaignSpec, u: np.ndarray) -> tuple[Scenario, dict[str, float]]:
    """The perturbed (not yet validated) scenario for the unit draws ``u``."""
    base = spec.scenario
    params: dict[str, float] = {}
    k = iter(float(x) for x in u)

    def offset(name: str, half: float) -> float:
        value = half * (2.0 * next(k) - 1.0)
        params[name] = value
        return value

    dx, dy, dth = offset("start.dx_m", spec.start_offset_m), offset("start.dy_m", spec.start_offset_m), offset(
        "start.dtheta_rad", spec.start_heading_rad
    )
    start = dataclasses.replace(base.start, x_m=base.start.x_m + dx, y_m=base.start.y_m + dy,
                                theta_rad=base.start.theta_rad + dth)
    obstacles = []
    for j, o in enumerate(base.obstacles):
        ox = offset(f"obstacles[{j}].dx_m", spec.obstacle_offset_m)
        oy = offset(f"obstacles[{j}].dy_m", spec.obstacle_offset_m)
        dr = offset(f"obstacles[{j}].dradius_m", spec.obstacle_radius_m)
        dh = offset(f"obstacles[{j}].dheight_m", spec.obstacle_height_m)
        obstacles.append(dataclasses.replace(
            o, center_m=(o.center_m[0] + ox, o.center_m[1] + oy), radius_m=o.radius_m + dr, height_m=o.height_m + dh
        ))
    tx, ty = offset("target.dx_m", spec.target_offset_m), offset("target.dy_m", spec.target_offset_m)
    tth = offset("target.dheading_rad", spec.target_heading_rad)
    points = base.target.points_m
    cx = sum(p[0] for p in points) / len(points)
    cy = sum(p[1] for p in points) / len(points)
    c, s = math.cos(tth), math.sin(tth)

    def move(x: float, y: float) -> tuple[float, float]:  # rotate about the target centre, then shift
        return (cx + c * (x - cx) - s * (y - cy) + tx, cy + s * (x - cx) + c * (y - cy) + ty)

    target = dataclasses.replace(base.target, points_m=tuple((*move(p[0], p[1]), p[2]) for p in points))
    gx, gy = move(base.goal.x_m, base.goal.y_m)
    goal = dataclasses.replace(base.goal, x_m=gx, y_m=gy, theta_rad=base.goal.theta_rad + tth)
    gains = base.gains
    changes = {}
    for name, field in _GAIN_FIELDS.items():
        value = getattr(base.gains, field) * getattr(spec, name).at(next(k))
        params[f"gains.{field}"] = value
        changes[field] = value
    gains = dataclasses.replace(gains, **changes)
    scenario = dataclasses.replace(base, start=start, goal=goal, target=target, obstacles=tuple(obstacles), gains=gains)
    return scenario, params


def sample_scenario(spec: CampaignSpec, index: int) -> SampledScenario:
    """Draw and validate sample ``index`` of ``spec`` (deterministic in ``(spec, index)``).

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    index : int
        ``0 <= index < spec.samples``.

    Returns
    -------
    SampledScenario
        The first draw that passes every rule of :mod:`visnav.scenario`, or the
        last failure after ``spec.max_attempts`` draws.
    """
    from visnav.scenario import ScenarioError, scenario_from_toml, scenario_to_toml

    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < spec.samples:
        raise CampaignSpecError("index", index, f"an integer in [0, {spec.samples})", "use a sample index of the campaign")
    rng = _rng(spec, int(index))
    n_slots = _slots(len(spec.scenario.obstacles))
    detail = ""
    params: dict[str, float] = {}
    for attempt in range(1, spec.max_attempts + 1):
        candidate, params = _draw(spec, rng.random(n_slots))
        try:
            # The TOML round trip applies every validation rule; floats are written as repr (exact).
            scenario = scenario_from_toml(scenario_to_toml(candidate), f"{spec.scenario.name}#{index}")
        except ScenarioError as err:
            detail = str(err)
            continue
        return SampledScenario(index=int(index), scenario=scenario, parameters=tuple(sorted(params.items())),
                               attempts=attempt, detail="")
    return SampledScenario(index=int(index), scenario=None, parameters=tuple(sorted(params.items())),
                           attempts=spec.max_attempts, detail=detail)


# ---------------------------------------------------------------------------------------------
# One sample
# ---------------------------------------------------------------------------------------------


_FLOAT_FIELDS = (
    "min_clearance_m",
    "final_feature_error_px",
    "max_reconstruction_error_px",
    "max_depth_error_mm",
    "occlusion_duration_s",
    "sim_time_s",
)


@dataclass(frozen=True, kw_only=True, slots=True)
class SampleResult:
    """The outcome of one sample; metrics are ``None`` when the run did not produce them.

    Attributes
    ----------
    index : int
        Sample index.
    outcome : str
        One of :data:`OUTCOMES`.
    detail : str
        Why the run failed (divergence cause, broken scenario rule, exception), else "".
    parameters : tuple of (str, float)
        The drawn values (see :class:`SampledScenario`), sorted by name.
    attempts : int
        Draws used to find a valid scenario.
    scenario_digest : str or None
        :func:`visnav.scenario.scenario_digest` of the scenario run.
    min_clearance_m, final_feature_error_px, max_reconstruction_error_px, max_depth_error_mm : float or None
        As in :class:`visnav.simulation.Metrics` (``None`` for non-finite values, e.g.
        the clearance without obstacles).
    occlusion_duration_s, sim_time_s : float or None
        As in :class:`visnav.simulation.Metrics`.
    transitions, chatter_count, steps : int or None
        Number of supervisor transitions, chattering ones, samples.
    within_actuator_limits : bool or None
        Whether the inputs stayed within the stated limits.
    """

    index: int
    outcome: str
    detail: str = ""
    parameters: tuple[tuple[str, float], ...] = ()
    attempts: int = 0
    scenario_digest: str | None = None
    min_clearance_m: float | None = None
    final_feature_error_px: float | None = None
    max_reconstruction_error_px: float | None = None
    max_depth_error_mm: float | None = None
    occlusion_duration_s: float | None = None
    sim_time_s: float | None = None
    transitions: int | None = None
    chatter_count: int | None = None
    steps: int | None = None
    within_actuator_limits: bool | None = None

    @property
    def success(self) -> bool:
        """Whether the outcome is ``"success"``."""
        return self.outcome == "success"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (``parameters`` as an object)."""
        out = {name: getattr(self, name) for name in self.__slots__}  # type: ignore[attr-defined]
        out["parameters"] = dict(self.parameters)
        return jsonable(out)

    @classmethod
    def from_dict(cls, data: Any) -> SampleResult:
        """Rebuild from :meth:`as_dict`; ``ValueError`` naming the field for anything malformed."""
        if not isinstance(data, dict):
            raise ValueError(f"expected a JSON object, found {type(data).__name__}")
        names = set(cls.__slots__)  # type: ignore[attr-defined]
        if set(data) != names:
            missing, extra = sorted(names - set(data)), sorted(set(data) - names)
            raise ValueError(f"fields differ from a sample result (missing {missing}, unexpected {extra})")
        _expect(data, "index", lambda v: _is_int(v) and v >= 0, "an integer >= 0")
        _expect(data, "outcome", lambda v: v in OUTCOMES, f"one of {', '.join(OUTCOMES)}")
        _expect(data, "detail", lambda v: isinstance(v, str), "a string")
        _expect(data, "attempts", lambda v: _is_int(v) and v >= 0, "an integer >= 0")
        _expect(data, "scenario_digest", lambda v: v is None or isinstance(v, str), "a string or null")
        for name in _FLOAT_FIELDS:
            _expect(data, name, lambda v: v is None or (_is_number(v) and math.isfinite(v)), "a number or null")
        for name in ("transitions", "chatter_count", "steps"):
            _expect(data, name, lambda v: v is None or (_is_int(v) and v >= 0), "an integer >= 0 or null")
        _expect(data, "within_actuator_limits", lambda v: v is None or isinstance(v, bool), "true, false or null")
        _expect(data, "parameters", lambda v: isinstance(v, dict) and all(_is_number(x) for x in v.values()),
                "an object of numbers")
        values = dict(data)
        values["parameters"] = tuple(sorted((str(k), float(v)) for k, v in data["parameters"].items()))
        for name in _FLOAT_FIELDS:
            if values[name] is not None:
                values[name] = float(values[name])
        return cls(**values)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _expect(data: dict[str, Any], name: str, test: Callable[[Any], bool], expected: str) -> None:
    if not test(data[name]):
        raise ValueError(f"field {name!r} = {data[name]!r}: expected {expected}")


def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def classify(metrics: Any) -> str:
    """Outcome class of a finished run from its :class:`visnav.simulation.Metrics`.

    A collision anywhere on the exact trajectory wins over the termination
    reason; otherwise ``"success"``, and ``"timeout"`` for a run that used its
    whole duration.
    """
    if metrics.collided or metrics.termination == "collision":
        return "collision"
    if metrics.termination == "success":
        return "success"
    return "timeout"


def run_sample(spec: CampaignSpec, index: int) -> SampleResult:
    """Draw sample ``index`` of ``spec``, simulate it, classify it; never raises for a failed run.

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    index : int
        ``0 <= index < spec.samples``.

    Returns
    -------
    SampleResult
        Deterministic in ``(spec, index)`` (no wall-clock time in it).

    Raises
    ------
    CampaignSpecError
        Only for an ``index`` outside the campaign (a caller's mistake, not a failed run).
    """
    from hybrid import DivergenceError

    from visnav import simulation
    from visnav.scenario import scenario_digest

    try:
        drawn = sample_scenario(spec, index)
    except CampaignSpecError:
        raise
    except Exception as err:  # noqa: BLE001 - classified, not raised
        return SampleResult(index=int(index), outcome="error", detail=f"{type(err).__name__}: {err}")
    common = {"index": drawn.index, "parameters": drawn.parameters, "attempts": drawn.attempts}
    if drawn.scenario is None:
        return SampleResult(outcome="invalid_scenario", detail=drawn.detail, **common)
    digest = scenario_digest(drawn.scenario)
    try:
        metrics = simulation.simulate(drawn.scenario).metrics
    except DivergenceError as err:
        return SampleResult(outcome="diverged", detail=str(err), scenario_digest=digest, **common)
    except Exception as err:  # noqa: BLE001 - classified, not raised
        return SampleResult(outcome="error", detail=f"{type(err).__name__}: {err}", scenario_digest=digest, **common)
    return SampleResult(
        outcome=classify(metrics),
        scenario_digest=digest,
        min_clearance_m=_finite(metrics.min_clearance_m),
        final_feature_error_px=_finite(metrics.final_feature_error_px),
        max_reconstruction_error_px=_finite(metrics.max_reconstruction_error_px),
        max_depth_error_mm=_finite(metrics.max_depth_error_mm),
        occlusion_duration_s=_finite(metrics.occlusion_duration_s),
        sim_time_s=_finite(metrics.sim_time_s),
        transitions=len(metrics.transitions),
        chatter_count=int(metrics.chatter_count),
        steps=int(metrics.steps),
        within_actuator_limits=bool(metrics.within_actuator_limits),
        **common,
    )


# ---------------------------------------------------------------------------------------------
# Aggregation
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class CampaignSummary:
    """Aggregate of a campaign's results (independent of their completion order).

    Attributes
    ----------
    spec_hash : str
        :meth:`CampaignSpec.spec_hash`.
    samples_requested, samples_done : int
        ``N`` and the number of results summarised.
    complete : bool
        Every index ``0..N-1`` is present.
    counts : tuple of (str, int)
        Results per outcome class, in :data:`OUTCOMES` order.
    success_rate : float or None
        Successes over results (``None`` without results).
    success_interval : tuple of 2 floats or None
        95 % Wilson score interval of the success rate.
    clearance_quantiles_m : tuple of (float, float)
        ``(level, value)`` for :data:`QUANTILES`, over runs with a clearance.
    reconstruction_error_quantiles_px : tuple of (float, float)
        Same for the largest reconstruction error, over runs with an occlusion.
    final_error_quantiles_px : tuple of (float, float)
        Same for the final feature error, over simulated runs.
    failures : tuple of (str, tuple of int)
        The indices of every non-successful outcome class present.
    """

    spec_hash: str
    samples_requested: int
    samples_done: int
    complete: bool
    counts: tuple[tuple[str, int], ...]
    success_rate: float | None
    success_interval: tuple[float, float] | None
    clearance_quantiles_m: tuple[tuple[float, float], ...]
    reconstruction_error_quantiles_px: tuple[tuple[float, float], ...]
    final_error_quantiles_px: tuple[tuple[float, float], ...]
    failures: tuple[tuple[str, tuple[int, ...]], ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (quantiles as ``{"0.05": value}``, failures and counts as objects)."""
        def quantiles(pairs: tuple[tuple[float, float], ...]) -> dict[str, float]:
            return {f"{level:g}": value for level, value in pairs}

        return jsonable({
            "spec_hash": self.spec_hash,
            "samples_requested": self.samples_requested,
            "samples_done": self.samples_done,
            "complete": self.complete,
            "counts": dict(self.counts),
            "success_rate": self.success_rate,
            "success_interval_95": self.success_interval,
            "clearance_quantiles_m": quantiles(self.clearance_quantiles_m),
            "reconstruction_error_quantiles_px": quantiles(self.reconstruction_error_quantiles_px),
            "final_error_quantiles_px": quantiles(self.final_error_quantiles_px),
            "failures": {name: list(indices) for name, indices in self.failures},
        })


def wilson_interval(successes: int, n: int, z: float = WILSON_Z) -> tuple[float, float] | None:
    """Wilson score interval of a binomial proportion (``None`` for ``n = 0``).

    Examples
    --------
    >>> lo, hi = wilson_interval(10, 10)
    >>> round(lo, 4), hi
    (0.7225, 1.0)
    """
    if n == 0:
        return None
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)  # exact bounds, not 1 - 1e-16
    high = 1.0 if successes == n else min(1.0, centre + half)
    return (low, high)


def _quantiles(values: Sequence[float]) -> tuple[tuple[float, float], ...]:
    if not values:
        return ()
    q = np.quantile(np.asarray(values, dtype=float), QUANTILES, method="linear")
    return tuple((level, float(v)) for level, v in zip(QUANTILES, q))


def summarise(spec: CampaignSpec, results: Iterable[SampleResult]) -> CampaignSummary:
    """Aggregate ``results`` of ``spec`` in index order.

    Raises
    ------
    ValueError
        For a result whose index is duplicated or outside ``[0, spec.samples)``.
    """
    ordered = sorted(results, key=lambda r: r.index)
    seen: set[int] = set()
    for r in ordered:
        if not 0 <= r.index < spec.samples:
            raise ValueError(f"result index {r.index}: expected an index in [0, {spec.samples}); "
                             "fix: summarise the results of this campaign only")
        if r.index in seen:
            raise ValueError(f"result index {r.index} appears twice; fix: keep one result per sample")
        seen.add(r.index)
    counts = {name: 0 for name in OUTCOMES}
    for r in ordered:
        counts[r.outcome] += 1
    n = len(ordered)
    successes = counts["success"]
    simulated = [r for r in ordered if r.outcome in _METRIC_OUTCOMES]
    return CampaignSummary(
        spec_hash=spec.spec_hash(),
        samples_requested=spec.samples,
        samples_done=n,
        complete=n == spec.samples,
        counts=tuple(counts.items()),
        success_rate=successes / n if n else None,
        success_interval=wilson_interval(successes, n),
        clearance_quantiles_m=_quantiles([r.min_clearance_m for r in simulated if r.min_clearance_m is not None]),
        reconstruction_error_quantiles_px=_quantiles([
            r.max_reconstruction_error_px for r in simulated
            if r.max_reconstruction_error_px is not None and (r.occlusion_duration_s or 0.0) > 0.0
        ]),
        final_error_quantiles_px=_quantiles(
            [r.final_feature_error_px for r in simulated if r.final_feature_error_px is not None]
        ),
        failures=tuple(
            (name, tuple(r.index for r in ordered if r.outcome == name))
            for name in OUTCOMES if name != "success" and counts[name]
        ),
    )


# ---------------------------------------------------------------------------------------------
# Execution
# ---------------------------------------------------------------------------------------------


class InlineExecutor(cf.Executor):
    """An executor that runs each call at submission, in the calling process (``--workers 1``)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        """Run ``fn(*args, **kwargs)`` now; return a finished future."""
        future: cf.Future = cf.Future()
        future.set_running_or_notify_cancel()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as err:  # noqa: BLE001 - delivered through the future, as other executors do
            future.set_exception(err)
        return future


def run_campaign(
    spec: CampaignSpec,
    executor: cf.Executor,
    sink: Callable[[SampleResult], None],
    *,
    skip: Collection[int] = (),
    window: int = 8,
    interrupt_grace_s: float = 5.0,
) -> int:
    """Run every sample of ``spec`` not in ``skip`` on ``executor``; call ``sink`` with each result.

    At most ``window`` samples are in flight; results are handed over as they
    complete (in any order: :func:`summarise` sorts them).

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    executor : concurrent.futures.Executor
        Where :func:`run_sample` runs.
    sink : callable
        Receives each :class:`SampleResult` in the calling thread (e.g. appends it to a file).
    skip : collection of int
        Indices already done (a resumed campaign).
    window : int
        Samples submitted ahead (a few per worker keeps them busy).
    interrupt_grace_s : float
        On ``KeyboardInterrupt``: queued samples are cancelled, running ones are
        waited for up to this long and their results still reach ``sink``; then
        the interrupt propagates.

    Returns
    -------
    int
        Number of results handed to ``sink``.
    """
    _check_int("window", window, 1, "use a few samples per worker, e.g. 8")
    skip = frozenset(skip)
    todo = iter([i for i in range(spec.samples) if i not in skip])
    pending: dict[cf.Future, int] = {}
    delivered = 0

    def submit_next() -> None:
        index = next(todo, None)
        if index is not None:
            pending[executor.submit(run_sample, spec, index)] = index

    def deliver(future: cf.Future) -> None:
        nonlocal delivered
        index = pending.pop(future)
        result = future.result()
        if not isinstance(result, SampleResult) or result.index != index:
            raise RuntimeError(f"sample {index}: the executor returned {result!r}, not its SampleResult")
        sink(result)
        delivered += 1

    try:
        for _ in range(window):
            submit_next()
        while pending:
            done, _ = cf.wait(list(pending), return_when=cf.FIRST_COMPLETED)
            for future in sorted(done, key=pending.__getitem__):
                deliver(future)
                submit_next()
    except KeyboardInterrupt:
        for future in pending:
            future.cancel()
        running = [f for f in pending if not f.cancelled()]
        if running:
            cf.wait(running, timeout=interrupt_grace_s)
        for future in sorted(running, key=pending.__getitem__):
            if future.done() and not future.cancelled() and future.exception() is None:
                deliver(future)
        raise
    except BaseException:
        for future in pending:
            future.cancel()
        raise
    return delivered


@dataclass(frozen=True, kw_only=True, slots=True)
class CampaignBackend:
    """An executor ready for :func:`run_campaign`.

    Attributes
    ----------
    executor : concurrent.futures.Executor
        The executor.
    kind : str
        ``"inline"``, ``"process"`` or ``"dask"``.
    workers : int
        Worker processes (Dask: threads over all workers).
    description : str
        Human description (``"process pool, 2 workers"``, ``"dask tcp://...: 2 workers"``).
    window : int
        Suggested :func:`run_campaign` window.
    """

    executor: cf.Executor
    kind: str
    workers: int
    description: str
    window: int


ORPHAN_POLL_S = 1.0
"""How often a pool worker checks that its parent is alive [s]."""


def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (Linux ``/proc``; elsewhere existence only)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as handle:
            state = handle.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in ("Z", "X")


def _init_worker(campaign_pid: int) -> None:
    """Pool worker initialiser.

    The parent handles Ctrl-C (the terminal sends it to the whole process group),
    so workers ignore SIGINT.  A worker whose campaign process dies (killed with
    SIGKILL) exits within :data:`ORPHAN_POLL_S` instead of waiting forever on its
    task queue; the forkserver and the resource tracker then exit by themselves.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while True:
            time.sleep(ORPHAN_POLL_S)
            if not _process_alive(campaign_pid):
                os._exit(1)

    threading.Thread(target=watch, name="visnav-orphan-watch", daemon=True).start()


def process_pool(workers: int) -> cf.ProcessPoolExecutor:
    """The process pool of ``visnav sweep --workers N`` (forkserver start, SIGINT ignored, orphans exit).

    ``forkserver`` (with ``visnav`` preloaded in the server) keeps the pool safe in a process
    that already has threads (a Dask client, a test runner) and makes worker start-up cheap.
    """
    _check_int("--workers", workers, 1, "give the number of worker processes, e.g. 2")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["visnav.studies.campaign", "visnav.simulation", "visnav.scenario"])
    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_init_worker,
                                  initargs=(os.getpid(),))


def probe_scheduler(address: str, timeout_s: float) -> None:
    """Ask the Dask scheduler at ``address`` for its identity, within ``timeout_s`` overall.

    ``distributed.Client(address, timeout=...)`` can wait indefinitely on a peer
    that accepts the connection but never answers; this probe cannot.

    Raises
    ------
    SchedulerUnavailableError
        If nothing answers the identity request in time.
    """
    from distributed.comm import connect

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s))
    except (OSError, asyncio.TimeoutError, ValueError) as err:
        raise SchedulerUnavailableError(
            address, timeout_s, f"no Dask scheduler answered ({type(err).__name__}: {err})".replace(" ()", ""),
            "start one (`dask scheduler`, then `dask worker ADDRESS`), check the address and port, "
            "or raise --connect-timeout",
        ) from err
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise SchedulerUnavailableError(
            address, timeout_s, f"the peer answered but is not a Dask scheduler ({reply!r:.80})",
            "give the address of a Dask scheduler",
        )


def _check_address(address: str) -> None:
    match = _ADDRESS.match(address) if isinstance(address, str) else None
    if match is None or not 0 < int(match[2]) < 65536:
        raise CampaignSpecError("--scheduler", address, "an address tcp://HOST:PORT (or tls://HOST:PORT)",
                                "e.g. --scheduler tcp://127.0.0.1:8786")


@contextlib.contextmanager
def campaign_executor(
    *,
    workers: int | None = None,
    dask_local: int | None = None,
    scheduler: str | None = None,
    connect_timeout_s: float = 10.0,
) -> Iterator[CampaignBackend]:
    """An executor for a campaign, shut down (cluster included) on exit.

    Give at most one of ``workers``, ``dask_local`` and ``scheduler``; with none,
    a process pool of ``os.cpu_count()`` workers.

    Parameters
    ----------
    workers : int, optional
        Process pool size (:func:`process_pool`); 1 runs in the calling process
        (:class:`InlineExecutor`).
    dask_local : int, optional
        Workers of a ``distributed.LocalCluster`` (one process and one thread each).
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running Dask scheduler; its workers must be able to import
        ``visnav``.
    connect_timeout_s : float
        Bound on reaching the scheduler, and on waiting for its first worker [s].

    Raises
    ------
    CampaignSpecError
        Bad option values.
    SchedulerUnavailableError
        The scheduler does not answer, or has no worker, within ``connect_timeout_s``.
    """
    options = {"--workers": workers, "--dask-local": dask_local, "--scheduler": scheduler}
    chosen = [name for name, value in options.items() if value is not None]
    if len(chosen) > 1:
        raise CampaignSpecError(chosen[1], options[chosen[1]],
                                f"one executor option, but {' and '.join(chosen)} were given", "keep one of them")
    if isinstance(connect_timeout_s, bool) or not isinstance(connect_timeout_s, (int, float)) or not (
        math.isfinite(connect_timeout_s) and connect_timeout_s > 0
    ):
        raise CampaignSpecError("--connect-timeout", connect_timeout_s, "a positive number of seconds", "e.g. 10")
    if scheduler is not None:
        _check_address(scheduler)
        probe_scheduler(scheduler, float(connect_timeout_s))
        from distributed import Client

        try:
            client = Client(scheduler, timeout=connect_timeout_s, set_as_default=False)
        except (OSError, asyncio.TimeoutError) as err:
            raise SchedulerUnavailableError(scheduler, connect_timeout_s, f"the client could not connect ({err})",
                                            "check the scheduler and raise --connect-timeout") from err
        try:
            try:
                client.wait_for_workers(1, timeout=connect_timeout_s)
            except (OSError, asyncio.TimeoutError) as err:
                raise SchedulerUnavailableError(scheduler, connect_timeout_s, "the scheduler has no worker",
                                                "start workers with `dask worker ADDRESS`") from err
            threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
            executor = client.get_executor(pure=False)
            yield CampaignBackend(executor=executor, kind="dask", workers=threads,
                                  description=f"dask scheduler {scheduler}: {threads} worker threads",
                                  window=max(4, 2 * threads))
        finally:
            client.close()
        return
    if dask_local is not None:
        _check_int("--dask-local", dask_local, 1, "give the number of Dask worker processes, e.g. 2")
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=dask_local, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as cluster, Client(cluster, set_as_default=False) as client:
            yield CampaignBackend(executor=client.get_executor(pure=False), kind="dask", workers=dask_local,
                                  description=f"dask LocalCluster, {dask_local} workers",
                                  window=max(4, 2 * dask_local))
        return
    n = (os.cpu_count() or 1) if workers is None else workers
    _check_int("--workers", n, 1, "give the number of worker processes, e.g. 2")
    if n == 1:
        yield CampaignBackend(executor=InlineExecutor(), kind="inline", workers=1,
                              description="1 worker (in process)", window=1)
        return
    pool = process_pool(n)
    try:
        yield CampaignBackend(executor=pool, kind="process", workers=n, description=f"process pool, {n} workers",
                              window=2 * n)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
