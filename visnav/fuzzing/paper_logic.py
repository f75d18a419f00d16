"""The paper's flag logic as written: a literal transcription of (2), (3) and section V.A.

Two things live here:

* :func:`mu_coll_cases` and :func:`mu_occ_cases`: the printed cases of (2)
  and (3), each returning *every* case whose condition holds with its value.
  Where one case holds, or all holding cases agree, the paper is
  unambiguous; the fuzzer's ``differential`` property compares the explicit
  automaton with them exactly there.
* :func:`paper_variant`: the as-written flag logic as a hybrid automaton,
  fuzzed with the same properties as the resolved automaton of
  :mod:`visnav.supervisor` (``visnav fuzz --variant paper``; the findings
  are in ``docs/fuzzing.md``).

To execute the text some readings are unavoidable; each is the most literal
one (:data:`READINGS`).  The open questions of docs/supervisor.md are left as the
paper leaves them: AVOID and LEAVE are never reset, the cases are evaluated
in printed order, nothing arms the "ϑ = 0" test, and there is no release
phase.

Examples
--------
>>> from visnav.parameters import Envelopes
>>> env = Envelopes()
>>> mu_coll_cases(0.7, avoid=0, leave=0, d_leave=float("inf"), envelopes=env)  # case 1 only
((1, 0.0),)
>>> mu_occ_cases(65.0, 100.0, occlu=0, D_leave=60.0, envelopes=env)  # cases 1 and 3 overlap (Q8)
((1, 0.0), (3, 0.75))
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hybrid import HybridAutomaton, MemoryVariable, Mode, Transition

from visnav.fuzzing.mutants import SupervisorVariant
from visnav.parameters import Envelopes, SupervisorSettings
from visnav.supervisor import (
    I_D_BORD,
    I_D_NEAREST,
    I_D_OCC,
    I_PAN,
    SIGNALS,
    SupervisorModel,
    mode_name,
    split_mode,
)

__all__ = [
    "PAPER",
    "READINGS",
    "COLLISION_PHASES",
    "OCCLUSION_PHASES",
    "mu_coll_cases",
    "mu_occ_cases",
    "PaperModel",
    "build_paper_supervisor",
    "paper_variant",
]

PAPER = "paper"
"""Variant name of the as-written logic."""

READINGS = (
    "d_coll is the distance to the closest obstacle, read at every sample (no latch, no hysteresis)",
    "AVOID is set when d_coll <= d- ('enters the zone surrounded by xi-') and never reset (not stated)",
    "'theta = 0' on sampled data: the raw pan angle is 0 at a sample or changes sign between two samples "
    "(no wrapping, no arming)",
    "LEAVE is set at that sample if mu_occ = 0; otherwise it is 'maintained to 0 until there is no more "
    "occlusion risk' and set as soon as mu_occ = 0; it is never reset (not stated)",
    "dL is latched when LEAVE is set (the other reading, dL = d_coll at every sample, makes case 3 of (2) "
    "identically 1: mutant drop_dl_latch)",
    "OCCLU is set when d_occ <= D- and reset when d_bord = 0 or d_occ >= D0 (the condition of case 3 of (3)); "
    "DL := d_occ when it is reset",
    "dL and DL are +inf until first latched (case 3 cannot hold before)",
    "the cases of (2) and (3) are evaluated in printed order, the first that holds wins",
)
"""The readings needed to execute the printed text (``docs/fuzzing.md``)."""

COLLISION_PHASES = ("FREE", "AVOID", "HELD", "LEAVE")
"""``FREE`` (AVOID = LEAVE = 0), ``AVOID``, ``HELD`` (ϑ = 0 seen while µ_occ > 0, LEAVE held at 0), ``LEAVE``."""
OCCLUSION_PHASES = ("CLEAR", "OCCLUDED")

_FLAGS = {"FREE": (0, 0), "AVOID": (1, 0), "HELD": (1, 0), "LEAVE": (1, 1)}


def mu_coll_cases(
    d: float, *, avoid: int, leave: int, d_leave: float, envelopes: Envelopes
) -> tuple[tuple[int, float], ...]:
    """Every case of the printed (2) that holds, with its value, in printed order.

    Parameters
    ----------
    d : float
        d_coll [m].
    avoid, leave : int
        The flags AVOID and LEAVE.
    d_leave : float
        dL [m] (``inf`` if never latched).
    envelopes : Envelopes

    Returns
    -------
    tuple of (case, value)
        Cases 1–3 whose condition holds; ``((4, 1.0),)`` ("otherwise") if none.
        Case 3 needs ``dL < d+`` (its formula divides by ``dL − d+``).
    """
    d_minus, d_zero, d_plus = envelopes.d_minus_m, envelopes.d_zero_m, envelopes.d_plus_m
    cases: list[tuple[int, float]] = []
    if d > d_zero and not avoid and not leave:
        cases.append((1, 0.0))
    if d_minus <= d <= d_zero and not avoid:
        cases.append((2, (d - d_zero) / (d_minus - d_zero)))
    if leave and d_leave < d_plus and d_leave <= d <= d_plus:
        cases.append((3, (d - d_plus) / (d_leave - d_plus)))
    return tuple(cases) or ((4, 1.0),)


def _first_mu_occ(envelopes: Envelopes, occlusion_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
    cases = mu_occ_cases(
        v[I_D_OCC], v[I_D_BORD], occlu=int(occlusion_phase == "OCCLUDED"), D_leave=memory["DL"], envelopes=envelopes
    )
    return cases[0][1]


def mu_occ_cases(
    d_occ: float, d_bord: float, *, occlu: int, D_leave: float, envelopes: Envelopes
) -> tuple[tuple[int, float], ...]:
    """Every case of the printed (3) that holds, with its value, in printed order.

    Case 3 reads "d_occ ∈ [DL, D+] and (d_bord = 0 or d_occ ≥ D0)" and does not
    mention OCCLU; it needs ``DL < D+``.  Returns ``((4, 1.0),)`` if no case 1–3 holds.
    """
    D_minus, D_zero, D_plus = envelopes.D_minus_px, envelopes.D_zero_px, envelopes.D_plus_px
    cases: list[tuple[int, float]] = []
    if d_occ > D_zero and not occlu:
        cases.append((1, 0.0))
    if D_minus <= d_occ <= D_zero and not occlu:
        cases.append((2, (d_occ - D_zero) / (D_minus - D_zero)))
    if D_leave < D_plus and D_leave <= d_occ <= D_plus and (d_bord == 0.0 or d_occ >= D_zero):
        cases.append((3, (d_occ - D_plus) / (D_leave - D_plus)))
    return tuple(cases) or ((4, 1.0),)


@dataclass(frozen=True, kw_only=True, slots=True)
class PaperModel(SupervisorModel):
    """Risk outputs of the as-written logic: the first printed case that holds.

    Modes are ``collision|occlusion`` with collision phases
    :data:`COLLISION_PHASES` and occlusion phases :data:`OCCLUSION_PHASES`;
    the memory holds ``dL`` and ``DL``.
    """

    def mu_coll(self, collision_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        """First case of (2) that holds, with d_coll = the nearest obstacle's distance."""
        avoid, leave = _FLAGS[collision_phase]
        cases = mu_coll_cases(v[I_D_NEAREST], avoid=avoid, leave=leave, d_leave=memory["dL"], envelopes=self.envelopes)
        return cases[0][1]

    def mu_occ(self, occlusion_phase: str, v: Sequence[float], memory: Mapping[str, float]) -> float:
        """First case of (3) that holds."""
        return _first_mu_occ(self.envelopes, occlusion_phase, v, memory)

    def flags(self, mode: str) -> dict[str, int]:
        """AVOID, LEAVE, OCCLU of a mode."""
        collision, occlusion = split_mode(mode)
        avoid, leave = _FLAGS[collision]
        return {"AVOID": avoid, "LEAVE": leave, "OCCLU": int(occlusion == "OCCLUDED")}


