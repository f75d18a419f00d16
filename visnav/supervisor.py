"""The paper's AVOID / LEAVE / OCCLU flag logic as an explicit hybrid automaton.

The supervisor is the synchronous product of a *collision* component and an
*occlusion* component (``docs/supervisor.md`` has the mode graph and the
answer to every open question of the paper's flag logic):

collision phases
    ``FAR``      no obstacle within d+ (AVOID = LEAVE = 0), µ_coll = 0 (the formula of
                 APPROACH on the nearest obstacle, which is 0 beyond d0).
    ``APPROACH`` an obstacle within d+ is latched with its bypass side
                 (AVOID = LEAVE = 0); µ_coll = clip((d0 − d)/(d0 − d−)), case 1–2 of (2).
    ``AVOID``    entered ξ− (AVOID = 1, LEAVE = 0), µ_coll = 1.
    ``ARMED``    AVOID and |ϑ| has exceeded the arming angle: a return of ϑ to
                 zero now means "obstacle overcome".
    ``PASSED``   ϑ returned to zero while µ_occ > 0: LEAVE is held back.
    ``LEAVE``    AVOID = LEAVE = 1, dL latched; µ_coll = clip((d − d_end)/(dL − d_end)),
                 case 3 of (2) with d_end = max(d+, dL + (d+ − d0)).
occlusion phases
    ``CLEAR``    OCCLU = 0, µ_occ = clip((D0 − d_occ)/(D0 − D−)), cases 1–2 of (3).
    ``OCCLUDED`` OCCLU = 1, µ_occ = 1.
    ``RELEASE``  OCCLU reset, DL latched; µ_occ = clip((d_occ − D_end)/(DL − D_end)),
                 case 3 of (3) with D_end = max(D+, DL + (D+ − D0)).

Every transition happens where both sides give the same µ, so µ_coll and
µ_occ are continuous functions of time along any run whose measurements are
continuous; the tests check it at every transition.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hybrid import Box, HybridAutomaton, HybridSystem, MemoryVariable, Mode, Transition
from hybrid.decide import ParameterSpace
from hybrid.errors import ParameterError
from hybrid.symbolic import (
    Expr,
    coordinates,
    ite,
    maximum,
    memory as memory_refs,
    minimum,
    output_map,
    param,
    reset as memory_reset,
    select,
)

from visnav.parameters import Envelopes, SupervisorSettings

__all__ = [
    "COLLISION_PHASES",
    "OCCLUSION_PHASES",
    "SIGNALS",
    "SupervisorModel",
    "build_supervisor",
    "mode_name",
    "split_mode",
    "measurement_system",
    "measurement_box",
    "measurement_rates",
    "no_obstacle_distance",
    "parameter_space",
]

COLLISION_PHASES = ("FAR", "APPROACH", "AVOID", "ARMED", "PASSED", "LEAVE")
OCCLUSION_PHASES = ("CLEAR", "OCCLUDED", "RELEASE")

SIGNALS = ("d_nearest_m", "nearest_obstacle", "bypass_side", "d_occ_px", "d_bord_px", "pan_wrapped_rad")
"""Signals read by the supervisor, followed by one ``d_coll_<i>_m`` per obstacle."""

I_D_NEAREST, I_NEAREST, I_SIDE, I_D_OCC, I_D_BORD, I_PAN = range(6)
I_FIRST_OBSTACLE = 6

_FLAGS = {
    "FAR": (0, 0),
    "APPROACH": (0, 0),
    "AVOID": (1, 0),
    "ARMED": (1, 0),
    "PASSED": (1, 0),
    "LEAVE": (1, 1),
}


def mode_name(collision: str, occlusion: str) -> str:
    """Product mode name, e.g. ``"AVOID|OCCLUDED"``."""
    return f"{collision}|{occlusion}"


def split_mode(name: str) -> tuple[str, str]:
    """Inverse of :func:`mode_name`."""
    collision, occlusion = name.split("|")
    return collision, occlusion


def _clip01(value: float) -> float:
    return 0.0 if value <= 0.0 else (1.0 if value >= 1.0 else value)


@dataclass(frozen=True, kw_only=True, slots=True)
class SupervisorModel:
    """The supervisor automaton and its risk-parameter outputs.

    Attributes
    ----------
    automaton : HybridAutomaton
        The product automaton (18 modes).
    envelopes : Envelopes
    settings : SupervisorSettings
    n_obstacles : int
    """

    automaton: HybridAutomaton
    envelopes: Envelopes
    settings: SupervisorSettings
    n_obstacles: int

    def phases(self, mode: str) -> tuple[str, str]:
        """``(collision phase, occlusion phase)`` of a product mode."""
        return split_mode(mode)

    def mu_coll(self, collision_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        """Collision risk µ_coll ∈ [0, 1], eq. (2) as resolved in ``docs/supervisor.md``."""
        env = self.envelopes
        if collision_phase == "FAR":  # cases 1-2 of (2) on the nearest obstacle (0 beyond d0)
            return _clip01((env.d_zero_m - v[I_D_NEAREST]) / (env.d_zero_m - env.d_minus_m))
        d = v[I_FIRST_OBSTACLE + int(memory["obstacle"])]
        if collision_phase == "APPROACH":
            return _clip01((env.d_zero_m - d) / (env.d_zero_m - env.d_minus_m))
        if collision_phase == "LEAVE":
            d_end = memory["d_end"]
            return _clip01((d - d_end) / (memory["dL"] - d_end))
        return 1.0

    def mu_occ(self, occlusion_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        """Occlusion risk µ_occ ∈ [0, 1], eq. (3) as resolved in ``docs/supervisor.md``."""
        env = self.envelopes
        d = v[I_D_OCC]
        if occlusion_phase == "CLEAR":
            return _clip01((env.D_zero_px - d) / (env.D_zero_px - env.D_minus_px))
        if occlusion_phase == "RELEASE":
            d_end = memory["D_end"]
            if math.isinf(d):
                return 0.0
            return _clip01((d - d_end) / (memory["DL"] - d_end))
        return 1.0

    def risk(self, mode: str, v: Sequence[float], memory: Mapping[str, float]) -> tuple[float, float]:
        """``(µ_coll, µ_occ)`` in ``mode`` at signals ``v``."""
        collision, occlusion = split_mode(mode)
        return self.mu_coll(collision, v, memory), self.mu_occ(occlusion, v, memory)

    def flags(self, mode: str) -> dict[str, int]:
        """The paper's flags ``AVOID``, ``LEAVE``, ``OCCLU`` in ``mode``."""
        collision, occlusion = split_mode(mode)
        avoid, leave = _FLAGS[collision]
        return {"AVOID": avoid, "LEAVE": leave, "OCCLU": int(occlusion == "OCCLUDED")}


