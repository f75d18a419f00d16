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
mutant                        defect (the open question of NOTES.md it answers the other way)
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

Examples
--------
>>> from visnav.parameters import Envelopes, SupervisorSettings
>>> variant = build_variant("equal_priority", Envelopes(), SupervisorSettings(), 1)
>>> [(t.name, t.priority) for t in variant.model.automaton.outgoing("ARMED|CLEAR") if t.name.startswith("ARMED->")]
[('ARMED->LEAVE@CLEAR', 10), ('ARMED->PASSED@CLEAR', 10)]
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

from hybrid import HybridAutomaton, Mode, Transition

from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import (
    I_FIRST_OBSTACLE,
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
    """

    name: str
    description: str
    model: SupervisorModel
    wrap_pan: bool = True
    latches_obstacle: bool = True


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


MUTANTS: Mapping[str, str] = MappingProxyType({
    "drop_dl_latch": "dL follows d_coll instead of being latched when LEAVE is set (Q5)",
    "reset_avoid_on_leave": "AVOID is reset when LEAVE is set; case 2 of (2) applies again in [d-, d0] (Q1)",
    "raw_pan": "the guards read the raw pan angle instead of the angle wrapped to (-pi, pi] (Q6)",
    "equal_priority": "ARMED -> PASSED has the priority of ARMED -> LEAVE (a removed priority)",
    "no_hysteresis": "detection hysteresis 0: FAR -> APPROACH and back are both enabled at d = d+",
    "no_release_phase": "OCCLU is reset straight to CLEAR without the release phase (Q8)",
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
    }
    model = builders[name](base) if name in builders else base
    return SupervisorVariant(name=name, description=MUTANTS[name], model=model, wrap_pan=name != "raw_pan")

