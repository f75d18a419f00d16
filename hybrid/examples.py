"""Reference hybrid systems with known answers.

Two families of small models live here, each wrapped in a
:class:`ReferenceModel` (the system, an initial condition, a declared
:class:`~hybrid.region.Box`, a simulation horizon and the list of defects it
carries on purpose):

* **physical models with closed forms**, against which executors are checked:
  the bouncing ball (:func:`bouncing_ball`, impact times, apex heights and the
  Zeno time), the thermostat (:func:`thermostat`, switching times from the
  exponential decay) and the two water tanks of Johansson, Egerstedt, Lygeros
  and Sastry (:func:`water_tanks`, switching times and Zeno time).  They are
  structurally *clean*: ``planted == ()``;
* **deliberately broken models**, against which structural checkers are
  checked: every one plants the defects named in ``planted`` and nothing else
  (:func:`nondeterministic`, :func:`deadlock`, :func:`bad_reset`,
  :func:`retrigger`, :func:`unreachable`).

Guards, invariants, flows and jump maps are affine (the exports rely on it)
and written once, symbolically, with the builders of :mod:`hybrid.symbolic`
(``v.x >= 1.0``, ``flow_map``, ``jump_map``), never as Python lambdas: a
checker hands them to an SMT solver, and their text (``guard_text``,
``invariant_text``, ``reset_text``) is derived from them, never written a
second time.  A comparison's level form is the same arithmetic, in the same
order, as the formula in its docstring (``x <= 3`` is ``3 - x``), and so
evaluates bit for bit like the plain float expression; a threshold that is a
parameter, and may be ``0.0``, is compared with
:func:`~hybrid.symbolic.exactly`, whose level form keeps the subtraction as
written (``+0.0`` on the face, as in float arithmetic).  Conjunctions are
built with :func:`~hybrid.model.all_of` (a :class:`~hybrid.model.Conjunction`
of level forms, with the text of each comparison; the exports write one
inequality per term).  Every invariant is such a conjunction, of a single
term where there is one: unlike a bare symbolic condition, which refuses
``bool()``, a conjunction can stand in ``mode.invariant or default``, and its
value is its term's value.  A transition's ``reset_text`` is its jump map's
text (:func:`~hybrid.model.jump_text`: the components it changes); a
transition without a jump map keeps the state (its ``reset_text`` is then
empty).

Two remarks for whoever writes a checker against ``planted``:

* the jump sets of the physical models are *faces* of the box (``h = 0``,
  ``T = low``, ``x2 = r2``): a guard sampled only in the interior of the box is
  never enabled there;
* the Zeno points are where jumps accumulate, and they are single points: the
  bouncing ball's self-loop lands back on its own guard only at
  ``(h, v) = (0, 0)``, and the water tanks jump back and forth between their
  modes only at the corner ``(x1, x2) = (r1, r2)``.  These are the physics of
  the models, not planted defects; a check of ``"reset_retriggers"`` that
  reports jump maps landing on their own guard on a set of measure zero will
  flag them.

Examples
--------
>>> models = reference_models()
>>> list(models)[:3]
['bouncing_ball', 'thermostat', 'water_tanks']
>>> models["deadlock"].planted
('deadlock',)
>>> ball = bouncing_ball()
>>> ball.system.flow("fly", 0.0, (1.0, -2.0), {})
(-2.0, -9.81)
>>> round(bouncing_ball_zeno_time(), 6)
4.063713
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ModelDefinitionError
from .examples_physical import (  # the physical models, re-exported; the shared parameter checks
    FINDING_KINDS,
    GRAVITY,
    HORIZON_EVENT,
    ReferenceModel,
    bouncing_ball,
    bouncing_ball_apex_heights,
    bouncing_ball_impact_times,
    bouncing_ball_zeno_time,
    thermostat,
    thermostat_switch_times,
    water_tanks,
    water_tanks_switch_times,
    water_tanks_zeno_time,
    real_parameter as _real,
    positive_parameter as _positive,
    event_horizon as _horizon,
    thermostat_parameters as _thermostat,
    require_symbolic as _require_symbolic,
    with_jump_texts as _with_jump_texts,
)
from .model import HybridAutomaton, Mode, Transition, all_of
from .region import Box
from .symbolic import SymbolicVector, coordinates, exactly, flow_map, jump_map
from .system import HybridSystem

__all__ = [
    "FINDING_KINDS",
    "ReferenceModel",
    "bouncing_ball",
    "bouncing_ball_impact_times",
    "bouncing_ball_apex_heights",
    "bouncing_ball_zeno_time",
    "thermostat",
    "thermostat_switch_times",
    "water_tanks",
    "water_tanks_switch_times",
    "water_tanks_zeno_time",
    "nondeterministic",
    "deadlock",
    "bad_reset",
    "retrigger",
    "unreachable",
    "reference_models",
]


# ---------------------------------------------------------------------- planted defects
def _unit_speed_model(
    *,
    name: str,
    description: str,
    modes: tuple[Mode, ...],
    transitions: tuple[Transition, ...],
    flows: dict[str, SymbolicVector],
    jumps: dict[str, SymbolicVector],
    initial_mode: str,
    bounds: tuple[float, float],
    duration: float,
    planted: tuple[str, ...],
    x0: float = 0.0,
) -> ReferenceModel:
    """A one-state (``x``) model from its symbolic parts (see :func:`_require_symbolic`)."""
    _require_symbolic(name, modes, transitions, flows, jumps)
    transitions = _with_jump_texts(transitions, jumps, ("x",))
    automaton = HybridAutomaton(
        name=name,
        modes=modes,
        transitions=transitions,
        variables=("x",),
        initial_mode=initial_mode,
        description=description,
    )
    system = HybridSystem(automaton=automaton, state_names=("x",), flows=flows, jumps=jumps)
    return ReferenceModel(
        name=name,
        system=system,
        x0=(x0,),
        initial_mode=initial_mode,
        box=Box(bounds={"x": bounds}),
        duration=duration,
        description=description,
        planted=planted,
    )


def _rise() -> SymbolicVector:
    """``ẋ = 1``."""
    return flow_map(1.0)


def _fall() -> SymbolicVector:
    """``ẋ = -1``."""
    return flow_map(-1.0)


def nondeterministic() -> ReferenceModel:
    """Two transitions of equal priority enabled together (planted ``"nondeterminism"``).

    State ``x``.  Mode ``a`` (``ẋ = 1``, invariant ``x <= 2``) has
    ``a_to_b`` (``x >= 1``) and ``a_to_c`` (``x >= 1.5``), both level-triggered
    with priority 0: for ``x ∈ [1.5, 2]`` both are enabled.  Mode ``b``
    (``ẋ = 1``, invariant ``x <= 3``) returns by ``b_to_a`` at ``x >= 3`` with
    ``x := 0``; mode ``c`` (``ẋ = -1``, invariant ``x >= 0``) returns by
    ``c_to_a`` at ``x <= 0``.  Box ``x ∈ [0, 3]``, ``x0 = 0`` in ``a``.

    From ``x0`` a run crosses ``x = 1`` first and only ever takes ``a_to_b``
    (period 3 s); ``c`` is reachable in the mode graph, not along this run.

    Examples
    --------
    >>> model = nondeterministic()
    >>> [t.name for t in model.system.automaton.enabled("a", (1.75,), {})]
    ['a_to_b', 'a_to_c']
    """
    v = coordinates("x")  # signal
    modes = (
        Mode(name="a", description="x rises until one of two overlapping guards fires",
             invariant=all_of(v.x <= 2.0)),
        Mode(name="b", description="x rises to 3, then returns to a at x = 0",
             invariant=all_of(v.x <= 3.0)),
        Mode(name="c", description="x falls to 0, then returns to a",
             invariant=all_of(v.x >= 0.0)),
    )
    transitions = (
        Transition(name="a_to_b", source="a", target="b", guard=v.x >= 1.0, reads=("x",), priority=0),
        Transition(name="a_to_c", source="a", target="c", guard=v.x >= 1.5, reads=("x",), priority=0),
        Transition(name="b_to_a", source="b", target="a", guard=v.x >= 3.0, reads=("x",)),
        Transition(name="c_to_a", source="c", target="a", guard=v.x <= 0.0, reads=("x",)),
    )
    return _unit_speed_model(
        name="nondeterministic",
        description=(
            "Planted non-determinism: in mode 'a', a_to_b (x >= 1) and a_to_c (x >= 1.5) have the same "
            "priority and are both enabled for x in [1.5, 2]. Otherwise clean."
        ),
        modes=modes,
        transitions=transitions,
        flows={"a": _rise(), "b": _rise(), "c": _fall()},
        jumps={"b_to_a": jump_map(0.0)},
        initial_mode="a",
        bounds=(0.0, 3.0),
        duration=8.0,  # switches at 1, 3, 4, 6, 7, 9, ...: 8 is not one of them
        planted=("nondeterminism",),
    )


def deadlock() -> ReferenceModel:
    """A flow that leaves the invariant where no transition is enabled (planted ``"deadlock"``).

    One mode ``run``: ``ẋ = 1``, invariant ``x <= 1``; its only transition,
    the self-loop ``rewind``, is enabled for ``x <= -0.5`` and jumps
    ``x := x + 1``.  From ``x0 = 0`` the state reaches the boundary ``x = 1``
    at ``t = 1`` with no transition enabled: it can neither flow nor jump.

    The guard is satisfiable inside the invariant (``x ∈ [-1, -0.5]`` of the
    box ``x ∈ [-1, 2]``), and its jump lands in ``[0, 0.5]``, inside the
    invariant and off the guard, so the deadlock is the only defect even for a
    checker that also reports guards that can never hold in their source mode.

    Examples
    --------
    >>> model = deadlock()
    >>> model.system.automaton.enabled("run", (1.0,), {})
    ()
    """
    v = coordinates("x")  # signal
    x = coordinates("x")  # state
    modes = (
        Mode(name="run", description="x rises towards the end x = 1 of its invariant",
             invariant=all_of(v.x <= 1.0)),
    )
    transitions = (
        Transition(name="rewind", source="run", target="run", guard=v.x <= -0.5, reads=("x",)),
    )
    return _unit_speed_model(
        name="deadlock",
        description=(
            "Planted deadlock: in mode 'run' x rises at unit speed to the invariant boundary x = 1 "
            "(reached at t = 1 from x0 = 0), where the only transition (x <= -0.5) is not enabled."
        ),
        modes=modes,
        transitions=transitions,
        flows={"run": _rise()},
        jumps={"rewind": jump_map(x.x + 1.0)},
        initial_mode="run",
        bounds=(-1.0, 2.0),
        duration=2.0,
        planted=("deadlock",),
    )


def bad_reset() -> ReferenceModel:
    """A jump map that lands outside the target's invariant (planted ``"reset_outside_invariant"``).

    Mode ``up`` (``ẋ = 1``, invariant ``x <= 1``) goes to ``down`` by
    ``reverse`` at ``x >= 1`` with ``x := x + 1``, i.e. to ``x = 2``; mode
    ``down`` (``ẋ = -1``, invariant ``0 <= x <= 1.5``) returns by ``rearm``
    at ``x <= 0``.  Box ``x ∈ [0, 2.5]``, ``x0 = 0`` in ``up``; the bad jump
    happens at ``t = 1``.

    Examples
    --------
    >>> model = bad_reset()
    >>> model.system.jump("reverse", 1.0, (1.0,), {})
    (2.0,)
    >>> model.system.automaton.mode("down").invariant((2.0,), {}) < 0
    True
    """
    v = coordinates("x")  # signal
    x = coordinates("x")  # state
    modes = (
        Mode(name="up", description="x rises to 1",
             invariant=all_of(v.x <= 1.0)),
        Mode(name="down", description="x falls to 0; x must stay within [0, 1.5]",
             invariant=all_of(v.x >= 0.0, v.x <= 1.5)),
    )
    transitions = (
        Transition(name="reverse", source="up", target="down", guard=v.x >= 1.0, reads=("x",)),
        Transition(name="rearm", source="down", target="up", guard=v.x <= 0.0, reads=("x",)),
    )
    return _unit_speed_model(
        name="bad_reset",
        description=(
            "Planted reset outside the invariant: 'reverse' (up -> down at x = 1) jumps to x := x + 1 = 2, "
            "outside the invariant 0 <= x <= 1.5 of 'down'. Otherwise clean."
        ),
        modes=modes,
        transitions=transitions,
        flows={"up": _rise(), "down": _fall()},
        jumps={"reverse": jump_map(x.x + 1.0)},
        initial_mode="up",
        bounds=(0.0, 2.5),
        duration=3.0,
        planted=("reset_outside_invariant",),
    )


def retrigger() -> ReferenceModel:
    """A level-triggered self-loop that lands back on its own guard (planted ``"reset_retriggers"``).

    Mode ``tick``: ``ẋ = 1``, invariant ``x <= 1``; the self-loop ``fire``
    is enabled for ``x >= 1`` and keeps ``x`` (``x := x``), so once ``x = 1``
    (at ``t = 1`` from ``x0 = 0``) it fires again and again at the same
    instant.  Box ``x ∈ [0, 2]``.

    Examples
    --------
    >>> model = retrigger()
    >>> fire = model.system.automaton.transitions[0]
    >>> fire.guard(model.system.jump("fire", 1.0, (1.0,), {}), {}) >= 0
    True
    """
    v = coordinates("x")  # signal
    x = coordinates("x")  # state
    modes = (
        Mode(name="tick", description="x rises to 1, where the self-loop fires forever",
             invariant=all_of(v.x <= 1.0)),
    )
    transitions = (
        Transition(name="fire", source="tick", target="tick", guard=v.x >= 1.0, reads=("x",)),
    )
    return _unit_speed_model(
        name="retrigger",
        description=(
            "Planted re-triggering reset: the level-triggered self-loop 'fire' (x >= 1) keeps x, so it is "
            "enabled again right after each jump (infinitely many jumps at t = 1). Otherwise clean."
        ),
        modes=modes,
        transitions=transitions,
        flows={"tick": _rise()},
        jumps={"fire": jump_map(x.x)},
        initial_mode="tick",
        bounds=(0.0, 2.0),
        duration=2.0,
        planted=("reset_retriggers",),
    )


def unreachable() -> ReferenceModel:
    """A mode that no transition enters (planted ``"unreachable_mode"``, ``"unreachable_transition"``).

    Mode ``main`` (initial; ``ẋ = 1``, invariant ``x <= 1``) wraps around by
    the self-loop ``wrap`` at ``x >= 1`` with ``x := 0``.  Mode ``orphan``
    (``ẋ = -1``, invariant ``x >= 0``) is entered by no transition; its
    transition ``orphan_to_main`` (``x <= 0``) can therefore never fire.  Box
    ``x ∈ [0, 1]``.

    Examples
    --------
    >>> model = unreachable()
    >>> [(t.source, t.target) for t in model.system.automaton.transitions]
    [('main', 'main'), ('orphan', 'main')]
    """
    v = coordinates("x")  # signal
    modes = (
        Mode(name="main", description="x rises to 1 and wraps around to 0",
             invariant=all_of(v.x <= 1.0)),
        Mode(name="orphan", description="never entered: x would fall to 0 and go to main",
             invariant=all_of(v.x >= 0.0)),
    )
    transitions = (
        Transition(name="wrap", source="main", target="main", guard=v.x >= 1.0, reads=("x",)),
        Transition(name="orphan_to_main", source="orphan", target="main", guard=v.x <= 0.0, reads=("x",)),
    )
    return _unit_speed_model(
        name="unreachable",
        description=(
            "Planted unreachable mode: no transition enters 'orphan', so 'orphan' and its transition "
            "'orphan_to_main' are unreachable from the initial mode 'main'. Otherwise clean."
        ),
        modes=modes,
        transitions=transitions,
        flows={"main": _rise(), "orphan": _fall()},
        jumps={"wrap": jump_map(0.0)},
        initial_mode="main",
        bounds=(0.0, 1.0),
        duration=2.5,  # wraps at t = 1, 2, 3, ...: 2.5 is between two of them
        planted=("unreachable_mode", "unreachable_transition"),
    )


# ---------------------------------------------------------------------- catalogue
def reference_models() -> dict[str, ReferenceModel]:
    """All reference models with their default parameters, by name.

    Returns
    -------
    dict of str to ReferenceModel
        In this order: the clean physical models ``bouncing_ball``,
        ``thermostat``, ``water_tanks``, then the planted ones
        ``nondeterministic``, ``deadlock``, ``bad_reset``, ``retrigger``,
        ``unreachable``.  A fresh dict (and fresh models) on every call.

    Examples
    --------
    >>> {name: model.planted for name, model in reference_models().items() if model.planted}["unreachable"]
    ('unreachable_mode', 'unreachable_transition')
    """
    factories = (
        bouncing_ball,
        thermostat,
        water_tanks,
        nondeterministic,
        deadlock,
        bad_reset,
        retrigger,
        unreachable,
    )
    models = [factory() for factory in factories]
    return {model.name: model for model in models}


# ---------------------------------------------------------------------- periodic orbits with closed forms
# Three physical models whose steady state is a limit cycle, each with the cycle in closed form, for
# the periodic-orbit analysis (analysis.periodic): the thermostat's cycle between its thresholds, the
# symmetric oscillation of a relay feedback loop, and the periodic steady state of a PWM buck converter.
# The closed forms use matrix exponentials: numpy here (already loaded by hybrid.model), scipy on first use.


@dataclass(frozen=True, kw_only=True, slots=True)
class ThermostatCycle:
    """The limit cycle of :func:`thermostat` between its thresholds, in closed form.

    Attributes
    ----------
    time_off, time_on : float
        Durations of the off phase (``high`` down to ``low``) and of the on phase (``low`` up to ``high``) [s].
    period : float
        ``time_off + time_on`` [s].
    fixed_point : tuple of float
        ``(low,)``: the state on the section of ``heat_on``, just before it fires.
    multiplier : float
        The only Floquet multiplier (one state: the trivial one), exactly 1.
    """

    time_off: float
    time_on: float
    period: float
    fixed_point: tuple[float, ...]
    multiplier: float = 1.0


def thermostat_cycle(
    *,
    ambient: float = 10.0,
    heater: float = 30.0,
    rate: float = 0.1,
    low: float = 19.0,
    high: float = 21.0,
) -> ThermostatCycle:
    """The period of the thermostat's limit cycle (the parameters of :func:`thermostat`).

    Returns
    -------
    ThermostatCycle

    Raises
    ------
    ModelDefinitionError
        As :func:`thermostat`.

    Notes
    -----
    Off: ``T(t) = ambient + (high - ambient) e^{-rate t}`` reaches ``low`` after
    ``t_off = ln((high - ambient)/(low - ambient))/rate``; on: ``T(t) = heater - (heater - low)
    e^{-rate t}`` reaches ``high`` after ``t_on = ln((heater - low)/(heater - high))/rate``
    (evaluated as ``log1p`` of the relative band).  The monodromy of the one-state cycle is
    ``(f_off(low)/f_on(low)) · (f_on(high)/f_off(high)) · Φ_on · Φ_off`` with
    ``Φ_off = (low - ambient)/(high - ambient)`` and ``Φ_on = (heater - high)/(heater - low)``:
    the saltation ratios cancel the flows' contraction exactly, the product is 1.

    Examples
    --------
    >>> cycle = thermostat_cycle()
    >>> round(cycle.period, 9), cycle.fixed_point
    (4.013413909, (19.0,))
    """
    a, u, k, lo, hi, _, _ = _thermostat("thermostat_cycle", ambient, heater, rate, low, high, low, False)
    t_off = math.log1p((hi - lo) / (lo - a)) / k
    t_on = math.log1p((hi - lo) / (u - hi)) / k
    return ThermostatCycle(time_off=t_off, time_on=t_on, period=t_off + t_on, fixed_point=(lo,))


# ---------------------------------------------------------------------- relay feedback
_RELAY_STATES = ("x1", "x2", "x3")
"""States of :func:`relay_feedback`: the outputs of the three first-order lags, ``y = x1``."""


def _relay(where: str, relay: object, hysteresis: object, gain: object, time_constant: object
           ) -> tuple[float, float, float, float]:
    d = _positive(where, "relay", relay, "relay amplitude d")
    eps = _positive(where, "hysteresis", hysteresis, "hysteresis half-width eps")
    k = _positive(where, "gain", gain, "plant gain K")
    tau = _positive(where, "time_constant", time_constant, "time constant tau [s]")
    if eps >= k * d:
        raise ModelDefinitionError(
            f"{where}: hysteresis = {hysteresis!r} >= gain * relay = {k * d!r}; expected eps < K d (the output "
            "y never reaches the relay's threshold otherwise, and there is no oscillation)")
    return d, eps, k, tau


def _relay_matrices(k: float, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of ``G(s) = K/(tau s + 1)^3`` as three lags in series, ``y = x1``."""

    a = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]]) / tau
    b = np.array([0.0, 0.0, k / tau])
    c = np.array([1.0, 0.0, 0.0])
    return a, b, c


