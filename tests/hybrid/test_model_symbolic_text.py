"""A model written once (issue 26): a symbolic guard, invariant and reset give their own text; the time
symbol is used as it is; a state jump map given as a memory reset is refused at definition."""

from __future__ import annotations

import pytest

from hybrid import HybridAutomaton, Mode, Transition
from hybrid.errors import ModelDefinitionError
from hybrid.export import to_dot
from hybrid.symbolic import coordinates, flow_map, jump_map, memory, render, reset, time


def _thermostat():
    v = coordinates("T")
    return HybridAutomaton(
        name="room", variables=("T",), initial_mode="off",
        modes=(Mode(name="off", invariant=v.T >= 19.5), Mode(name="on", invariant=v.T <= 20.5)),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=v.T <= 19.5),
                     Transition(name="heat_off", source="on", target="off", guard=v.T >= 20.5)))


def test_symbolic_guards_and_invariants_give_their_text_to_the_exports():
    a = _thermostat()
    assert a.mode("off").invariant_text == "T >= 19.5" and a.outgoing("off")[0].guard_text == "T <= 19.5"
    dot = to_dot(a)
    assert '"off" -> "on" [label="[0] T <= 19.5"]' in dot and "inv: T <= 20.5" in dot


def test_a_given_text_is_kept_and_a_level_form_reads_as_a_comparison():
    v = coordinates("x")
    t = Transition(name="t", source="a", target="b", guard=v.x - 1.0, guard_text="x reaches 1")
    assert t.guard_text == "x reaches 1"
    assert Transition(name="u", source="a", target="b", guard=v.x - 1.0).guard_text == "(x - 1) >= 0"


def test_a_symbolic_reset_gives_its_assignments():
    v, m = coordinates("d"), memory("dL")
    t = Transition(name="latch", source="a", target="b", guard=v.d >= 0, reset=reset(dL=v.d))
    assert t.reset_text == "dL := d" and t.writes == ("dL",)


def test_a_state_jump_map_given_as_a_reset_is_refused_naming_jumps():
    v = coordinates("x")
    with pytest.raises(ModelDefinitionError, match=r"jumps=\{'bounce': jump_map"):
        Transition(name="bounce", source="a", target="a", guard=v.x <= 0, reset=jump_map(-v.x))


def test_time_is_a_symbol_usable_as_it_is_and_time_call_still_works():
    v = coordinates("x")
    assert render(time >= 3.0) == "t >= 3"
    assert flow_map(time * v.x)(2.0, (3.0,), {}) == (6.0,) == flow_map(time() * v.x)(2.0, (3.0,), {})
