"""Fuzzing the supervisor's switching logic with hypothesis: strategies, properties, runner, replay.

The supervisor is driven in two ways:

* **signal sequences**: the raw measurements of every sample
  (:class:`MeasurementSpace`: ``d_coll`` per obstacle, the bypass side,
  ``d_occ``, ``d_bord``, the raw pan angle ϑ, α and the visible fraction) are
  drawn by the strategies of :mod:`analysis.fuzzing` — bounded-rate
  (physically plausible) or unbounded (adversarial), respecting the paper's
  hypothesis that the robot is near one obstacle at a time or not — and fed
  sample by sample to a :class:`~visnav.fuzzing.mutants.SupervisorVariant`
  (:class:`SupervisorRunner`, the same semantics as :func:`hybrid.settle`,
  recording what the properties need);
* **whole scenarios**: random layouts (obstacles, heights, target, start) run
  through the closed loop (:func:`scenarios`, :func:`simulate_variant`).

Every property is a named, documented check in :data:`PROPERTIES`
(``visnav fuzz --property NAME``; the docstrings are the specification).
:func:`fuzz` runs a selection on one variant (the resolved automaton, a
mutant of :mod:`visnav.fuzzing.mutants` or the as-written logic of
:mod:`visnav.fuzzing.paper_logic`) and returns :class:`FuzzReport`; a failure comes
with a shrunk :class:`Counterexample` that :func:`counterexample_to_json`
serialises (format version :data:`FORMAT_VERSION`) and :func:`replay` runs
again.  Nothing here prints or writes files.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import json
import math
import time
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from analysis.fuzzing import (
    Channel,
    Observer,
    PropertyRun,
    PropertyViolation,
    Segment,
    adversarial_sequences,
    bounded_rate_sequences,
    follow_waypoints,
    run_machine,
    run_property,
    waypoint_strategy,
)
from hybrid import DivergenceError, HybridError, Plant, SampledTrace, simulate_sampled, transition_fires

from visnav import model as kinematics
from visnav.closed_loop import ClosedLoop, LoopState, robot_plant
from visnav.controllers import avoidance_control, blend
from visnav.geometry import wrap_angle
from visnav.fuzzing.mutants import MUTANTS, RESOLVED, SupervisorVariant, build_variant
from visnav.fuzzing.paper_logic import PAPER, mu_coll_cases, mu_occ_cases, paper_variant
from visnav.scenario import load_scenario, target_square
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
    Target,
)
from visnav.simulation import Metrics, compute_metrics
from visnav.supervisor import I_D_BORD, I_D_NEAREST, I_D_OCC, I_NEAREST, I_PAN, I_SIDE, split_mode

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "MAX_JUMPS_PER_SAMPLE",
    "OUTCOMES",
    "VARIANTS",
    "MeasurementSpace",
    "Jump",
    "Step",
    "SupervisorRunner",
    "run_supervisor",
    "respect_hypotheses",
    "hypotheses_prefix",
    "signal_runs",
    "bypass_runs",
    "scenarios",
    "Property",
    "PROPERTIES",
    "property_names",
    "make_variant",
    "VariantLoop",
    "simulate_variant",
    "ScenarioRun",
    "classify_outcome",
    "supervisor_machine",
    "Counterexample",
    "CounterexampleError",
    "counterexample_to_json",
    "counterexample_from_json",
    "PropertyResult",
    "FuzzReport",
    "budget",
    "fuzz_property",
    "fuzz",
    "Replay",
    "replay",
    "RESPECTING",
    "STATEFUL_STEPS",
    "TOLERANCE",
    "CONTROL_TOLERANCE",
    "MAX_JUMPS_BOUNDED",
    "TARGET_LOST_WINDOW_S",
    "check_mu_range",
    "check_mu_continuity",
    "check_determinism",
    "check_no_chatter",
    "check_flag_consistency",
    "check_control_continuity",
    "check_leave_timing",
    "check_leave_release",
    "check_differential",
    "check_stateful",
    "check_no_collision",
    "check_classified_outcome",
    "check_closed_loop_continuity",
]

FORMAT = "visnav-fuzz-counterexample"
"""Value of the ``format`` key of a counterexample file."""
FORMAT_VERSION = 1
"""Version of the counterexample file format (:func:`counterexample_from_json` accepts only this one)."""

MAX_JUMPS_PER_SAMPLE = 8
"""Jumps allowed at one sample before the run counts as instantaneous Zeno (as :func:`hybrid.simulate_sampled`)."""

MAX_JUMPS_BOUNDED = 4
"""Jumps per sample that bounded-rate measurements may cause (two per component)."""

TOLERANCE = 1e-12
"""Absolute tolerance of the equalities checked on µ."""
CONTROL_TOLERANCE = 1e-9
"""Absolute tolerance on the control at a switch [m/s, rad/s]."""

OUTCOMES = ("success", "collision", "timeout", "stuck_in_loop", "target_lost")
"""Classified ends of a closed-loop run (:func:`classify_outcome`)."""

VARIANTS = (RESOLVED, PAPER, *MUTANTS)
"""Names accepted by :func:`make_variant`."""

TARGET_LOST_WINDOW_S = 5.0
"""A run that ends with no target point visible for this long counts as ``target_lost`` [s]."""


# =============================================================================================
# Measurements
# =============================================================================================


@dataclass(frozen=True, kw_only=True, slots=True)
class MeasurementSpace:
    """What one sample of measurements holds, its plausible rates and the specification's constants.

    A measurement row is ``(d_coll_0, ..., d_coll_{n-1}, side, d_occ, d_bord,
    pan, alpha, visible)``: distances to every obstacle [m], the bypass side
    (±1), the distance before occlusion and the occluder's distance to the
    border [px], the *raw* pan angle ϑ [rad] (the measurement stage wraps it
    unless the variant says otherwise), the heading error α [rad] and the
    fraction of visible target points.

    The rate bounds are per sample (T = ``period_s``); the defaults are the
    avoidance speed v_coll = 0.2 m/s, 80 px/s, 120 px/s, 0.8 rad/s of pan,
    2 rad/s of α and a quarter of the points per sample.  The properties read
    the specification's constants (envelopes, arming angle, hysteresis) from
    here, never from the variant under test.
    """

    envelopes: Envelopes = field(default_factory=Envelopes)
    settings: SupervisorSettings = field(default_factory=SupervisorSettings)
    n_obstacles: int = 2
    camera_half_width_px: float = 320.0
    period_s: float = 0.05
    max_step_d_m: float = 0.01
    max_step_d_occ_px: float = 4.0
    max_step_d_bord_px: float = 6.0
    max_step_pan_rad: float = 0.04
    max_step_alpha_rad: float = 0.1
    max_step_visible: float = 0.25

    def __post_init__(self) -> None:
        if not (isinstance(self.n_obstacles, int) and self.n_obstacles >= 1):
            raise ValueError(f"MeasurementSpace.n_obstacles = {self.n_obstacles!r}: expected an integer >= 1")

    @property
    def names(self) -> tuple[str, ...]:
        """Channel names in row order."""
        return tuple(f"d_coll_{i}_m" for i in range(self.n_obstacles)) + (
            "side", "d_occ_px", "d_bord_px", "pan_rad", "alpha_rad", "visible",
        )

    def index(self, name: str) -> int:
        """Column of channel ``name``."""
        return self.names.index(name)

    def channels(self) -> tuple[Channel, ...]:
        """The :class:`analysis.fuzzing.Channel` of every column, with the guards' thresholds as landmarks."""
        env, s = self.envelopes, self.settings
        d_landmarks = (
            env.d_minus_m, env.d_zero_m, env.d_plus_m, env.d_plus_m + s.detection_hysteresis_m,
            env.d_plus_m + s.detection_hysteresis_m + (env.d_plus_m - env.d_zero_m),
        )
        d_channels = tuple(
            Channel(name=f"d_coll_{i}_m", low=0.0, high=env.d_plus_m + 1.0, max_step=self.max_step_d_m,
                    landmarks=d_landmarks)
            for i in range(self.n_obstacles)
        )
        arm = s.arm_angle_rad
        pi, two_pi = math.pi, 2.0 * math.pi
        return d_channels + (
            Channel(name="side", choices=(1.0, -1.0)),
            Channel(name="d_occ_px", low=0.0, high=2.0 * env.D_plus_px, max_step=self.max_step_d_occ_px,
                    landmarks=(env.D_minus_px, 0.5 * (env.D_minus_px + env.D_zero_px), env.D_zero_px, env.D_plus_px,
                               0.0, env.D_plus_px + (env.D_plus_px - env.D_zero_px)),
                    specials=(math.inf,)),
            Channel(name="d_bord_px", low=0.0, high=self.camera_half_width_px, max_step=self.max_step_d_bord_px,
                    landmarks=(0.0, self.camera_half_width_px), specials=(math.inf,)),
            Channel(name="pan_rad", low=-two_pi - 1.0, high=two_pi + 1.0, max_step=self.max_step_pan_rad,
                    landmarks=(0.0, arm, -arm, 0.5 * pi, -0.5 * pi, pi, -pi, two_pi, -two_pi, two_pi + 2 * arm,
                               two_pi - 2 * arm)),
            Channel(name="alpha_rad", low=-math.pi, high=math.pi, max_step=self.max_step_alpha_rad, landmarks=(0.0,)),
            Channel(name="visible", low=0.0, high=1.0, max_step=self.max_step_visible, landmarks=(0.0, 1.0)),
        )

    def lipschitz_mu_coll(self) -> float:
        """Bound on ``|Δµ_coll| / max_i |Δd_coll_i|`` claimed by ``docs/supervisor.md`` [1/m]."""
        env = self.envelopes
        return 1.0 / min(env.d_zero_m - env.d_minus_m, env.d_plus_m - env.d_zero_m)

    def lipschitz_mu_occ(self) -> float:
        """Bound on ``|Δµ_occ| / |Δd_occ|`` [1/px]."""
        env = self.envelopes
        return 1.0 / min(env.D_zero_px - env.D_minus_px, env.D_plus_px - env.D_zero_px)

    def min_reversal_gap(self) -> int:
        """Samples a component needs to undo a switch under bounded rates.

        The narrowest hysteresis bands are the detection hysteresis (crossed
        at ``max_step_d_m``) and half the occlusion band ``(D0 − D−)/2`` (the
        release margin of the ``d_bord`` branch, crossed at ``max_step_d_occ_px``).
        """
        env = self.envelopes
        return int(math.floor(min(
            self.settings.detection_hysteresis_m / self.max_step_d_m,
            0.5 * (env.D_zero_px - env.D_minus_px) / self.max_step_d_occ_px,
        )))


def respect_hypotheses(rows: Sequence[Sequence[float]], space: MeasurementSpace) -> tuple[tuple[float, ...], ...]:
    """Project measurement rows onto the paper's hypothesis "obstacles more than 2 d+ apart".

    Surface-to-surface separation ``>= 2 d+`` implies ``d_i + d_j >= 2 d+``
    for any robot position; ``d_j := max(d_j, 2 d+ − min_{i<j} d_i)``
    enforces it and keeps every rate bound (a max of bounded-rate signals is
    bounded-rate with the same bound).
    """
    n = space.n_obstacles
    two_d_plus = 2.0 * space.envelopes.d_plus_m
    out = []
    for row in rows:
        ds = list(row[:n])
        smallest = ds[0]
        for j in range(1, n):
            ds[j] = max(ds[j], two_d_plus - smallest)
            smallest = min(smallest, ds[j])
        out.append((*ds, *row[n:]))
    return tuple(out)


