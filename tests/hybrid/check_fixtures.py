"""Models of the completeness tests of :func:`hybrid.check` (``test_check_complete.py``) and of
``visnav check-model --problem`` (``tests/visnav/app/check_model_problems.py`` wraps them as problems).

Each builder returns a :class:`hybrid.HybridSystem`; :data:`BOX` is the box over ``T`` they are checked on.
"""

from __future__ import annotations

import math

from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition
from hybrid.symbolic import coordinates, flow_map, time

__all__ = ["BOX", "thermostat", "plain_zero_band", "time_flow_zero_band", "bad_guard", "BAD_GUARDS",
           "plain_overlap"]

BOX = Box(bounds={"T": (15.0, 25.0)})
"""The box every fixture is checked over [°C]."""


def thermostat(low: float, high: float, *, symbolic: bool, time_flow: bool = False) -> HybridSystem:
    """A thermostat switching on at ``T <= low`` and off at ``T >= high`` (``low == high``: no hysteresis).

    ``symbolic`` writes guards, invariants and flows with :mod:`hybrid.symbolic`; ``time_flow`` makes the
    flows read the time symbol (``t``), which the SMT questions of the flow cannot take.
    """
    if symbolic:
        v, t = coordinates("T"), time()
        modes = (Mode(name="off", invariant=v.T - low), Mode(name="on", invariant=high - v.T))
        transitions = (Transition(name="heat_on", source="off", target="on", guard=low - v.T),
                       Transition(name="heat_off", source="on", target="off", guard=v.T - high))
        drift = 1e-3 * t if time_flow else 0.0
        flows = {"off": flow_map(-0.1 * (v.T - 10.0) + drift), "on": flow_map(-0.1 * (v.T - 30.0) + drift)}
    else:
        modes = (Mode(name="off", invariant=lambda v, m: v[0] - low),
                 Mode(name="on", invariant=lambda v, m: high - v[0]))
        transitions = (Transition(name="heat_on", source="off", target="on", guard=lambda v, m: low - v[0]),
                       Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - high))
        flows = {"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),), "on": lambda t, x, m: (-0.1 * (x[0] - 30.0),)}
    automaton = HybridAutomaton(name="thermostat", modes=modes, transitions=transitions, variables=("T",),
                                initial_mode="off")
    return HybridSystem(automaton=automaton, state_names=("T",), flows=flows)


def plain_zero_band() -> HybridSystem:
    """No hysteresis, plain callables: each switch re-enables the other at ``T = 20`` (two re-triggers)."""
    return thermostat(20.0, 20.0, symbolic=False)


def time_flow_zero_band() -> HybridSystem:
    """No hysteresis, symbolic guards, flows reading time: the re-trigger is decidable, the flow is not."""
    return thermostat(20.0, 20.0, symbolic=True, time_flow=True)


def _raises(v, m):
    raise RuntimeError("sensor table missing")


BAD_GUARDS = {"raises": _raises, "nan": lambda v, m: math.nan, "none": lambda v, m: None}
"""Guards that never give a real number: raising, NaN, ``None``."""


def bad_guard(how: str) -> HybridSystem:
    """The hysteresis thermostat (symbolic invariants and flows) whose ``heat_on`` guard is ``BAD_GUARDS[how]``."""
    v = coordinates("T")
    automaton = HybridAutomaton(
        name=f"guard-{how}",
        modes=(Mode(name="off", invariant=v.T - 19.0), Mode(name="on", invariant=21.0 - v.T)),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=BAD_GUARDS[how]),
                     Transition(name="heat_off", source="on", target="off", guard=v.T - 21.0)),
        variables=("T",), initial_mode="off")
    return HybridSystem(automaton=automaton, state_names=("T",),
                        flows={"off": flow_map(-0.1 * (v.T - 10.0)), "on": flow_map(-0.1 * (v.T - 30.0))})


def plain_overlap() -> HybridSystem:
    """Mode ``off`` with two plain-callable transitions of different priority, both enabled below 19 °C."""
    automaton = HybridAutomaton(
        name="overlap",
        modes=(Mode(name="off"), Mode(name="on"), Mode(name="boost")),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=lambda v, m: 19.0 - v[0]),
                     Transition(name="boost_on", source="off", target="boost", guard=lambda v, m: 18.0 - v[0],
                                priority=1),
                     Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - 21.0),
                     Transition(name="boost_off", source="boost", target="off", guard=lambda v, m: v[0] - 21.0)),
        variables=("T",), initial_mode="off")
    return HybridSystem(automaton=automaton, state_names=("T",),
                        flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10.0),),
                               "on": lambda t, x, m: (-0.1 * (x[0] - 30.0),),
                               "boost": lambda t, x, m: (-0.2 * (x[0] - 30.0),)})
