"""A small hybrid-automaton library: models, mode graph, executors, traces.

It knows nothing of robots.  Models: :mod:`hybrid.model` (automata),
:mod:`hybrid.system` (flows, jump maps, outputs), :mod:`hybrid.region` (boxes);
the one rule of an instant: :mod:`hybrid.instant`; executors:
:mod:`hybrid.sampled`, :mod:`hybrid.continuous`; diagnostics and checks:
:mod:`hybrid.diagnostics`, :mod:`hybrid.check` (sampled), :mod:`hybrid.decide` (SMT-decided, on models
written with :mod:`hybrid.symbolic`; z3 terms in :mod:`hybrid.smt`); graph and exports:
:mod:`hybrid.graph`, :mod:`hybrid.affine`, :mod:`hybrid.export`; the JSON
policy: :mod:`hybrid.jsonable`; reference systems: :mod:`hybrid.examples`.

The executors (:mod:`hybrid.continuous`, :mod:`hybrid.sampled`, which load
SciPy's integrators) are imported on first use of one of their names, so that
a structural check does not pay for them.
"""

import importlib as _importlib
from typing import Any as _Any

from .check import CheckReport, Finding, Witness, check
from .decide import Claim, Decision, ParameterSpace, decide, exclusive_for_all
from .diagnostics import ChatterEpisode, ZenoReport, estimate_zeno, find_chatter
from .errors import (
    DivergenceError,
    ExecutionError,
    HybridError,
    ModelDefinitionError,
    NumericalFailure,
    UserFunctionError,
    ZenoError,
)
from .affine import AffineForm, NotAffine, NotAffineError, affine_form
from .export import spacex_config, to_dot, to_json, to_spacex
from .graph import mode_graph
from .model import Conjunction, HybridAutomaton, MemoryVariable, Mode, Transition, all_of, transition_fires
from .region import Box
from .system import HybridSystem
from .symbolic import coordinates, flow_map, jump_map, memory, output_map, param, reset

_LAZY = {
    **dict.fromkeys(("FlowSegment", "HybridEvent", "HybridTrajectory", "simulate_continuous", "GuardResolutionWarning",
                     "UnresolvedWindow"), "continuous"),
    **dict.fromkeys(("Plant", "SampledEvent", "SampledTrace", "settle", "simulate_sampled"), "sampled"),
}


def __getattr__(name: str) -> _Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hybrid' has no attribute {name!r}")
    value = getattr(_importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

__all__ = [
    "coordinates",
    "memory",
    "param",
    "flow_map",
    "jump_map",
    "output_map",
    "reset",
    "check",
    "decide",
    "exclusive_for_all",
    "Decision",
    "Claim",
    "ParameterSpace",
    "CheckReport",
    "Finding",
    "Witness",
    "FlowSegment",
    "HybridEvent",
    "HybridTrajectory",
    "simulate_continuous",
    "ChatterEpisode",
    "ZenoReport",
    "estimate_zeno",
    "find_chatter",
    "DivergenceError",
    "ExecutionError",
    "HybridError",
    "ModelDefinitionError",
    "NumericalFailure",
    "ZenoError",
    "UserFunctionError",
    "GuardResolutionWarning",
    "UnresolvedWindow",
    "mode_graph",
    "to_dot",
    "to_json",
    "to_spacex",
    "spacex_config",
    "affine_form",
    "AffineForm",
    "NotAffine",
    "NotAffineError",
    "HybridAutomaton",
    "MemoryVariable",
    "Mode",
    "Transition",
    "transition_fires",
    "Conjunction",
    "all_of",
    "Plant",
    "SampledEvent",
    "SampledTrace",
    "simulate_sampled",
    "settle",
    "HybridSystem",
    "Box",
]
