"""The reference models are written symbolically, and mean exactly what their docstrings say.

Every guard, invariant (term), flow and jump map of every model of
:func:`hybrid.examples.reference_models` must be a :mod:`hybrid.symbolic`
object (so that a checker can hand it to an SMT solver), and must evaluate,
bit for bit, like the float formula of the model's docstring written out here
by hand, independently of :mod:`hybrid.examples`, with the default parameters.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from hybrid import Conjunction
from hybrid.examples import reference_models
from hybrid.symbolic import free_symbols, is_symbolic, transcendental_terms

# ---------------------------------------------------------------------- the formulas, by hand
# Default parameters of the factories (their signatures and docstrings).
G, E = 9.81, 0.8  # bouncing ball: gravity, restitution
AMBIENT, HEATER, RATE, LOW, HIGH = 10.0, 30.0, 0.1, 19.0, 21.0  # thermostat
W, V1, V2, R1, R2 = 0.75, 0.5, 0.5, 0.0, 0.0  # water tanks: inflow, outflows, thresholds

# Per model: the terms of every invariant and guard (a conjunction has several), the flow of every
# mode and the jump map of every transition that has one (the others keep the state).  The
# arguments are the state components, in the model's state_names order (the signals are the states).
FORMULAS = {
    "bouncing_ball": {  # fly: h' = v, v' = -g, h >= 0; bounce: h <= 0 and v <= 0, (h, v) -> (h, -e v)
        "invariant": {"fly": [lambda h, v: h]},
        "guard": {"bounce": [lambda h, v: -h, lambda h, v: -v]},
        "flow": {"fly": lambda h, v: (v, -G)},
        "jump": {"bounce": lambda h, v: (h, -E * v)},
    },
    "thermostat": {  # off: T' = -rate (T - ambient), T >= low; on: T' = -rate (T - heater), T <= high
        "invariant": {"off": [lambda T: T - LOW], "on": [lambda T: HIGH - T]},
        "guard": {"heat_on": [lambda T: LOW - T], "heat_off": [lambda T: T - HIGH]},
        "flow": {"off": lambda T: (-RATE * (T - AMBIENT),), "on": lambda T: (-RATE * (T - HEATER),)},
        "jump": {},
    },
    "water_tanks": {  # fill1: x1' = w - v1, x2' = -v2, x2 >= r2; fill2: x1' = -v1, x2' = w - v2, x1 >= r1
        "invariant": {"fill1": [lambda x1, x2: x2 - R2], "fill2": [lambda x1, x2: x1 - R1]},
        "guard": {"to_fill2": [lambda x1, x2: R2 - x2], "to_fill1": [lambda x1, x2: R1 - x1]},
        "flow": {"fill1": lambda x1, x2: (W - V1, -V2), "fill2": lambda x1, x2: (-V1, W - V2)},
        "jump": {},
    },
    "nondeterministic": {
        "invariant": {"a": [lambda x: 2.0 - x], "b": [lambda x: 3.0 - x], "c": [lambda x: x]},
        "guard": {
            "a_to_b": [lambda x: x - 1.0],
            "a_to_c": [lambda x: x - 1.5],
            "b_to_a": [lambda x: x - 3.0],
            "c_to_a": [lambda x: -x],
        },
        "flow": {"a": lambda x: (1.0,), "b": lambda x: (1.0,), "c": lambda x: (-1.0,)},
        "jump": {"b_to_a": lambda x: (0.0,)},
    },
    "deadlock": {
        "invariant": {"run": [lambda x: 1.0 - x]},
        "guard": {"rewind": [lambda x: -0.5 - x]},
        "flow": {"run": lambda x: (1.0,)},
        "jump": {"rewind": lambda x: (x + 1.0,)},
    },
    "bad_reset": {
        "invariant": {"up": [lambda x: 1.0 - x], "down": [lambda x: x, lambda x: 1.5 - x]},
        "guard": {"reverse": [lambda x: x - 1.0], "rearm": [lambda x: -x]},
        "flow": {"up": lambda x: (1.0,), "down": lambda x: (-1.0,)},
        "jump": {"reverse": lambda x: (x + 1.0,)},
    },
    "retrigger": {
        "invariant": {"tick": [lambda x: 1.0 - x]},
        "guard": {"fire": [lambda x: x - 1.0]},
        "flow": {"tick": lambda x: (1.0,)},
        "jump": {"fire": lambda x: (x,)},
    },
    "unreachable": {
        "invariant": {"main": [lambda x: 1.0 - x], "orphan": [lambda x: x]},
        "guard": {"wrap": [lambda x: x - 1.0], "orphan_to_main": [lambda x: -x]},
        "flow": {"main": lambda x: (1.0,), "orphan": lambda x: (-1.0,)},
        "jump": {"wrap": lambda x: (0.0,)},
    },
}

NAMES = list(reference_models())


# ---------------------------------------------------------------------- helpers
def _terms(function):
    return function.terms if isinstance(function, Conjunction) else (function,)


def _bits(value):
    """The exact bits of a float (``-0.0`` and ``0.0`` differ), or of each component of a tuple."""
    if isinstance(value, (tuple, list)):
        return tuple(_bits(c) for c in value)
    assert type(value) is float, f"{value!r} is a {type(value).__name__}, not a float"
    return value.hex()


def _points(model, count=200):
    """``count`` uniform points of the box (default_rng(0)), then its corners (the jump sets are faces)."""
    names = model.system.state_names
    low = [model.box.bounds[n][0] for n in names]
    high = [model.box.bounds[n][1] for n in names]
    rng = np.random.default_rng(0)
    random = [tuple(float(c) for c in rng.uniform(low, high)) for _ in range(count)]
    corners = [tuple(float(c) for c in p) for p in itertools.product(*zip(low, high))]
    return random + corners


def _parts(model):
    """``(kind, name, function)`` for every invariant, guard, flow and jump map of the model."""
    system, automaton = model.system, model.system.automaton
    parts = [("invariant", m.name, m.invariant) for m in automaton.modes if m.invariant is not None]
    parts += [("guard", t.name, t.guard) for t in automaton.transitions]
    parts += [("flow", mode, f) for mode, f in system.flows.items()]
    parts += [("jump", name, r) for name, r in system.jumps.items()]
    return parts


# ---------------------------------------------------------------------- tests
def test_every_reference_model_has_formulas():
    assert set(FORMULAS) == set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_the_formulas_cover_every_part_of_the_model(name):
    model, formulas = reference_models()[name], FORMULAS[name]
    a = model.system.automaton
    assert model.system.output is None and a.variables == model.system.state_names  # guards read the states
    assert set(formulas["invariant"]) == {m.name for m in a.modes if m.invariant is not None}
    assert set(formulas["guard"]) == {t.name for t in a.transitions}
    assert set(formulas["flow"]) == set(a.mode_names) == set(model.system.flows)
    assert set(formulas["jump"]) == set(model.system.jumps)
    for kind, part, function in _parts(model):
        if kind in ("invariant", "guard"):
            assert len(_terms(function)) == len(formulas[kind][part]), (kind, part)


@pytest.mark.parametrize("name", NAMES)
def test_every_guard_invariant_flow_and_jump_map_is_symbolic(name):
    model = reference_models()[name]
    states = set(model.system.state_names)
    parts = _parts(model)
    assert parts
    for kind, part, function in parts:
        terms = _terms(function) if kind in ("invariant", "guard") else (function,)
        for term in terms:
            assert is_symbolic(term), f"{name}: the {kind} {part!r} has a term {term!r} that is not symbolic"
        expressions = terms if kind in ("invariant", "guard") else function.components
        for e in expressions:
            symbols = free_symbols(e)
            assert symbols["coordinates"] <= states, (kind, part)
            assert not symbols["memory"] and not symbols["params"] and not symbols["time"], (kind, part)
            assert transcendental_terms(e) == [], (kind, part)  # affine, so an SMT solver decides it exactly
        if kind == "flow":
            assert function.kind == "flow" and len(function) == len(states)
        if kind == "jump":
            assert function.kind == "jump" and len(function) == len(states)


@pytest.mark.parametrize("name", NAMES)
def test_values_equal_the_docstring_formulas_to_the_bit(name):
    model, formulas = reference_models()[name], FORMULAS[name]
    system, automaton = model.system, model.system.automaton
    points = _points(model)
    assert len(points) == 200 + 2 ** system.dimension
    for p in points:
        for mode in automaton.modes:
            terms = formulas["invariant"].get(mode.name)
            if terms is not None:
                expected = [f(*p) for f in terms]
                for term, want in zip(_terms(mode.invariant), expected):
                    assert _bits(term(p, {})) == _bits(want), (mode.name, p)
                assert _bits(mode.invariant(p, {})) == _bits(min(expected)), (mode.name, p)
            want = formulas["flow"][mode.name](*p)
            assert _bits(system.flows[mode.name](0.0, p, {})) == _bits(want), (mode.name, p)
            assert _bits(system.flow(mode.name, 0.0, p, {})) == _bits(want), (mode.name, p)
        for t in automaton.transitions:
            expected = [f(*p) for f in formulas["guard"][t.name]]
            for term, want in zip(_terms(t.guard), expected):
                assert _bits(term(p, {})) == _bits(want), (t.name, p)
            assert _bits(t.guard(p, {})) == _bits(min(expected)), (t.name, p)
            jump = formulas["jump"].get(t.name, lambda *x: tuple(x))  # no jump map: the state is kept
            assert _bits(system.jump(t.name, 0.0, p, {})) == _bits(jump(*p)), (t.name, p)


def test_a_zero_threshold_keeps_the_sign_of_zero_on_the_face():
    """``r2 - x2`` at ``r2 = x2 = 0`` is ``+0.0``, as in float arithmetic (not ``-x2 = -0.0``)."""
    tanks = reference_models()["water_tanks"]
    to_fill2 = tanks.system.automaton.transitions[0]
    assert to_fill2.name == "to_fill2" and R2 == 0.0
    assert math.copysign(1.0, to_fill2.guard((1.0, 0.0), {})) == 1.0
    assert _bits(to_fill2.guard((1.0, 0.0), {})) == _bits(R2 - 0.0)