def relay_feedback(
    *,
    relay: float = 1.0,
    hysteresis: float = 0.1,
    gain: float = 1.0,
    time_constant: float = 1.0,
    x0: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> ReferenceModel:
    """A relay with hysteresis in feedback with ``G(s) = K/(tau s + 1)^3`` (Åström's relay oscillation).

    ``ẋ1 = (x2 - x1)/tau``, ``ẋ2 = (x3 - x2)/tau``, ``ẋ3 = (K u - x3)/tau``, ``y = x1``, and
    ``u = -d sign(y)`` with hysteresis ``eps``: mode ``plus`` (``u = +d``, invariant ``y <= eps``)
    switches to ``minus`` by ``to_minus`` when ``y >= eps``; mode ``minus`` (``u = -d``,
    invariant ``y >= -eps``) back by ``to_plus`` when ``y <= -eps``.  Level-triggered, no jump
    maps (the state is kept).  The steady state is the symmetric limit cycle of
    :func:`relay_feedback_cycle` (relay feedback oscillations: Åström & Hägglund 1984; their
    exact analysis, e.g. Johansson, Rantzer & Åström 1999).

    Parameters
    ----------
    relay : float
        Relay amplitude ``d > 0``.
    hysteresis : float
        Half-width ``eps`` of the hysteresis, ``0 < eps < K d``.
    gain, time_constant : float
        ``K > 0`` and ``tau > 0`` [s] of the plant.
    x0 : tuple of float
        Initial state (default: at rest), in mode ``plus``.

    Returns
    -------
    ReferenceModel
        Clean; box ``|x_i| <= K d`` (each lag's output stays below the relay's DC level); the
        duration is ten periods of the cycle (from rest the run settles on it).

    Examples
    --------
    >>> loop = relay_feedback()
    >>> loop.system.flow("plus", 0.0, (0.0, 0.0, 0.0), {})
    (0.0, 0.0, 1.0)
    """
    d, eps, k, tau = _relay("relay_feedback", relay, hysteresis, gain, time_constant)
    v = coordinates(*_RELAY_STATES)
    x = coordinates(*_RELAY_STATES)
    modes = (
        Mode(name="plus", description="relay output +d: the plant output rises",
             invariant=all_of(exactly(v.x1 <= eps))),
        Mode(name="minus", description="relay output -d: the plant output falls",
             invariant=all_of(exactly(v.x1 >= -eps))),
    )
    transitions = (
        Transition(name="to_minus", source="plus", target="minus", guard=exactly(v.x1 >= eps), reads=("x1",)),
        Transition(name="to_plus", source="minus", target="plus", guard=v.x1 <= -eps, reads=("x1",)),
    )
    automaton = HybridAutomaton(name="relay_feedback", modes=modes, transitions=transitions, variables=_RELAY_STATES,
                                initial_mode="plus",
                                description=f"relay (d = {d:g}, hysteresis {eps:g}) around K/(tau s + 1)^3")

    def lags(u: float) -> SymbolicVector:
        return flow_map((x.x2 - x.x1) / tau, (x.x3 - x.x2) / tau, (k * u - x.x3) / tau)

    flows = {"plus": lags(d), "minus": lags(-d)}
    _require_symbolic("relay_feedback", automaton.modes, automaton.transitions, flows, {})
    system = HybridSystem(automaton=automaton, state_names=_RELAY_STATES, flows=flows)
    cycle = relay_feedback_cycle(relay=d, hysteresis=eps, gain=k, time_constant=tau)
    bound = k * d
    return ReferenceModel(
        name="relay_feedback", system=system, x0=tuple(float(c) for c in x0), initial_mode="plus",
        box=Box(bounds={name: (-bound, bound) for name in _RELAY_STATES}), duration=10.0 * cycle.period,
        description=(f"Relay feedback (d = {d:g}, hysteresis {eps:g}) around {k:g}/({tau:g} s + 1)^3: a symmetric "
                     f"limit cycle of period {cycle.period:.6g} s in closed form (matrix exponentials), and its "
                     "describing-function approximation. Clean."),
        planted=(),
    )


@dataclass(frozen=True, kw_only=True, slots=True)
class RelayCycle:
    """The symmetric limit cycle of :func:`relay_feedback`: exact, and by the describing function.

    Attributes
    ----------
    half_period, period : float
        ``h`` and ``2h`` of the exact cycle [s].
    switch_state : tuple of float, shape (3,)
        ``x*``: the state where ``to_plus`` fires (``y = -eps``), on the section of ``to_plus``.
    amplitude : float
        ``max |y|`` over the exact cycle.
    first_harmonic : float
        Amplitude of the fundamental of the exact ``y``: ``|(2/T) ∫_0^T y e^{-iωt} dt|``, ``ω = 2π/T``
        (what the describing function's ``a`` stands for).
    monodromy : tuple of tuple of float, shape (3, 3)
        ``e^{Ah} S_2 e^{Ah} S_1`` at ``x*`` from the closed forms (``S`` the saltation matrices).
    multipliers : tuple of complex
        Its eigenvalues by decreasing modulus (one of them the trivial 1).
    df_frequency, df_period, df_amplitude : float
        The describing-function prediction: ``ω`` [rad/s], ``2π/ω`` [s] and the amplitude ``a`` of ``y``.
    harmonic_ratio : float
        ``Σ_{k = 3, 5, ...} |G(ikω)| / (k |G(iω)|)`` at the predicted ``ω``: the odd harmonics of the
        relay's square wave that reach ``y``, relative to the fundamental, which the describing
        function neglects (its accuracy is of this order).
    """

    half_period: float
    period: float
    switch_state: tuple[float, ...]
    amplitude: float
    first_harmonic: float
    monodromy: tuple[tuple[float, ...], ...]
    multipliers: tuple[complex, ...]
    df_frequency: float
    df_period: float
    df_amplitude: float
    harmonic_ratio: float


def relay_feedback_cycle(
    *,
    relay: float = 1.0,
    hysteresis: float = 0.1,
    gain: float = 1.0,
    time_constant: float = 1.0,
) -> RelayCycle:
    """The symmetric limit cycle of :func:`relay_feedback` in closed form, and the describing function's.

    Returns
    -------
    RelayCycle

    Notes
    -----
    **Exact.**  With ``u = +d`` from ``x*`` (``C x* = -eps``) for a half period ``h``,
    ``x(h) = e^{Ah} x* + A⁻¹(e^{Ah} - I) B d``; the cycle is symmetric when ``x(h) = -x*``, so
    ``x*(h) = -(I + e^{Ah})⁻¹ A⁻¹ (e^{Ah} - I) B d`` and ``h`` is the first root of
    ``C x*(h) + eps = 0`` (bracketed on a grid, then Brent's method); the output must stay below
    ``eps`` on ``(0, h)``, which is checked on the closed form.

    **Describing function.**  A relay with hysteresis driven by ``a sin ωt`` has
    ``N(a) = 4d/(πa) e^{-i arcsin(eps/a)}``; the harmonic balance ``G(iω) N(a) = -1`` reads
    ``G(iω) = -(π/4d)(sqrt(a² - eps²) + i eps)``: ``Im G(iω) = -π eps/(4d)`` gives ``ω`` (the root
    with ``Re G < 0``, beyond the minimum of ``Im G``) and ``a = hypot(4d Re G(iω)/π, eps)``.

    Examples
    --------
    >>> cycle = relay_feedback_cycle()
    >>> round(cycle.period, 6), round(cycle.df_period, 6)
    (4.787672, 4.739289)
    """
    from scipy.linalg import expm
    from scipy.optimize import brentq

    where = "relay_feedback_cycle"
    d, eps, k, tau = _relay(where, relay, hysteresis, gain, time_constant)
    a, b, c = _relay_matrices(k, tau)
    a_inv = np.linalg.inv(a)
    eye = np.eye(3)

    def start(h: float) -> np.ndarray:
        e = expm(a * h)
        return -np.linalg.solve(eye + e, a_inv @ (e - eye) @ b * d)

    grid = tau * np.geomspace(1e-3, 60.0, 150)
    values = [float(c @ start(h)) + eps for h in grid]
    crossing = next((i for i in range(1, grid.size) if values[i - 1] > 0.0 >= values[i]), None)
    if crossing is None:
        raise ModelDefinitionError(f"{where}: no symmetric cycle found for half periods up to {60 * tau:g} s")
    h = float(brentq(lambda s: float(c @ start(s)) + eps, grid[crossing - 1], grid[crossing], xtol=1e-15))
    x_star = start(h)
    amplitude = _relay_amplitude(a, a_inv, b * d, c, x_star, h, eps, where)
    first_harmonic = _relay_first_harmonic(a, a_inv, b * d, c, x_star, h)
    monodromy = _relay_monodromy(a, b * d, c, x_star, h)
    w, a_df, ratio = _relay_describing_function(d, eps, k, tau, where)
    return RelayCycle(
        half_period=h, period=2.0 * h, switch_state=tuple(float(v) for v in x_star), amplitude=amplitude,
        first_harmonic=first_harmonic,
        monodromy=tuple(tuple(float(v) for v in row) for row in monodromy),
        multipliers=tuple(complex(z) for z in sorted(np.linalg.eigvals(monodromy), key=lambda z: (-abs(z), -z.real))),
        df_frequency=w, df_period=2.0 * math.pi / w, df_amplitude=a_df, harmonic_ratio=ratio,
    )


def _relay_amplitude(a: np.ndarray, a_inv: np.ndarray, bd: np.ndarray, c: np.ndarray, x_star: np.ndarray, h: float,
                     eps: float, where: str) -> float:
    """``max |y|`` over the plus half of the cycle (the minus half mirrors it); ``y < eps`` inside is checked.

    ``y`` on 801 points by the exact affine recursion ``x_{j+1} = E x_j + F`` (``E = e^{A h/800}``),
    the maximum refined between its neighbours by a bounded scalar search on the closed form.
    """
    from scipy.linalg import expm
    from scipy.optimize import minimize_scalar

    def state(t: float) -> np.ndarray:
        e = expm(a * t)
        return e @ x_star + a_inv @ (e - np.eye(3)) @ bd

    steps = 800
    e_step = expm(a * (h / steps))
    f_step = a_inv @ (e_step - np.eye(3)) @ bd
    xs = [np.asarray(x_star, dtype=float)]
    for _ in range(steps):
        xs.append(e_step @ xs[-1] + f_step)
    ys = np.array([float(c @ x) for x in xs])
    if np.any(ys[1:-1] >= eps):
        raise ModelDefinitionError(f"{where}: the symmetric candidate crosses y = {eps:g} before its half period "
                                   f"{h:g} s; it is not the relay's cycle")
    i = int(np.argmax(np.abs(ys)))
    lo, hi = h * max(i - 1, 0) / steps, h * min(i + 1, steps) / steps
    best = minimize_scalar(lambda t: -abs(float(c @ state(t))), bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-12})
    return float(max(abs(ys[i]), -best.fun))