def build_supervisor(envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int) -> SupervisorModel:
    """Build the supervisor automaton for a scene with ``n_obstacles`` obstacles.

    Parameters
    ----------
    envelopes : Envelopes
        d−, d0, d+ [m] and D−, D0, D+ [px].
    settings : SupervisorSettings
        Arming angle of the LEAVE condition and detection hysteresis.
    n_obstacles : int
        Number of obstacles (``>= 0``); the signals carry one distance per obstacle.  With
        none, the latched distance is ``d_nearest`` (``inf`` in the closed loop): no
        collision transition is ever enabled and the supervisor stays in ``FAR``
        (µ_coll = 0), the occlusion component works as usual.

    Raises
    ------
    hybrid.errors.ParameterError
        ``n_obstacles`` not an integer ``>= 0`` (a ``ValueError``).
    """
    if isinstance(n_obstacles, bool) or not isinstance(n_obstacles, numbers.Integral) or n_obstacles < 0:
        raise ParameterError("n_obstacles", n_obstacles,
                             "an integer >= 0 (the number of obstacles of the scene, for build_supervisor)",
                             "pass len(scenario.obstacles)")
    env = envelopes
    d_minus, d_zero, d_plus = (param("d_minus", env.d_minus_m), param("d_zero", env.d_zero_m),
                               param("d_plus", env.d_plus_m))
    D_minus, D_zero, D_plus = (param("D_minus", env.D_minus_px), param("D_zero", env.D_zero_px),
                               param("D_plus", env.D_plus_px))
    arm = param("arm", settings.arm_angle_rad)
    hysteresis = param("hysteresis", settings.detection_hysteresis_m)
    release_margin = 0.5 * (D_zero - D_minus)
    n_obstacles = int(n_obstacles)
    v = coordinates(SIGNALS + tuple(f"d_coll_{i}_m" for i in range(n_obstacles)))
    m = memory_refs("obstacle", "side", "arm_sign", "dL", "d_end", "DL", "D_end")
    pan, d_occ, d_bord = v.pan_wrapped_rad, v.d_occ_px, v.d_bord_px
    # the latched obstacle's distance (with no obstacle, the nearest distance, which is then inf)
    d_latched: Expr = (select(m.obstacle, [v[f"d_coll_{i}_m"] for i in range(n_obstacles)])
                       if n_obstacles else v.d_nearest_m)
    # ϑ (wrapped) is back on the other side of zero from where it was armed, near 0
    crossed_zero = minimum(-m.arm_sign * pan, 0.5 * math.pi - abs(pan))

    # ---- resets --------------------------------------------------------------------
    latch_obstacle = memory_reset(obstacle=v.nearest_obstacle, side=v.bypass_side)
    forget_obstacle = memory_reset(obstacle=0.0, side=0.0, arm_sign=0.0, dL=0.0, d_end=0.0)
    arm_leave = memory_reset(arm_sign=ite(pan > 0.0, 1.0, -1.0))
    latch_dl = memory_reset(dL=d_latched, d_end=maximum(d_plus, d_latched + (d_plus - d_zero)))
    disarm = memory_reset(arm_sign=0.0, dL=0.0, d_end=0.0)
    latched_occ = ite(d_occ < math.inf, d_occ, D_zero)  # an occluder out of view latches D0
    latch_DL = memory_reset(DL=latched_occ, D_end=maximum(D_plus, latched_occ + (D_plus - D_zero)))
    clear_DL = memory_reset(DL=0.0, D_end=0.0)

    # ---- collision component -------------------------------------------------------------
    # (source, target, guard, reset, writes, guard_text, reset_text, priority, occlusion phases or None=all)
    collision_rules = [
        ("FAR", "APPROACH", d_plus - v.d_nearest_m, latch_obstacle, ("obstacle", "side"),
         "d_nearest <= d+", "obstacle := nearest; side := bypass side", 10, None),
        ("APPROACH", "AVOID", d_minus - d_latched, None, (),
         "d <= d-", "", 10, None),
        ("APPROACH", "FAR", d_latched - (d_plus + hysteresis), forget_obstacle,
         ("obstacle", "side", "arm_sign", "dL", "d_end"), "d >= d+ + hysteresis", "forget obstacle", 11, None),
        ("AVOID", "ARMED", abs(pan) - arm, arm_leave, ("arm_sign",),
         "|wrap(pan)| >= arm", "arm_sign := sign(pan)", 10, None),
        ("ARMED", "LEAVE", minimum(crossed_zero, d_occ - D_zero), latch_dl, ("dL", "d_end"),
         "pan back through 0 and mu_occ = 0", "dL := d; d_end := max(d+, dL + d+ - d0)", 10, ("CLEAR",)),
        ("ARMED", "PASSED", crossed_zero, None, (),
         "pan back through 0 and mu_occ > 0", "", 11, None),
        ("PASSED", "LEAVE", d_occ - D_zero, latch_dl, ("dL", "d_end"),
         "mu_occ = 0", "dL := d; d_end := max(d+, dL + d+ - d0)", 10, ("CLEAR",)),
        ("LEAVE", "FAR", d_latched - maximum(m.d_end, d_plus + hysteresis), forget_obstacle,
         ("obstacle", "side", "arm_sign", "dL", "d_end"), "d >= max(d_end, d+ + hysteresis)", "AVOID := LEAVE := 0",
         10, None),
        ("LEAVE", "AVOID", minimum(d_minus - d_latched, m.dL - 0.01 - d_latched), disarm,
         ("arm_sign", "dL", "d_end"), "d <= min(d-, dL - 1 cm)", "LEAVE := 0; disarm", 11, None),
    ]
    # ---- occlusion component ----------------------------------------------------------------
    occlusion_rules = [
        ("CLEAR", "OCCLUDED", D_minus - d_occ, None, (), "d_occ <= D-", "", 0),
        ("OCCLUDED", "RELEASE",
         maximum(d_occ - D_zero, minimum(-d_bord, d_occ - (D_minus + release_margin))),
         latch_DL, ("DL", "D_end"), "d_occ >= D0 or (d_bord = 0 and d_occ >= (D- + D0)/2)",
         "DL := d_occ; D_end := max(D+, DL + D+ - D0)", 0),
        ("RELEASE", "CLEAR", d_occ - m.D_end, clear_DL, ("DL", "D_end"),
         "d_occ >= D_end", "", 0),
        ("RELEASE", "OCCLUDED", D_minus - d_occ, clear_DL, ("DL", "D_end"),
         "d_occ <= D-", "", 1),
    ]

    modes = _supervisor_modes()
    transitions = _supervisor_transitions(collision_rules, occlusion_rules)
    memory = _supervisor_memory()
    variables = SIGNALS + tuple(f"d_coll_{i}_m" for i in range(n_obstacles))
    automaton = HybridAutomaton(
        name="folio-cadenat-supervisor",
        modes=tuple(modes),
        transitions=tuple(transitions),
        variables=variables,
        memory=memory,
        initial_mode=mode_name("FAR", "CLEAR"),
        description="AVOID/LEAVE/OCCLU logic of Folio & Cadenat as a product automaton",
    )
    return SupervisorModel(automaton=automaton, envelopes=envelopes, settings=settings, n_obstacles=n_obstacles)


