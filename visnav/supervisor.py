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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hybrid import Box, HybridAutomaton, HybridSystem, MemoryVariable, Mode, Transition

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
        Number of obstacles; the signals carry one distance per obstacle.
    """
    env = envelopes
    d_minus, d_zero, d_plus = env.d_minus_m, env.d_zero_m, env.d_plus_m
    D_minus, D_zero, D_plus = env.D_minus_px, env.D_zero_px, env.D_plus_px
    arm = settings.arm_angle_rad
    hysteresis = settings.detection_hysteresis_m
    release_margin = 0.5 * (D_zero - D_minus)

    def d_latched(v: Sequence[float], m: Mapping[str, float]) -> float:
        return v[I_FIRST_OBSTACLE + int(m["obstacle"])]

    def crossed_zero(v: Sequence[float], m: Mapping[str, float]) -> float:
        # ϑ (wrapped) is back on the other side of zero from where it was armed, near 0
        pan = v[I_PAN]
        return min(-m["arm_sign"] * pan, 0.5 * math.pi - abs(pan))

    # ---- resets --------------------------------------------------------------------
    def latch_obstacle(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"obstacle": float(v[I_NEAREST]), "side": float(v[I_SIDE])}

    def forget_obstacle(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"obstacle": 0.0, "side": 0.0, "arm_sign": 0.0, "dL": 0.0, "d_end": 0.0}

    def arm_leave(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"arm_sign": 1.0 if v[I_PAN] > 0.0 else -1.0}

    def latch_dl(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        dl = d_latched(v, m)
        return {"dL": dl, "d_end": max(d_plus, dl + (d_plus - d_zero))}

    def disarm(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"arm_sign": 0.0, "dL": 0.0, "d_end": 0.0}

    def latch_DL(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        d = v[I_D_OCC]
        dl = d if math.isfinite(d) else D_zero
        return {"DL": dl, "D_end": max(D_plus, dl + (D_plus - D_zero))}

    def clear_DL(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"DL": 0.0, "D_end": 0.0}

    # ---- collision component -------------------------------------------------------------
    # (source, target, guard, reset, writes, guard_text, reset_text, priority, occlusion phases or None=all)
    collision_rules = [
        ("FAR", "APPROACH", lambda v, m: d_plus - v[I_D_NEAREST], latch_obstacle, ("obstacle", "side"),
         "d_nearest <= d+", "obstacle := nearest; side := bypass side", 10, None),
        ("APPROACH", "AVOID", lambda v, m: d_minus - d_latched(v, m), None, (),
         "d <= d-", "", 10, None),
        ("APPROACH", "FAR", lambda v, m: d_latched(v, m) - (d_plus + hysteresis), forget_obstacle,
         ("obstacle", "side", "arm_sign", "dL", "d_end"), "d >= d+ + hysteresis", "forget obstacle", 11, None),
        ("AVOID", "ARMED", lambda v, m: abs(v[I_PAN]) - arm, arm_leave, ("arm_sign",),
         "|wrap(pan)| >= arm", "arm_sign := sign(pan)", 10, None),
        ("ARMED", "LEAVE", lambda v, m: min(crossed_zero(v, m), v[I_D_OCC] - D_zero), latch_dl, ("dL", "d_end"),
         "pan back through 0 and mu_occ = 0", "dL := d; d_end := max(d+, dL + d+ - d0)", 10, ("CLEAR",)),
        ("ARMED", "PASSED", crossed_zero, None, (),
         "pan back through 0 and mu_occ > 0", "", 11, None),
        ("PASSED", "LEAVE", lambda v, m: v[I_D_OCC] - D_zero, latch_dl, ("dL", "d_end"),
         "mu_occ = 0", "dL := d; d_end := max(d+, dL + d+ - d0)", 10, ("CLEAR",)),
        ("LEAVE", "FAR", lambda v, m: d_latched(v, m) - max(m["d_end"], d_plus + hysteresis), forget_obstacle,
         ("obstacle", "side", "arm_sign", "dL", "d_end"), "d >= max(d_end, d+ + hysteresis)", "AVOID := LEAVE := 0",
         10, None),
        ("LEAVE", "AVOID", lambda v, m: min(d_minus - d_latched(v, m), m["dL"] - 0.01 - d_latched(v, m)), disarm,
         ("arm_sign", "dL", "d_end"), "d <= min(d-, dL - 1 cm)", "LEAVE := 0; disarm", 11, None),
    ]
    # ---- occlusion component ----------------------------------------------------------------
    occlusion_rules = [
        ("CLEAR", "OCCLUDED", lambda v, m: D_minus - v[I_D_OCC], None, (), "d_occ <= D-", "", 0),
        ("OCCLUDED", "RELEASE",
         lambda v, m: max(v[I_D_OCC] - D_zero, min(-v[I_D_BORD], v[I_D_OCC] - (D_minus + release_margin))),
         latch_DL, ("DL", "D_end"), "d_occ >= D0 or (d_bord = 0 and d_occ >= (D- + D0)/2)",
         "DL := d_occ; D_end := max(D+, DL + D+ - D0)", 0),
        ("RELEASE", "CLEAR", lambda v, m: v[I_D_OCC] - m["D_end"], clear_DL, ("DL", "D_end"),
         "d_occ >= D_end", "", 0),
        ("RELEASE", "OCCLUDED", lambda v, m: D_minus - v[I_D_OCC], clear_DL, ("DL", "D_end"),
         "d_occ <= D-", "", 1),
    ]

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
    memory = (
        MemoryVariable(name="obstacle", initial=0.0, description="index of the latched obstacle"),
        MemoryVariable(name="side", initial=0.0, description="bypass side: +1 obstacle on the left, -1 right"),
        MemoryVariable(name="arm_sign", initial=0.0, description="sign of pan when the LEAVE test was armed"),
        MemoryVariable(name="dL", initial=0.0, description="d_coll latched when LEAVE was set [m]"),
        MemoryVariable(name="d_end", initial=0.0, description="end of the collision release band [m]"),
        MemoryVariable(name="DL", initial=0.0, description="d_occ latched when OCCLU was reset [px]"),
        MemoryVariable(name="D_end", initial=0.0, description="end of the occlusion release band [px]"),
    )
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


def measurement_system(model: SupervisorModel) -> HybridSystem:
    """The supervisor over a *consistent* measurement state, for :func:`hybrid.check`.

    The supervisor's signals are not independent: ``d_nearest`` is the
    smallest ``d_coll_i`` and ``nearest_obstacle`` its index.  Searching a box
    over the signals themselves would visit impossible combinations and
    report defects that no robot can produce, so the checks search over the
    raw measurements ``(d_coll_0, ..., d_coll_{n-1}, bypass_side, d_occ,
    d_bord, pan)`` and the output map derives the signals from them.

    The flow is zero in every mode (the measurements are exogenous to the
    supervisor); it plays no part in the checks because no mode of the
    supervisor has an invariant (it is evaluated at every sample, and the
    deadlock question is void).
    """
    names = tuple(f"d_coll_{i}_m" for i in range(model.n_obstacles)) + (
        "bypass_side", "d_occ_px", "d_bord_px", "pan_rad",
    )
    n = model.n_obstacles

    def output(t: float, x: Sequence[float]) -> tuple[float, ...]:
        distances = tuple(x[:n])
        nearest = min(range(n), key=distances.__getitem__) if n else 0
        d_nearest = distances[nearest] if n else math.inf
        side, d_occ, d_bord, pan = x[n:]
        wrapped = math.atan2(math.sin(pan), math.cos(pan))
        return (d_nearest, float(nearest), side, d_occ, d_bord, wrapped, *distances)

    zero = tuple(0.0 for _ in names)
    return HybridSystem(
        automaton=model.automaton,
        state_names=names,
        flows={mode: (lambda t, x, m: zero) for mode in model.automaton.mode_names},
        output=output,
    )


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
        "pan_rad": (-math.pi, math.pi),
    })
    return Box(bounds=bounds, choices={"bypass_side": (-1.0, 1.0)})