def _relay_first_harmonic(a: np.ndarray, a_inv: np.ndarray, bd: np.ndarray, c: np.ndarray, x_star: np.ndarray,
                          h: float) -> float:
    """``|(4/T) ∫_0^h y e^{-iωt} dt|`` (half-wave symmetry ``y(t + h) = -y(t)``, ``ωh = π``), in closed form.

    ``∫_0^h e^{At} e^{-iωt} dt = (A - iω)⁻¹ (e^{(A - iω)h} - I)`` and ``∫_0^h e^{-iωt} dt = 2/(iω)``.
    """
    from scipy.linalg import expm

    w = math.pi / h
    shifted = a - 1j * w * np.eye(3)
    kernel = np.linalg.solve(shifted, expm(shifted * h) - np.eye(3))
    integral = c @ kernel @ x_star + c @ a_inv @ (kernel - (2.0 / (1j * w)) * np.eye(3)) @ bd
    return float(abs(4.0 / (2.0 * h) * integral))


def _relay_monodromy(a: np.ndarray, bd: np.ndarray, c: np.ndarray, x_star: np.ndarray, h: float) -> np.ndarray:
    """``e^{Ah} S_2 e^{Ah} S_1``: ``S_1`` at ``x*`` (``to_plus``, ``∇g = -C``), ``S_2`` at ``-x*`` (``to_minus``).

    ``S = I + (f⁺ − f⁻) ∇gᵀ / (∇gᵀ f⁻)`` (identity jumps), written out here independently of
    :mod:`analysis.periodic`.
    """
    from scipy.linalg import expm

    def saltation(grad: np.ndarray, f_before: np.ndarray, f_after: np.ndarray) -> np.ndarray:
        return np.eye(3) + np.outer(f_after - f_before, grad) / float(grad @ f_before)

    s1 = saltation(-c, a @ x_star - bd, a @ x_star + bd)
    s2 = saltation(c, a @ -x_star + bd, a @ -x_star - bd)
    phi = expm(a * h)
    return phi @ s2 @ phi @ s1


