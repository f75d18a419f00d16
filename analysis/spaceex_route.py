"""The input route of a SpaceEx problem with bounded non-deterministic inputs, as ``visnav reach`` reads it.

:func:`analysis.spaceex.spaceex_problem` simulates a model with inputs through :class:`analysis.spaceex.InputSignals`
(each input a piecewise-constant signal of problem parameters); reachability takes each input instead as any
measurable signal within its bounds (:mod:`analysis.spaceex_reach`).  :func:`problem_input_route` gives what a
reachability run of the whole problem needs (:func:`analysis.reach.problem.problem_reach`): the model with every
input at 0, ``{mode: ModeInput}`` and the parameters of the simulated signals (which are not states of a flowpipe).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hybrid.spaceex_inputs import SpaceExInput
from hybrid.system import HybridSystem

from analysis.spaceex import InputSignals, input_parameters
from analysis.verify.problems import HybridSimulation

__all__ = ["InputRoute", "problem_input_route"]


@dataclass(frozen=True, kw_only=True, slots=True)
class InputRoute:
    """A problem's model with bounded non-deterministic inputs, as reachability reads it.

    Attributes
    ----------
    system : HybridSystem
        The model with every input at 0 (affine when reachability can read it).
    matrices : dict {mode: ModeInput}
        ``B`` and the input box per mode.
    inputs : tuple of SpaceExInput
        The inputs (name, bounds).
    signal_parameters : tuple of str
        The problem's parameters of the simulated input signals (not states of the flowpipe).
    """

    system: HybridSystem
    matrices: Mapping[str, Any]
    inputs: tuple[SpaceExInput, ...]
    signal_parameters: tuple[str, ...]


def problem_input_route(problem: Any) -> InputRoute | None:
    """The input route of a SpaceEx problem with inputs (:func:`analysis.spaceex.spaceex_problem`), else None.

    Raises
    ------
    analysis.reach.affine.AffineError
        A flow not affine in the states and the inputs (:func:`analysis.spaceex_reach.input_reach_model`).
    """
    from analysis.spaceex_reach import input_reach_model

    build = problem.simulate.build if isinstance(problem.simulate, HybridSimulation) else None
    if not isinstance(build, InputSignals) or not build.inputs:
        return None
    zero, matrices = input_reach_model(build.system, build.input_flows, build.inputs)
    names = tuple(p.name for p in input_parameters(build.inputs, build.points))
    return InputRoute(system=zero, matrices=matrices, inputs=tuple(build.inputs), signal_parameters=names)
