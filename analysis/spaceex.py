"""A verification problem from a SpaceEx model and its configuration (``visnav verify FILE.xml --config FILE.cfg``).

The model is imported by :mod:`hybrid.spaceex_import`, the configuration by
:mod:`hybrid.spaceex_config`: the initial set becomes the problem's box (a
fixed value where the set is a point, a :class:`~analysis.verify.verification.Parameter`
named ``<state>0`` where it is a range), ``loc(...) == name`` the initial mode,
``time-horizon`` the horizon and the forbidden set the requirement
``safe: always[0, T] not (forbidden)``.  docs/spaceex.md describes the
mapping and what it leaves out.

A model with non-deterministic inputs (:mod:`hybrid.spaceex_inputs`) is simulated with each input a
piecewise-constant signal of :data:`INPUT_POINTS` values over the horizon, each value a problem
parameter ``input_<name>_<k>`` in the input's bounds (so falsification searches the signal), and
reachability takes the input as a bounded non-deterministic input (:mod:`analysis.spaceex_reach`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from hybrid.spaceex_config import forbidden_formula, initial_box, parse_config
from hybrid.spaceex_import import SpaceExModel, load_spaceex, read_bytes
from hybrid.spaceex_inputs import SpaceExInput, input_signal, with_inputs
from hybrid.spaceex_syntax import SpaceExError
from hybrid.system import HybridSystem

from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter, VerificationProblem

__all__ = ["spaceex_problem", "split_spaceex_spec", "is_spaceex_spec", "InitialLocation", "LOCATION_PARAMETER",
           "TRACE_SAMPLES", "INPUT_POINTS", "InputSignals", "input_parameters", "SAMPLED_CYCLES", "SAMPLED_HORIZON", "config_unbounded"]

SAMPLED_CYCLES = 3
"""An unbounded property (``time-horizon = -1``) is simulated and falsified over this many longest cycles
(:func:`analysis.reach.induction.cycle_model`; PLAN01: 3 × 40 s), unless ``sampled_horizon`` is given."""

SAMPLED_HORIZON = 100.0
"""The sampled horizon [s] of an unbounded property whose automaton has no bounded cycle (no induction either)."""

UNBOUNDED_NOTE = ("time-horizon < 0: the property is for all t >= 0; the simulations and falsification cover "
                  "[0, {horizon:g}] s only (sampled_horizon), reachability decides it for all time by cycle induction "
                  "only (a bounded flowpipe proves nothing here)")

INPUT_POINTS = 10
"""Values of each input's piecewise-constant signal over the horizon (one problem parameter each).

Ten pieces of a tenth of the horizon: enough to switch the input between its bounds a few times within
the slowest dynamics of the ARCH models (the building's 20 s, the platoon's 20 s), while the search space
of falsification grows by ten dimensions per input only.  Falsification over these signals is a search
over a subset of SpaceEx's inputs (any measurable signal): a ``not_falsified`` verdict stays SAMPLED."""

TRACE_SAMPLES = 2000
"""Samples of the STL trace over the horizon (plus both sides of every jump)."""

LOCATION_PARAMETER = "initial_location"
"""The parameter choosing the initial location when the initial set names none (its value rounded: an index)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class InitialLocation:
    """``point -> mode``: the initial location of index ``round(point[LOCATION_PARAMETER])``."""

    modes: tuple[str, ...]

    def __call__(self, point: Mapping[str, float]) -> str:
        index = int(round(float(point.get(LOCATION_PARAMETER, 0.0))))
        return self.modes[min(max(index, 0), len(self.modes) - 1)]


def input_parameters(inputs: tuple[SpaceExInput, ...], points: int) -> tuple[Parameter, ...]:
    """The parameters ``<input.symbol>_<k>`` (``k < points``) of the inputs' signals, each in the input's bounds."""
    return tuple(Parameter(name=f"{i.symbol}_{k}", low=i.low, high=i.high) for i in inputs for k in range(points))


@dataclass(frozen=True, kw_only=True, slots=True)
class InputSignals:
    """``point -> HybridSystem``: the model with each input the piecewise-constant signal of the point's values."""

    system: HybridSystem
    input_flows: Mapping[str, object]
    inputs: tuple[SpaceExInput, ...]
    points: int
    horizon: float

    def __call__(self, point: Mapping[str, float]) -> HybridSystem:
        signals = {i.name: input_signal([float(point.get(f"{i.symbol}_{k}", i.middle)) for k in range(self.points)],
                                        self.horizon) for i in self.inputs}
        return with_inputs(self.system, self.input_flows, self.inputs, signals)