def _relay_describing_function(d: float, eps: float, k: float, tau: float, where: str) -> tuple[float, float, float]:
    """``(ω, a, harmonic ratio)`` of the harmonic balance ``G(iω) N(a) = -1`` (see :func:`relay_feedback_cycle`)."""
    from scipy.optimize import brentq, minimize_scalar

    def g(w: float) -> complex:
        return k / (1j * w * tau + 1.0) ** 3

    target = -math.pi * eps / (4.0 * d)
    lowest = minimize_scalar(lambda w: g(w).imag, bounds=(1e-9 / tau, math.sqrt(3.0) / tau), method="bounded",
                             options={"xatol": 1e-12 / tau})
    if lowest.fun >= target:
        raise ModelDefinitionError(f"{where}: hysteresis = {eps!r}: no harmonic balance (Im G(iω) never reaches "
                                   f"-π eps/(4d) = {target:.6g}); the describing function predicts no oscillation")
    w = float(brentq(lambda s: g(s).imag - target, float(lowest.x), math.sqrt(3.0) / tau, xtol=1e-15))
    amplitude = math.hypot(4.0 * d * g(w).real / math.pi, eps)
    ratio = sum(abs(g(n * w)) / (n * abs(g(w))) for n in range(3, 400, 2))
    return w, amplitude, ratio