def hypotheses_prefix(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step]) -> int:
    """Length of the prefix of a run on which the closed-loop hypothesis of the bypass holds.

    (H2) While the supervisor asks for pure avoidance (AVOID = 1, LEAVE = 0
    after a sample), the path follower keeps the robot within ξ+ of the
    obstacle it avoids (the nearest one when AVOID was set): at the next
    sample that distance is at most d+.  This is what case 3 of (2)
    presumes (its release band is [dL, d+], empty if LEAVE came beyond d+)
    and what ``visnav analyse`` bounds along a bypass; open-loop measurement
    sequences can break it, so the properties on hypothesis-respecting
    inputs are checked on the prefix before the first sample that does.
    (H1, obstacles more than 2 d+ apart, is enforced by :func:`respect_hypotheses`.)
    """
    n = space.n_obstacles
    d_plus = space.envelopes.d_plus_m
    obstacle = -1
    avoiding = False
    prev_avoid = _flags(variant, variant.model.automaton.initial_mode)[0]
    for k, s in enumerate(steps):
        ds = _distances(s, n)
        if avoiding and ds[obstacle] > d_plus:
            return k
        avoid, leave, _ = _flags(variant, s.mode)
        if avoid and not prev_avoid:
            obstacle = min(range(n), key=ds.__getitem__)
        avoiding = bool(avoid and not leave and obstacle >= 0)
        prev_avoid = avoid
    return len(steps)


@st.composite
def _bypasses(draw: Callable[[st.SearchStrategy[Any]], Any], space: MeasurementSpace) -> tuple[tuple[float, ...], ...]:
    channels = _channels(space)
    env, settings = space.envelopes, space.settings
    n = space.n_obstacles
    i_pan, i_occ, i_bord = space.index("pan_rad"), space.index("d_occ_px"), space.index("d_bord_px")
    start = [draw(waypoint_strategy(ch)) for ch in channels]
    obstacle = draw(st.integers(0, n - 1))
    offset = draw(st.sampled_from((0.0, 2.0 * math.pi, -2.0 * math.pi)))
    sign = draw(st.sampled_from((1.0, -1.0)))
    arm = settings.arm_angle_rad
    start[obstacle] = draw(st.floats(env.d_plus_m + 0.02, env.d_plus_m + 0.4))
    start[i_pan] = offset + draw(st.floats(-0.05, 0.05))
    inside = st.one_of(st.sampled_from((env.d_minus_m, env.d_minus_m - 0.01)), st.floats(0.05, env.d_minus_m))
    band = st.floats(env.d_minus_m, env.d_zero_m + 0.05)
    story = [
        {obstacle: draw(inside)},                                                       # enter xi-
        {i_pan: offset + sign * draw(st.floats(arm, arm + 1.2)), obstacle: draw(band)},  # go round, pan swings out
        {i_pan: offset - sign * draw(st.floats(0.0, 0.5)), obstacle: draw(band)},        # pan back through 0
        {obstacle: draw(st.floats(env.d_plus_m, env.d_plus_m + 1.0))},                  # move away
    ]
    current = list(start)
    segments = []
    for leg in story:
        targets: list[float | None] = [None] * len(channels)
        speeds = [0.0] * len(channels)
        for col, goal in leg.items():
            targets[col] = goal
            speeds[col] = channels[col].max_step * (1.0 - draw(st.floats(0.0, 0.5)))  # shrinks to full speed
        for col in (i_occ, i_bord):  # the occluder does what it likes, within its rates
            if draw(st.booleans()):
                targets[col] = draw(waypoint_strategy(channels[col]))
                speeds[col] = channels[col].max_step * draw(st.floats(0.0, 1.0))
        for col, ch in enumerate(channels):
            if targets[col] is None and col not in leg and col not in (i_occ, i_bord) and col != obstacle:
                targets[col] = draw(waypoint_strategy(ch))
                speeds[col] = math.inf if ch.choices else ch.max_step * draw(st.floats(0.0, 1.0))
        needed = max(
            (abs(goal - current[col]) / speeds[col] for col, goal in leg.items() if speeds[col] > 0.0), default=1.0
        )
        duration = min(200, int(math.ceil(needed)) + draw(st.integers(0, 20)))
        segments.append(Segment(duration=max(1, duration), targets=tuple(targets), speeds=tuple(speeds)))
        for col, goal in leg.items():
            current[col] = goal
    return follow_waypoints(tuple(start), segments)


def bypass_runs(space: MeasurementSpace) -> st.SearchStrategy[tuple[tuple[float, ...], ...]]:
    """Bounded-rate runs shaped like an obstacle bypass (the story the supervisor is built for).

    One obstacle is approached into ξ−, the robot goes round it while the pan
    angle swings out past the arming angle and comes back through zero, then
    the robot moves away; the pan may start a full turn away (ϑ near ±2π, as
    after going the long way round), the occluder and the other channels move
    freely within their rates.  Every leg has a drawn speed and an extra
    dwell, so the timing of LEAVE, the release and the occlusion varies.
    """
    return _bypasses(space)


def signal_runs(
    space: MeasurementSpace, *, bounded: bool = True, respect: bool = True, max_length: int = 400
) -> st.SearchStrategy[tuple[tuple[float, ...], ...]]:
    """Measurement sequences for the signal-level properties.

    Parameters
    ----------
    bounded : bool
        ``True``: every channel within its rate bound (physically plausible);
        ``False``: also jumps, fast ramps and special values (``inf``).
    respect : bool
        Project onto the one-obstacle-at-a-time hypothesis (:func:`respect_hypotheses`).

    Both mix the generic waypoint sequences of :mod:`analysis.fuzzing` with
    :func:`bypass_runs`.
    """
    channels = _channels(space)
    if bounded:
        generic = bounded_rate_sequences(channels, max_length=max_length)
    else:
        generic = adversarial_sequences(channels, max_length=max_length)
    strategy = st.one_of(generic, bypass_runs(space))
    if respect:
        return strategy.map(lambda rows: respect_hypotheses(rows, space))
    return strategy


# =============================================================================================
# Driving a variant sample by sample
# =============================================================================================


@dataclass(frozen=True, kw_only=True, slots=True)
class Jump:
    """One discrete jump at a sample.

    Attributes
    ----------
    transition, source, target : str
    memory_before, memory_after : Mapping[str, float]
    enabled : tuple of str
        Transitions enabled at the jump, winner first.
    tied : tuple of str
        Enabled transitions with the winner's priority (non-determinism).
    """

    transition: str
    source: str
    target: str
    memory_before: Mapping[str, float]
    memory_after: Mapping[str, float]
    enabled: tuple[str, ...]
    tied: tuple[str, ...]


@dataclass(frozen=True, kw_only=True, slots=True)
class Step:
    """The supervisor at one sample.

    Attributes
    ----------
    index : int
    measurement : tuple of float
        The row of :class:`MeasurementSpace`.
    signals : tuple of float
        What the guards read (the variant's measurement stage).
    mode_before, memory_before :
        Discrete state before the sample's jumps.
    mode, memory :
        Discrete state after them.
    jumps : tuple of Jump
    mu_coll, mu_occ : float
        Risk outputs after the jumps.
    zeno : bool
        More than :data:`MAX_JUMPS_PER_SAMPLE` jumps were enabled in a row (settling stopped).
    """

    index: int
    measurement: tuple[float, ...]
    signals: tuple[float, ...]
    mode_before: str
    memory_before: Mapping[str, float]
    mode: str
    memory: Mapping[str, float]
    jumps: tuple[Jump, ...]
    mu_coll: float
    mu_occ: float
    zeno: bool


class SupervisorRunner:
    """Feeds measurement rows to a variant one sample at a time (state owned by one run).

    The semantics are those of :func:`hybrid.settle`: the enabled
    transition with the smallest priority fires, level-triggered successors
    fire at the same instant, crossing-triggered ones compare with the
    previous sample's signals.  Instead of raising on non-determinism or
    Zeno behaviour it records them (:attr:`Jump.tied`, :attr:`Step.zeno`), so
    that the properties can report them with the run that caused them.
    """

    def __init__(self, variant: SupervisorVariant, space: MeasurementSpace) -> None:
        automaton = variant.model.automaton
        if len(automaton.variables) != 6 + space.n_obstacles:
            raise ValueError(
                f"variant {variant.name!r} reads {len(automaton.variables) - 6} obstacle distance(s), the "
                f"measurement space has {space.n_obstacles}; build both for the same number of obstacles"
            )
        self.variant = variant
        self.space = space
        self._outgoing = {name: automaton.outgoing(name) for name in automaton.mode_names}
        self._risk = variant.model.risk
        self._wrap = variant.wrap_pan
        self._n = space.n_obstacles
        self.mode = automaton.initial_mode
        self.memory: Mapping[str, float] = MappingProxyType(automaton.initial_memory())
        self.previous: tuple[float, ...] | None = None
        self.index = 0

    def signals(self, row: Sequence[float]) -> tuple[float, ...]:
        """The variant's measurement stage: the supervisor's signals of one measurement row."""
        n = self._n
        ds = tuple(float(x) for x in row[:n])
        nearest = min(range(n), key=ds.__getitem__)
        pan = row[n + 3]
        return (ds[nearest], float(nearest), float(row[n]), float(row[n + 1]), float(row[n + 2]),
                wrap_angle(pan) if self._wrap else float(pan), *ds)

    def step(self, row: Sequence[float]) -> Step:
        """Evaluate one sample; return what happened."""
        v = self.signals(row)
        mode_before, memory_before = self.mode, self.memory
        mode, memory = mode_before, memory_before
        jumps: list[Jump] = []
        zeno = False
        previous = self.previous
        while True:
            candidates = [t for t in self._outgoing[mode] if transition_fires(t, v, memory, previous)]
            if not candidates:
                break
            if len(jumps) >= MAX_JUMPS_PER_SAMPLE:
                zeno = True
                break
            winner = candidates[0]
            after = memory
            if winner.reset is not None:
                after = MappingProxyType({**memory, **winner.reset(v, memory)})
            jumps.append(Jump(
                transition=winner.name, source=mode, target=winner.target, memory_before=memory,
                memory_after=after, enabled=tuple(t.name for t in candidates),
                tied=tuple(t.name for t in candidates[1:] if t.priority == winner.priority),
            ))
            mode, memory = winner.target, after
        mu_coll, mu_occ = self._risk(mode, v, memory)
        step = Step(
            index=self.index, measurement=tuple(row), signals=v, mode_before=mode_before,
            memory_before=memory_before, mode=mode, memory=memory, jumps=tuple(jumps), mu_coll=mu_coll,
            mu_occ=mu_occ, zeno=zeno,
        )
        self.mode, self.memory, self.previous = mode, memory, v
        self.index += 1
        return step


def run_supervisor(
    variant: SupervisorVariant, space: MeasurementSpace, rows: Iterable[Sequence[float]]
) -> tuple[Step, ...]:
    """Every sample of a measurement sequence through a fresh :class:`SupervisorRunner`."""
    runner = SupervisorRunner(variant, space)
    return tuple(runner.step(row) for row in rows)


# =============================================================================================
# Variants
# =============================================================================================