def _supervisor_modes() -> list[Mode]:
    """The product modes of :func:`build_supervisor`: one per (collision phase, occlusion phase), labelled."""
    modes = []
    for collision in COLLISION_PHASES:
        for occlusion in OCCLUSION_PHASES:
            avoid, leave = _FLAGS[collision]
            modes.append(
                Mode(
                    name=mode_name(collision, occlusion),
                    description=f"collision {collision}, occlusion {occlusion}",
                    labels={
                        "collision": collision,
                        "occlusion": occlusion,
                        "AVOID": avoid,
                        "LEAVE": leave,
                        "OCCLU": int(occlusion == "OCCLUDED"),
                    },
                )
            )
    return modes


def _supervisor_transitions(collision_rules: list[tuple], occlusion_rules: list[tuple]) -> list[Transition]:
    """The transitions of :func:`build_supervisor`: each collision rule in every occlusion phase it applies to
    (``None``: all), then each occlusion rule in every collision phase."""
    reads_coll = ("d_nearest_m", "nearest_obstacle", "bypass_side", "pan_wrapped_rad", "d_occ_px")
    transitions = []
    for src, dst, guard, reset, writes, gtext, rtext, prio, only in collision_rules:
        for occlusion in OCCLUSION_PHASES:
            if only is not None and occlusion not in only:
                continue
            transitions.append(
                Transition(
                    name=f"{src}->{dst}@{occlusion}",
                    source=mode_name(src, occlusion),
                    target=mode_name(dst, occlusion),
                    guard=guard,
                    reset=reset,
                    writes=writes,
                    reads=reads_coll,
                    priority=prio,
                    guard_text=gtext,
                    reset_text=rtext,
                )
            )
    for src, dst, guard, reset, writes, gtext, rtext, prio in occlusion_rules:
        for collision in COLLISION_PHASES:
            transitions.append(
                Transition(
                    name=f"{collision}@{src}->{dst}",
                    source=mode_name(collision, src),
                    target=mode_name(collision, dst),
                    guard=guard,
                    reset=reset,
                    writes=writes,
                    reads=("d_occ_px", "d_bord_px"),
                    priority=prio,
                    guard_text=gtext,
                    reset_text=rtext,
                )
            )
    return transitions


