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


def test_a_conjunction_of_comparisons_keeps_each_terms_text_and_level():
    from hybrid import all_of

    v = coordinates("h", "v")
    inv = all_of(v.h >= 0.0, all_of(v.v <= 10.0, v.h <= 2.0))
    assert Mode(name="fly", invariant=inv).invariant_text == "h >= 0 and v <= 10 and h <= 2"
    # the terms are the level forms (h, 10 - v, 2 - h), evaluated by hand at (1.5, 4)
    assert [t((1.5, 4.0), {}) for t in inv.terms] == [1.5, 6.0, 0.5] and inv((1.5, 4.0), {}) == 0.5
    # a plain function among the terms: no text can be derived, none is invented
    assert Mode(name="m", invariant=all_of(v.h >= 0.0, lambda s, m: 1.0)).invariant_text == ""


def test_exactly_keeps_the_subtraction_so_a_zero_threshold_gives_plus_zero_on_the_face():
    import math

    from hybrid.symbolic import exactly

    v = coordinates("x")
    r = 0.0
    plain, exact = Transition(name="p", source="a", target="b", guard=v.x <= r), \
        Transition(name="e", source="a", target="b", guard=exactly(v.x <= r))
    assert plain.guard_text == exact.guard_text == "x <= 0"
    assert math.copysign(1.0, plain.guard((0.0,), {})) == -1.0  # -x: -0.0
    assert math.copysign(1.0, exact.guard((0.0,), {})) == 1.0 == math.copysign(1.0, r - 0.0)  # r - x, as floats
    both = exactly((v.x >= r) & (v.x <= 1.0))
    assert math.copysign(1.0, Transition(name="b", source="a", target="b", guard=both).guard((0.0,), {})) == 1.0


def test_jump_text_names_the_changed_components_and_is_never_empty_for_a_jump():
    from hybrid.model import jump_text

    x = coordinates("h", "v")
    assert jump_text(jump_map(x.h, -0.5 * x.v), ("h", "v")) == "v := (-0.5 * v)"
    assert jump_text(jump_map(x.h, x.v), ("h", "v")) == "h := h, v := v"
    assert jump_text(jump_map(0.0, x.v), ("h", "v")) == "h := 0"
    assert jump_text(lambda x, m: x, ("h", "v")) == ""
