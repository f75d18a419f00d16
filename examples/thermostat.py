"""Worked example: verify a thermostat with hysteresis (docs/verify.md walks through it).

A room heated by an on/off thermostat. In mode ``off`` the room cools towards
the outside temperature, in mode ``on`` it heats towards the heater's; the
thermostat switches on at ``setpoint - band/2`` and off at ``setpoint + band/2``.

Two requirements:

``comfort``
    the temperature stays within 1.5 °C of the setpoint;
``min_dwell``
    once the heater switches on it stays on for at least 0.25 s, and once off,
    off for at least 0.25 s (the relay's wear limit).

``stability=True`` adds the stability analysis to the report (and to ``visnav analyse --problem``):
both modes' equilibria (10 °C and 30 °C) lie outside their invariants, so the steady state is the
limit cycle between the thresholds, found by shooting on the guard of ``heat_off``.

Verify it with::

    visnav verify examples/thermostat.py:problem      # band 1 °C: not falsified (exit 0)
    visnav verify examples/thermostat.py:zero_band    # band 0: min_dwell falsified (exit 1)

With a zero band both switching guards hold at the setpoint: the thermostat
switches on and off again at the same instant (an instantaneous, Zeno,
cycle); the executor stops the run there and ``min_dwell`` is violated at
that instant.
"""

from __future__ import annotations

from analysis.verify import Parameter, Requirement, VerificationProblem, hybrid_problem, min_dwell
from hybrid import Box, HybridAutomaton, HybridSystem, Mode, Transition, coordinates, flow_map

OUTSIDE_C = 10.0
HEATER_C = 30.0
SETPOINT_C = 20.0
HORIZON_S = 120.0

REQUIREMENTS = (
    Requirement(name="comfort", formula=f"always[0, {HORIZON_S:g}] (abs(T - {SETPOINT_C:g}) <= 1.5)",
                description="the room stays within 1.5 °C of the setpoint"),
    min_dwell("min_dwell", 0.25, ("off", "on"), HORIZON_S,
              description="the heater stays on (off) for at least 0.25 s after switching (a trace that ends sooner "
                          "is judged on what it has)"),
)


_AUTOMATA: dict[float, HybridAutomaton] = {}


def thermostat_automaton(band: float) -> HybridAutomaton:
    """The thermostat's modes and switching (no flows): built, validated and compiled once per band.

    The automaton does not depend on the room's rate: a problem that builds a system for every point of its
    box (:func:`thermostat_problem`) shares it, and with it the compiled guards and invariants.

    Parameters
    ----------
    band : float
        Hysteresis band [°C], ``>= 0``.
    """
    if band in _AUTOMATA:
        return _AUTOMATA[band]
    low, high = SETPOINT_C - band / 2, SETPOINT_C + band / 2
    v = coordinates("T")  # written once: each guard, invariant and flow gives its text, z3 form and bounds
    _AUTOMATA[band] = HybridAutomaton(
        name="thermostat",
        modes=(Mode(name="off", invariant=v.T >= low), Mode(name="on", invariant=v.T <= high)),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=v.T <= low),
                     Transition(name="heat_off", source="on", target="off", guard=v.T >= high)),
        variables=("T",),
        initial_mode="off",
    )
    return _AUTOMATA[band]


def thermostat_system(band: float, rate: float) -> HybridSystem:
    """The room and its thermostat: state ``T`` [°C], modes ``off`` and ``on``.

    Parameters
    ----------
    band : float
        Hysteresis band [°C], ``>= 0``.
    rate : float
        Inverse time constant of the room [1/s].
    """
    v = coordinates("T")
    return HybridSystem(automaton=thermostat_automaton(band), state_names=("T",),
                        flows={"off": flow_map(-rate * (v.T - OUTSIDE_C)), "on": flow_map(-rate * (v.T - HEATER_C))})


def _builder(band: float):
    def build(point):
        return thermostat_system(band, point["rate"])
    return build


def _initial_mode(point) -> str:
    return "off" if point["T0"] >= SETPOINT_C else "on"


def thermostat_problem(band: float = 1.0) -> VerificationProblem:
    """The verification problem: initial temperature and room rate in a box, 120 s, both requirements."""
    return hybrid_problem(
        name=f"thermostat-band-{band:g}",
        system=_builder(band),
        initial={"T": Parameter(name="T0", low=SETPOINT_C - band / 2, high=SETPOINT_C + band / 2,
                                nominal=SETPOINT_C, unit="°C")},
        parameters=(Parameter(name="rate", low=0.05, high=0.2, nominal=0.1, unit="1/s"),),
        initial_mode=_initial_mode,
        horizon=HORIZON_S,
        sample_period=0.25,
        requirements=REQUIREMENTS,
        check_box=Box(bounds={"T": (15.0, 25.0)}),
        stability=True,
        description=f"on/off thermostat, hysteresis band {band:g} °C around {SETPOINT_C:g} °C",
    )


problem = thermostat_problem(1.0)
zero_band = thermostat_problem(0.0)
