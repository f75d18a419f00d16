"""The input route's unbounded-time case: ``always φ`` (no window) proven by cycle induction, re-checked.

A requirement ``always φ`` over ``[0, ∞)`` (a SpaceEx ``.cfg`` with a negative ``time-horizon``,
docs/spaceex.md) is out of reach of one flowpipe.  :class:`CycleInductionProof` proves it by the induction of
:mod:`analysis.reach.induction`: the cycle model of the input-free affine model at the initial location, a box ``W``
of the carried states found by :func:`analysis.reach.induction.find_invariant` (flowpipes of
:func:`analysis.reach.reach` with the model's bounded inputs), and the cycle requirement — ``φ`` everywhere, the
carried states in ``W`` at the next entry into the initial location — re-checked on the re-check's own sets by
:func:`analysis.reach.recheck.recheck_flowpipe`.  ``holds`` and ``rechecked`` only when the producer decided it, the
re-check passed, the initial box lies in ``W`` (exact) and the cycle bound is below the flowpipe's horizon (exact:
no run of a cycle is cut).  An automaton without such a cycle gets a proof that does not hold, naming why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from hybrid.spaceex_inputs import SpaceExInput
from hybrid.system import HybridSystem

from analysis.verify.verification import Proof

__all__ = ["CycleInductionProof", "InductionOutcome", "induction", "INDUCTION_ORDER", "INDUCTION_KAPPAS",
           "induction_proofs", "cycle_of", "RECHECK_MAX_FLOWPIPES"]

INDUCTION_ORDER = 100
"""Generators per dimension of the input sum (the engine's ``order``): at the default 20 the platoon's input sum,
boxed by Girard's reduction, loses the correlation of ``e``, ``v`` and ``a`` that the next location's flow reads
(PLAN01 at steps of 0.05 s, ``ȧ1`` over the set at t = 9.9 s: ±48 at order 20, ±19 at 100, ±14.8 at 200, the exact
±14.5; at the induction's 0.2 s steps, four times fewer generators, order 100 suffices)."""

INDUCTION_KAPPAS = (3.2, 0.8)
"""``‖A_aug‖∞ δ`` of the initial location's step and of the other locations' steps.  The cycle starts from ``W``
(far from the origin) in the initial location and contracts before it leaves it, so a long step's interpolation
bound (``F |X|``, proportional to ``|X|``) fades there; the next locations start on jump sets far from the origin,
where it does not fade before the jump back (measured on PLAN01: 0.2 s / 0.1 s leaves the entry 0.63 outside ``W``,
0.2 s / 0.05 s inside)."""

CYCLE_STEPS = 40
"""At least this many steps over the longest cycle in every location (a slow automaton's ``κ`` step would be coarse)."""

STORED_ORDER = 2
"""Order of the stored segments (memory: tens of thousands of flowpipes; the decisions read the box too)."""

RECHECK_MAX_FLOWPIPES = 2_000
"""A cycle flowpipe of more flowpipes is not re-checked (the proof then does not hold as proven): the re-check's
exact contraction of each entry zonotope (``deadlock.contract_zonotope``, rationals) costs about 0.6 s a call —
PLAN01's cycle, 23,167 flowpipes, would take days; 25 of its flowpipes took 137 s under cProfile (measured)."""

MAX_FLOWPIPES = 60_000
"""Flowpipes of one cycle (one per jump: every segment meeting a guard jumps on its own, ``jump_cluster = 1``:
the union of several segments' zonotopes loses the correlations again)."""


def _input_free(system: HybridSystem, input_flows: Mapping[str, Any], inputs: tuple[SpaceExInput, ...]
                ) -> tuple[HybridSystem, dict[str, Any]]:
    """The model with every input at 0 and ``{mode: ModeInput}`` (the model itself without inputs)."""
    from analysis.spaceex_reach import input_reach_model

    return input_reach_model(system, input_flows, inputs) if inputs else (system, {})


def cycle_of(model: Any, box: Mapping[str, tuple[float, float]], modes: list[str]) -> Any:
    """The :class:`~analysis.reach.induction.CycleModel` of a SpaceEx model at its one initial location (``None``
    when there is none: several initial locations, a model reachability cannot read, no bounded cycle)."""
    from hybrid.errors import ModelDefinitionError, ParameterError

    from analysis.reach.affine import AffineError
    from analysis.reach.induction import NoCycle, cycle_model
    from analysis.reach.model import affine_model

    if len(modes) != 1:
        return None
    try:
        zero, matrices = _input_free(model.system, model.input_flows, tuple(model.inputs))
        return cycle_model(affine_model(zero), modes[0], box, matrices)
    except (NoCycle, AffineError, ParameterError, ModelDefinitionError):
        return None


def induction_proofs(model: Any, parsed: Any, initial: Mapping[str, Any], initial_mode: Any
                     ) -> dict[str, "CycleInductionProof"]:
    """``{requirement: CycleInductionProof}`` for the requirements ``always[0, b] φ`` of the safety fragment (read as
    ``always φ`` for all time: the problem's unbounded property), with a single initial location."""
    from analysis.reach.fragment import NotInFragment, safety_fragment

    if not isinstance(initial_mode, str):
        return {}
    box = tuple((k, float(getattr(v, "low", v)), float(getattr(v, "high", v))) for k, v in initial.items())
    out = {}
    for p in parsed:
        try:
            fragment = safety_fragment(p.formula.tree, model.system.state_names, ("mode",))
        except NotInFragment:
            continue
        out[p.name] = CycleInductionProof(system=model.system, input_flows=dict(model.input_flows),
                                          inputs=tuple(model.inputs), body=fragment.body,
                                          text=f"the requirement {p.name!r}", initial=box,
                                          initial_mode=initial_mode)
    return out


def _steps(model: Any, horizon: float, home: str, bound: float) -> dict[str, float]:
    """The step per location: ``κ / ‖A_aug‖∞`` (:data:`INDUCTION_KAPPAS`), at most ``bound /`` :data:`CYCLE_STEPS`."""
    from analysis.reach.autostep import mode_norms

    out = {}
    for mode, norm in mode_norms(model).items():
        kappa = INDUCTION_KAPPAS[0] if mode == home else INDUCTION_KAPPAS[1]
        out[mode] = min(kappa / norm, bound / CYCLE_STEPS, horizon)
    return out


@dataclass(frozen=True, kw_only=True, slots=True)
class InductionOutcome:
    """What the induction computed: the cycle model, the search for ``W``, the re-check (``None``: not run), the
    flowpipe's horizon and steps, whether the initial box lies in ``W`` and whether the cycle bound is below the
    horizon (both exact)."""

    cycle: Any
    search: Any
    check: Any
    horizon: float
    steps: Mapping[str, float]
    start_in_w: bool
    uncut: bool

    @property
    def w(self) -> dict[str, tuple[float, float]]:
        """The last round's ``W`` (carried state -> ``(lo, hi)``)."""
        return {name: (lo, hi) for name, lo, hi in self.search.steps[-1].w}

    @property
    def proven(self) -> bool:
        """Closed by the producer, re-checked, the initial box in ``W``, no run cut."""
        return bool(self.search.holds and self.check is not None and self.check.passed and self.start_in_w
                    and self.uncut)


def induction(cycle: Any, matrices: Mapping[str, Any], body: Any, text: str,
              initial: Mapping[str, tuple[float, float]]) -> InductionOutcome:
    """The search for ``W`` on ``cycle`` (with the inputs ``matrices``) and the re-check of a closed round."""
    from analysis.reach import reach
    from analysis.reach.induction import ENTERED, HORIZON_PAD, find_invariant
    from analysis.reach.recheck import recheck_flowpipe
    from analysis.reach.verdict import MAX_SEGMENTS, decide

    horizon = float(cycle.bound) + HORIZON_PAD
    steps = _steps(cycle.model, horizon, cycle.home, float(cycle.bound))
    base = steps[cycle.home]
    others = {k: v for k, v in steps.items() if k != cycle.home}

    def flowpipe(box: Mapping[str, tuple[float, float]], end: float) -> Any:
        return reach(cycle.model, dict(box), horizon=end, time_step=base, initial_mode=cycle.home,
                     max_jumps=len(cycle.model.modes), inputs=dict(matrices), order=INDUCTION_ORDER,
                     stored_order=STORED_ORDER, max_segments=8 * MAX_SEGMENTS, max_flowpipes=MAX_FLOWPIPES,
                     mode_time_steps={**others, ENTERED: end}, jump_cluster=1)

    search = find_invariant(cycle, body, text, initial, flowpipe, lambda r, f, b: decide(r, f, cycle.model, b))
    check = None
    if search.holds and len(search.result.terminations) <= RECHECK_MAX_FLOWPIPES:
        check = recheck_flowpipe(search.result.to_json(), cycle.model, search.initial, search.fragment,
                                 initial_mode=cycle.home, inputs=dict(matrices))
    w = {name: (lo, hi) for name, lo, hi in search.steps[-1].w}
    start_in_w = all(Fraction(lo) <= Fraction(initial[k][0]) and Fraction(initial[k][1]) <= Fraction(hi)
                     for k, (lo, hi) in w.items())
    return InductionOutcome(cycle=cycle, search=search, check=check, horizon=horizon,
                            steps={k: v for k, v in steps.items() if k != ENTERED}, start_in_w=start_in_w,
                            uncut=cycle.bound < Fraction(horizon))


def _evidence(outcome: InductionOutcome) -> str:
    """The proof's evidence in words (deterministic: no timings)."""
    cycle, search, check = outcome.cycle, outcome.search, outcome.check
    last = search.steps[-1]
    pipes = len(search.result.terminations)
    if check is None and search.holds:
        again = (f"NOT re-checked: the cycle's flowpipe has {pipes} flowpipes, above the re-check's limit "
                 f"{RECHECK_MAX_FLOWPIPES} (its exact contraction of every entry set would take far too long)")
    elif check is None:
        again = "not re-checked (the producer did not close the induction: nothing to re-check)"
    elif check.passed:
        again = (f"re-checked from the saved flowpipe with the inputs ({check.segments} segments, {check.jumps} "
                 f"jumps), exact margin {check.margin}")
    else:
        again = f"re-check FAILED ({check.failure})"
    rounds = "; ".join(f"round {i + 1}: {'closed' if s.holds else 'open'}, {s.segments} segments, "
                       f"{s.flowpipes} flowpipes" for i, s in enumerate(search.steps))
    return (f"cycle induction at {cycle.home!r} (every transition into it, {', '.join(cycle.redirected)}, sets "
            f"{', '.join(cycle.model.state_names[k] for k, _ in cycle.reset)}; longest cycle "
            f"{float(cycle.bound):g} s, flowpipe horizon {outcome.horizon:g} s): W = "
            + ", ".join(f"{k} in [{lo:.6g}, {hi:.6g}]" for k, (lo, hi) in outcome.w.items())
            + f"; {last.reason}" + (f", margin {last.margin:.6g}" if math.isfinite(last.margin) else "")
            + f"; {rounds}; steps " + ", ".join(f"{v:.4g} s at {k!r}" for k, v in sorted(outcome.steps.items()))
            + f"; {again}; the initial box {'lies' if outcome.start_in_w else 'does NOT lie'} in W")


@dataclass(frozen=True, kw_only=True, slots=True)
class CycleInductionProof:
    """``() -> Proof`` of ``always φ`` for all time by cycle induction (see the module)."""

    system: HybridSystem
    input_flows: Mapping[str, Any]
    inputs: tuple[SpaceExInput, ...]
    body: Any
    text: str
    initial: tuple[tuple[str, float, float], ...]
    initial_mode: str

    def run(self) -> InductionOutcome:
        """The induction (raises :class:`~analysis.reach.induction.NoCycle` when it does not apply, and what reading
        the model as an affine automaton raises)."""
        from analysis.reach.induction import cycle_model
        from analysis.reach.model import affine_model

        initial = {k: (lo, hi) for k, lo, hi in self.initial}
        zero, matrices = _input_free(self.system, self.input_flows, self.inputs)
        cycle = cycle_model(affine_model(zero), self.initial_mode, initial, matrices)
        return induction(cycle, matrices, self.body, self.text, initial)

    def __call__(self) -> Proof:
        """The proof (never raises: what the induction cannot handle gives a proof that does not hold)."""
        from hybrid.errors import ModelDefinitionError, ParameterError

        from analysis.reach.affine import AffineError
        from analysis.reach.induction import NoCycle

        method = ("cycle induction for all t >= 0, a box W of the carried states closed by one cycle's flowpipe"
                  + (" with bounded non-deterministic inputs" if self.inputs else "") + ", re-checked")
        bounds = ", ".join(f"{i.name} in [{i.low:g}, {i.high:g}]" for i in self.inputs)
        assumptions = (f"the initial box {dict((k, (lo, hi)) for k, lo, hi in self.initial)}",
                       *((f"the inputs {bounds} (any measurable signal)",) if self.inputs else ()),
                       "all time t >= 0 (unbounded)")
        relaxed = relaxed_proof(self.system, self.input_flows, self.inputs, self.initial_mode,
                                {k: (lo, hi) for k, lo, hi in self.initial}, self.body, self.text,
                                assumptions=assumptions)
        if isinstance(relaxed, Proof):
            return relaxed
        try:
            outcome = self.run()
        except NoCycle as exc:
            return Proof(holds=False, method=method, evidence=f"not decided for all time: {exc}", rechecked=False,
                         assumptions=assumptions)
        except (AffineError, ParameterError, ModelDefinitionError) as exc:
            return Proof(holds=False, method=method, evidence=f"not decided by reachability: {exc}",
                         rechecked=False, assumptions=assumptions)
        last = outcome.search.steps[-1]
        holds = outcome.search.holds and outcome.start_in_w and outcome.uncut
        return Proof(holds=holds, method=method, evidence=_evidence(outcome) + f"; {relaxed}", rechecked=outcome.proven,
                     assumptions=assumptions, margin=last.margin if holds and math.isfinite(last.margin) else None)


RELAXED_METHOD = ("induction over the arbitrary-switching relaxation for all t >= 0 (the clocks projected out, a box W "
                  "the relaxation maps into itself), re-checked")


def relaxed_proof(system: HybridSystem, input_flows: Mapping[str, Any], inputs: tuple[SpaceExInput, ...],
                  initial_mode: str, initial: Mapping[str, tuple[float, float]], body: Any, text: str, *,
                  assumptions: tuple[str, ...]) -> Proof | str:
    """The relaxation's induction (:mod:`analysis.reach.relaxed_induction`) when it holds, re-checked: the
    projection by :func:`analysis.reach.recheck_projection.recheck_projection`, each of the four decisions by
    :func:`analysis.reach.recheck_relaxed.recheck_relaxed` on its own sets.  A :class:`Proof` when the producer's
    decisions all hold (``rechecked`` only when every re-check passed), else the reason in words (for the evidence
    of the cycle induction that runs then)."""
    from hybrid.errors import ModelDefinitionError, ParameterError

    from analysis.reach.affine import AffineError
    from analysis.reach.model import affine_model
    from analysis.reach.recheck_projection import recheck_projection
    from analysis.reach.recheck_relaxed import recheck_relaxed
    from analysis.reach.relaxed import NoGroup
    from analysis.reach.relaxed_induction import relaxed_induction

    try:
        zero, matrices = _input_free(system, input_flows, inputs)
        found = relaxed_induction(affine_model(zero), matrices, initial_mode, initial, body, text)
    except NoGroup as exc:
        return f"the relaxation's induction does not apply: {exc}"
    except (AffineError, ParameterError, ModelDefinitionError) as exc:
        return f"the relaxation's induction cannot read the model: {exc}"
    if not found.holds:
        return f"the relaxation's induction does not hold: {found.reason}"
    cf = found.projection
    failure = recheck_projection(zero, cf.model, cf.kept, matrices, cf.inputs)
    margins = []
    for result, box, fragment, _, _, _ in found.checks:
        if failure:
            break
        saved = {"time_step": result.time_step, "schedule": dict(result.schedule)}
        check = recheck_relaxed(saved, cf.model, box, fragment, initial_mode=initial_mode, inputs=cf.inputs)
        failure = "" if check.passed else f"{fragment.text}: {check.failure}"
        margins.append(check.margin)
    again = (f"re-check FAILED ({failure})" if failure else
             f"re-checked: the projection exactly, the four decisions on the re-check's own sets of the relaxation "
             f"(exact margins {', '.join(str(m) for m in margins)})")
    evidence = (f"the clocks {', '.join(cf.clocks)} projected out (no flow, reset or requirement of the other states "
                f"reads them; every transition keeps those): every run solves the relaxation "
                f"ẋ ∈ conv{{A_i x + c_i}} + B U; W = " + ", ".join(f"{k} in [{lo:.6g}, {hi:.6g}]"
                                                                  for k, (lo, hi) in found.w.items())
                + f"; P = {found.probe:g} s, T = {found.period:.6g} s, step {found.time_step:.4g} s: from the initial "
                f"box safe over [0, P + T] and in W at P, from W safe over [T, 2T] and back in W at T (so x(P + kT) "
                f"in W for every k and every later state in the flowpipe from W over [T, 2T]), margin "
                f"{found.margin:.6g}; {again}")
    return Proof(holds=True, method=RELAXED_METHOD, evidence=evidence, rechecked=not failure,
                 assumptions=assumptions + ("any switching of the locations (the relaxation covers every timing)",),
                 margin=found.margin)
