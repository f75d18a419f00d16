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
from hybrid.model import symbolic_text
from hybrid.decide import ParameterSpace
from hybrid.errors import ParameterError
from hybrid.symbolic import (
    Condition,
    Expr,
    SymbolicReset,
    coordinates,
    flow_map,
    ite,
    maximum,
    memory as memory_refs,
    minimum,
    output_map,
    param,
    reset as memory_reset,
    select,
    substitute,
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


# ---------------------------------------------------------------------------- the rules, written once
@dataclass(frozen=True, kw_only=True, slots=True)
class SupervisorRule:
    """One rule of a component of the supervisor: ``source -> target`` when ``guard``, with ``reset``.

    Written once, symbolically, over the signals (:data:`SIGNALS`), the memory, the named envelopes and
    settings (:data:`RULE_PARAMETERS`, placeholders that :func:`build_supervisor` replaces by the scenario's
    values) and ``d``, the latched obstacle's distance (:data:`LATCHED_DISTANCE`, replaced by
    ``select(obstacle, [d_coll_0, ...])``).  The transition's guard, reset, ``writes`` and texts are all
    derived from these expressions.

    Attributes
    ----------
    source, target : str
        Phases of the component (collision phases for :data:`COLLISION_RULES`, occlusion phases for
        :data:`OCCLUSION_RULES`).
    guard : hybrid.symbolic.Condition
        When the rule fires (its level form is the transition's guard; closed).
    reset : hybrid.symbolic.SymbolicReset or None
        The memory it latches or clears.
    priority : int
        Smaller fires first among the rules enabled in a product mode.
    phases : tuple of str or None
        A collision rule applies in these occlusion phases only (``None``: in all).
    """

    source: str
    target: str
    guard: Condition
    reset: SymbolicReset | None = None
    priority: int = 0
    phases: tuple[str, ...] | None = None

    @property
    def guard_text(self) -> str:
        """The guard as written (``d <= d_minus``)."""
        return symbolic_text(self.guard)

    @property
    def reset_text(self) -> str:
        """The reset as written (``dL := d, d_end := ...``); empty without a reset."""
        return symbolic_text(self.reset)


LATCHED_DISTANCE = "d"
"""The name the rules give the latched obstacle's distance (``d`` in the paper, ``d_coll`` of the latched one)."""

RULE_PARAMETERS = ("d_minus", "d_zero", "d_plus", "D_minus", "D_zero", "D_plus", "arm", "hysteresis")
"""The named constants of the rules: the envelopes d−, d0, d+ [m], D−, D0, D+ [px], the arming angle [rad] and the
detection hysteresis [m]."""

_v = coordinates(SIGNALS + (LATCHED_DISTANCE,))
_m = memory_refs("obstacle", "side", "arm_sign", "dL", "d_end", "DL", "D_end")
_p = {name: param(name, 0.0) for name in RULE_PARAMETERS}
_d, _pan, _d_occ = _v[LATCHED_DISTANCE], _v.pan_wrapped_rad, _v.d_occ_px
# ϑ (wrapped) is back on the other side of zero from where it was armed, near 0
_pan_back_through_zero = (-_m.arm_sign * _pan >= 0.0) & (abs(_pan) <= 0.5 * math.pi)
_latch_dl = memory_reset(dL=_d, d_end=maximum(_p["d_plus"], _d + (_p["d_plus"] - _p["d_zero"])))
_forget_obstacle = memory_reset(obstacle=0.0, side=0.0, arm_sign=0.0, dL=0.0, d_end=0.0)
_latched_occ = ite(_d_occ < math.inf, _d_occ, _p["D_zero"])  # an occluder out of view latches D0
_clear_DL = memory_reset(DL=0.0, D_end=0.0)

COLLISION_RULES: tuple[SupervisorRule, ...] = (
    SupervisorRule(source="FAR", target="APPROACH", guard=_v.d_nearest_m <= _p["d_plus"], priority=10,
                   reset=memory_reset(obstacle=_v.nearest_obstacle, side=_v.bypass_side)),
    SupervisorRule(source="APPROACH", target="AVOID", guard=_d <= _p["d_minus"], priority=10),
    SupervisorRule(source="APPROACH", target="FAR", guard=_d >= _p["d_plus"] + _p["hysteresis"],
                   reset=_forget_obstacle, priority=11),
    SupervisorRule(source="AVOID", target="ARMED", guard=abs(_pan) >= _p["arm"],
                   reset=memory_reset(arm_sign=ite(_pan > 0.0, 1.0, -1.0)), priority=10),
    SupervisorRule(source="ARMED", target="LEAVE", guard=_pan_back_through_zero & (_d_occ >= _p["D_zero"]),
                   reset=_latch_dl, priority=10, phases=("CLEAR",)),
    SupervisorRule(source="ARMED", target="PASSED", guard=_pan_back_through_zero, priority=11),
    SupervisorRule(source="PASSED", target="LEAVE", guard=_d_occ >= _p["D_zero"], reset=_latch_dl, priority=10,
                   phases=("CLEAR",)),
    SupervisorRule(source="LEAVE", target="FAR", guard=_d >= maximum(_m.d_end, _p["d_plus"] + _p["hysteresis"]),
                   reset=_forget_obstacle, priority=10),
    SupervisorRule(source="LEAVE", target="AVOID", guard=(_d <= _p["d_minus"]) & (_d <= _m.dL - 0.01),
                   reset=memory_reset(arm_sign=0.0, dL=0.0, d_end=0.0), priority=11),
)
"""The collision component's rules (AVOID and LEAVE, eq. (18) of the paper as resolved in docs/supervisor.md):
each applies in every occlusion phase of its ``phases``.  LEAVE is set only with no occlusion risk
(``d_occ >= D0`` and phase ``CLEAR``); ``LEAVE -> AVOID`` re-enters ξ− 1 cm below the latched ``dL``."""

OCCLUSION_RULES: tuple[SupervisorRule, ...] = (
    SupervisorRule(source="CLEAR", target="OCCLUDED", guard=_d_occ <= _p["D_minus"]),
    SupervisorRule(source="OCCLUDED", target="RELEASE",
                   guard=(_d_occ >= _p["D_zero"]) | ((_v.d_bord_px <= 0.0)
                                                    & (_d_occ >= _p["D_minus"] + 0.5 * (_p["D_zero"] - _p["D_minus"]))),
                   reset=memory_reset(DL=_latched_occ,
                                      D_end=maximum(_p["D_plus"], _latched_occ + (_p["D_plus"] - _p["D_zero"])))),
    SupervisorRule(source="RELEASE", target="CLEAR", guard=_d_occ >= _m.D_end, reset=_clear_DL),
    SupervisorRule(source="RELEASE", target="OCCLUDED", guard=_d_occ <= _p["D_minus"], reset=_clear_DL, priority=1),
)
"""The occlusion component's rules (OCCLU, eq. (19) of the paper as resolved in docs/supervisor.md): each applies
in every collision phase.  OCCLU is released at ``d_occ >= D0``, or once the occluder touches the image border
(``d_bord = 0``) half-way between D− and D0."""


def build_supervisor(envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int) -> SupervisorModel:
    """Build the supervisor automaton for a scene with ``n_obstacles`` obstacles.

    The transitions are :data:`COLLISION_RULES` and :data:`OCCLUSION_RULES` with the scenario's envelopes and
    settings put in for :data:`RULE_PARAMETERS` (named parameters, which a parametric question of
    :mod:`hybrid.decide` may leave free) and the latched obstacle's distance for ``d``.

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
    values = {"d_minus": env.d_minus_m, "d_zero": env.d_zero_m, "d_plus": env.d_plus_m, "D_minus": env.D_minus_px,
              "D_zero": env.D_zero_px, "D_plus": env.D_plus_px, "arm": settings.arm_angle_rad,
              "hysteresis": settings.detection_hysteresis_m}
    n_obstacles = int(n_obstacles)
    variables = SIGNALS + tuple(f"d_coll_{i}_m" for i in range(n_obstacles))
    v = coordinates(variables)
    # the latched obstacle's distance (with no obstacle, the nearest distance, which is then inf)
    d_latched: Expr = (select(_m.obstacle, [v[f"d_coll_{i}_m"] for i in range(n_obstacles)])
                       if n_obstacles else v.d_nearest_m)
    instance = _Instance(d_latched, {name: param(name, values[name]) for name in RULE_PARAMETERS})
    automaton = HybridAutomaton(
        name="folio-cadenat-supervisor",
        modes=tuple(_supervisor_modes()),
        transitions=tuple(_supervisor_transitions(instance)),
        variables=variables,
        memory=_supervisor_memory(),
        initial_mode=mode_name("FAR", "CLEAR"),
        description="AVOID/LEAVE/OCCLU logic of Folio & Cadenat as a product automaton",
    )
    return SupervisorModel(automaton=automaton, envelopes=envelopes, settings=settings, n_obstacles=n_obstacles)


class _Instance:
    """The rules' placeholders replaced: ``d`` by the latched distance, the parameters by their values."""

    def __init__(self, d_latched: Expr, params: Mapping[str, Expr]) -> None:
        self.coordinates = {LATCHED_DISTANCE: d_latched}
        self.params = dict(params)

    def guard(self, rule: SupervisorRule) -> Condition:
        return substitute(rule.guard, coordinates=self.coordinates, params=self.params)

    def reset(self, rule: SupervisorRule) -> SymbolicReset | None:
        if rule.reset is None:
            return None
        return memory_reset({name: substitute(e, coordinates=self.coordinates, params=self.params)
                             for name, e in rule.reset.assignments.items()})


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


def _supervisor_transitions(instance: _Instance) -> list[Transition]:
    """The transitions of :func:`build_supervisor`: each collision rule in every occlusion phase it applies to
    (``None``: all), then each occlusion rule in every collision phase.

    The texts are the rules' own (over ``d`` and the parameters' names), the guard and reset their instances.
    """
    reads_coll = ("d_nearest_m", "nearest_obstacle", "bypass_side", "pan_wrapped_rad", "d_occ_px")
    transitions = []
    for rule in COLLISION_RULES:
        guard, reset = instance.guard(rule), instance.reset(rule)
        for occlusion in OCCLUSION_PHASES:
            if rule.phases is not None and occlusion not in rule.phases:
                continue
            transitions.append(Transition(
                name=f"{rule.source}->{rule.target}@{occlusion}", source=mode_name(rule.source, occlusion),
                target=mode_name(rule.target, occlusion), guard=guard, reset=reset, reads=reads_coll,
                priority=rule.priority, guard_text=rule.guard_text, reset_text=rule.reset_text))
    for rule in OCCLUSION_RULES:
        guard, reset = instance.guard(rule), instance.reset(rule)
        for collision in COLLISION_PHASES:
            transitions.append(Transition(
                name=f"{collision}@{rule.source}->{rule.target}", source=mode_name(collision, rule.source),
                target=mode_name(collision, rule.target), guard=guard, reset=reset, reads=("d_occ_px", "d_bord_px"),
                priority=rule.priority, guard_text=rule.guard_text, reset_text=rule.reset_text))
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


def measurement_system(model: SupervisorModel, *, held: bool = False) -> HybridSystem:
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
    the measurements' rate bounds instead (:func:`measurement_rates`).  That
    zero is not a fact about the measurements, so by default it is a plain
    function the checker cannot read: a symbolic zero flow would be enclosed
    as the rate bound 0, and the dwell bounds would then take the measurements
    for constant (an unsound proof of no Zeno behaviour).

    ``held=True`` writes it symbolically, ``flow_map(0, ..., 0)``: the
    measurements held between the supervisor's evaluations.  That is the form
    the exports need (:func:`hybrid.spaceex_export.to_spaceex` writes the
    automaton with ``x' == 0`` flows); do not give it to :func:`hybrid.check`
    with rate bounds.

    Parameters
    ----------
    model : SupervisorModel
    held : bool
        Symbolic zero flows (for the exports) instead of the plain zero function (for the checks).

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
    flow = flow_map(zero) if held else (lambda t, x, m: zero)
    return HybridSystem(automaton=model.automaton, state_names=names,
                        flows={mode: flow for mode in model.automaton.mode_names}, output=output)


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
