"""Variants of the supervisor: the resolved automaton and copies of it with one planted defect.

A :class:`SupervisorVariant` is what the fuzzer drives: an automaton with its
risk outputs (a :class:`~visnav.supervisor.SupervisorModel`, or a subclass
that changes µ or the flags) and the measurement stage in front of it
(whether ϑ is wrapped to (−π, π] before the guards read it).

Each mutant is a *real variant of the built automaton*: it starts from
:func:`~visnav.supervisor.build_supervisor` and changes exactly one thing by
a documented transform (a guard that reads an un-latched memory view, a
changed priority, a changed target, a subclass that changes one case of µ).
Nothing is monkeypatched; the resolved automaton is untouched.

============================  =====================================================================
mutant                        defect (the open question of docs/supervisor.md it answers the other way)
============================  =====================================================================
``drop_dl_latch``             dL follows d_coll instead of being latched when LEAVE is set (Q5):
                              case 3 of (2) is identically 1 and the release guards never hold
``reset_avoid_on_leave``      AVOID is reset when LEAVE is set (Q1): with AVOID = 0, case 2 of (2)
                              applies in [d−, d0] and µ_coll jumps down at the switch
``raw_pan``                   the guards read the raw pan angle ϑ instead of ϑ wrapped to (−π, π]
                              (Q6): after a full turn of the platform LEAVE never comes
``equal_priority``            ARMED → PASSED gets the priority of ARMED → LEAVE: both are enabled
                              together when ϑ returns with µ_occ = 0 (a removed priority)
``no_hysteresis``             detection hysteresis 0: FAR → APPROACH and APPROACH → FAR are both
                              enabled at d = d+ (a guard that fires again right after its own jump)
``no_release_phase``          OCCLU is reset straight to CLEAR, without the release phase (Q8):
                              µ_occ jumps from 1 to 0 (or to case 2) when the occluder leaves
============================  =====================================================================

Slips an engineer implementing ``docs/supervisor.md`` could make (issue 13, item 8), one class each;
every one is caught by a property whose name says the slip (``docs/fuzzing.md``, "Slips"):

============================  =====================================================================
mutant                        slip (class)
============================  =====================================================================
``late_occlu_release``        OCCLUDED → RELEASE reads D+ where it should read D0 (threshold moved):
                              OCCLU is reset only at d_occ >= D+
``release_band_d0``           d_end := max(d0, dL + d+ − d0) instead of max(d+, …) (threshold moved
                              in a latched distance): the LEAVE band ends before d+ whenever dL < d0
``occlu_set_at_d0``           CLEAR → OCCLUDED reads D0 where it should read D− (D− ↔ D0 swapped)
``strict_occlu_set``          CLEAR → OCCLUDED at d_occ < D− instead of <= D− (a ``<`` for ``<=``)
``unlatched_side``            the controllers read the bypass side measured at every sample instead
                              of the side latched at FAR → APPROACH (a latch updated continuously)
``drop_occlu_latch``          DL follows d_occ instead of being latched when OCCLU is reset (a latch
                              updated continuously): µ_occ = 1 in RELEASE, which reaches CLEAR only
                              at d_occ = ∞
``no_leave_hysteresis``       LEAVE → FAR at d >= d_end, without the ``d+ + hysteresis`` floor (a
                              hysteresis band dropped): the obstacle is forgotten at d+
``no_occlu_margin``           OCCLUDED → RELEASE on d_bord = 0 without the margin d_occ >= (D− + D0)/2
                              (a hysteresis band dropped): OCCLU toggles at one instant (Zeno)
``flipped_side``              FAR → APPROACH latches side := −bypass side (the bypass side flipped)
============================  =====================================================================

The closed-loop slips (estimator, blend of the controllers) are in :mod:`visnav.fuzzing.loop_mutants`.

Examples
--------
>>> from visnav.parameters import Envelopes, SupervisorSettings
>>> variant = build_variant("equal_priority", Envelopes(), SupervisorSettings(), 1)
>>> [(t.name, t.priority) for t in variant.model.automaton.outgoing("ARMED|CLEAR") if t.name.startswith("ARMED->")]
[('ARMED->LEAVE@CLEAR', 10), ('ARMED->PASSED@CLEAR', 10)]
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

from hybrid import HybridAutomaton, Mode, Transition

from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import (
    I_D_BORD,
    I_D_OCC,
    I_FIRST_OBSTACLE,
    I_NEAREST,
    I_SIDE,
    SupervisorModel,
    build_supervisor,
    split_mode,
)

__all__ = [
    "SupervisorVariant",
    "MUTANTS",
    "RESOLVED",
    "resolved_variant",
    "build_variant",
    "rebuild",
]

RESOLVED = "resolved"
"""Name of the unmodified automaton of :mod:`visnav.supervisor`."""


@dataclass(frozen=True, kw_only=True, slots=True)
class SupervisorVariant:
    """A supervisor the fuzzer can drive.

    Attributes
    ----------
    name : str
        ``"resolved"``, a mutant name of :data:`MUTANTS`, or ``"paper"``.
    description : str
        One line: what differs from the resolved automaton.
    model : SupervisorModel
        Automaton, µ_coll / µ_occ and flags (``risk``, ``flags``).
    wrap_pan : bool
        Whether the measurement stage wraps ϑ to (−π, π] before the guards read it.
    latches_obstacle : bool
        Whether the automaton's memory holds the avoided obstacle and its side
        (``obstacle``, ``side``); otherwise controllers use the nearest one.
    controller_view : callable or None
        ``view(v, memory) -> memory``: what the controllers read of the memory
        (the avoided obstacle and its bypass side), when it is not the memory
        itself (a mutant whose output un-latches a memory variable).
    """

    name: str
    description: str
    model: SupervisorModel
    wrap_pan: bool = True
    latches_obstacle: bool = True
    controller_view: Callable[[Sequence[float], Mapping[str, float]], Mapping[str, float]] | None = None

    def controller_memory(self, v: Sequence[float], memory: Mapping[str, float]) -> Mapping[str, float]:
        """The memory as the controllers read it at signals ``v`` (``obstacle``, ``side``, ...).

        The memory itself for the resolved automaton; the nearest obstacle and the
        current bypass side for a variant that does not latch them; then the
        variant's :attr:`controller_view`, if any.
        """
        if not self.latches_obstacle:
            memory = {**memory, "obstacle": float(v[I_NEAREST]), "side": float(v[I_SIDE])}
        if self.controller_view is not None:
            memory = self.controller_view(v, memory)
        return memory


def rebuild(
    model: SupervisorModel,
    *,
    suffix: str,
    transition: Callable[[Transition], Transition | None] = lambda t: t,
    mode: Callable[[Mode], Mode] = lambda m: m,
    model_class: type[SupervisorModel] | None = None,
) -> SupervisorModel:
    """A copy of ``model`` with every transition and mode passed through a transform.

    Parameters
    ----------
    suffix : str
        Appended to the automaton's name (``folio-cadenat-supervisor~suffix``).
    transition : callable
        ``Transition -> Transition`` (or ``None`` to drop it).
    mode : callable
        ``Mode -> Mode``.
    model_class : SupervisorModel subclass or None
        Class of the result (to change µ or the flags); the model's own class by default.
    """
    a = model.automaton
    transitions = tuple(t2 for t2 in (transition(t) for t in a.transitions) if t2 is not None)
    automaton = HybridAutomaton(
        name=f"{a.name}~{suffix}",
        modes=tuple(mode(m) for m in a.modes),
        transitions=transitions,
        variables=a.variables,
        memory=a.memory,
        initial_mode=a.initial_mode,
        description=f"{a.description} (mutant {suffix})",
    )
    cls = model_class or type(model)
    return cls(automaton=automaton, envelopes=model.envelopes, settings=model.settings, n_obstacles=model.n_obstacles)


def _latched_distance(v: Sequence[float], m: Mapping[str, float]) -> float:
    return v[I_FIRST_OBSTACLE + int(m["obstacle"])]


def _unlatched_view(envelopes: Envelopes, v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
    """The memory as if dL were continuously equal to the current d_coll (and d_end with it)."""
    d = _latched_distance(v, m)
    return {**m, "dL": d, "d_end": max(envelopes.d_plus_m, d + (envelopes.d_plus_m - envelopes.d_zero_m))}


@dataclass(frozen=True, kw_only=True, slots=True)
class _UnlatchedModel(SupervisorModel):
    """µ_coll in LEAVE evaluated with dL = the current d_coll (mutant ``drop_dl_latch``)."""

    def mu_coll(self, collision_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        if collision_phase == "LEAVE":
            memory = _unlatched_view(self.envelopes, v, memory)
        return SupervisorModel.mu_coll(self, collision_phase, v, memory)


def _drop_dl_latch(base: SupervisorModel) -> SupervisorModel:
    env = base.envelopes

    def transition(t: Transition) -> Transition:
        if t.source.startswith("LEAVE|"):
            guard = t.guard
            return dataclasses.replace(t, guard=lambda v, m, g=guard: g(v, _unlatched_view(env, v, m)))
        return t

    return rebuild(base, suffix="drop_dl_latch", transition=transition, model_class=_UnlatchedModel)


@dataclass(frozen=True, kw_only=True, slots=True)
class _AvoidResetModel(SupervisorModel):
    """LEAVE with AVOID = 0: the printed cases of (2) in order (mutant ``reset_avoid_on_leave``)."""

    def mu_coll(self, collision_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        if collision_phase == "LEAVE":
            env = self.envelopes
            d = _latched_distance(v, memory)
            if env.d_minus_m <= d <= env.d_zero_m:  # case 2: "d in [d-, d0] and AVOID = 0"
                return (env.d_zero_m - d) / (env.d_zero_m - env.d_minus_m)
        return SupervisorModel.mu_coll(self, collision_phase, v, memory)

    def flags(self, mode: str) -> dict[str, int]:
        out = SupervisorModel.flags(self, mode)
        if split_mode(mode)[0] == "LEAVE":
            out["AVOID"] = 0
        return out


def _reset_avoid_on_leave(base: SupervisorModel) -> SupervisorModel:
    def mode(m: Mode) -> Mode:
        if m.labels.get("collision") == "LEAVE":
            return dataclasses.replace(m, labels=MappingProxyType({**m.labels, "AVOID": 0}))
        return m

    return rebuild(base, suffix="reset_avoid_on_leave", mode=mode, model_class=_AvoidResetModel)


def _equal_priority(base: SupervisorModel) -> SupervisorModel:
    leave_priority = next(t.priority for t in base.automaton.transitions if t.name.startswith("ARMED->LEAVE"))

    def transition(t: Transition) -> Transition:
        if t.name.startswith("ARMED->PASSED"):
            return dataclasses.replace(t, priority=leave_priority)
        return t

    return rebuild(base, suffix="equal_priority", transition=transition)


def _no_release_phase(base: SupervisorModel) -> SupervisorModel:
    def transition(t: Transition) -> Transition:
        if t.name.endswith("@OCCLUDED->RELEASE"):
            collision = split_mode(t.source)[0]
            return dataclasses.replace(
                t, name=f"{collision}@OCCLUDED->CLEAR", target=f"{collision}|CLEAR", reset_text=""
            )
        return t

    return rebuild(base, suffix="no_release_phase", transition=transition)


def _replace_rule(base: SupervisorModel, suffix: str, rule: str, **changes: object) -> SupervisorModel:
    """``base`` with the transitions of one rule (``"SRC->DST"`` of one component, in every product mode) changed.

    Each keyword is a field of :class:`hybrid.Transition` and its new value
    (``guard=...``, ``guard_text=...``).
    """
    src, dst = rule.split("->")

    def matches(t: Transition) -> bool:
        a, b = split_mode(t.source), split_mode(t.target)
        return (a[0] == src and b[0] == dst and a[1] == b[1]) or (a[1] == src and b[1] == dst and a[0] == b[0])

    def transition(t: Transition) -> Transition:
        if not matches(t):
            return t
        return dataclasses.replace(t, **changes)  # type: ignore[arg-type]

    if not any(matches(t) for t in base.automaton.transitions):  # pragma: no cover - a typo in a rule name
        raise ValueError(f"no transition of rule {rule!r} in {base.automaton.name}")
    return rebuild(base, suffix=suffix, transition=transition)


def _late_occlu_release(base: SupervisorModel) -> SupervisorModel:
    env = base.envelopes
    D_minus, D_zero, D_plus = env.D_minus_px, env.D_zero_px, env.D_plus_px
    margin = 0.5 * (D_zero - D_minus)
    return _replace_rule(
        base, "late_occlu_release", "OCCLUDED->RELEASE",
        guard=lambda v, m: max(v[I_D_OCC] - D_plus, min(-v[I_D_BORD], v[I_D_OCC] - (D_minus + margin))),
        guard_text="d_occ >= D+ or (d_bord = 0 and d_occ >= (D- + D0)/2)",
    )


def _release_band_d0(base: SupervisorModel) -> SupervisorModel:
    env = base.envelopes
    d_zero, d_plus = env.d_zero_m, env.d_plus_m

    def latch_dl(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        dl = _latched_distance(v, m)
        return {"dL": dl, "d_end": max(d_zero, dl + (d_plus - d_zero))}

    def transition(t: Transition) -> Transition:
        if split_mode(t.target)[0] == "LEAVE" and split_mode(t.source)[0] != "LEAVE":
            return dataclasses.replace(t, reset=latch_dl, reset_text="dL := d; d_end := max(d0, dL + d+ - d0)")
        return t

    return rebuild(base, suffix="release_band_d0", transition=transition)


def _occlu_set_at_d0(base: SupervisorModel) -> SupervisorModel:
    D_zero = base.envelopes.D_zero_px
    return _replace_rule(base, "occlu_set_at_d0", "CLEAR->OCCLUDED",
                         guard=lambda v, m: D_zero - v[I_D_OCC], guard_text="d_occ <= D0")


def _strict(guard: Callable[[Sequence[float], Mapping[str, float]], float]) -> Callable[..., float]:
    """The guard with its boundary excluded: enabled when its margin is > 0 (``<`` for ``<=``)."""

    def strict(v: Sequence[float], m: Mapping[str, float]) -> float:
        margin = guard(v, m)
        return margin if margin != 0.0 else -math.ulp(0.0)

    return strict


def _strict_occlu_set(base: SupervisorModel) -> SupervisorModel:
    def transition(t: Transition) -> Transition:
        if t.name.endswith("@CLEAR->OCCLUDED"):
            return dataclasses.replace(t, guard=_strict(t.guard), guard_text="d_occ < D-")
        return t

    return rebuild(base, suffix="strict_occlu_set", transition=transition)


def _unlatched_side_view(v: Sequence[float], m: Mapping[str, float]) -> Mapping[str, float]:
    """The memory with the bypass side measured now instead of the latched one (mutant ``unlatched_side``)."""
    return {**m, "side": float(v[I_SIDE])}


def _unlatched_occ_view(envelopes: Envelopes, v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
    """The memory as if DL were continuously equal to the current d_occ (and D_end with it)."""
    d = v[I_D_OCC]
    dl = d if math.isfinite(d) else envelopes.D_zero_px
    return {**m, "DL": dl, "D_end": max(envelopes.D_plus_px, dl + (envelopes.D_plus_px - envelopes.D_zero_px))}


@dataclass(frozen=True, kw_only=True, slots=True)
class _UnlatchedOccModel(SupervisorModel):
    """µ_occ in RELEASE evaluated with DL = the current d_occ (mutant ``drop_occlu_latch``)."""

    def mu_occ(self, occlusion_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        if occlusion_phase == "RELEASE":
            memory = _unlatched_occ_view(self.envelopes, v, memory)
        return SupervisorModel.mu_occ(self, occlusion_phase, v, memory)


def _drop_occlu_latch(base: SupervisorModel) -> SupervisorModel:
    env = base.envelopes

    def transition(t: Transition) -> Transition:
        if split_mode(t.source)[1] == "RELEASE" and split_mode(t.target)[1] != "RELEASE":
            guard = t.guard
            return dataclasses.replace(t, guard=lambda v, m, g=guard: g(v, _unlatched_occ_view(env, v, m)))
        return t

    return rebuild(base, suffix="drop_occlu_latch", transition=transition, model_class=_UnlatchedOccModel)


def _no_leave_hysteresis(base: SupervisorModel) -> SupervisorModel:
    def guard(v: Sequence[float], m: Mapping[str, float]) -> float:
        return _latched_distance(v, m) - m["d_end"]

    return _replace_rule(base, "no_leave_hysteresis", "LEAVE->FAR", guard=guard, guard_text="d >= d_end")


def _no_occlu_margin(base: SupervisorModel) -> SupervisorModel:
    D_zero = base.envelopes.D_zero_px
    return _replace_rule(
        base, "no_occlu_margin", "OCCLUDED->RELEASE",
        guard=lambda v, m: max(v[I_D_OCC] - D_zero, -v[I_D_BORD]), guard_text="d_occ >= D0 or d_bord = 0",
    )


def _flipped_side(base: SupervisorModel) -> SupervisorModel:
    def transition(t: Transition) -> Transition:
        if t.name.startswith("FAR->APPROACH@"):
            reset = t.reset
            assert reset is not None

            def flipped(v: Sequence[float], m: Mapping[str, float], r: Callable[..., dict[str, float]] = reset
                        ) -> dict[str, float]:
                out = r(v, m)
                return {**out, "side": -out["side"]}

            return dataclasses.replace(t, reset=flipped, reset_text="obstacle := nearest; side := -bypass side")
        return t

    return rebuild(base, suffix="flipped_side", transition=transition)


MUTANTS: Mapping[str, str] = MappingProxyType({
    "drop_dl_latch": "dL follows d_coll instead of being latched when LEAVE is set (Q5)",
    "reset_avoid_on_leave": "AVOID is reset when LEAVE is set; case 2 of (2) applies again in [d-, d0] (Q1)",
    "raw_pan": "the guards read the raw pan angle instead of the angle wrapped to (-pi, pi] (Q6)",
    "equal_priority": "ARMED -> PASSED has the priority of ARMED -> LEAVE (a removed priority)",
    "no_hysteresis": "detection hysteresis 0: FAR -> APPROACH and back are both enabled at d = d+",
    "no_release_phase": "OCCLU is reset straight to CLEAR without the release phase (Q8)",
    "late_occlu_release": "OCCLUDED -> RELEASE at d_occ >= D+ instead of D0 (threshold moved: release too late)",
    "release_band_d0": "d_end := max(d0, dL + d+ - d0) instead of max(d+, ...) (threshold moved in a latched distance)",
    "occlu_set_at_d0": "CLEAR -> OCCLUDED at d_occ <= D0 instead of D- (D- and D0 swapped)",
    "strict_occlu_set": "CLEAR -> OCCLUDED at d_occ < D- instead of <= D- (a strict inequality)",
    "unlatched_side": "the controllers read the bypass side measured at every sample, not the latched one",
    "drop_occlu_latch": "DL follows d_occ instead of being latched when OCCLU is reset",
    "no_leave_hysteresis": "LEAVE -> FAR at d >= d_end: the d+ + hysteresis floor dropped",
    "no_occlu_margin": "OCCLUDED -> RELEASE on d_bord = 0 without the margin d_occ >= (D- + D0)/2",
    "flipped_side": "FAR -> APPROACH latches side := -bypass side (the bypass side flipped)",
})
"""Planted defects: name -> one-line description."""


def resolved_variant(envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int) -> SupervisorVariant:
    """The automaton of :mod:`visnav.supervisor` as built, with the pan wrapped."""
    return SupervisorVariant(
        name=RESOLVED,
        description="the automaton of visnav.supervisor (docs/supervisor.md)",
        model=build_supervisor(envelopes, settings, n_obstacles),
    )


def build_variant(
    name: str, envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int
) -> SupervisorVariant:
    """The resolved automaton (``"resolved"``) or one of the :data:`MUTANTS`.

    The as-written paper logic is :func:`visnav.fuzzing.paper_logic.paper_variant`.

    Raises
    ------
    KeyError
        For an unknown name (the message lists the known ones).
    """
    if name == RESOLVED:
        return resolved_variant(envelopes, settings, n_obstacles)
    if name not in MUTANTS:
        raise KeyError(f"unknown supervisor variant {name!r}; known: {', '.join((RESOLVED, *MUTANTS))}")
    if name == "no_hysteresis":
        settings = dataclasses.replace(settings, detection_hysteresis_m=0.0)
    base = build_supervisor(envelopes, settings, n_obstacles)
    builders: dict[str, Callable[[SupervisorModel], SupervisorModel]] = {
        "drop_dl_latch": _drop_dl_latch,
        "reset_avoid_on_leave": _reset_avoid_on_leave,
        "equal_priority": _equal_priority,
        "no_release_phase": _no_release_phase,
        "late_occlu_release": _late_occlu_release,
        "release_band_d0": _release_band_d0,
        "occlu_set_at_d0": _occlu_set_at_d0,
        "strict_occlu_set": _strict_occlu_set,
        "unlatched_side": lambda m: rebuild(m, suffix="unlatched_side"),
        "drop_occlu_latch": _drop_occlu_latch,
        "no_leave_hysteresis": _no_leave_hysteresis,
        "no_occlu_margin": _no_occlu_margin,
        "flipped_side": _flipped_side,
    }
    model = builders[name](base) if name in builders else base
    return SupervisorVariant(
        name=name, description=MUTANTS[name], model=model, wrap_pan=name != "raw_pan",
        controller_view=_unlatched_side_view if name == "unlatched_side" else None,
    )

