import networkx as nx
import pytest

from hybrid import HybridAutomaton, MemoryVariable, Mode, ModelDefinitionError, Transition, mode_graph, to_dot


def always(v, m):
    return 1.0


def thermostat(**overrides):
    kwargs = dict(
        name="thermostat",
        modes=(Mode(name="off"), Mode(name="on")),
        transitions=(
            Transition(name="heat", source="off", target="on", guard=lambda v, m: 19.0 - v[0], guard_text="T <= 19"),
            Transition(name="cool", source="on", target="off", guard=lambda v, m: v[0] - 21.0, guard_text="T >= 21"),
        ),
        variables=("T",),
        memory=(MemoryVariable(name="count", initial=0.0),),
        initial_mode="off",
    )
    kwargs.update(overrides)
    return HybridAutomaton(**kwargs)


def test_valid_automaton_queries():
    a = thermostat()
    assert a.mode_names == ("off", "on")
    assert [t.name for t in a.enabled("off", (18.0,), {})] == ["heat"]
    assert a.enabled("off", (20.0,), {}) == ()
    assert a.initial_memory() == {"count": 0.0}


def test_duplicate_mode_names():
    with pytest.raises(ModelDefinitionError, match=r"duplicate mode name\(s\) \['off'\]"):
        thermostat(modes=(Mode(name="off"), Mode(name="off"), Mode(name="on")))


def test_unknown_target_mode():
    bad = Transition(name="x", source="off", target="nowhere", guard=always)
    with pytest.raises(ModelDefinitionError, match=r"target = 'nowhere' is not a mode"):
        thermostat(transitions=(bad,))


def test_unknown_initial_mode():
    with pytest.raises(ModelDefinitionError, match=r"initial_mode = 'idle' is not a mode"):
        thermostat(initial_mode="idle")


def test_reset_writes_unknown_memory():
    bad = Transition(name="x", source="off", target="on", guard=always, reset=lambda v, m: {"n": 1.0}, writes=("n",))
    with pytest.raises(ModelDefinitionError, match=r"writes unknown memory variable\(s\) \['n'\]"):
        thermostat(transitions=(bad,))


def test_guard_reads_unknown_signal():
    bad = Transition(name="x", source="off", target="on", guard=always, reads=("pressure",))
    with pytest.raises(ModelDefinitionError, match=r"reads unknown signal\(s\) \['pressure'\]"):
        thermostat(transitions=(bad,))


def test_transition_field_checks():
    with pytest.raises(ModelDefinitionError, match="direction = 2"):
        Transition(name="x", source="a", target="b", guard=always, direction=2)
    with pytest.raises(ModelDefinitionError, match="guard = 3 is not callable"):
        Transition(name="x", source="a", target="b", guard=3)
    with pytest.raises(ModelDefinitionError, match="writes = \\('m',\\) but reset is None"):
        Transition(name="x", source="a", target="b", guard=always, writes=("m",))
    with pytest.raises(ModelDefinitionError, match="priority = 1.5"):
        Transition(name="x", source="a", target="b", guard=always, priority=1.5)


def test_crossing_direction_semantics():
    rising = Transition(name="up", source="off", target="on", guard=lambda v, m: v[0], direction=1)
    a = thermostat(transitions=(rising,))
    assert a.enabled("off", (0.5,), {}, previous=(-0.5,)) == (rising,)
    assert a.enabled("off", (0.5,), {}, previous=(0.2,)) == ()  # already positive: no crossing
    assert a.enabled("off", (0.5,), {}) == ()  # no history: crossing guards never fire


def test_mode_graph_is_a_frozen_view():
    a = thermostat()
    g = mode_graph(a)
    assert isinstance(g, nx.MultiDiGraph)
    assert nx.is_frozen(g)
    assert sorted(g.edges(keys=True)) == [("off", "on", "heat"), ("on", "off", "cool")]
    assert g.edges["off", "on", "heat"]["guard"] == "T <= 19"
    with pytest.raises(nx.NetworkXError):
        g.add_node("extra")


def test_dot_export_labels():
    dot = to_dot(thermostat())
    assert '"off" -> "on" [label="[0] T <= 19"];' in dot
    assert dot.startswith('digraph "thermostat" {')