def _supervisor_memory() -> tuple[MemoryVariable, ...]:
    """The latched quantities of :func:`build_supervisor` (all start at 0)."""
    memory = (
        MemoryVariable(name="obstacle", initial=0.0, description="index of the latched obstacle"),
        MemoryVariable(name="side", initial=0.0, description="bypass side: +1 obstacle on the left, -1 right"),
        MemoryVariable(name="arm_sign", initial=0.0, description="sign of pan when the LEAVE test was armed"),
        MemoryVariable(name="dL", initial=0.0, description="d_coll latched when LEAVE was set [m]"),
        MemoryVariable(name="d_end", initial=0.0, description="end of the collision release band [m]"),
        MemoryVariable(name="DL", initial=0.0, description="d_occ latched when OCCLU was reset [px]"),
        MemoryVariable(name="D_end", initial=0.0, description="end of the occlusion release band [px]"),
    )
    return memory


def measurement_system(model: SupervisorModel) -> HybridSystem:
    """The supervisor over a *consistent* measurement state, for :func:`hybrid.check`.

    The supervisor's signals are not independent: ``d_nearest`` is the
    smallest ``d_coll_i`` and ``nearest_obstacle`` its index (the first one on
    a tie).  Searching a box over the signals themselves would visit
    impossible combinations and report defects that no robot can produce, so
    the checks search over the raw measurements ``(d_coll_0, ...,
    d_coll_{n-1}, bypass_side, d_occ, d_bord, pan_wrapped)`` and the output
    map, symbolic like the guards, derives the signals from them.  The pan
    angle is measured already wrapped into (−π, π], as the supervisor reads it.

    The flow is zero in every mode (the measurements are exogenous to the
    supervisor); it plays no part in the checks because no mode of the
    supervisor has an invariant (it is evaluated at every sample, and the
    deadlock question is void).  The dwell-time bounds of the Zeno check take
    the measurements' rate bounds instead (:func:`measurement_rates`).

    Without obstacles (``n_obstacles = 0``) there is no distance coordinate:
    the closed loop then measures ``d_nearest = inf``, and the checks read the
    finite :func:`no_obstacle_distance` instead (a solver cannot represent
    ``inf``, and a latched ``dL = inf`` would make ``d − d_end`` NaN), which
    behaves as ``inf`` in every guard: no collision transition is ever enabled
    from ``FAR``.
    """
    n = model.n_obstacles
    names = tuple(f"d_coll_{i}_m" for i in range(n)) + (
        "bypass_side", "d_occ_px", "d_bord_px", "pan_wrapped_rad",
    )
    x = coordinates(names)
    distances = [x[f"d_coll_{i}_m"] for i in range(n)]
    if n:
        nearest: Expr = minimum(*distances)
        index: Expr = 0.0 * distances[0]  # the first minimal distance's index, as min(range(n), key=...)
        for i in range(1, n):
            index = ite(distances[i] < minimum(*distances[:i]), float(i), index)
    else:  # no obstacle: a finite distance beyond every collision threshold (see the docstring)
        far = no_obstacle_distance(model.envelopes)
        nearest, index = 0.0 * x.d_occ_px + far, 0.0 * x.d_occ_px  # type: ignore[assignment]
    output = output_map(nearest, index, x.bypass_side, x.d_occ_px, x.d_bord_px, x.pan_wrapped_rad, *distances)
    zero = tuple(0.0 for _ in names)
    return HybridSystem(
        automaton=model.automaton,
        state_names=names,
        flows={mode: (lambda t, x, m: zero) for mode in model.automaton.mode_names},
        output=output,
    )