def is_spaceex_spec(spec: str) -> bool:
    """Whether a problem spec names a SpaceEx model (``FILE.xml`` or ``FILE.xml:COMPONENT``)."""
    if not isinstance(spec, str):
        return False
    head = spec.rsplit(":", 1)[0] if spec.count(":") and not spec.endswith(".xml") else spec
    return head.lower().endswith(".xml")


def split_spaceex_spec(spec: str) -> tuple[str, str | None]:
    """``(file, component or None)`` of ``FILE.xml[:COMPONENT]``."""
    if spec.lower().endswith(".xml"):
        return spec, None
    head, _, tail = spec.rpartition(":")
    return head, (tail or None)


def spaceex_problem(xml: str | Path, config: str | Path, component: str | None = None, *,
                    sample_period: float | None = None, input_points: int = INPUT_POINTS,
                    constants: dict[str, float] | None = None,
                    reach_options: dict[str, Any] | None = None,
                    sampled_horizon: float | None = None) -> VerificationProblem:
    """The verification problem of a SpaceEx model and configuration.

    Parameters
    ----------
    xml : str or Path
        The SpaceEx model file.
    config : str or Path
        Its ``.cfg`` (system, initially, forbidden, time-horizon).
    component : str or None
        The component to analyse; default: the configuration's ``system``, else the file's last component.
    sample_period : float or None
        Uniform sampling of the flows for the STL trace [s] (default: horizon / :data:`TRACE_SAMPLES`; the
        integrator's own steps would be too sparse on smooth arcs: an exactly integrated parabola takes one
        step, and its apex would not be a sample).
    input_points : int
        Values of each input's piecewise-constant signal (:data:`INPUT_POINTS`).
    constants : dict or None
        Values of the component's own constants that no bind maps (:func:`hybrid.spaceex_import.load_spaceex`).
    reach_options : dict or None
        Options of the reachability proof (:func:`analysis.verify.problems.hybrid_problem`), e.g.
        ``{"time_step": 0.5, "mode_time_steps": {"P3": 0.02}}`` for a model with a fast location.  Without a
        ``time_step`` here, the configuration's ``sampling-time`` is the step (when it has one); without
        either, the steps are chosen from the dynamics (:mod:`analysis.reach.autostep`).
    sampled_horizon : float or None
        Only for an unbounded ``time-horizon`` (negative, SpaceEx's ``-1``): the horizon [s] of the simulations and
        of falsification, which cover ``[0, sampled_horizon]`` only (default: :data:`SAMPLED_CYCLES` longest cycles,
        else :data:`SAMPLED_HORIZON`).  The property for all ``t >= 0`` is decided by cycle induction only
        (:mod:`analysis.spaceex_induction`); the requirement's formula is ``always[0, sampled_horizon] ...``.

    Raises
    ------
    SpaceExError
        A model or configuration that cannot be imported (naming file, line and element), a missing
        horizon, an initial set that is not a box.
    """
    cfg = parse_config(read_bytes(config, "SpaceEx configuration (--config)").decode("utf-8", "replace"),
                       str(config))
    name = component or cfg.system
    if isinstance(input_points, bool) or not isinstance(input_points, int) or not 1 <= input_points <= 1000:
        raise SpaceExError("input_points", input_points, "a whole number in [1, 1000]",
                           f"give the number of values of each input's signal (default {INPUT_POINTS})")
    model = load_spaceex(xml, name, constants=constants, initially=cfg.initially)
    if cfg.horizon is None:
        raise SpaceExError(f"{config}: time-horizon", None, "a time horizon [s]", "write time-horizon = 10")
    box, modes = initial_box(model, cfg)
    unbounded = cfg.unbounded
    cfg = replace(cfg, horizon=_sampled_horizon(model, cfg, box, modes, sampled_horizon, str(config)))
    initial: dict[str, Parameter | float] = {}
    for s, (lo, hi) in box.items():
        initial[s] = lo if lo == hi else Parameter(name=f"{s}_0", low=lo, high=hi)
    formula, instant = _instant_formula(model, cfg, box)
    if formula is None:
        raise SpaceExError(f"{config}: forbidden", None, "a forbidden set (the property to verify)",
                           'write forbidden = "x >= 10" (the states that must never be reached)')
    always = f", for all t >= 0 (unbounded; sampled over [0, {cfg.horizon:g}] s)" if unbounded else ""
    requirements = (Requirement(name="safe", formula=formula,
                                description=f"the forbidden set of {Path(config).name} is never reached{always}"),)
    notes = [*model.notes, *([UNBOUNDED_NOTE.format(horizon=cfg.horizon)] if unbounded else [])]
    period = sample_period or cfg.horizon / TRACE_SAMPLES
    if instant is not None:
        period = instant / math.ceil(instant / period)  # the instant on the sampling grid
        notes.append(f"the forbidden set holds at the clock's instant {instant!r} s only: checked there "
                     f"(always[{instant!r}, {instant!r}]), the trace sampled every {period!r} s")
    parameters, mode = _choices(model, cfg, modes, input_points, notes)
    reach_options = dict(reach_options or {})
    if cfg.sampling_time is not None and "time_step" not in reach_options:
        reach_options["time_step"] = cfg.sampling_time
        notes.append(f"reachability steps of sampling-time = {cfg.sampling_time!r} s (from {Path(config).name})")
    notes.append("hybrid fires each transition as soon as its guard holds; SpaceEx may fire it later while the "
                 "invariant holds: the simulated runs are runs of the SpaceEx model, not all of them")
    system: HybridSystem | InputSignals = model.system
    if model.inputs:
        system = InputSignals(system=model.system, input_flows=model.input_flows, inputs=model.inputs,
                              points=input_points, horizon=float(cfg.horizon))
    problem = hybrid_problem(
        name=f"spaceex-{Path(xml).stem}-{model.system.automaton.name}-{Path(config).stem}",  # a campaign per cfg
        system=system, initial=initial, horizon=cfg.horizon, requirements=requirements,
        parameters=parameters, initial_mode=mode, sample_period=period,
        description=f"SpaceEx model {xml} (component {model.system.automaton.name!r}) with {config}. "
                    + " ".join(notes),
        source=f"{xml}:{model.system.automaton.name} --config {config}", reach_options=reach_options,
    )
    if unbounded:
        from analysis.spaceex_induction import induction_proofs

        return replace(problem, proofs=induction_proofs(model, problem.parsed, initial, mode))
    return _with_input_proofs(problem, model, initial, mode, reach_options)