# ---------------------------------------------------------------------- PWM buck converter
_BUCK_STATES = ("i_L", "v_C", "phase")
"""States of :func:`buck_converter`: inductor current [A], capacitor voltage [V], PWM phase (sawtooth, 0 to 1)."""


def _buck(where: str, v_in: object, inductance: object, capacitance: object, load: object, frequency: object,
          duty: object) -> tuple[float, float, float, float, float, float]:
    vin = _positive(where, "v_in", v_in, "input voltage [V]")
    ind = _positive(where, "inductance", inductance, "inductance [H]")
    cap = _positive(where, "capacitance", capacitance, "capacitance [F]")
    res = _positive(where, "load", load, "load resistance [Ω]")
    f = _positive(where, "frequency", frequency, "switching frequency [Hz]")
    dd = _real(where, "duty", duty, lambda c: 0.0 < c < 1.0, "a duty ratio in (0, 1)")
    return vin, ind, cap, res, f, dd


def buck_converter(
    *,
    v_in: float = 12.0,
    inductance: float = 47e-6,
    capacitance: float = 100e-6,
    load: float = 2.5,
    frequency: float = 100e3,
    duty: float = 5.0 / 12.0,
) -> ReferenceModel:
    """A synchronous PWM buck converter (12 V to 5 V at 2 A, 100 kHz) with a sawtooth clock.

    States ``i_L`` [A], ``v_C`` [V] and the PWM ``phase`` (``phase' = f_s``, from 0 to 1 over a
    switching period ``T_s = 1/f_s``).  Mode ``on`` (high-side switch closed):
    ``i_L' = (V_in - v_C)/L``; mode ``off`` (low-side switch closed): ``i_L' = -v_C/L``; in both
    ``v_C' = (i_L - v_C/R)/C``.  ``switch_off`` (on → off) fires when the phase reaches the duty
    ratio, ``phase >= D``; ``switch_on`` (off → on) at the period's end, ``phase >= 1``, and resets
    the clock (``phase := 0``).  The switching is time-driven: the system is autonomous, the time
    lives in the clock.  Synchronous rectification: the current may reverse, there is no
    discontinuous conduction mode to model.

    Parameters
    ----------
    v_in : float
        Input voltage [V].
    inductance, capacitance, load : float
        ``L`` [H], ``C`` [F], ``R`` [Ω].
    frequency : float
        Switching frequency ``f_s`` [Hz].
    duty : float
        Duty ratio ``D`` in ``(0, 1)``; the mean output is ``D V_in``.

    Returns
    -------
    ReferenceModel
        Clean; from rest at the start of a period (``x0 = (0, 0, 0)``, mode ``on``); box
        ``|i_L| <= 2 V_in/sqrt(L/C)``, ``-V_in <= v_C <= 2 V_in``, ``0 <= phase <= 1``; the duration
        lies halfway between the 8th and 9th switches.

    Examples
    --------
    >>> buck = buck_converter()
    >>> [round(c, 6) for c in buck.system.flow("on", 0.0, (2.0, 5.0, 0.0), {})][:2]
    [148936.170213, 0.0]
    """
    vin, ind, cap, res, f, dd = _buck("buck_converter", v_in, inductance, capacitance, load, frequency, duty)
    v = coordinates(*_BUCK_STATES)
    x = coordinates(*_BUCK_STATES)
    modes = (
        Mode(name="on", description="high-side switch closed: the input drives the inductor",
             invariant=all_of(exactly(v.phase <= dd))),
        Mode(name="off", description="low-side switch closed: the inductor freewheels into the load",
             invariant=all_of(v.phase <= 1.0)),
    )
    transitions = (
        Transition(name="switch_off", source="on", target="off", guard=exactly(v.phase >= dd), reads=("phase",)),
        Transition(name="switch_on", source="off", target="on", guard=v.phase >= 1.0, reads=("phase",)),
    )
    capacitor = (x.i_L - x.v_C / res) / cap
    flows = {"on": flow_map((vin - x.v_C) / ind, capacitor, f),
             "off": flow_map(-x.v_C / ind, capacitor, f)}
    jumps = {"switch_on": jump_map(x.i_L, x.v_C, 0.0)}
    transitions = _with_jump_texts(transitions, jumps, _BUCK_STATES)
    automaton = HybridAutomaton(name="buck_converter", modes=modes, transitions=transitions, variables=_BUCK_STATES,
                                initial_mode="on",
                                description=f"PWM buck converter {vin:g} V, duty {dd:g}, {f:g} Hz")
    _require_symbolic("buck_converter", automaton.modes, automaton.transitions, flows, jumps)
    system = HybridSystem(automaton=automaton, state_names=_BUCK_STATES, flows=flows, jumps=jumps)
    period = 1.0 / f
    switches = tuple(t for k in range(HORIZON_EVENT) for t in ((k + dd) * period, (k + 1) * period))
    i_max = 2.0 * vin / math.sqrt(ind / cap)
    return ReferenceModel(
        name="buck_converter", system=system, x0=(0.0, 0.0, 0.0), initial_mode="on",
        box=Box(bounds={"i_L": (-i_max, i_max), "v_C": (-vin, 2.0 * vin), "phase": (0.0, 1.0)}),
        duration=_horizon(switches[:HORIZON_EVENT + 1]),
        description=(f"Synchronous buck converter ({vin:g} V, L = {ind:g} H, C = {cap:g} F, R = {res:g} Ω, "
                     f"{f:g} Hz, duty {dd:g}): periodic steady state in closed form (matrix exponentials), ripple "
                     "against the first-order formula. Clean."),
        planted=(),
    )


