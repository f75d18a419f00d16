"""Reachability of symbolic affine hybrid automata with zonotopes (sound under floating point).

Build a :class:`hybrid.system.HybridSystem` with :mod:`hybrid.symbolic` flows, jump maps, guards and
invariants; :func:`reach` reads their affine forms exactly from the expression trees and returns a
:class:`ReachResult` (the flowpipe, the jumps, the reasons it stopped, the distances to unsafe sets).
The method and the soundness argument are in ``docs/reachability.md``.  Verdicts of STL safety
requirements from flowpipes, with an independent re-check: :mod:`analysis.reach.verdict`.

Examples
--------
>>> from hybrid.examples import thermostat
>>> from hybrid.symbolic import coordinates
>>> room = thermostat()
>>> T = coordinates("T")
>>> result = reach(room.system, {"T": (20.0, 20.0)}, horizon=30.0, time_step=0.05, max_jumps=4,
...                unsafe=[unsafe_set("too hot", T.T >= 21.05, ("T",))])
>>> result.status, result.distances[0][1] > 0
('complete', True)
"""

from .affine import AffineError, AffineForm, Halfspace, Polyhedron, affine_form, affine_vector, condition_polyhedra
from .engine import ModeInput, reach
from .fragment import NotInFragment, SafetyFragment, safety_fragment
from .initial import ReachError, initial_zonotope
from .model import AffineHybridModel, affine_model
from .result import INCONCLUSIVE, ReachJump, ReachResult, ReachSegment, Termination, zonotope_contains
from .sets import UnsafeSet, unsafe_set
from .recheck import RecheckResult, recheck_flowpipe
from .verdict import ReachDecision, ReachProof, decide, reach_proof
from .zonotope import Zonotope, interval_hull, linear_map, minkowski_sum, reduce_order, support_bounds

__all__ = [
    "AffineError",
    "AffineForm",
    "Halfspace",
    "Polyhedron",
    "affine_form",
    "affine_vector",
    "condition_polyhedra",
    "ModeInput",
    "ReachError",
    "initial_zonotope",
    "reach",
    "AffineHybridModel",
    "affine_model",
    "INCONCLUSIVE",
    "ReachJump",
    "ReachResult",
    "ReachSegment",
    "Termination",
    "zonotope_contains",
    "UnsafeSet",
    "unsafe_set",
    "Zonotope",
    "interval_hull",
    "linear_map",
    "minkowski_sum",
    "reduce_order",
    "support_bounds",
    "NotInFragment",
    "SafetyFragment",
    "safety_fragment",
    "RecheckResult",
    "recheck_flowpipe",
    "ReachDecision",
    "ReachProof",
    "decide",
    "reach_proof",
]