@functools.lru_cache(maxsize=64)
def make_variant(
    name: str, envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int
) -> SupervisorVariant:
    """``"resolved"``, ``"paper"`` (as written) or a mutant of :data:`visnav.fuzzing.mutants.MUTANTS` (cached).

    Raises
    ------
    KeyError
        Unknown name; the message lists :data:`VARIANTS`.
    """
    if name == PAPER:
        return paper_variant(envelopes, settings, n_obstacles)
    if name not in VARIANTS:
        raise KeyError(f"unknown supervisor variant {name!r}; known: {', '.join(VARIANTS)}")
    return build_variant(name, envelopes, settings, n_obstacles)


def _variant_for(name: str, space: MeasurementSpace) -> SupervisorVariant:
    return make_variant(name, space.envelopes, space.settings, space.n_obstacles)


# =============================================================================================
# Properties on signal sequences
# =============================================================================================


def _flags(variant: SupervisorVariant, mode: str) -> tuple[int, int, int]:
    f = variant.model.flags(mode)
    return f["AVOID"], f["LEAVE"], f["OCCLU"]


def _fail(prop: str, message: str, step: Step | None = None, **details: Any) -> PropertyViolation:
    if step is not None:
        details.setdefault("mode", step.mode)
        details.setdefault("mu", [step.mu_coll, step.mu_occ])
        details.setdefault("jumps", [j.transition for j in step.jumps])
    return PropertyViolation(prop, message, sample=None if step is None else step.index, details=details)


def _distances(step: Step, n: int) -> tuple[float, ...]:
    return step.measurement[:n]


def check_mu_range(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer) -> None:
    """µ_coll and µ_occ lie in [0, 1] at every sample and in every mode visited at an instant.

    Inputs: adversarial sequences (jumps, ``inf``), hypotheses possibly broken.
    """
    for s in steps:
        values = [(s.mode, s.mu_coll, s.mu_occ)]
        for j in s.jumps:
            values.append((j.target, *variant.model.risk(j.target, s.signals, j.memory_after)))
        for mode, mu_c, mu_o in values:
            for name, mu in (("mu_coll", mu_c), ("mu_occ", mu_o)):
                if not 0.0 <= mu <= 1.0:
                    raise _fail("mu_range", f"{name} = {mu!r} outside [0, 1] in mode {mode}", s)