@dataclass(frozen=True, kw_only=True, slots=True)
class BuckSteadyState:
    """The periodic steady state of :func:`buck_converter` in closed form.

    Attributes
    ----------
    period : float
        Switching period ``T_s`` [s].
    duty : float
    fixed_point : tuple of float, shape (3,)
        ``(i_valley, v_0, 1)``: the state on the section of ``switch_on``, just before it fires.
    peak_current, valley_current : float
        ``i_L`` at the end of the on phase and at the period's start [A].
    ripple : float
        ``peak - valley`` [A] (``i_L`` is monotone in each phase: ``0 < v_C < V_in``).
    ripple_first_order : float
        ``(V_in - V_out) D T_s / L`` with ``V_out = D V_in`` [A].
    ripple_bound : float
        ``Δv_C D T_s / L`` [A]: ``|ripple - ripple_first_order|`` is at most this (Notes).
    voltage_ripple : float
        ``Δv_C``: max − min of ``v_C`` over the period [V].
    mean_voltage, mean_current : float
        ``D V_in`` [V] and ``D V_in / R`` [A], exact averages over the period.
    multipliers : tuple of complex, shape (2,)
        Nontrivial Floquet multipliers: the eigenvalues of ``e^{A T_s}`` (the two modes share
        ``A``); the trivial one is 1 (the clock).
    """

    period: float
    duty: float
    fixed_point: tuple[float, ...]
    peak_current: float
    valley_current: float
    ripple: float
    ripple_first_order: float
    ripple_bound: float
    voltage_ripple: float
    mean_voltage: float
    mean_current: float
    multipliers: tuple[complex, ...]


