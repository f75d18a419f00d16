"""Reachability for SpaceEx models with non-deterministic inputs (the ``ModeInput`` route).

A SpaceEx input ``u(t) ∈ [low, high]`` (:mod:`hybrid.spaceex_inputs`) enters the flow of every
location affinely: ``ẋ = A x + c + B u``.  :func:`input_reach` reads ``B`` exactly from the flows
(the input's placeholder taken as a coordinate: :func:`analysis.reach.affine.affine_vector`), builds
the input-free system (``u = 0``) and runs :func:`analysis.reach.reach` with
``inputs={mode: ModeInput(matrix=B, bounds=(low, high))}``.  :class:`InputReachProof` decides a
requirement of the STL safety fragment on that flowpipe (:func:`analysis.reach.verdict.decide`).

A decision that holds is re-checked from the saved flowpipe (whose JSON carries ``B`` and ``U``) by
:func:`analysis.reach.recheck.recheck_flowpipe` with the model's inputs
(its own sets with the input bounds of :mod:`analysis.reach.recheck_inputs`, outward-rounded intervals and exact
rationals: :mod:`analysis.reach.recheck_own`); only a passed re-check gives ``rechecked=True`` and so ``proven``.

Without a step (``time_step=None``) the steps are chosen from the dynamics as for a model without inputs
(:func:`analysis.reach.autostep.auto_choices`: ``‖A_aug‖∞ δ <= κ`` for ``κ`` in
:data:`analysis.reach.autostep.AUTO_INPUT_STEPS`, 3.9, 0.4 and 0.1, then with ``jump_cluster``), one choice after
the other until one is proven and re-checked; with a step, only the fast modes get one (``κ = 3.9``).  The input's
centre ``B u_c`` joins the constant column, scaled to at most 1 (so the ``+ 1`` of the bound covers it); the input's
spread is enclosed through sub-steps (:mod:`analysis.reach.input_step`), no longer up to ``e^κ`` times its reach set
per step; the finer choices of ``AUTO_INPUT_STEPS`` are kept.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from hybrid.spaceex_inputs import SpaceExInput, with_inputs
from hybrid.symbolic import Coordinate, flow_map, substitute
from hybrid.system import HybridSystem

from analysis.verify.verification import Proof

__all__ = ["input_reach_model", "InputReachProof", "NOT_RECHECKED", "input_proofs", "MAX_FLOWPIPES", "input_flowpipe"]

MAX_FLOWPIPES = 16
"""Flowpipes of one input proof (one per jump set): arbitrary switching that is not a group of
:func:`analysis.reach.relaxed.switching_group` (those take the relaxed route, :mod:`analysis.spaceex_relaxed`) would
otherwise start one per segment up to the jump bound; beyond, the flowpipe is inconclusive and proves nothing."""

NOT_RECHECKED = "not re-checked (the producer did not decide it: nothing to re-check)"
"""The evidence's tail when the producer's decision does not hold (nothing to re-check)."""


def input_reach_model(system: HybridSystem, input_flows: Mapping[str, Any],
                      inputs: Sequence[SpaceExInput]) -> tuple[HybridSystem, dict[str, Any]]:
    """The input-free affine system and ``{mode: ModeInput}`` of a model with inputs.

    Raises
    ------
    analysis.reach.affine.AffineError
        A flow that is not affine in the state and the inputs (a product of an input and a state), or an
        input coefficient that is not a double (``B`` is passed in floats; it must be exact).
    """
    from analysis.reach import ModeInput
    from analysis.reach.affine import AffineError, affine_vector

    names = (*system.state_names, *(i.name for i in inputs))
    as_coordinates = {i.symbol: Coordinate(i.name, len(system.state_names) + k) for k, i in enumerate(inputs)}
    matrices: dict[str, Any] = {}
    n = len(system.state_names)
    for mode, flow in input_flows.items():
        forms = affine_vector(flow_map(*(substitute(c, params=as_coordinates) for c in flow.components)), names,
                              role=f"flow of location {mode!r} (states and inputs)")
        rows = [[f.coefficients[n + k] for k in range(len(inputs))] for f in forms]
        if any(Fraction(float(q)) != q for row in rows for q in row):
            raise AffineError(f"flow of location {mode!r}: an input coefficient is not a double",
                              "write the input's coefficients as single numbers")
        matrices[mode] = ModeInput(matrix=[[float(q) for q in row] for row in rows],
                                   bounds=([i.low for i in inputs], [i.high for i in inputs]))
    zero = with_inputs(system, input_flows, inputs, {i.name: 0.0 for i in inputs})
    return zero, matrices


def input_flowpipe(system: Any, matrices: Mapping[str, Any], initial: Mapping[str, tuple[float, float]], *,
                   horizon: float, time_step: float, initial_mode: str, max_jumps: int, options: Mapping[str, Any],
                   progress: Any = None) -> Any:
    """The flowpipe of an input-free model with its bounded inputs: the one engine call of the input route.

    Parameters
    ----------
    system : HybridSystem or AffineHybridModel
        The model with every input at 0 (:func:`input_reach_model`).
    matrices : mapping {mode: ModeInput}
        ``B`` and the input box per mode (:func:`input_reach_model`).
    initial : mapping {state: (lo, hi)}
        The initial box over the model's states.
    horizon, time_step : float
        [s], ``0 < time_step <= horizon``.
    initial_mode : str
    max_jumps : int
    options : mapping
        Further engine options (``mode_time_steps``, ``jump_cluster``, ``merge_segments``).
    progress : callable or None
        ``progress(t)`` with the time reached [s].

    Returns
    -------
    analysis.reach.result.ReachResult
        At most :data:`MAX_FLOWPIPES` flowpipes and ``analysis.reach.verdict.MAX_SEGMENTS`` segments.
    """
    from analysis.reach import reach
    from analysis.reach.verdict import MAX_SEGMENTS

    return reach(system, dict(initial), horizon=horizon, time_step=time_step, initial_mode=initial_mode,
                 max_jumps=max_jumps, inputs=dict(matrices), max_segments=MAX_SEGMENTS, max_flowpipes=MAX_FLOWPIPES,
                 progress=progress, **dict(options))


@dataclass(frozen=True, kw_only=True, slots=True)
class InputReachProof:
    """``() -> Proof`` of one requirement by a flowpipe with the model's inputs, re-checked with them (see module)."""

    system: HybridSystem
    input_flows: Mapping[str, Any]
    inputs: tuple[SpaceExInput, ...]
    fragment: Any
    initial: tuple[tuple[str, float, float], ...]
    initial_mode: str
    time_step: float | None = None
    max_jumps: int | None = None

    def __call__(self) -> Proof:
        """The proof (never raises: what reachability cannot handle gives a proof that does not hold)."""
        from hybrid.errors import ModelDefinitionError, ParameterError

        from analysis.reach.affine import AffineError
        from analysis.reach.model import affine_model
        from analysis.reach.recheck import recheck_flowpipe
        from analysis.reach.autostep import AUTO_INPUT_STEPS, auto_choices, chosen_text
        from analysis.reach.verdict import MAX_SEGMENTS, METHOD, decide, default_max_jumps, default_time_step
        from analysis.spaceex_relaxed import relaxed_outcome

        method = METHOD.replace(", re-checked", " with bounded non-deterministic inputs, re-checked")
        end = max(self.fragment.end, 1e-9)
        step = min(default_time_step(end) if self.time_step is None else self.time_step, end)
        jumps = default_max_jumps(end) if self.max_jumps is None else self.max_jumps
        initial = {k: (lo, hi) for k, lo, hi in self.initial}
        bounds = ", ".join(f"{i.name} in [{i.low:g}, {i.high:g}]" for i in self.inputs)
        assumptions = (f"the initial box {dict((k, (lo, hi)) for k, lo, hi in self.initial)}",
                       f"the inputs {bounds} (any measurable signal)",
                       f"the window [{self.fragment.start:g}, {self.fragment.end:g}] s")
        try:
            zero, matrices = input_reach_model(self.system, self.input_flows, self.inputs)
            note = relaxed_outcome(zero, matrices, initial, self.fragment, self.initial_mode, step, method=method,
                                   bounds=bounds, assumptions=assumptions)  # arbitrary switching (PLAA01)
            if isinstance(note, Proof):
                return note
            kappas = AUTO_INPUT_STEPS if self.time_step is None else AUTO_INPUT_STEPS[:1]
            choices = auto_choices(affine_model(zero), end, step, {}, kappas, MAX_SEGMENTS) or [(None, {})]
            for kappa, options in choices:
                result = input_flowpipe(zero, matrices, initial, horizon=end, time_step=step,
                                        initial_mode=self.initial_mode, max_jumps=jumps, options=options)
                holds, margin, reason = decide(result, self.fragment, affine_model(zero), initial)
                check = recheck_flowpipe(result.to_json(), zero, initial, self.fragment,
                                         initial_mode=self.initial_mode, inputs=matrices) if holds else None
                if check is not None and check.passed:
                    break
        except (AffineError, ParameterError, ModelDefinitionError) as exc:
            return Proof(holds=False, method=method, evidence=f"not decided by reachability: {exc}", rechecked=False)
        reason += chosen_text(kappa, options)
        if check is None:
            again = NOT_RECHECKED
        elif check.passed:
            again = (f"re-checked from the saved flowpipe with the inputs ({check.segments} segments, {check.jumps} "
                     f"jumps), exact margin {check.margin}")
        else:
            again = f"re-check FAILED ({check.failure})"
        evidence = (f"reachability with inputs {bounds}: {reason}"
                    + (f", margin {margin:.6g}" if math.isfinite(margin) else "")
                    + f"; {len(result.segments)} segments, {len(result.jumps)} jumps, step {step:g} s; "
                    + again + note)  # no timing: the verdict JSON quoting it is byte-deterministic
        return Proof(holds=holds, method=method, evidence=evidence, rechecked=check is not None and check.passed,
                     assumptions=assumptions, margin=margin if math.isfinite(margin) else None)


def input_proofs(system: HybridSystem, input_flows: Mapping[str, Any], inputs: Sequence[SpaceExInput],
                 parsed: Sequence[Any], initial: Mapping[str, Any], initial_mode: Any, *,
                 time_step: float | None = None, max_jumps: int | None = None) -> dict[str, InputReachProof]:
    """``{requirement: InputReachProof}`` for the requirements in the safety fragment (a single initial mode), with
    the user's step and jump bound (``None``: steps chosen from the dynamics, the default jump bound)."""
    from analysis.reach.fragment import NotInFragment, safety_fragment

    if not isinstance(initial_mode, str):
        return {}
    box = tuple((k, float(getattr(v, "low", v)), float(getattr(v, "high", v))) for k, v in initial.items())
    out = {}
    for p in parsed:
        try:
            fragment = safety_fragment(p.formula.tree, system.state_names, ("mode",))
        except NotInFragment:
            continue
        out[p.name] = InputReachProof(system=system, input_flows=dict(input_flows), inputs=tuple(inputs),
                                      fragment=fragment, initial=box, initial_mode=initial_mode,
                                      time_step=time_step, max_jumps=max_jumps)
    return out

