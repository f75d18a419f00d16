"""Gradients of the robustness for the ``whitebox`` search: from the model's sensitivities, one simulation each.

A problem whose model differentiates its run (:attr:`analysis.verify.verification.VerificationProblem.sensitivities`:
``d signal(t_i) / d p`` at the trace's samples, e.g. forward-mode dual numbers through the model's own code,
:mod:`analysis.dual`) gives the gradient of each requirement's robustness with one simulation: the sensitivity
of the atom at the sample that decides the robustness (:func:`analysis.stl.gradient.robustness_gradient`),
converted to the search's unit coordinates (:func:`unit_gradients`).  A problem without sensitivities is
differentiated by central finite differences (``2k`` simulations, ``central_gradient`` of
:mod:`analysis.verify.falsification_search`); :func:`gradient_source` says which, and the search's result
and journal carry it (:attr:`analysis.verify.falsification_book.Outcome.gradient_method`).

Counting: a gradient is one simulation (phase ``gradient``), counted in the budget like any other, even at
a point simulated plainly before (the plain run computed no sensitivities); its wall time is that of the
simulation with sensitivities (dual arithmetic: about 17 times a plain AT run, ``docs/verify.md``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from analysis.stl import SignalTrace, TraceError
from analysis.stl.gradient import robustness_gradient
from analysis.verify.falsification_book import Evaluation, Search
from analysis.verify.verification import Parameter, VerificationProblem

__all__ = ["SENSITIVITIES", "FINITE_DIFFERENCES", "gradient_source", "unit_slope", "unit_gradients",
           "simulate_with_gradient", "gradient_of", "sensitivity_gradient", "differentiate_restart"]

SENSITIVITIES = "sensitivities"
""":attr:`Outcome.gradient_method` of a gradient from the model's sensitivities."""
FINITE_DIFFERENCES = "central finite differences"
"""The gradient of a problem without sensitivities (``2k`` simulations per gradient)."""


def gradient_source(problem: VerificationProblem) -> str:
    """How ``whitebox`` differentiates ``problem``'s robustness, in words."""
    if problem.sensitivities is not None:
        return f"{SENSITIVITIES} (the model's, one simulation per gradient)"
    return f"{FINITE_DIFFERENCES} (the problem gives no sensitivities; 2k = {2 * problem.dimension} simulations " \
           "per gradient)"


def unit_slope(parameter: Parameter, u: float, slope: float) -> float:
    """``d rho / d u`` at unit coordinate ``u`` from ``slope = d rho / d p`` (:meth:`Parameter.at` is piecewise
    linear in ``u``).  At ``u = 0``, a kink: the slope of the side a descent would move to (``up`` when
    ``slope < 0``, ``down`` otherwise); with the nominal value at an end (``p`` depends on ``|u|``) the slope of
    ``|u|`` when moving away from nominal lowers the robustness, else 0 (nominal is a local minimiser along ``u``)."""
    nominal = float(parameter.nominal)  # type: ignore[arg-type]
    up, down = parameter.high - nominal, nominal - parameter.low
    if up == 0 and down == 0:
        return 0.0
    if up == 0 or down == 0:
        along = (up - down) * slope  # d rho / d |u|
        if u != 0:
            return math.copysign(1.0, u) * along
        return min(0.0, along)
    if u > 0:
        return up * slope
    if u < 0:
        return down * slope
    return up * slope if slope < 0 else down * slope


def unit_gradients(problem: VerificationProblem, unit: Sequence[float], trace: SignalTrace,
                   sensitivities: Mapping[str, np.ndarray]) -> tuple[tuple[tuple[float, ...], ...], str]:
    """Each requirement's robustness gradient in unit coordinates at ``unit`` (shape ``(k,)`` each), and how it
    was obtained: :data:`SENSITIVITIES`, with the reason when a requirement has none (an empty tuple: a
    signal it reads has no sensitivity)."""
    k = problem.dimension
    out, missing = [], []
    for req, parsed in zip(problem.requirements, problem.parsed):
        try:
            _, g = robustness_gradient(parsed.formula, trace, sensitivities, k)
        except TraceError as error:
            out.append(())
            missing.append(f"{req.name}: {error}")
            continue
        out.append(tuple(unit_slope(p, u, float(s)) if math.isfinite(s) else 0.0
                         for p, u, s in zip(problem.parameters, unit, g)))
    how = SENSITIVITIES if not missing else f"{SENSITIVITIES}; none for {'; '.join(missing)}"
    return tuple(out), how


def simulate_with_gradient(search: Search, x: np.ndarray, phase: str) -> Evaluation:
    """Simulate ``x`` (shape ``(k,)``, clipped to the box) with its sensitivities: :meth:`Search.run_gradient`
    with the search's evaluator, :func:`analysis.verify.falsification.evaluate`, called with
    ``sensitivities=True``.  Raises :class:`~analysis.verify.falsification_book.BudgetExhausted` when the budget
    ends."""
    def differentiate(problem: VerificationProblem, unit: tuple[float, ...], timeout_s: float | None):
        return search.evaluator(problem, unit, timeout_s, sensitivities=True)  # type: ignore[call-arg]

    return search.run_gradient(tuple(float(v) for v in np.clip(x, -1.0, 1.0)), phase, differentiate)


def gradient_of(e: Evaluation, r: int) -> tuple[float | None, np.ndarray | None]:
    """Robustness of requirement ``r`` (clipped to ``+-1e300``) and its gradient in unit coordinates from a
    simulation with sensitivities: ``(None, None)`` when the run was not evaluated, ``(f, None)`` when the model
    gave no gradient for ``r``."""
    o = e.outcome
    if not o.evaluated:
        return None, None
    value = o.robustness[r]
    f0 = 1e300 if math.isnan(value) else max(-1e300, min(1e300, value))
    if len(o.gradient) <= r or not o.gradient[r]:
        return f0, None
    return f0, np.asarray(o.gradient[r], dtype=float)


def sensitivity_gradient(search: Search, r: int, x: np.ndarray, phase: str = "gradient"
                         ) -> tuple[float | None, np.ndarray | None]:
    """Robustness of requirement ``r`` at ``x`` (shape ``(k,)``) and its gradient in unit coordinates (shape
    ``(k,)``) from one simulation with sensitivities (:func:`simulate_with_gradient`, :func:`gradient_of`).
    Raises :class:`~analysis.verify.falsification_book.BudgetExhausted` when the budget ends."""
    return gradient_of(simulate_with_gradient(search, x, phase), r)


def differentiate_restart(search: Search, restart: np.ndarray) -> bool:
    """Where a descent restarts from ``restart``: with sensitivities, simulate it with them now (phase ``start``),
    so that the plain run the search then asks for, and the gradient the next step needs, are this one
    simulation; without, nothing.  Returns ``True`` (the descent restarted)."""
    if search.problem.sensitivities is not None:
        sensitivity_gradient(search, 0, np.clip(restart, -1.0, 1.0), phase="start")
    return True