def no_obstacle_distance(envelopes: Envelopes) -> float:
    """The obstacle distance [m] the structural checks read in a scene without obstacles.

    ``10 (d+ + 1 m)``: beyond every collision threshold of the guards (``d+``,
    ``d+ + hysteresis``) for every envelope and hysteresis of
    :func:`parameter_space` (``d+ <= d+ + 1 m``, hysteresis ``<= 1 m``), so it acts
    as the closed loop's ``d_nearest = inf`` (``FAR -> APPROACH`` never enabled)
    while staying a finite number a solver can represent.

    Examples
    --------
    >>> no_obstacle_distance(Envelopes())
    16.0
    """
    return 10.0 * (envelopes.d_plus_m + 1.0)


def parameter_space(model: SupervisorModel) -> ParameterSpace:
    """The envelopes and settings left free under the scenario's validation rules, for parametric questions.

    ``0 < d− < d0 < d+`` (each at most the measurement box's largest distance),
    ``0 < D− < D0 < D+`` (at most its largest ``d_occ``), ``h > 0`` (at most
    1 m) and ``0 < arm < π/2``: the rules :func:`visnav.scenario.load_scenario`
    enforces.  :func:`hybrid.decide.exclusive_for_all` then answers "exclusive
    for every admissible envelope", over the measurement box of ``model``.
    """
    env = model.envelopes
    d_high, D_high = env.d_plus_m + 1.0, 2.0 * env.D_plus_px
    p = {n: param(n, 0.0) for n in ("d_minus", "d_zero", "d_plus", "D_minus", "D_zero", "D_plus", "hysteresis",
                                     "arm")}
    return ParameterSpace(
        bounds={"d_minus": (0.0, d_high), "d_zero": (0.0, d_high), "d_plus": (0.0, d_high),
                "D_minus": (0.0, D_high), "D_zero": (0.0, D_high), "D_plus": (0.0, D_high),
                "hysteresis": (0.0, 1.0), "arm": (0.0, 0.5 * math.pi)},
        assumptions=(p["d_minus"] > 0.0, p["d_minus"] < p["d_zero"], p["d_zero"] < p["d_plus"],
                     p["D_minus"] > 0.0, p["D_minus"] < p["D_zero"], p["D_zero"] < p["D_plus"],
                     p["hysteresis"] > 0.0, p["arm"] > 0.0, p["arm"] < 0.5 * math.pi),
        description=(f"every 0 < d- < d0 < d+ <= {d_high:g} m, 0 < D- < D0 < D+ <= {D_high:g} px, "
                     "0 < hysteresis <= 1 m and 0 < arm < pi/2 (the scenario's validation rules)"),
    )