def buck_converter_steady_state(
    *,
    v_in: float = 12.0,
    inductance: float = 47e-6,
    capacitance: float = 100e-6,
    load: float = 2.5,
    frequency: float = 100e3,
    duty: float = 5.0 / 12.0,
) -> BuckSteadyState:
    """The exact periodic steady state of :func:`buck_converter` (same parameters).

    Returns
    -------
    BuckSteadyState

    Notes
    -----
    With ``z = (i_L, v_C)``, ``A = [[0, -1/L], [1/C, -1/(RC)]]`` in both modes and
    ``b_on = (V_in/L, 0)``, ``b_off = 0``: over a time ``t``, ``z ↦ Φ(t) z + c(t)`` with
    ``[Φ c] `` the top rows of ``exp([[A, b], [0, 0]] t)``.  The stroboscopic map at the period's
    start is ``z ↦ Φ_off (Φ_on z + c_on) + c_off`` (``Φ_on = Φ(D T_s)``, ``Φ_off = Φ((1 - D) T_s)``);
    its fixed point solves ``(I - Φ_off Φ_on) z = Φ_off c_on + c_off``.

    **Ripple.**  On the on phase ``L i_L' = V_in - v_C``, so exactly
    ``ripple = (1/L) ∫_0^{D T_s} (V_in - v_C) dt``; the first-order formula replaces ``v_C`` by its
    mean ``V_out = D V_in`` (the inductor's mean voltage vanishes in steady state), so the two
    differ by ``(1/L) ∫ (V_out - v_C) dt``, at most ``Δv_C · D T_s / L`` in modulus.  ``Δv_C`` is
    taken from the closed form on 4001 points per phase.

    Examples
    --------
    >>> s = buck_converter_steady_state()
    >>> round(s.ripple, 6), round(s.ripple_first_order, 6), round(s.mean_voltage, 12)
    (0.620835, 0.620567, 5.0)
    """
    from scipy.linalg import expm

    vin, ind, cap, res, f, dd = _buck("buck_converter_steady_state", v_in, inductance, capacitance, load, frequency,
                                      duty)
    a = np.array([[0.0, -1.0 / ind], [1.0 / cap, -1.0 / (res * cap)]])
    period = 1.0 / f

    def affine(b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = a, b
        e = expm(aug * t)
        return e[:2, :2], e[:2, 2]

    b_on, b_off = np.array([vin / ind, 0.0]), np.zeros(2)
    phi_on, c_on = affine(b_on, dd * period)
    phi_off, c_off = affine(b_off, (1.0 - dd) * period)
    z0 = np.linalg.solve(np.eye(2) - phi_off @ phi_on, phi_off @ c_on + c_off)
    z1 = phi_on @ z0 + c_on
    voltages = []
    for z, b, span in ((z0, b_on, dd * period), (z1, b_off, (1.0 - dd) * period)):
        phi, c = affine(b, span / 4000)  # the exact recursion z_{j+1} = Φ z_j + c on 4001 points
        for _ in range(4001):
            voltages.append(z[1])
            z = phi @ z + c
    dv = float(max(voltages) - min(voltages))
    mu = np.linalg.eigvals(expm(a * period))
    return BuckSteadyState(
        period=period, duty=dd, fixed_point=(float(z0[0]), float(z0[1]), 1.0), peak_current=float(z1[0]),
        valley_current=float(z0[0]), ripple=float(z1[0] - z0[0]),
        ripple_first_order=(vin - dd * vin) * dd * period / ind,
        ripple_bound=dv * dd * period / ind, voltage_ripple=dv, mean_voltage=dd * vin, mean_current=dd * vin / res,
        multipliers=tuple(complex(z) for z in sorted(mu, key=lambda z: (-abs(z), -z.imag))),
    )


__all__ += [
    "ThermostatCycle",
    "thermostat_cycle",
    "relay_feedback",
    "RelayCycle",
    "relay_feedback_cycle",
    "buck_converter",
    "BuckSteadyState",
    "buck_converter_steady_state",
]