def config_unbounded(config: str | Path) -> bool:
    """Whether the ``.cfg`` at ``config`` has an unbounded horizon (a negative ``time-horizon``; ``False`` when it
    cannot be read: the problem's loading reports that)."""
    try:
        text = read_bytes(config, "SpaceEx configuration (--config)").decode("utf-8", "replace")
        return parse_config(text, str(config)).unbounded
    except SpaceExError:
        return False


def _sampled_horizon(model: SpaceExModel, cfg: Any, box: Mapping[str, tuple[float, float]], modes: list[str],
                     given: float | None, where: str) -> float:
    """The problem's horizon: a bounded one as it is (``given`` refused), an unbounded one's sampled horizon: ``given``
    (checked), else :data:`SAMPLED_CYCLES` longest cycles, else :data:`SAMPLED_HORIZON`."""
    if not cfg.unbounded:
        if given is not None:
            raise SpaceExError("sampled_horizon", given, f"no value: {where} has a bounded time-horizon "
                               f"({cfg.horizon!r} s)", "leave sampled_horizon out (it is for time-horizon = -1 only)")
        return cfg.horizon
    if given is not None:
        if isinstance(given, bool) or not isinstance(given, (int, float)) or not (0.0 < given < math.inf):
            raise SpaceExError("sampled_horizon", given, "a finite time > 0 [s]",
                               f"give e.g. sampled_horizon=100.0 (the simulated part of {where}'s unbounded property)")
        return float(given)
    from analysis.spaceex_induction import cycle_of

    cycle = cycle_of(model, box, modes)
    return SAMPLED_HORIZON if cycle is None else SAMPLED_CYCLES * float(cycle.bound)


