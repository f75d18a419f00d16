"""Monte-Carlo campaigns of the robot over scenario and gain distributions.

A :class:`CampaignSpec` names a base scenario, a number of samples, a seed and
the distributions of the perturbations: start pose, obstacle positions, radii
and heights, target pose (moved rigidly with the goal, so that ``s*`` is
unchanged) and relative factors on the gains ``k_path``, ``λ_VS`` and
``v_coll``; :meth:`CampaignSpec.perturbation` declares them as a
:class:`visnav.perturbation.Perturbation`.  Sample ``i`` is drawn from
``SeedSequence(seed).spawn(...)[i]`` only, so a campaign's results do not
depend on the order in which samples run, on the number of workers or on
interruptions.

:func:`run_sample` simulates one sample and never raises for a failed run: it
classifies it (:data:`CAMPAIGN_OUTCOMES`, names of :data:`visnav.simulation.OUTCOMES`).
:func:`summarise` aggregates results in index order (success rate with a
Wilson interval, quantiles of the clearance and of the reconstruction error,
the failure classes).  :func:`run_campaign` runs the samples with the generic
machinery of :mod:`analysis.campaigns` (any executor, results streamed to a
sink, done indices skipped).

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

import concurrent.futures as cf
import hashlib
import math
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.campaigns import InlineExecutor, quantiles, run_tasks, wilson_interval
from analysis.campaigns import process_pool as _generic_process_pool
from hybrid import DivergenceError
from hybrid.errors import ParameterError
from hybrid.jsonable import canonical_json, to_jsonable

from visnav import simulation
from visnav.parameters import Scenario
from visnav.perturbation import Move, Perturbation, Symmetric, Uniform, apply_perturbation
from visnav.scenario import scenario_digest, scenario_to_toml

__all__ = [
    "CAMPAIGN_FORMAT",
    "CAMPAIGN_VERSION",
    "CAMPAIGN_OUTCOMES",
    "QUANTILES",
    "PRELOAD",
    "CampaignSpecError",
    "Uniform",
    "CampaignSpec",
    "SampledScenario",
    "SampleResult",
    "CampaignSummary",
    "InlineExecutor",  # re-exported from analysis.campaigns
    "store_header",
    "sample_scenario",
    "run_sample",
    "summarise",
    "run_campaign",
    "process_pool",
]

CAMPAIGN_FORMAT = "visnav-campaign"
"""Name of the campaign file format (header of the results file, spec hash)."""
CAMPAIGN_VERSION = 1
"""Version of the sampling scheme and of the result records; part of the spec hash."""

CAMPAIGN_OUTCOMES = tuple(name for name in simulation.OUTCOMES if simulation.without_diagnosis(name) == name)
"""Outcome classes of a sample, in report order: the names of :data:`visnav.simulation.OUTCOMES`.

``success``, ``collision``, ``timeout`` (:func:`visnav.simulation.classify_run`), ``diverged``
(:class:`hybrid.DivergenceError`, the detail gives time, mode and cause), ``invalid_scenario`` (no
draw within ``max_attempts`` satisfied the scenario rules, ``docs/scenarios.md``), ``error`` (any
other exception; its type and message are the detail).  Format version 1 records a timeout without
its diagnosis (``stuck_in_loop`` and ``target_lost`` are stored as ``timeout``,
:func:`visnav.simulation.without_diagnosis`).
"""

QUANTILES = (0.0, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)
"""Quantile levels reported by :func:`summarise` (linear interpolation)."""

PRELOAD = ("visnav.studies.campaign", "visnav.simulation", "visnav.scenario")
"""Modules a process pool's forkserver imports before starting campaign workers."""


class CampaignSpecError(ParameterError):
    """An invalid campaign specification.

    ``parameter``, ``value``, ``expected`` and ``fix`` as in :class:`hybrid.errors.ParameterError`.
    """



