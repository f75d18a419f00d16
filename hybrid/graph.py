"""The mode graph: a derived, frozen ``networkx.MultiDiGraph`` view of an automaton.

Its Graphviz rendering is :func:`hybrid.export.to_dot`.
"""

from __future__ import annotations

import networkx as nx

from .model import HybridAutomaton

__all__ = ["mode_graph"]


def mode_graph(automaton: HybridAutomaton) -> nx.MultiDiGraph:
    """Frozen multigraph: one node per mode, one edge (keyed by name) per transition.

    Node attributes: ``description``, ``invariant``, ``labels``.  Edge attributes:
    ``guard``, ``reset``, ``priority``, ``direction``.  The graph is a view
    derived from the automaton, never its source of truth: it is frozen
    (``nx.is_frozen``) so that nobody edits it by mistake.

    Examples
    --------
    >>> from hybrid.model import HybridAutomaton, Mode, Transition
    >>> a = HybridAutomaton(name="a", modes=(Mode(name="x"), Mode(name="y")),
    ...     transitions=(Transition(name="go", source="x", target="y", guard=lambda v, m: 1.0),),
    ...     variables=())
    >>> g = mode_graph(a)
    >>> list(g.edges(keys=True))
    [('x', 'y', 'go')]
    """
    graph = nx.MultiDiGraph(name=automaton.name, initial_mode=automaton.initial_mode)
    for mode in automaton.modes:
        graph.add_node(
            mode.name,
            description=mode.description,
            invariant=mode.invariant_text,
            labels=dict(mode.labels),
        )
    for t in automaton.transitions:
        graph.add_edge(
            t.source,
            t.target,
            key=t.name,
            guard=t.guard_text,
            reset=t.reset_text,
            priority=t.priority,
            direction=t.direction,
        )
    return nx.freeze(graph)