def check_mu_continuity(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """µ never jumps: equal on both sides of every transition, Lipschitz in the measurements between samples.

    At every jump, µ of the source mode (memory before the reset) equals µ
    of the target mode (memory after) at the same signals, to 1e-12; between
    samples ``|Δµ_coll| <= max_i |Δd_coll_i| / min(d0 − d−, d+ − d0)`` and
    ``|Δµ_occ| <= |Δd_occ| / min(D0 − D−, D+ − D0)`` (+1e-12).  The bound holds
    whatever the rates, so the inputs are adversarial (jumps, ``inf``) but
    respect the one-obstacle-at-a-time hypothesis.  The equality at a jump is
    required at samples reached by a plausible move (every channel within its
    rate bound, as in :func:`signal_runs` with ``bounded=True``): after a jump
    of the measurements an intermediate mode of the instant may see them in
    the wrong phase (e.g. APPROACH → FAR when the latched obstacle jumped away
    while another jumped inside d0, or d_occ jumping to ∞ while OCCLUDED), and
    only the Lipschitz bound on the sample's µ is meaningful.  Guided search maximises
    the largest ratio ``|Δµ| / bound``.
    """
    n = space.n_obstacles
    lc, lo = space.lipschitz_mu_coll(), space.lipschitz_mu_occ()
    i_occ = space.index("d_occ_px")
    prev: Step | None = None
    worst = 0.0
    risk = variant.model.risk
    channels = _channels(space)
    for s in steps:
        plausible = prev is None or _plausible(channels, prev.measurement, s.measurement)
        for j in s.jumps if plausible else ():
            before = risk(j.source, s.signals, j.memory_before)
            after = risk(j.target, s.signals, j.memory_after)
            if abs(before[0] - after[0]) > TOLERANCE or abs(before[1] - after[1]) > TOLERANCE:
                raise _fail(
                    "mu_continuity",
                    f"(mu_coll, mu_occ) jumps from {before} to {after} at transition {j.transition}", s,
                    transition=j.transition,
                )
        if prev is not None:
            dd = max(_delta(a, b) for a, b in zip(_distances(prev, n), _distances(s, n)))
            docc = _delta(prev.measurement[i_occ], s.measurement[i_occ])
            for name, dmu, bound in (
                ("mu_coll", abs(s.mu_coll - prev.mu_coll), lc * dd),
                ("mu_occ", abs(s.mu_occ - prev.mu_occ), lo * docc),
            ):
                if dmu > bound + TOLERANCE:
                    raise _fail(
                        "mu_continuity",
                        f"|d{name}| = {dmu:.6g} between samples {prev.index} and {s.index} exceeds the bound "
                        f"{bound:.6g} from the measurement change ({prev.mode} -> {s.mode})", s,
                        delta=dmu, bound=bound,
                    )
                if dmu > 0.0:
                    worst = max(worst, dmu / bound if bound > 0.0 else math.inf)
        prev = s
    observe("largest |dmu| / Lipschitz bound", worst)


@functools.lru_cache(maxsize=16)
def _channels(space: MeasurementSpace) -> tuple[Channel, ...]:
    return space.channels()


def _plausible(channels: Sequence[Channel], before: Sequence[float], after: Sequence[float]) -> bool:
    """Whether every continuous channel moved within its rate bound (finite values only)."""
    for ch, a, b in zip(channels, before, after):
        if ch.choices or a == b:
            continue
        if not (math.isfinite(a) and math.isfinite(b)) or abs(b - a) > ch.max_step * (1.0 + 1e-9):
            return False
    return True


def _delta(a: float, b: float) -> float:
    if a == b:
        return 0.0
    return abs(b - a) if math.isfinite(a) and math.isfinite(b) else math.inf


def check_determinism(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """Never two enabled transitions without a priority between them.

    At every jump, no other enabled transition has the winner's priority
    (the executor would raise; here the run goes on with the first declared).
    Inputs: adversarial sequences, hypotheses possibly broken.
    """
    for s in steps:
        for j in s.jumps:
            if j.tied:
                raise _fail(
                    "determinism",
                    f"transitions {[j.transition, *j.tied]} are enabled together in mode {j.source} with the "
                    "same priority", s, enabled=list(j.enabled),
                )


def check_no_chatter(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """No chatter under bounded-rate measurements.

    (a) No instantaneous Zeno: at most :data:`MAX_JUMPS_BOUNDED` = 4 jumps at
    one sample (never the executor's limit of 8).  (b) No component (collision
    or occlusion phase) undoes a switch sooner than
    :meth:`MeasurementSpace.min_reversal_gap` samples (2 with the defaults:
    the 2 cm detection hysteresis at 1 cm/sample), i.e. at most
    ``1 / (gap T)`` = 10 back-and-forth switches per second per component.
    A reversal is a *toggle*, and counts, when it restores the memory the
    first switch wrote (FAR → APPROACH latching obstacle A, then APPROACH →
    FAR forgetting it); when the latched values differ it is a *hand-over*
    and does not count (APPROACH → FAR → APPROACH as the robot leaves one
    obstacle's hysteresis band while entering the next one's detection
    range, which obstacles exactly 2 d+ apart allow).  Guided search
    maximises the number of switches within any 1 s window.
    """
    gap = space.min_reversal_gap()
    window = max(1, int(round(1.0 / space.period_s)))
    writes = {t.name: t.writes for t in variant.model.automaton.transitions}
    last: dict[tuple[int, str, str], tuple[int, Mapping[str, float], tuple[str, ...]]] = {}
    switch_samples: list[int] = []
    busiest = 0
    for s in steps:
        if s.zeno:
            chain = " -> ".join(j.transition for j in s.jumps)
            raise _fail("no_chatter", f"instantaneous Zeno: more than {MAX_JUMPS_PER_SAMPLE} jumps at one sample "
                        f"({chain} -> ...)", s)
        if len(s.jumps) > MAX_JUMPS_BOUNDED:
            raise _fail("no_chatter", f"{len(s.jumps)} jumps at one sample (bounded rates allow "
                        f"{MAX_JUMPS_BOUNDED})", s)
        for j in s.jumps:
            for component in (0, 1):
                a, b = split_mode(j.source)[component], split_mode(j.target)[component]
                if a == b:
                    continue
                back, memory_then, written = last.get((component, b, a), (None, {}, ()))
                handover = any(memory_then[name] != j.memory_after[name] for name in written)
                if back is not None and s.index - back < gap and not handover:
                    raise _fail(
                        "no_chatter",
                        f"{'collision' if component == 0 else 'occlusion'} phase {b} -> {a} at sample {back} undone "
                        f"by {a} -> {b} ({j.transition}) {s.index - back} sample(s) later; bounded rates need >= {gap}",
                        s, reversal_gap=s.index - back, min_gap=gap,
                    )
                last[(component, a, b)] = (s.index, j.memory_before, writes[j.transition])
                switch_samples.append(s.index)
        while switch_samples and switch_samples[0] <= s.index - window:
            switch_samples.pop(0)
        busiest = max(busiest, len(switch_samples))
    observe("switches within 1 s", float(busiest))


def check_flag_consistency(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """The flags and µ tell the same story (the unambiguous parts of (2), (3) and remark 3).

    At every sample: LEAVE ⇒ AVOID; OCCLU ⇒ µ_occ = 1; AVOID ∧ ¬LEAVE ⇒
    µ_coll = 1 ("otherwise" of (2)); ¬AVOID ∧ ¬LEAVE with every obstacle
    beyond d0 ⇒ µ_coll = 0 (case 1 of (2)); LEAVE is set only at a sample
    where µ_occ = 0 (section V.A).  Inputs: adversarial, hypotheses possibly broken.
    """
    d_zero = space.envelopes.d_zero_m
    n = space.n_obstacles
    prev_leave = _flags(variant, variant.model.automaton.initial_mode)[1]
    for s in steps:
        avoid, leave, occlu = _flags(variant, s.mode)
        if leave and not avoid:
            raise _fail("flag_consistency", f"LEAVE = 1 with AVOID = 0 in mode {s.mode}", s)
        if occlu and s.mu_occ != 1.0:
            raise _fail("flag_consistency", f"OCCLU = 1 but mu_occ = {s.mu_occ!r} in mode {s.mode}", s)
        if avoid and not leave and s.mu_coll != 1.0:
            raise _fail("flag_consistency", f"AVOID = 1, LEAVE = 0 but mu_coll = {s.mu_coll!r} in mode {s.mode}", s)
        if not avoid and not leave and min(_distances(s, n)) > d_zero and s.mu_coll != 0.0:
            raise _fail("flag_consistency", f"AVOID = LEAVE = 0, every obstacle beyond d0 but mu_coll = "
                        f"{s.mu_coll!r} in mode {s.mode}", s)
        if leave and not prev_leave and s.mu_occ != 0.0:
            raise _fail("flag_consistency", f"LEAVE set while mu_occ = {s.mu_occ!r} > 0", s)
        prev_leave = leave


def _abstract_control(
    variant: SupervisorVariant, space: MeasurementSpace, step: Step, mode: str, memory: Mapping[str, float]
) -> tuple[float, float, float]:
    """The global control (19) with fixed sub-controllers and the real blending and path following."""
    n = space.n_obstacles
    row = step.measurement
    alpha, visible = row[n + 4], row[n + 5]
    mu_c, mu_o = variant.model.risk(mode, step.signals, memory)
    if variant.latches_obstacle:
        obstacle, side = int(memory["obstacle"]), memory["side"]
    else:
        obstacle, side = int(step.signals[I_NEAREST]), step.signals[I_SIDE]
    d = row[obstacle]
    radius = 0.5
    v_coll, k = 0.2, 4.0
    q_vs = (0.3, 0.2 * math.sin(alpha), 0.1)
    q_occ = (0.1, -0.3, 0.4 * visible - 0.2)
    q_coll = None
    if mu_c > 0.0:
        omega = kinematics.path_following_omega(d - space.envelopes.d_zero_m, alpha, 1.0 / (max(d, 0.0) + radius),
                                                side, v_coll, k)
        q_coll = avoidance_control(v_coll, omega, -omega, -omega + 0.1, mu_o)
    return blend(mu_c, mu_o, q_vs, q_occ, q_coll)


def check_control_continuity(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """Switching never makes the control jump.

    The control (19) is evaluated with the real blending and path-following
    law on fixed sub-controllers (q̇_VS, q̇_occ constant, q̇_coll from (11)
    with the latched bypass side and the measured α).  At every sample after
    the first, the control of the mode *after* the sample's jumps equals the
    control of the mode *before* them at the same measurements
    (``|Δq̇|∞ <= 1e-9``): the supervisor's discrete update contributes nothing
    to ``q̇[k] − q̇[k−1]``.  Inputs: bounded-rate, hypotheses respected (a
    jump of the measurements may legitimately land inside a band).
    """
    worst = 0.0
    for s in steps[1:]:
        if not s.jumps:
            continue
        before = _abstract_control(variant, space, s, s.mode_before, s.memory_before)
        after = _abstract_control(variant, space, s, s.mode, s.memory)
        gap = max(abs(a - b) for a, b in zip(before, after))
        worst = max(worst, gap)
        if gap > CONTROL_TOLERANCE:
            raise _fail(
                "control_continuity",
                f"the control jumps by {gap:.6g} at the switch {s.mode_before} -> {s.mode}: {before} -> {after}", s,
                before=list(before), after=list(after),
            )
    observe("largest control jump at a switch", worst)


def check_leave_timing(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """LEAVE comes exactly when the obstacle is overcome, and not before.

    A monitor independent of the automaton follows section V.A with the
    answers of ``docs/supervisor.md``: once AVOID is set, the LEAVE test is
    *armed* when the wrapped pan angle ``w = wrap(ϑ)`` reaches the arming
    angle (its sign latched); it *fires* at the first later sample where
    ``w`` is back through zero on the other side with ``|w| <= π/2``.  If
    µ_occ = 0 there, LEAVE must be set at that sample; otherwise it must be
    set at the first sample where µ_occ = 0.  At every other sample of the
    avoidance phase LEAVE must stay 0.  Inputs: bounded-rate, hypotheses
    respected.  Guided search maximises the time from AVOID to LEAVE.
    """
    arm = space.settings.arm_angle_rad
    i_pan = space.index("pan_rad")
    p_avoid, p_leave, _ = _flags(variant, variant.model.automaton.initial_mode)
    armed = 0
    pending = False
    since = 0
    longest = 0
    for s in steps:
        avoid, leave, _ = _flags(variant, s.mode)
        w = wrap_angle(s.measurement[i_pan])
        fresh = (avoid and not p_avoid) or (p_leave and not leave and avoid)
        if fresh:
            armed, pending, since = 0, False, s.index
        if avoid and (p_avoid and not p_leave) and not fresh:
            crossing = armed != 0 and -armed * w >= 0.0 and abs(w) <= 0.5 * math.pi
            expect = False
            if crossing or pending:
                if s.mu_occ == 0.0:
                    expect = True
                else:
                    pending = True
            if bool(leave) != expect:
                why = ("the armed pan angle came back through zero with mu_occ = 0" if expect else
                       "the pan angle has not come back through zero since arming" if armed else
                       "the LEAVE test is not armed (|wrap(pan)| never reached the arming angle since AVOID)")
                raise _fail(
                    "leave_timing",
                    f"LEAVE = {leave}, expected {int(expect)}: {why} (wrap(pan) = {w:.6g}, armed sign {armed}, "
                    f"pending {pending}, mu_occ = {s.mu_occ:.6g})", s, wrapped_pan=w, armed=armed,
                )
            if expect:
                longest = max(longest, s.index - since)
        elif fresh and leave:
            raise _fail("leave_timing", "LEAVE set at the sample AVOID was (re)entered, before any arming", s)
        if avoid and not leave and armed == 0 and abs(w) >= arm:
            armed = 1 if w > 0.0 else -1
        p_avoid, p_leave = avoid, leave
    observe("samples from AVOID to LEAVE", float(longest))


def check_leave_release(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """LEAVE ends: µ_coll returns to 0 at the end of the release band.

    When LEAVE is set at distance dL from the obstacle being avoided (the
    nearest one when AVOID was set), AVOID and LEAVE must both be 0 and
    µ_coll = 0 at the latest at the first sample where that distance reaches
    ``max(dL + (d+ − d0), d+ + hysteresis)`` — unless the robot went back
    into ξ− (LEAVE → AVOID) before.  Inputs: bounded-rate, hypotheses
    respected.  Guided search maximises how far beyond that point LEAVE is held.
    """
    env, s_ = space.envelopes, space.settings
    n = space.n_obstacles
    p_avoid, p_leave, _ = _flags(variant, variant.model.automaton.initial_mode)
    obstacle = -1
    release_at: float | None = None
    overstay = 0.0
    for s in steps:
        avoid, leave, _ = _flags(variant, s.mode)
        ds = _distances(s, n)
        if avoid and not p_avoid:
            obstacle = min(range(n), key=ds.__getitem__)
        if leave and not p_leave and obstacle >= 0:
            d_leave = ds[obstacle]
            release_at = max(d_leave + (env.d_plus_m - env.d_zero_m), env.d_plus_m + s_.detection_hysteresis_m)
        if release_at is not None:
            d = ds[obstacle]
            if not leave and avoid:
                release_at = None
            elif not avoid and not leave:
                release_at = None
            elif d >= release_at + TOLERANCE:
                raise _fail(
                    "leave_release",
                    f"still AVOID = {avoid}, LEAVE = {leave}, mu_coll = {s.mu_coll:.6g} at d = {d:.6g} m >= "
                    f"{release_at:.6g} m (end of the release band)", s, distance=d, release_at=release_at,
                )
            else:
                overstay = max(overstay, d - release_at)
        p_avoid, p_leave = avoid, leave
    observe("distance beyond the release point with LEAVE held [m]", overstay)


def check_differential(
    variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer
) -> None:
    """The automaton agrees with a literal transcription of (2)–(3) wherever the paper is unambiguous.

    With the flags the automaton holds and dL, DL taken from the run (d_coll
    when LEAVE was set, d_occ when OCCLU was reset), every case of the
    printed (2) and (3) that holds is evaluated (:mod:`visnav.fuzzing.paper_logic`);
    where they agree, µ must equal them (1e-9).  Also literal: AVOID is set
    at a sample where the robot is inside ξ− (d_coll <= d−), and only there;
    OCCLU likewise with Ξ− (d_occ <= D−).  Not compared, because the paper
    is silent or deliberately resolved otherwise in ``docs/supervisor.md``:
    samples where two obstacles are within d+ + hysteresis (hypothesis
    broken; the sensors' "closest obstacle" is not unique); LEAVE = 1 beyond
    d+ (question 2: the printed "otherwise" keeps µ_coll = 1 for ever);
    LEAVE = 1 with dL > d0 inside the widened band [dL, dL + d+ − d0]
    (question 8's construction); OCCLU = 0 in the release phase after an
    OCCLU reset until µ_occ = 0 (question 8).  A sample with two obstacles
    within d+ + hysteresis taints the collision checks until the robot is
    again beyond that range with AVOID = LEAVE = 0 (the latched values stem
    from an ambiguous "closest obstacle").  Inputs: adversarial.
    """
    env, s_ = space.envelopes, space.settings
    n = space.n_obstacles
    crowd = env.d_plus_m + s_.detection_hysteresis_m
    p_avoid, p_leave, p_occlu = _flags(variant, variant.model.automaton.initial_mode)
    d_leave = D_leave = math.inf
    releasing = crowded = False
    compared = 0
    for s in steps:
        avoid, leave, occlu = _flags(variant, s.mode)
        ds = _distances(s, n)
        d = s.signals[I_D_NEAREST]
        d_occ, d_bord = s.signals[I_D_OCC], s.signals[I_D_BORD]
        if sum(1 for x in ds if x <= crowd) >= 2:
            crowded = True  # and stays so while the collision component holds an obstacle
        elif not avoid and not leave and min(ds) > crowd:
            crowded = False
        if leave and not p_leave:
            d_leave = d
        if p_occlu and not occlu:
            D_leave, releasing = d_occ, True
        if occlu or s.mu_occ == 0.0:
            releasing = False
        # flag rules
        if not crowded and not p_avoid and d <= env.d_minus_m and not avoid:
            raise _fail("differential", f"d_coll = {d!r} <= d- but AVOID was not set", s)
        if avoid and not p_avoid and d > env.d_minus_m:
            raise _fail("differential", f"AVOID set at d_coll = {d!r} > d- (outside xi-)", s)
        if not p_occlu and d_occ <= env.D_minus_px and not occlu:
            raise _fail("differential", f"d_occ = {d_occ!r} <= D- but OCCLU was not set", s)
        if occlu and not p_occlu and d_occ > env.D_minus_px:
            raise _fail("differential", f"OCCLU set at d_occ = {d_occ!r} > D-", s)
        # mu_coll
        skip = crowded or (leave and d > env.d_plus_m) or (
            leave and d_leave > env.d_zero_m and d < d_leave + (env.d_plus_m - env.d_zero_m))
        if not skip:
            cases = mu_coll_cases(d, avoid=avoid, leave=leave, d_leave=d_leave, envelopes=env)
            if _unanimous(cases):
                compared += 1
                if abs(s.mu_coll - cases[0][1]) > 1e-9:
                    raise _fail("differential", f"mu_coll = {s.mu_coll!r} but the printed (2) gives "
                                f"{cases[0][1]!r} (case {cases[0][0]}; AVOID={avoid} LEAVE={leave} d={d!r} "
                                f"dL={d_leave!r})", s, cases=[list(c) for c in cases])
        # mu_occ
        if not (releasing and not occlu):
            cases = mu_occ_cases(d_occ, d_bord, occlu=occlu, D_leave=D_leave, envelopes=env)
            if _unanimous(cases):
                compared += 1
                if abs(s.mu_occ - cases[0][1]) > 1e-9:
                    raise _fail("differential", f"mu_occ = {s.mu_occ!r} but the printed (3) gives "
                                f"{cases[0][1]!r} (case {cases[0][0]}; OCCLU={occlu} d_occ={d_occ!r} "
                                f"d_bord={d_bord!r} DL={D_leave!r})", s, cases=[list(c) for c in cases])
        p_avoid, p_leave, p_occlu = avoid, leave, occlu
    observe("samples compared with the printed equations", float(compared))


def _unanimous(cases: Sequence[tuple[int, float]]) -> bool:
    first = cases[0][1]
    return all(abs(value - first) <= TOLERANCE for _, value in cases[1:])


# ---- stateful ------------------------------------------------------------------------------


def _check_sample(variant: SupervisorVariant, space: MeasurementSpace, s: Step, prev: Step | None) -> None:
    """The invariants of the state machine at one sample (``prev``: the sample before)."""
    prop = "stateful"
    if s.zeno:
        raise _fail(prop, f"instantaneous Zeno: more than {MAX_JUMPS_PER_SAMPLE} jumps at one sample", s)
    plausible = prev is None or _plausible(_channels(space), prev.measurement, s.measurement)
    for j in s.jumps:
        if j.tied:
            raise _fail(prop, f"transitions {[j.transition, *j.tied]} enabled together with the same priority", s)
        if not plausible:
            continue
        before = variant.model.risk(j.source, s.signals, j.memory_before)
        after = variant.model.risk(j.target, s.signals, j.memory_after)
        if max(abs(before[0] - after[0]), abs(before[1] - after[1])) > TOLERANCE:
            raise _fail(prop, f"(mu_coll, mu_occ) jumps from {before} to {after} at {j.transition}", s)
    for name, mu in (("mu_coll", s.mu_coll), ("mu_occ", s.mu_occ)):
        if not 0.0 <= mu <= 1.0:
            raise _fail(prop, f"{name} = {mu!r} outside [0, 1]", s)
    avoid, leave, occlu = _flags(variant, s.mode)
    if leave and not avoid:
        raise _fail(prop, "LEAVE = 1 with AVOID = 0", s)
    if occlu and s.mu_occ != 1.0:
        raise _fail(prop, f"OCCLU = 1 but mu_occ = {s.mu_occ!r}", s)
    if prev is not None:
        n = space.n_obstacles
        i_occ = space.index("d_occ_px")
        dd = max(_delta(a, b) for a, b in zip(_distances(prev, n), _distances(s, n)))
        docc = _delta(prev.measurement[i_occ], s.measurement[i_occ])
        if abs(s.mu_coll - prev.mu_coll) > space.lipschitz_mu_coll() * dd + TOLERANCE:
            raise _fail(prop, f"|dmu_coll| = {abs(s.mu_coll - prev.mu_coll):.6g} exceeds the Lipschitz bound", s)
        if abs(s.mu_occ - prev.mu_occ) > space.lipschitz_mu_occ() * docc + TOLERANCE:
            raise _fail(prop, f"|dmu_occ| = {abs(s.mu_occ - prev.mu_occ):.6g} exceeds the Lipschitz bound", s)


def check_stateful(variant: SupervisorVariant, space: MeasurementSpace, steps: Sequence[Step], observe: Observer) -> None:
    """The state machine's invariants hold at every sample of a sequence (replays its runs).

    µ in [0, 1], no µ jump at any transition reached by a plausible move,
    the Lipschitz bound between samples (as ``mu_continuity``), LEAVE ⇒ AVOID, OCCLU ⇒ µ_occ = 1, no tie of priorities, no
    instantaneous Zeno.
    """
    prev = None
    for s in steps:
        _check_sample(variant, space, s, prev)
        prev = s


def supervisor_machine(variant: SupervisorVariant, space: MeasurementSpace) -> type[RuleBasedStateMachine]:
    """A :class:`~hypothesis.stateful.RuleBasedStateMachine` driving ``variant`` step by step.

    Rules move the measurements the way a robot and its camera can (ramps of
    a distance, of the pan angle, of the occluder at their rate bounds; holds;
    a flip of the bypass side) and the way they cannot (jumps of a distance or
    of ``d_occ``, including to ``inf``, the occluder leaving the image at
    once); the hypotheses are kept: obstacles more than 2 d+ apart (H1,
    :func:`respect_hypotheses`) and, as the path follower does in closed loop,
    the avoided obstacle within d+ until LEAVE (H2, :func:`hypotheses_prefix`).
    After every rule
    the invariants of :func:`check_stateful` are checked on every sample the
    rule fed.  The machine's ``measurements`` are replayable with the
    ``stateful`` property.
    """
    channels = space.channels()
    n = space.n_obstacles
    d_plus = space.envelopes.d_plus_m
    by_name = {ch.name: ch for ch in channels}
    i_occ, i_bord, i_pan, i_side = (space.index(x) for x in ("d_occ_px", "d_bord_px", "pan_rad", "side"))

    def waypoints(name: str, adversarial: bool = False) -> st.SearchStrategy[float]:
        ch = by_name[name]
        options = [st.sampled_from(ch.waypoints()), st.floats(ch.low, ch.high)]
        if adversarial and ch.specials:
            options.append(st.sampled_from(ch.specials))
        return st.one_of(*options)

    class SupervisorMachine(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            self.runner = SupervisorRunner(variant, space)
            far = space.envelopes.d_plus_m + 1.0
            self.current = [far] * n + [1.0, 2.0 * space.envelopes.D_plus_px, space.camera_half_width_px, 0.0, 0.0, 1.0]
            self.measurements: list[tuple[float, ...]] = []
            self.fresh: list[Step] = []
            self.last: Step | None = None
            self.steps = 0
            self.avoided = 0
            self.avoiding = False
            self.avoid_before = False

        def _feed(self, count: int = 1) -> None:
            for _ in range(count):
                if self.avoiding:  # (H2) the path follower keeps the avoided obstacle within d+ ...
                    a = self.avoided
                    self.current[a] = min(self.current[a], d_plus)
                    for j in range(n):  # ... so the others are >= 2 d+ - d_a away (H1 around it)
                        if j != a:
                            self.current[j] = max(self.current[j], 2.0 * d_plus - self.current[a])
                row = respect_hypotheses([self.current], space)[0]
                self.current = list(row)
                self.measurements.append(row)
                step = self.runner.step(row)
                self.fresh.append(step)
                self.steps += 1
                avoid, leave, _ = _flags(variant, step.mode)
                if avoid and not self.avoid_before:
                    self.avoided = min(range(n), key=row.__getitem__)
                self.avoiding = bool(avoid and not leave)
                self.avoid_before = avoid

        def _ramp(self, column: int, goal: float, rate: float, limit: int = 250) -> None:
            self.fresh = []
            for _ in range(limit):
                now = self.current[column]
                if now == goal:
                    break
                self.current[column] = min(goal, now + rate) if goal > now else max(goal, now - rate)
                self._feed()
            if not self.fresh:
                self._feed()

        @rule(i=st.integers(0, n - 1), goal=waypoints("d_coll_0_m"))
        def move_obstacle(self, i: int, goal: float) -> None:
            self._ramp(i, goal, space.max_step_d_m)

        @rule(goal=waypoints("pan_rad"))
        def swing_pan(self, goal: float) -> None:
            self._ramp(i_pan, goal, space.max_step_pan_rad)

        @rule(goal=waypoints("d_occ_px"))
        def move_occluder(self, goal: float) -> None:
            self._ramp(i_occ, goal, space.max_step_d_occ_px)

        @rule(goal=waypoints("d_bord_px"))
        def move_border(self, goal: float) -> None:
            self._ramp(i_bord, goal, space.max_step_d_bord_px)

        @rule(i=st.integers(0, n - 1), sign=st.sampled_from((1.0, -1.0)), swing=st.floats(0.0, 1.0),
              back=st.floats(0.0, 0.5), away=waypoints("d_coll_0_m"))
        def bypass(self, i: int, sign: float, swing: float, back: float, away: float) -> None:
            """The whole story: into ξ−, the pan out past the arming angle and back through 0, then away."""
            arm = space.settings.arm_angle_rad
            offset = 2.0 * math.pi * round(self.current[i_pan] / (2.0 * math.pi))
            fed: list[Step] = []
            for column, goal, rate in (
                (i, space.envelopes.d_minus_m, space.max_step_d_m),
                (i_pan, offset + sign * (arm + swing), space.max_step_pan_rad),
                (i_pan, offset - sign * back, space.max_step_pan_rad),
                (i, away, space.max_step_d_m),
            ):
                self._ramp(column, goal, rate)
                fed += self.fresh
            self.fresh = fed

        @rule(count=st.integers(1, 30))
        def hold(self, count: int) -> None:
            self.fresh = []
            self._feed(count)

        @rule()
        def flip_side(self) -> None:
            self.fresh = []
            self.current[i_side] = -self.current[i_side]
            self._feed()

        @rule(i=st.integers(0, n - 1), value=waypoints("d_coll_0_m"))
        def jump_obstacle(self, i: int, value: float) -> None:
            self.fresh = []
            self.current[i] = value
            self._feed()

        @rule(value=waypoints("d_occ_px", adversarial=True), border=st.booleans())
        def jump_occluder(self, value: float, border: bool) -> None:
            self.fresh = []
            self.current[i_occ] = value
            if border:
                self.current[i_bord] = 0.0
            self._feed()

        @invariant()
        def invariants_hold(self) -> None:
            prev = self.last
            for s in self.fresh:
                _check_sample(variant, space, s, prev)
                prev = s
            self.last = prev
            self.fresh = []

    SupervisorMachine.__name__ = SupervisorMachine.__qualname__ = f"SupervisorMachine_{variant.name}"
    return SupervisorMachine


# =============================================================================================
# Whole scenarios
# =============================================================================================


@functools.lru_cache(maxsize=1)
def _base_scenario() -> Scenario:
    return dataclasses.replace(load_scenario("paper"), duration_s=90.0, description="random layout (visnav.fuzzing.core)")


@st.composite
def _layouts(draw: Callable[[st.SearchStrategy[Any]], Any], respect: bool) -> Scenario:
    base = _base_scenario()
    env = base.envelopes
    goal_x = draw(st.floats(4.0, 8.0))
    goal_y = draw(st.floats(-1.0, 1.0))
    theta0 = draw(st.floats(-0.3, 0.3))
    n = draw(st.integers(1, 3))
    goal_clearance = env.d_plus_m + 0.5
    obstacles: list[Obstacle] = []
    cursor = draw(st.floats(0.2, 1.5)) if not respect else 1.2
    for i in range(n):
        radius = draw(st.floats(0.2, 1.2))
        tall = draw(st.booleans())
        y = draw(st.floats(-1.2, 1.2))
        gap = draw(st.floats(0.0, 1.0))
        if not respect:
            gap -= 2.0 * env.d_plus_m * draw(st.floats(0.0, 1.0))  # may bring them closer than 2 d+
        x = cursor + radius
        cursor = x + radius + 2.0 * env.d_plus_m + gap
        too_near_goal = math.hypot(goal_x - x, goal_y - y) - radius < goal_clearance
        near_start = math.hypot(x, y) - radius < env.d_plus_m
        if respect and (too_near_goal or near_start):
            continue
        obstacles.append(Obstacle(name=f"o{i}", center_m=(x, y), radius_m=radius, height_m=1.5 if tall else 0.3))
    if not respect and draw(st.booleans()):  # an obstacle in the goal's neighbourhood
        radius = draw(st.floats(0.2, 0.6))
        dx = draw(st.floats(-1.5, -0.2))
        obstacles.append(Obstacle(name="near-goal", center_m=(goal_x + dx - radius, goal_y + draw(st.floats(-0.6, 0.6))),
                                  radius_m=radius, height_m=1.5 if draw(st.booleans()) else 0.3))
    normal = math.pi + draw(st.floats(-0.2, 0.2))
    centre = (goal_x + base.robot.pan_offset_m + 1.0, goal_y, base.robot.camera_height_m)
    target = Target(points_m=target_square(centre, normal, 0.3))
    return dataclasses.replace(
        base,
        name=f"random-{'respecting' if respect else 'breaking'}",
        obstacles=tuple(obstacles),
        target=target,
        start=Pose(x_m=0.0, y_m=0.0, theta_rad=theta0, pan_rad=0.0),
        goal=Pose(x_m=goal_x, y_m=goal_y, theta_rad=0.0, pan_rad=0.0),
    )


def scenarios(*, respect: bool = True) -> st.SearchStrategy[Scenario]:
    """Random scenarios on the paper's robot, camera, envelopes and gains.

    ``respect=True`` keeps the paper's hypotheses: 1–3 obstacles (low or
    tall, radius 0.2–1.2 m) between the start and the goal, at least 2 d+
    apart surface to surface, none within d+ of the start nor within
    d+ + 0.5 m of the goal; a 0.3 m square target 1 m in front of the goal's
    camera, the goal 4–8 m ahead, start heading within ±0.3 rad.
    ``respect=False`` breaks them on purpose: obstacles closer than 2 d+ (or
    overlapping), one possibly near the start or in the goal's neighbourhood.
    The scenario validator is bypassed (it would reject those).
    """
    return _layouts(respect)


@dataclass(frozen=True, kw_only=True, slots=True)
class VariantLoop(ClosedLoop):
    """The paper's closed loop around a supervisor variant instead of the resolved automaton.

    The measurement stage passes ϑ unwrapped when the variant says so; a
    variant that does not latch the avoided obstacle is given the nearest one
    and the current bypass side (as the paper reads them at every sample);
    success needs the variant's initial mode (no risk flag) instead of
    ``FAR|CLEAR``.
    """

    variant: SupervisorVariant

    def __post_init__(self) -> None:
        ClosedLoop.__post_init__(self)
        object.__setattr__(self, "supervisor", self.variant.model)

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        """As :meth:`ClosedLoop.measure`, with the raw pan angle for a variant that does not wrap it."""
        v, c = ClosedLoop.measure(self, t, x, c)
        if not self.variant.wrap_pan:
            v = (*v[:I_PAN], float(x[3]), *v[I_PAN + 1:])
        return v, c

    def _view(self, v: Sequence[float], memory: Mapping[str, float]) -> Mapping[str, float]:
        if self.variant.latches_obstacle:
            return memory
        return {**memory, "obstacle": float(v[I_NEAREST]), "side": float(v[I_SIDE])}

    def control(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
                memory: Mapping[str, float]) -> tuple[tuple[float, float, float], LoopState, tuple[float, ...]]:
        """As :meth:`ClosedLoop.control` with the variant's µ."""
        return ClosedLoop.control(self, t, x, c, v, mode, self._view(v, memory))

    def stop(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
             memory: Mapping[str, float]) -> str | None:
        """``"collision"``, ``"success"`` (in the variant's initial mode) or ``None``."""
        if c.clearance <= 0.0:
            return "collision"
        if c.feature_error_px <= self.scenario.success_tolerance_px and mode == self.supervisor.automaton.initial_mode:
            return "success"
        return None


class _SwitchProbe:
    """Wraps a loop; at every sample whose jumps changed the mode, compares the controls of both modes."""

    def __init__(self, loop: VariantLoop) -> None:
        self.loop = loop
        self.record_names = loop.record_names
        self.previous: tuple[str, Mapping[str, float]] | None = None
        self.worst = 0.0
        self.worst_at: dict[str, Any] = {}

    def initial_state(self, t: float, x: Sequence[float]) -> LoopState:
        return self.loop.initial_state(t, x)

    def measure(self, t: float, x: Sequence[float], c: LoopState) -> tuple[tuple[float, ...], LoopState]:
        return self.loop.measure(t, x, c)

    def control(self, t: float, x: Sequence[float], c: LoopState, v: Sequence[float], mode: str,
                memory: Mapping[str, float]) -> tuple[tuple[float, float, float], LoopState, tuple[float, ...]]:
        loop = self.loop
        if self.previous is not None and self.previous[0] != mode and c.image is not None:
            features = tuple(tr if vis else es for tr, es, vis in zip(c.true_features, c.estimated, c.image.visible))
            before_mode, before_memory = self.previous
            u_before = loop.command(x, v, c.image, features, c.estimated, before_mode, loop._view(v, before_memory))
            u_after = loop.command(x, v, c.image, features, c.estimated, mode, loop._view(v, memory))
            gap = max(abs(a - b) for a, b in zip(u_before, u_after))
            if gap > self.worst:
                self.worst = gap
                self.worst_at = {"t_s": t, "from": before_mode, "to": mode, "before": list(u_before),
                                 "after": list(u_after)}
        u, c, row = loop.control(t, x, c, v, mode, memory)
        self.previous = (mode, dict(memory))
        return u, c, row


@dataclass(frozen=True, kw_only=True, slots=True)
class ScenarioRun:
    """A closed-loop run of a variant: trace, metrics, outcome and the largest control jump at a switch."""

    scenario: Scenario
    variant: str
    trace: SampledTrace
    metrics: Metrics
    outcome: str
    switch_jump: float
    switch_jump_at: Mapping[str, Any]


def classify_outcome(scenario: Scenario, trace: SampledTrace, metrics: Metrics) -> str:
    """One of :data:`OUTCOMES`.

    ``collision`` (the dense clearance reached 0; first, whatever else
    happened), ``success``, ``target_lost`` (no target point visible during the
    last :data:`TARGET_LOST_WINDOW_S`), ``stuck_in_loop`` (the heading turned
    through a full circle, or one transition fired three times or more: the
    robot went round an obstacle or around the mode graph), else ``timeout``.
    """
    if metrics.collided:
        return "collision"
    if metrics.success:
        return "success"
    n_points = len(scenario.target.points_m)
    window = max(1, int(round(TARGET_LOST_WINDOW_S / trace.period)))
    hidden = trace.record("n_hidden")
    if len(hidden) >= window and bool((hidden[-window:] >= n_points).all()):
        return "target_lost"
    theta = trace.state("theta_rad")
    counts: dict[str, int] = {}
    for e in trace.events:
        counts[e.transition] = counts.get(e.transition, 0) + 1
    if float(theta.max() - theta.min()) >= 2.0 * math.pi or (counts and max(counts.values()) >= 3):
        return "stuck_in_loop"
    return "timeout"


def simulate_variant(scenario: Scenario, variant: str = RESOLVED) -> ScenarioRun:
    """Run ``scenario``'s closed loop around a variant and classify the outcome.

    Raises
    ------
    hybrid.DivergenceError
        When the numerics break down (the properties report it).
    """
    model_variant = make_variant(variant, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    loop = VariantLoop(scenario=scenario, variant=model_variant)
    probe = _SwitchProbe(loop)
    plant: Plant = robot_plant()
    trace = simulate_sampled(
        loop.supervisor.automaton, plant, probe, scenario.start.as_tuple(),
        period=scenario.sampling_period_s, duration=scenario.duration_s, stop=loop.stop,
    )
    metrics = compute_metrics(scenario, trace)
    return ScenarioRun(
        scenario=scenario, variant=variant, trace=trace, metrics=metrics,
        outcome=classify_outcome(scenario, trace, metrics), switch_jump=probe.worst,
        switch_jump_at=MappingProxyType(dict(probe.worst_at)),
    )


def _scenario_run(prop: str, variant: str, scenario: Scenario) -> ScenarioRun:
    try:
        return simulate_variant(scenario, variant)
    except DivergenceError as err:
        raise PropertyViolation(prop, f"the run raised DivergenceError: {err}",
                                details={"time_s": err.time, "mode": err.mode, "cause": err.cause}) from err
    except HybridError as err:  # ZenoError (a jump loop at one instant), ExecutionError (e.g. a tie)
        raise PropertyViolation(prop, f"the run raised {type(err).__name__}: {err}") from err


def check_no_collision(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """No collision whenever the paper's hypotheses hold.

    The dense clearance (exact arcs between samples) stays > 0.  Inputs:
    random scenarios respecting the hypotheses.  Guided search minimises the clearance.
    """
    run = _scenario_run("no_collision", variant, scenario)
    observe("negative minimum clearance [m]", -run.metrics.min_clearance_m)
    if run.metrics.collided:
        raise PropertyViolation(
            "no_collision", f"collision: minimum clearance {run.metrics.min_clearance_m:.6g} m "
            f"(outcome {run.outcome}, termination {run.metrics.termination})",
            details={"min_clearance_m": run.metrics.min_clearance_m, "t_end_s": run.metrics.sim_time_s},
        )
    return run


def check_classified_outcome(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """Every run ends in a classified outcome, never an exception.

    The outcome is one of :data:`OUTCOMES` (:func:`classify_outcome`); a
    success ends in the variant's initial mode within the feature tolerance.
    A :class:`hybrid.DivergenceError` or any other exception is a violation.
    Inputs: random scenarios, half of them breaking the hypotheses.
    """
    run = _scenario_run("classified_outcome", variant, scenario)
    if run.outcome not in OUTCOMES or run.metrics.termination not in ("end_time", "success", "collision"):
        raise PropertyViolation("classified_outcome", f"unclassified end: outcome {run.outcome!r}, termination "
                                f"{run.metrics.termination!r}")
    if run.outcome == "success" and not run.metrics.final_feature_error_px <= scenario.success_tolerance_px:
        raise PropertyViolation("classified_outcome", f"success with a feature error of "
                                f"{run.metrics.final_feature_error_px!r} px", details={"final_mode": run.trace.final_mode})
    return run


def check_closed_loop_continuity(variant: str, scenario: Scenario, observe: Observer) -> ScenarioRun:
    """In the closed loop, the control (19) does not jump at any switch.

    At every sample whose jumps changed the mode, the control of the mode
    before and the mode after, at the same state and image, agree to 1e-9
    (the real controllers, estimator and measurements).  Inputs: random
    scenarios respecting the hypotheses.  Guided search maximises the jump.
    """
    run = _scenario_run("closed_loop_continuity", variant, scenario)
    observe("largest control jump at a switch (closed loop)", run.switch_jump)
    if run.switch_jump > CONTROL_TOLERANCE:
        at = dict(run.switch_jump_at)
        raise PropertyViolation(
            "closed_loop_continuity",
            f"the control jumps by {run.switch_jump:.6g} at t = {at.get('t_s', 0.0):.6g} s "
            f"({at.get('from')} -> {at.get('to')}): {at.get('before')} -> {at.get('after')}",
            details=at,
        )
    return run


# =============================================================================================
# Registry
# =============================================================================================


@dataclass(frozen=True, kw_only=True, slots=True)
class Property:
    """A named, documented property.

    Attributes
    ----------
    name : str
    kind : str
        ``"signals"`` (measurement sequences), ``"stateful"`` (a rule-based
        state machine, replayed as a sequence) or ``"scenario"`` (closed-loop runs).
    inputs : str
        What the examples are: ``"bounded"``, ``"adversarial-respecting"``,
        ``"adversarial"``, ``"machine"``, ``"scenarios-respecting"``, ``"scenarios-any"``.
    check : callable
        The check (its docstring is the specification).
    ci_examples : int
        Examples in the CI budget.
    """

    name: str
    kind: str
    inputs: str
    check: Callable[..., Any]
    ci_examples: int

    @property
    def doc(self) -> str:
        """The check's docstring, dedented."""
        return inspect.cleandoc(self.check.__doc__ or "")

    @property
    def summary(self) -> str:
        """First line of :attr:`doc`."""
        return self.doc.splitlines()[0] if self.doc else ""


PROPERTIES: Mapping[str, Property] = MappingProxyType({
    p.name: p for p in (
        Property(name="mu_range", kind="signals", inputs="adversarial", check=check_mu_range, ci_examples=120),
        Property(name="mu_continuity", kind="signals", inputs="adversarial-respecting", check=check_mu_continuity,
                 ci_examples=150),
        Property(name="determinism", kind="signals", inputs="adversarial", check=check_determinism, ci_examples=120),
        Property(name="no_chatter", kind="signals", inputs="bounded", check=check_no_chatter, ci_examples=150),
        Property(name="flag_consistency", kind="signals", inputs="adversarial", check=check_flag_consistency,
                 ci_examples=120),
        Property(name="control_continuity", kind="signals", inputs="bounded", check=check_control_continuity,
                 ci_examples=120),
        Property(name="leave_timing", kind="signals", inputs="bounded", check=check_leave_timing, ci_examples=150),
        Property(name="leave_release", kind="signals", inputs="bounded", check=check_leave_release, ci_examples=150),
        Property(name="differential", kind="signals", inputs="adversarial", check=check_differential,
                 ci_examples=120),
        Property(name="stateful", kind="stateful", inputs="machine", check=check_stateful, ci_examples=40),
        Property(name="no_collision", kind="scenario", inputs="scenarios-respecting", check=check_no_collision,
                 ci_examples=20),
        Property(name="classified_outcome", kind="scenario", inputs="scenarios-any", check=check_classified_outcome,
                 ci_examples=20),
        Property(name="closed_loop_continuity", kind="scenario", inputs="scenarios-respecting",
                 check=check_closed_loop_continuity, ci_examples=15),
    )
})
"""Every property, in the order ``visnav fuzz`` runs them."""


def property_names(kind: str | None = None) -> tuple[str, ...]:
    """Names of the properties (of one kind)."""
    return tuple(name for name, p in PROPERTIES.items() if kind is None or p.kind == kind)


STATEFUL_STEPS = 25
"""Rules per run of the state machine."""


def budget(name: str, profile: str = "ci") -> int:
    """Examples of property ``name`` in a budget: ``"ci"`` (the registry's) or ``"dev"`` (a fifth, >= 5)."""
    examples = PROPERTIES[name].ci_examples
    if profile == "ci":
        return examples
    if profile == "dev":
        return max(5, examples // 5)
    raise ValueError(f"budget profile {profile!r}: expected 'ci' or 'dev'")


RESPECTING = ("bounded", "adversarial-respecting", "machine")
"""Signal inputs that keep the paper's hypotheses (H1 by projection, H2 by :func:`hypotheses_prefix`)."""


def _signal_strategy(inputs: str, space: MeasurementSpace) -> st.SearchStrategy[Any]:
    if inputs == "bounded":
        return signal_runs(space, bounded=True, respect=True)
    if inputs == "adversarial-respecting":
        return signal_runs(space, bounded=False, respect=True)
    if inputs == "adversarial":
        return signal_runs(space, bounded=False, respect=False)
    raise ValueError(f"unknown signal inputs {inputs!r}")  # pragma: no cover


def _scenario_strategy(inputs: str) -> st.SearchStrategy[Scenario]:
    if inputs == "scenarios-respecting":
        return scenarios(respect=True)
    return st.one_of(scenarios(respect=True), scenarios(respect=False))


# =============================================================================================
# Counterexamples
# =============================================================================================


class CounterexampleError(ValueError):
    """A counterexample file that cannot be replayed (missing, corrupt, wrong format or version).

    Attributes
    ----------
    source : str
        The file (or label).
    problem : str
        What is wrong.
    """

    def __init__(self, source: str, problem: str) -> None:
        super().__init__(f"counterexample {source!r}: {problem}")
        self.source = source
        self.problem = problem


@dataclass(frozen=True, kw_only=True, slots=True)
class Counterexample:
    """A shrunk failing example, replayable.

    Attributes
    ----------
    property, variant : str
    kind : str
        ``"signals"``, ``"stateful"`` or ``"scenario"``.
    message : str
        The violation found by the fuzzer.
    sample : int or None
        Sample of the violation (signal kinds).
    details : Mapping[str, Any]
    space : MeasurementSpace
        Envelopes, settings, rates (signal kinds; the scenario's own otherwise).
    measurements : tuple of rows or None
        Signal kinds: the measurement sequence.
    scenario : Scenario or None
        Scenario kind: the full scenario.
    seed : int or None
        Seed of the run that found it (``None``: derandomised).
    """

    property: str
    variant: str
    kind: str
    message: str
    sample: int | None = None
    details: Mapping[str, Any] = field(default_factory=dict)
    space: MeasurementSpace = field(default_factory=MeasurementSpace)
    measurements: tuple[tuple[float, ...], ...] | None = None
    scenario: Scenario | None = None
    seed: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))
        if self.measurements is not None:
            object.__setattr__(self, "measurements", tuple(tuple(float(x) for x in row) for row in self.measurements))


def _enc(value: Any) -> Any:
    """JSON-ready value; non-finite floats as the strings ``"inf"``, ``"-inf"``, ``"nan"``."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        if math.isfinite(value):
            return value
        return "nan" if value != value else ("inf" if value > 0 else "-inf")
    if isinstance(value, Mapping):
        return {str(k): _enc(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_enc(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _enc(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if hasattr(value, "item"):  # numpy scalars
        return _enc(value.item())
    return str(value)


def _dec_float(value: Any, where: str, source: str) -> float:
    if isinstance(value, bool):
        raise CounterexampleError(source, f"{where} = {value!r}: expected a number")
    if isinstance(value, (int, float)):
        return float(value)
    if value in ("inf", "-inf", "nan"):
        return float(value)
    raise CounterexampleError(source, f"{where} = {value!r}: expected a number or 'inf', '-inf', 'nan'")


def _record(cls: type, data: Any, where: str, source: str) -> Any:
    """A flat (or nested) parameter dataclass from its JSON object, every value type-checked."""
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"{where}: expected an object, found {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise CounterexampleError(source, f"{where}: unknown key(s) {unknown}; expected some of {names}")
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        kind, key = hints[name], f"{where}.{name}"
        if dataclasses.is_dataclass(kind):
            kwargs[name] = _record(kind, value, key, source)
        elif kind is int:
            if not isinstance(value, int) or isinstance(value, bool):
                raise CounterexampleError(source, f"{key} = {value!r}: expected an integer")
            kwargs[name] = value
        elif kind is str:
            if not isinstance(value, str):
                raise CounterexampleError(source, f"{key} = {value!r}: expected a string")
            kwargs[name] = value
        else:
            kwargs[name] = _dec_float(value, key, source)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as err:
        raise CounterexampleError(source, f"{where}: {err}") from err


def _scenario_from_json(data: Any, source: str) -> Scenario:
    if not isinstance(data, Mapping):
        raise CounterexampleError(source, f"scenario: expected an object, found {type(data).__name__}")
    try:
        obstacles = tuple(
            Obstacle(name=str(o["name"]), center_m=tuple(_dec_float(c, "scenario.obstacles.center_m", source)
                                                         for c in o["center_m"]),
                     radius_m=_dec_float(o["radius_m"], "scenario.obstacles.radius_m", source),
                     height_m=_dec_float(o["height_m"], "scenario.obstacles.height_m", source))
            for o in data["obstacles"]
        )
        target = Target(points_m=tuple(tuple(_dec_float(c, "scenario.target", source) for c in p)
                                       for p in data["target"]["points_m"]))
        records = {
            "robot": _record(RobotGeometry, data["robot"], "scenario.robot", source),
            "camera": _record(CameraModel, data["camera"], "scenario.camera", source),
            "envelopes": _record(Envelopes, data["envelopes"], "scenario.envelopes", source),
            "gains": _record(Gains, data["gains"], "scenario.gains", source),
            "limits": _record(ActuatorLimits, data["limits"], "scenario.limits", source),
            "estimator": _record(EstimatorSettings, data["estimator"], "scenario.estimator", source),
            "supervisor": _record(SupervisorSettings, data["supervisor"], "scenario.supervisor", source),
        }
        return Scenario(
            name=str(data["name"]), description=str(data.get("description", "")), **records,
            obstacles=obstacles, target=target,
            start=_record(Pose, data["start"], "scenario.start", source),
            goal=_record(Pose, data["goal"], "scenario.goal", source),
            sampling_period_s=_dec_float(data["sampling_period_s"], "scenario.sampling_period_s", source),
            duration_s=_dec_float(data["duration_s"], "scenario.duration_s", source),
            success_tolerance_px=_dec_float(data["success_tolerance_px"], "scenario.success_tolerance_px", source),
        )
    except KeyError as err:
        raise CounterexampleError(source, f"scenario: missing key {err.args[0]!r}") from None
    except (TypeError, ValueError) as err:
        if isinstance(err, CounterexampleError):
            raise
        raise CounterexampleError(source, f"scenario: {err}") from err


def counterexample_to_json(cx: Counterexample) -> str:
    """Deterministic JSON text of a counterexample (floats exact, ``inf`` as a string)."""
    data: dict[str, Any] = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "property": cx.property,
        "variant": cx.variant,
        "kind": cx.kind,
        "violation": {"message": cx.message, "sample": cx.sample, "details": _enc(cx.details)},
        "seed": cx.seed,
        "space": _enc(cx.space),
    }
    if cx.scenario is not None:
        data["scenario"] = _enc(cx.scenario)
    if cx.measurements is None:
        return json.dumps(data, indent=1, sort_keys=True) + "\n"
    data["channels"] = list(cx.space.names)
    head = json.dumps(data, indent=1, sort_keys=True)
    rows = ",\n".join("  " + json.dumps(_enc(row)) for row in cx.measurements)
    return f'{head[:-2]},\n "measurements": [\n{rows}\n ]\n}}\n'  # one sample per line


def counterexample_from_json(text: str, source: str = "<string>") -> Counterexample:
    """Parse and validate a counterexample file's text.

    Raises
    ------
    CounterexampleError
        Not JSON, not a counterexample, another format version, an unknown
        property or variant, or malformed data (the message names the source
        and what is wrong).
    """
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise CounterexampleError(source, f"not valid JSON ({err.msg} at line {err.lineno}, column {err.colno})") from err
    if not isinstance(data, Mapping) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, Mapping) else type(data).__name__
        raise CounterexampleError(source, f"not a counterexample file (format = {found!r}, expected {FORMAT!r})")
    version = data.get("version")
    if version != FORMAT_VERSION:
        raise CounterexampleError(
            source, f"format version {version!r} is not supported (this visnav reads version {FORMAT_VERSION})"
        )
    prop = data.get("property")
    if prop not in PROPERTIES:
        raise CounterexampleError(source, f"unknown property {prop!r}; known: {', '.join(PROPERTIES)}")
    variant = data.get("variant")
    if variant not in VARIANTS:
        raise CounterexampleError(source, f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    kind = PROPERTIES[prop].kind
    if data.get("kind") != kind:
        raise CounterexampleError(source, f"kind {data.get('kind')!r} does not match property {prop!r} ({kind!r})")
    violation = data.get("violation")
    if not isinstance(violation, Mapping) or not isinstance(violation.get("message"), str):
        raise CounterexampleError(source, "violation: expected an object with a 'message' string")
    sample = violation.get("sample")
    if sample is not None and (not isinstance(sample, int) or isinstance(sample, bool)):
        raise CounterexampleError(source, f"violation.sample = {sample!r}: expected an integer or null")
    space = _record(MeasurementSpace, data.get("space", {}), "space", source)
    measurements = scenario = None
    if kind in ("signals", "stateful"):
        rows = data.get("measurements")
        if not isinstance(rows, list) or not rows:
            raise CounterexampleError(source, "measurements: expected a non-empty list of rows")
        width = len(space.names)
        parsed = []
        for k, row in enumerate(rows):
            if not isinstance(row, list) or len(row) != width:
                raise CounterexampleError(source, f"measurements[{k}]: expected a list of {width} numbers "
                                          f"({', '.join(space.names)})")
            parsed.append(tuple(_dec_float(x, f"measurements[{k}]", source) for x in row))
        measurements = tuple(parsed)
    else:
        scenario = _scenario_from_json(data.get("scenario"), source)
    seed = data.get("seed")
    if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool)):
        raise CounterexampleError(source, f"seed = {seed!r}: expected an integer or null")
    details = violation.get("details") or {}
    return Counterexample(
        property=prop, variant=variant, kind=kind, message=violation["message"], sample=sample,
        details=MappingProxyType(dict(details)) if isinstance(details, Mapping) else MappingProxyType({}),
        space=space, measurements=measurements, scenario=scenario, seed=seed,
    )


# =============================================================================================
# Runner
# =============================================================================================


@dataclass(frozen=True, kw_only=True, slots=True)
class PropertyResult:
    """One property fuzzed on one variant.

    Attributes
    ----------
    name, kind, variant : str
    examples : int
        Examples run (generation, targeting and shrinking).
    steps : int
        Supervisor steps run (signal kinds; on hypothesis-respecting inputs
        the properties check the prefix where the hypotheses hold) or
        closed-loop samples (scenarios).
    counterexample : Counterexample or None
    wall_time_s : float
        Not part of :meth:`as_dict` (the JSON is byte-identical for one seed).
    """

    name: str
    kind: str
    variant: str
    examples: int
    steps: int
    counterexample: Counterexample | None = None
    wall_time_s: float = 0.0

    @property
    def passed(self) -> bool:
        """Whether the property held on every example."""
        return self.counterexample is None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (deterministic)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "variant": self.variant,
            "examples": self.examples,
            "steps": self.steps,
            "failures": 0 if self.passed else 1,
            "message": None if self.counterexample is None else self.counterexample.message,
        }


@dataclass(frozen=True, kw_only=True, slots=True)
class FuzzReport:
    """Results of :func:`fuzz`, in run order."""

    variant: str
    seed: int | None
    results: tuple[PropertyResult, ...]

    @property
    def passed(self) -> bool:
        """Whether every property held."""
        return all(r.passed for r in self.results)


def fuzz_property(
    name: str,
    *,
    variant: str = RESOLVED,
    examples: int | None = None,
    seed: int | None = None,
    shrink: bool = True,
    space: MeasurementSpace | None = None,
    on_example: Callable[[int], None] | None = None,
) -> PropertyResult:
    """Fuzz one property on one variant.

    Parameters
    ----------
    name : str
        A key of :data:`PROPERTIES`.
    variant : str
        One of :data:`VARIANTS`.
    examples : int or None
        Examples to generate; the CI budget (:func:`budget`) by default.
    seed : int or None
        ``None``: derandomised; otherwise the hypothesis seed.
    shrink : bool
        Shrink a failure to a minimal counterexample.
    space : MeasurementSpace or None
        Signal kinds: the measurement model (default :class:`MeasurementSpace`).
    on_example : callable or None
        Progress callback (examples run so far).

    Raises
    ------
    KeyError
        Unknown property or variant (the message lists the known ones).
    ValueError
        ``examples < 1``.
    """
    if name not in PROPERTIES:
        raise KeyError(f"unknown property {name!r}; known: {', '.join(PROPERTIES)}")
    if variant not in VARIANTS:
        raise KeyError(f"unknown supervisor variant {variant!r}; known: {', '.join(VARIANTS)}")
    prop = PROPERTIES[name]
    n_examples = budget(name) if examples is None else examples
    if not (isinstance(n_examples, int) and n_examples >= 1):
        raise ValueError(f"examples = {n_examples!r}: expected an integer >= 1")
    space = space or MeasurementSpace()
    start = time.perf_counter()
    run: PropertyRun
    if prop.kind == "signals":
        model = _variant_for(variant, space)
        check = prop.check

        respecting = prop.inputs in RESPECTING

        def signal_check(rows: tuple[tuple[float, ...], ...], observe: Observer) -> int:
            steps = run_supervisor(model, space, rows)
            checked = steps[:hypotheses_prefix(model, space, steps)] if respecting else steps
            check(model, space, checked, observe)
            return len(steps)

        run = run_property(name, signal_check, _signal_strategy(prop.inputs, space), max_examples=n_examples,
                           seed=seed, shrink=shrink, on_example=on_example)
        cx = None if run.failure is None else Counterexample(
            property=name, variant=variant, kind=prop.kind, message=run.failure.message, sample=run.failure.sample,
            details=run.failure.details, space=space, measurements=tuple(run.failure.example), seed=seed,
        )
    elif prop.kind == "stateful":
        model = _variant_for(variant, space)
        run = run_machine(name, supervisor_machine(model, space), max_examples=n_examples,
                          steps_per_example=STATEFUL_STEPS, seed=seed, shrink=shrink,
                          record=lambda m: tuple(m.measurements), on_example=on_example)
        cx = None
        if run.failure is not None:
            rows = tuple(run.failure.example or ())
            cx = Counterexample(
                property=name, variant=variant, kind=prop.kind, message=run.failure.message,
                sample=run.failure.sample, details=run.failure.details, space=space, measurements=rows, seed=seed,
            )
    else:
        check = prop.check

        def scenario_check(scenario: Scenario, observe: Observer) -> int:
            return len(check(variant, scenario, observe).trace.times)

        run = run_property(name, scenario_check, _scenario_strategy(prop.inputs), max_examples=n_examples,
                           seed=seed, shrink=shrink, on_example=on_example)
        cx = None if run.failure is None else Counterexample(
            property=name, variant=variant, kind=prop.kind, message=run.failure.message, sample=run.failure.sample,
            details=run.failure.details, space=_scenario_space(run.failure.example), scenario=run.failure.example,
            seed=seed,
        )
    return PropertyResult(
        name=name, kind=prop.kind, variant=variant, examples=run.examples, steps=run.steps, counterexample=cx,
        wall_time_s=time.perf_counter() - start,
    )


def _scenario_space(scenario: Scenario) -> MeasurementSpace:
    return MeasurementSpace(envelopes=scenario.envelopes, settings=scenario.supervisor,
                            n_obstacles=max(1, len(scenario.obstacles)),
                            camera_half_width_px=scenario.camera.half_width_px,
                            period_s=scenario.sampling_period_s)


def fuzz(
    names: Sequence[str] | None = None,
    *,
    variant: str = RESOLVED,
    examples: int | None = None,
    seed: int | None = None,
    shrink: bool = True,
    on_property: Callable[[str, int, int], None] | None = None,
    on_example: Callable[[str, int], None] | None = None,
) -> FuzzReport:
    """Fuzz several properties (all by default, in registry order) on one variant.

    Parameters
    ----------
    on_property : callable or None
        ``on_property(name, index, total)`` before each property (progress).
    on_example : callable or None
        ``on_example(name, examples_so_far)`` (progress).
    Other parameters as :func:`fuzz_property`.
    """
    selected = tuple(names) if names else tuple(PROPERTIES)
    unknown = [n for n in selected if n not in PROPERTIES]
    if unknown:
        raise KeyError(f"unknown property {unknown[0]!r}; known: {', '.join(PROPERTIES)}")
    results = []
    for i, name in enumerate(selected):
        if on_property is not None:
            on_property(name, i, len(selected))
        callback = None if on_example is None else functools.partial(on_example, name)
        results.append(fuzz_property(name, variant=variant, examples=examples, seed=seed, shrink=shrink,
                                     on_example=callback))
    return FuzzReport(variant=variant, seed=seed, results=tuple(results))


# =============================================================================================
# Replay
# =============================================================================================


@dataclass(frozen=True, kw_only=True, slots=True)
class Replay:
    """A counterexample run again.

    Attributes
    ----------
    counterexample : Counterexample
    violated : bool
        Whether the property still fails.
    message : str
        The violation now (or ``"holds"``).
    sample : int or None
    trace : tuple of Mapping
        Signal kinds: one row per sample (``k``, the measurements by channel,
        ``mode``, ``mu_coll``, ``mu_occ``, ``jumps``); scenarios: one row per
        transition (``t_s``, ``transition``) then a row with the outcome and metrics.
    """

    counterexample: Counterexample
    violated: bool
    message: str
    sample: int | None
    trace: tuple[Mapping[str, Any], ...]


def replay(cx: Counterexample) -> Replay:
    """Run a counterexample's example through its property again."""
    prop = PROPERTIES[cx.property]
    error: PropertyViolation | None = None
    rows: list[Mapping[str, Any]] = []
    if prop.kind in ("signals", "stateful"):
        space = cx.space
        model = _variant_for(cx.variant, space)
        try:
            steps = run_supervisor(model, space, cx.measurements or ())
        except Exception as err:  # e.g. a NaN guard: the same failure as when it was found
            return Replay(counterexample=cx, violated=True, message=f"{type(err).__name__}: {err}", sample=None,
                          trace=())
        if prop.inputs in RESPECTING:
            steps = steps[:hypotheses_prefix(model, space, steps)]
        for s in steps:
            rows.append(MappingProxyType({
                "k": s.index,
                **{name: value for name, value in zip(space.names, s.measurement)},
                "mode": s.mode,
                "mu_coll": s.mu_coll,
                "mu_occ": s.mu_occ,
                "jumps": tuple(j.transition for j in s.jumps),
            }))
        try:
            prop.check(model, space, steps, lambda label, value: None)
        except PropertyViolation as err:
            error = err
        except Exception as err:
            error = PropertyViolation(cx.property, f"{type(err).__name__}: {err}")
    else:
        assert cx.scenario is not None
        run = None
        try:
            run = prop.check(cx.variant, cx.scenario, lambda label, value: None)
        except PropertyViolation as err:
            error = err
        except Exception as err:
            error = PropertyViolation(cx.property, f"{type(err).__name__}: {err}")
        if run is not None:
            for e in run.trace.events:
                rows.append(MappingProxyType({"t_s": e.time, "transition": e.transition}))
            rows.append(MappingProxyType({
                "outcome": run.outcome, "min_clearance_m": run.metrics.min_clearance_m,
                "termination": run.metrics.termination, "sim_time_s": run.metrics.sim_time_s,
            }))
    if error is None:
        return Replay(counterexample=cx, violated=False, message="holds", sample=None, trace=tuple(rows))
    return Replay(counterexample=cx, violated=True, message=error.message, sample=error.sample, trace=tuple(rows))