# ---------------------------------------------------------------------------------------------
# Specification
# ---------------------------------------------------------------------------------------------


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

    def perturbation(self) -> Perturbation:
        """The moves of a sample, in draw order: start ``x, y, θ``; per obstacle centre ``x, y``, radius
        and height; target ``x, y`` and heading (rigid, with the goal); the gain factors."""
        start = Symmetric(half_width=self.start_offset_m)
        moves = [Move(field="start.x_m", change="offset", draw=start),
                 Move(field="start.y_m", change="offset", draw=start),
                 Move(field="start.theta_rad", change="offset", draw=Symmetric(half_width=self.start_heading_rad))]
        centre = Symmetric(half_width=self.obstacle_offset_m)
        for j in range(len(self.scenario.obstacles)):
            moves += [Move(field=f"obstacles[{j}].x_m", change="offset", draw=centre),
                      Move(field=f"obstacles[{j}].y_m", change="offset", draw=centre),
                      Move(field=f"obstacles[{j}].radius_m", change="offset",
                           draw=Symmetric(half_width=self.obstacle_radius_m)),
                      Move(field=f"obstacles[{j}].height_m", change="offset",
                           draw=Symmetric(half_width=self.obstacle_height_m))]
        target = Symmetric(half_width=self.target_offset_m)
        moves += [Move(field="target.x_m", change="offset", draw=target),
                  Move(field="target.y_m", change="offset", draw=target),
                  Move(field="target.heading_rad", change="offset", draw=Symmetric(half_width=self.target_heading_rad))]
        moves += [Move(field=f"gains.{gain}", change="factor", draw=getattr(self, name))
                  for name, gain in _GAIN_FIELDS.items()]
        return Perturbation(moves=tuple(moves))


