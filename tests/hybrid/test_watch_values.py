"""One compiled function for all the symbolic watches of a mode (:mod:`hybrid.watch_values`).

The reference is each guard's and invariant's own evaluation (``g(v, m)``), the path the executor took before:
the combined function must give the same floats, bit for bit.
"""

from __future__ import annotations

import numpy as np

from hybrid import HybridAutomaton, Mode, Transition, all_of
from hybrid.symbolic import coordinates, memory, minimum
from hybrid.watch_values import structure_key, watch_function


def automaton(level: float = 1.5):
    v, m = coordinates("a", "b"), memory("k")
    return HybridAutomaton(
        name="watched", variables=("a", "b"),
        modes=(Mode(name="p", invariant=(v.a <= 3.0) & (v.b >= -2.0)), Mode(name="q")),
        transitions=(
            Transition(name="up", source="p", target="q", guard=v.a * v.b >= level),
            Transition(name="down", source="p", target="q", guard=v.a - m.k, direction=-1),
            Transition(name="both", source="p", target="q", guard=all_of(v.a >= 0.5, minimum(v.b, 2.0 - v.a))),
        ),
        initial_mode="p")


def test_the_compiled_watches_equal_each_functions_own_values_bit_for_bit():
    a = automaton()
    outgoing, invariant = a.outgoing("p"), a.mode("p").invariant
    phi = watch_function(outgoing, invariant)
    rng = np.random.default_rng(3)
    for _ in range(200):
        v = tuple(float(c) for c in rng.normal(size=2) * 3.0)
        m = {"k": float(rng.normal())}
        expected = [(-tr.guard(v, m) if tr.direction < 0 else tr.guard(v, m)) for tr in outgoing] + [-invariant(v, m)]
        got = list(phi(v, m))
        assert [x.hex() for x in got] == [float(x).hex() for x in expected]


def test_equal_guards_of_rebuilt_systems_share_one_function_and_others_do_not():
    first, second, other = automaton(), automaton(), automaton(level=2.5)
    f1 = watch_function(first.outgoing("p"), first.mode("p").invariant)
    assert f1 is watch_function(second.outgoing("p"), second.mode("p").invariant)
    assert f1 is not watch_function(other.outgoing("p"), other.mode("p").invariant)
    v = coordinates("a", "b")
    assert structure_key(v.a - 1.0) == structure_key(v.a - 1.0)  # two trees, one structure
    assert len({structure_key(v.a - 1.0), structure_key(v.b - 1.0), structure_key(v.a - 1.5),
                structure_key(1.0 - v.a)}) == 4


def test_a_plain_python_guard_or_no_watch_leaves_the_per_function_path():
    v = coordinates("a", "b")
    mixed = (Transition(name="t", source="p", target="q", guard=lambda s, m: s[0]),
             Transition(name="u", source="p", target="q", guard=v.a >= 1.0))
    assert watch_function(mixed, None) is None
    assert watch_function((), None) is None
    assert watch_function((), lambda s, m: 1.0) is None