def _choices(model: SpaceExModel, cfg: object, modes: list[str], input_points: int,
             notes: list[str]) -> tuple[tuple[Parameter, ...], str | InitialLocation]:
    """The parameters beyond the initial box (initial location, input signals) and the initial mode; notes added."""
    parameters: tuple[Parameter, ...] = ()
    mode: str | InitialLocation = modes[0]
    if len(modes) > 1:
        parameters = (Parameter(name=LOCATION_PARAMETER, low=0.0, high=float(len(modes) - 1)),)
        mode = InitialLocation(modes=tuple(modes))
        notes.append(f"the initial set names no location: every location is initial ({', '.join(modes)}), "
                     f"chosen by the parameter {LOCATION_PARAMETER} (rounded to an index)")
    if model.inputs:
        parameters = (*parameters, *input_parameters(model.inputs, input_points))
        notes.append(f"inputs {', '.join(i.name for i in model.inputs)}: simulated as piecewise-constant signals of "
                     f"{input_points} values over the horizon (parameters {model.inputs[0].symbol}_0, ...); "
                     "reachability takes them as any signal within their bounds")
    if cfg.ignored:
        notes.append(f"configuration keys ignored (SpaceEx algorithm settings): {', '.join(cfg.ignored)}")
    return parameters, mode


def _clock(model: SpaceExModel, name: str, box: Mapping[str, tuple[float, float]]) -> bool:
    """Whether state ``name`` is the time itself: flow 1 in every location, 0 initially, never reset."""
    from hybrid.symbolic import Const, Coordinate

    system = model.system
    if name not in system.state_names or box.get(name) != (0.0, 0.0):
        return False
    k = system.state_names.index(name)
    flows = model.input_flows or system.flows
    if not all(isinstance(f.components[k], Const) and f.components[k].value == 1.0 for f in flows.values()):
        return False
    return all(isinstance(j.components[k], Coordinate) and j.components[k].name == name for j in system.jumps.values())


def _instant_formula(model: SpaceExModel, cfg: object, box: Mapping[str, tuple[float, float]]
                     ) -> tuple[str | None, float | None]:
    """The requirement's formula, and the instant when the forbidden set is ``rest & clock == c``.

    A clock that is the time (:func:`_clock`) makes ``clock == c`` the instant ``c``: the forbidden set
    is ``rest`` at time ``c``, i.e. ``always[c, c] not (rest)``.  Read as an atom, the equality would be
    measure-zero on a sampled run (robustness at most 0: never a counterexample).
    """
    tree = cfg.forbidden
    parts = list(tree[1]) if tree is not None and tree[0] == "and" else []
    for k, c in enumerate(parts):
        if c[0] != "cmp" or c[1] != "==":
            continue
        for clock, value in ((c[2], c[3]), (c[3], c[2])):
            if clock[0] == "name" and value[0] == "num" and _clock(model, clock[1], box) \
                    and 0.0 <= float(value[1]) <= cfg.horizon:
                rest = parts[:k] + parts[k + 1:]
                others = rest[0] if len(rest) == 1 else ("and", tuple(rest))
                text = forbidden_formula(model, replace(cfg, forbidden=others), cfg.horizon)
                instant = float(value[1])
                return f"always[{instant!r}, {instant!r}]" + text[len(f"always[0, {cfg.horizon!r}]"):], instant
    return forbidden_formula(model, cfg, cfg.horizon), None


def _with_input_proofs(problem: VerificationProblem, model: SpaceExModel, initial: Mapping[str, object],
                       mode: object, reach_options: Mapping[str, Any]) -> VerificationProblem:
    """The problem with reachability proofs taking the model's inputs (none without inputs), with the step and the
    jump bound of ``reach_options`` (steps chosen from the dynamics without a step)."""
    from analysis.spaceex_reach import input_proofs

    if not model.inputs:
        return problem
    found = input_proofs(model.system, model.input_flows, model.inputs, problem.parsed, initial, mode,
                         time_step=reach_options.get("time_step"), max_jumps=reach_options.get("max_jumps"))
    return replace(problem, proofs={**problem.proofs, **found}) if found else problem