def build_paper_supervisor(envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int) -> PaperModel:
    """The as-written flag logic as a product automaton over the supervisor's signals.

    Parameters
    ----------
    envelopes : Envelopes
    settings : SupervisorSettings
        Kept on the model (the as-written logic has no arming angle and no hysteresis).
    n_obstacles : int
        The signals carry one distance per obstacle (as :func:`visnav.supervisor.build_supervisor`).
    """
    env = envelopes
    d_minus, D_minus, D_zero = env.d_minus_m, env.D_minus_px, env.D_zero_px

    def mu_occ_zero(occlusion: str):
        def guard(v: Sequence[float], m: Mapping[str, float]) -> float:
            return -_first_mu_occ(env, occlusion, v, m)

        return guard

    def latch_dl(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"dL": float(v[I_D_NEAREST])}

    def latch_DL(v: Sequence[float], m: Mapping[str, float]) -> dict[str, float]:
        return {"DL": float(v[I_D_OCC])}

    transitions: list[Transition] = []
    reads = ("d_nearest_m", "pan_wrapped_rad", "d_occ_px", "d_bord_px")
    for occlusion in OCCLUSION_PHASES:
        def add(name: str, src: str, dst: str, guard, text: str, priority: int, direction: int = 0,
                reset=None, writes: tuple[str, ...] = (), reset_text: str = "") -> None:
            transitions.append(Transition(
                name=f"{name}@{occlusion}", source=mode_name(src, occlusion), target=mode_name(dst, occlusion),
                guard=guard, guard_text=text, priority=priority, direction=direction, reset=reset, writes=writes,
                reset_text=reset_text, reads=reads,
            ))

        add("FREE->AVOID", "FREE", "AVOID", lambda v, m: d_minus - v[I_D_NEAREST], "d_coll <= d-", 10)
        add("AVOID->HELD:up", "AVOID", "HELD", lambda v, m: v[I_PAN], "pan crosses 0 upwards", 10, direction=1)
        add("AVOID->HELD:down", "AVOID", "HELD", lambda v, m: -v[I_PAN], "pan crosses 0 downwards", 11, direction=1)
        add("AVOID->HELD:zero", "AVOID", "HELD", lambda v, m: -abs(v[I_PAN]), "pan = 0", 12)
        add("HELD->LEAVE", "HELD", "LEAVE", mu_occ_zero(occlusion), "mu_occ = 0", 10,
            reset=latch_dl, writes=("dL",), reset_text="dL := d_coll")
    for collision in COLLISION_PHASES:
        transitions.append(Transition(
            name=f"{collision}@CLEAR->OCCLUDED", source=mode_name(collision, "CLEAR"),
            target=mode_name(collision, "OCCLUDED"), guard=lambda v, m: D_minus - v[I_D_OCC],
            guard_text="d_occ <= D-", priority=0, reads=("d_occ_px",),
        ))
        transitions.append(Transition(
            name=f"{collision}@OCCLUDED->CLEAR", source=mode_name(collision, "OCCLUDED"),
            target=mode_name(collision, "CLEAR"), guard=lambda v, m: max(-v[I_D_BORD], v[I_D_OCC] - D_zero),
            guard_text="d_bord = 0 or d_occ >= D0", priority=0, reset=latch_DL, writes=("DL",),
            reset_text="DL := d_occ", reads=("d_occ_px", "d_bord_px"),
        ))
    modes = []
    for collision in COLLISION_PHASES:
        for occlusion in OCCLUSION_PHASES:
            avoid, leave = _FLAGS[collision]
            modes.append(Mode(
                name=mode_name(collision, occlusion),
                description=f"as written: AVOID={avoid} LEAVE={leave} OCCLU={int(occlusion == 'OCCLUDED')}",
                labels={"collision": collision, "occlusion": occlusion, "AVOID": avoid, "LEAVE": leave,
                        "OCCLU": int(occlusion == "OCCLUDED")},
            ))
    automaton = HybridAutomaton(
        name="folio-cadenat-as-written",
        modes=tuple(modes),
        transitions=tuple(transitions),
        variables=_variables(n_obstacles),
        memory=(
            MemoryVariable(name="dL", initial=math.inf, description="d_coll when LEAVE was set [m]"),
            MemoryVariable(name="DL", initial=math.inf, description="d_occ when OCCLU was reset [px]"),
        ),
        initial_mode=mode_name("FREE", "CLEAR"),
        description="the flag logic of Folio & Cadenat as printed (visnav.fuzzing.paper_logic.READINGS)",
    )
    return PaperModel(automaton=automaton, envelopes=env, settings=settings, n_obstacles=n_obstacles)


def _variables(n_obstacles: int) -> tuple[str, ...]:
    return SIGNALS + tuple(f"d_coll_{i}_m" for i in range(n_obstacles))


def paper_variant(envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int) -> SupervisorVariant:
    """The as-written logic as a :class:`~visnav.fuzzing.mutants.SupervisorVariant` (raw ϑ, no obstacle latch)."""
    return SupervisorVariant(
        name=PAPER,
        description="the flag logic as printed in the paper (visnav.fuzzing.paper_logic.READINGS)",
        model=build_paper_supervisor(envelopes, settings, n_obstacles),
        wrap_pan=False,
        latches_obstacle=False,
    )