def _check_int(name: str, value: object, minimum: int, fix: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise CampaignSpecError(name, value, f"an integer >= {minimum}", fix)
    if value < minimum:
        raise CampaignSpecError(name, value, f"an integer >= {minimum}", fix)


def store_header(spec: CampaignSpec) -> dict[str, Any]:
    """Line 1 of the campaign's results file (:mod:`visnav.app.campaign_store`): format, version, spec."""
    return {"format": CAMPAIGN_FORMAT, "version": CAMPAIGN_VERSION, "spec_hash": spec.spec_hash(),
            "spec": spec.as_dict()}


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


def _rng(spec: CampaignSpec, index: int) -> np.random.Generator:
    # Identical to np.random.SeedSequence(spec.seed).spawn(index + 1)[index], without the spawn.
    return np.random.default_rng(np.random.SeedSequence(entropy=spec.seed, spawn_key=(index,)))


def sample_scenario(spec: CampaignSpec, index: int) -> SampledScenario:
    """Draw and validate sample ``index`` of ``spec`` (deterministic in ``(spec, index)``).

    Each attempt applies the unit draws ``rng.random(n)`` of the sample's generator
    to :meth:`CampaignSpec.perturbation` (:func:`visnav.perturbation.apply_perturbation`,
    which validates the result).

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
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < spec.samples:
        raise CampaignSpecError("index", index, f"an integer in [0, {spec.samples})", "use a sample index of the campaign")
    rng = _rng(spec, int(index))
    perturbation = spec.perturbation()
    source = f"{spec.scenario.name}#{index}"
    detail = ""
    params: tuple[tuple[str, float], ...] = ()
    for attempt in range(1, spec.max_attempts + 1):
        drawn = apply_perturbation(spec.scenario, perturbation, perturbation.from_unit(rng.random(perturbation.size)),
                                   source=source)
        params = drawn.parameters
        if drawn.scenario is None:
            detail = str(drawn.error)
            continue
        return SampledScenario(index=int(index), scenario=drawn.scenario, parameters=params, attempts=attempt,
                               detail="")
    return SampledScenario(index=int(index), scenario=None, parameters=params, attempts=spec.max_attempts,
                           detail=detail)


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
        One of :data:`CAMPAIGN_OUTCOMES`.
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
        return to_jsonable(out)

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
        _expect(data, "outcome", lambda v: v in CAMPAIGN_OUTCOMES, f"one of {', '.join(CAMPAIGN_OUTCOMES)}")
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


def _number(x: float) -> float | None:
    """A metric as stored: the float, ``None`` when not finite (e.g. the clearance without obstacles)."""
    return to_jsonable(float(x))


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
        run = simulation.simulate(drawn.scenario)
        outcome = simulation.without_diagnosis(simulation.classify_run(run.scenario, run.trace, run.metrics))
    except DivergenceError as err:
        return SampleResult(outcome="diverged", detail=str(err), scenario_digest=digest, **common)
    except Exception as err:  # noqa: BLE001 - classified, not raised
        return SampleResult(outcome="error", detail=f"{type(err).__name__}: {err}", scenario_digest=digest, **common)
    metrics = run.metrics
    return SampleResult(
        outcome=outcome,
        scenario_digest=digest,
        min_clearance_m=_number(metrics.min_clearance_m),
        final_feature_error_px=_number(metrics.final_feature_error_px),
        max_reconstruction_error_px=_number(metrics.max_reconstruction_error_px),
        max_depth_error_mm=_number(metrics.max_depth_error_mm),
        occlusion_duration_s=_number(metrics.occlusion_duration_s),
        sim_time_s=_number(metrics.sim_time_s),
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
        Results per outcome class, in :data:`CAMPAIGN_OUTCOMES` order.
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
        def by_level(pairs: tuple[tuple[float, float], ...]) -> dict[str, float]:
            return {f"{level:g}": value for level, value in pairs}

        return to_jsonable({
            "spec_hash": self.spec_hash,
            "samples_requested": self.samples_requested,
            "samples_done": self.samples_done,
            "complete": self.complete,
            "counts": dict(self.counts),
            "success_rate": self.success_rate,
            "success_interval_95": self.success_interval,
            "clearance_quantiles_m": by_level(self.clearance_quantiles_m),
            "reconstruction_error_quantiles_px": by_level(self.reconstruction_error_quantiles_px),
            "final_error_quantiles_px": by_level(self.final_error_quantiles_px),
            "failures": {name: list(indices) for name, indices in self.failures},
        })


def _quantiles(values: list[float]) -> tuple[tuple[float, float], ...]:
    return quantiles(values, QUANTILES)


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
    counts = {name: 0 for name in CAMPAIGN_OUTCOMES}
    for r in ordered:
        counts[r.outcome] += 1
    n = len(ordered)
    successes = counts["success"]
    simulated = [r for r in ordered if r.outcome in simulation.RUN_OUTCOMES]
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
            for name in CAMPAIGN_OUTCOMES if name != "success" and counts[name]
        ),
    )


# ---------------------------------------------------------------------------------------------
# Execution (the generic machinery is analysis.campaigns)
# ---------------------------------------------------------------------------------------------


def run_campaign(
    spec: CampaignSpec,
    executor: cf.Executor,
    sink: Callable[[SampleResult], None],
    *,
    skip: Collection[int] = (),
    window: int = 8,
    order: str = "completion",
    interrupt_grace_s: float = 5.0,
) -> int:
    """Run every sample of ``spec`` not in ``skip`` on ``executor``; call ``sink`` with each result.

    :func:`analysis.campaigns.run_tasks` with :func:`run_sample` as the task: at most
    ``window`` samples in flight, results handed over as they complete (``order="completion"``,
    :func:`summarise` sorts them) or in index order (``order="index"``); on
    ``KeyboardInterrupt`` the samples already running are waited for up to
    ``interrupt_grace_s`` [s] and still reach ``sink``.

    Parameters
    ----------
    spec : CampaignSpec
        The campaign.
    executor : concurrent.futures.Executor
        Where :func:`run_sample` runs (:func:`analysis.campaigns.campaign_executor`,
        :func:`process_pool`, :class:`~analysis.campaigns.InlineExecutor`).
    sink : callable
        Receives each :class:`SampleResult` in the calling thread (e.g. appends it to a file).
    skip : collection of int
        Indices already done (a resumed campaign).
    window, order, interrupt_grace_s
        As in :func:`analysis.campaigns.run_tasks`.

    Returns
    -------
    int
        Number of results handed to ``sink``.

    Raises
    ------
    analysis.campaigns.CampaignOptionError
        Bad ``window``, ``order`` or ``interrupt_grace_s``.
    RuntimeError
        The executor returned something else than the sample's :class:`SampleResult`.
    """
    def deliver(index: int, result: Any) -> None:
        if not isinstance(result, SampleResult) or result.index != index:
            raise RuntimeError(f"sample {index}: the executor returned {result!r:.200}, not its SampleResult")
        sink(result)

    return run_tasks(run_sample, spec, spec.samples, executor, deliver, skip=skip, window=window, order=order,
                     interrupt_grace_s=interrupt_grace_s)


def process_pool(workers: int) -> cf.ProcessPoolExecutor:
    """:func:`analysis.campaigns.process_pool` with the campaign modules preloaded (:data:`PRELOAD`).

    Raises
    ------
    analysis.campaigns.CampaignOptionError
        ``workers`` not an integer >= 1.
    """
    return _generic_process_pool(workers, preload=PRELOAD)
