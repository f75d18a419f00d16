"""What the supervisor fuzzer measures: the measurement space and the strategies of its signal runs.

One sample is a row of :class:`MeasurementSpace` (``d_coll`` per obstacle,
the bypass side, ``d_occ``, ``d_bord``, the raw pan angle ϑ, α and the
visible fraction).  :func:`signal_runs` mixes the generic waypoint sequences
of :mod:`analysis.fuzzing` — bounded-rate (physically plausible) or
unbounded (adversarial) — with :func:`bypass_runs` (the story the supervisor
is built for), optionally projected by :func:`respect_hypotheses` onto the
paper's hypothesis that the robot is near one obstacle at a time.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st

from analysis.fuzzing import (
    Channel,
    Segment,
    adversarial_sequences,
    bounded_rate_sequences,
    follow_waypoints,
    waypoint_strategy,
)

from visnav.parameters import Envelopes, Scenario, SupervisorSettings

__all__ = [
    "MeasurementSpace",
    "cached_channels",
    "respect_hypotheses",
    "bypass_runs",
    "signal_runs",
    "scenario_space",
]


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

    def rates_per_s(self) -> dict[str, float]:
        """Rate bounds [unit/s] of the coordinates of :func:`visnav.supervisor.measurement_system`.

        The per-sample bounds ``max_step_d_m`` (every obstacle distance), ``max_step_d_occ_px``,
        ``max_step_d_bord_px`` and ``max_step_pan_rad`` divided by ``period_s``
        (:func:`visnav.supervisor.measurement_rates`): the fuzzer's bounded-rate runs and the
        dwell bounds of the structural Zeno check read the same numbers.  ``bypass_side`` is
        discrete and has no rate.

        Examples
        --------
        >>> {k: round(r, 9) for k, r in MeasurementSpace(n_obstacles=1).rates_per_s().items()}
        {'d_coll_0_m': 0.2, 'd_occ_px': 80.0, 'd_bord_px': 120.0, 'pan_wrapped_rad': 0.8}
        """
        from visnav.supervisor import measurement_rates

        steps = {"d": self.max_step_d_m, "d_occ": self.max_step_d_occ_px, "d_bord": self.max_step_d_bord_px,
                 "pan": self.max_step_pan_rad}
        return measurement_rates(steps, self.period_s, self.n_obstacles)

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


@functools.lru_cache(maxsize=16)
def cached_channels(space: MeasurementSpace) -> tuple[Channel, ...]:
    """:meth:`MeasurementSpace.channels`, built once per space (the properties read them at every run)."""
    return space.channels()


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


@st.composite
def _bypasses(draw: Callable[[st.SearchStrategy[Any]], Any], space: MeasurementSpace) -> tuple[tuple[float, ...], ...]:
    channels = cached_channels(space)
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
    channels = cached_channels(space)
    if bounded:
        generic = bounded_rate_sequences(channels, max_length=max_length)
    else:
        generic = adversarial_sequences(channels, max_length=max_length)
    strategy = st.one_of(generic, bypass_runs(space))
    if respect:
        return strategy.map(lambda rows: respect_hypotheses(rows, space))
    return strategy


def scenario_space(scenario: Scenario) -> MeasurementSpace:
    """The measurement space of a scenario's supervisor (envelopes, settings, obstacles, camera, period)."""
    return MeasurementSpace(envelopes=scenario.envelopes, settings=scenario.supervisor,
                            n_obstacles=max(1, len(scenario.obstacles)),
                            camera_half_width_px=scenario.camera.half_width_px,
                            period_s=scenario.sampling_period_s)