def measurement_rates(max_step: Mapping[str, float], period_s: float, n_obstacles: int) -> dict[str, float]:
    """Rate bounds [unit/s] of the measurement coordinates of :func:`measurement_system`.

    Parameters
    ----------
    max_step : Mapping[str, float]
        Largest change per sample of ``d`` (every obstacle distance) [m],
        ``d_occ`` [px], ``d_bord`` [px] and ``pan`` [rad].
    period_s : float
        Sampling period [s].
    n_obstacles : int
    """
    rates = {f"d_coll_{i}_m": max_step["d"] / period_s for i in range(n_obstacles)}
    rates.update({"d_occ_px": max_step["d_occ"] / period_s, "d_bord_px": max_step["d_bord"] / period_s,
                  "pan_wrapped_rad": max_step["pan"] / period_s})
    return rates


def measurement_box(model: SupervisorModel, camera_half_width_px: float) -> Box:
    """The declared region of the measurements that :func:`measurement_system` is checked on.

    Distances from 0 to ``d+ + 1 m`` (beyond ``d+`` nothing changes),
    ``d_occ`` from 0 to ``2 D+`` and ``d_bord`` from 0 to the image half-width
    [px], any pan angle, and both bypass sides.  ``d_occ = ∞`` (no occluder in
    view) behaves as any ``d_occ >= D+`` in every guard, so the finite range
    covers it.
    """
    env = model.envelopes
    bounds = {f"d_coll_{i}_m": (0.0, env.d_plus_m + 1.0) for i in range(model.n_obstacles)}
    bounds.update({
        "d_occ_px": (0.0, 2.0 * env.D_plus_px),
        "d_bord_px": (0.0, float(camera_half_width_px)),
        "pan_wrapped_rad": (-math.pi, math.pi),
    })
    return Box(bounds=bounds, choices={"bypass_side": (-1.0, 1.0)})
