"""Gradients of the white-box search from a model's sensitivities (analysis.verify.falsification_gradient): the
closed form of a small model, one simulation per gradient, the journal saying which gradient was used, the
finite-difference fallback said, determinism and resumption from the journal."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from analysis.dual import exp, split
from analysis.stl import SignalTrace
from analysis.verify.falsification import Search, evaluate, falsify
from analysis.verify.falsification_book import Evaluation
from analysis.verify.falsification_gradient import sensitivity_gradient, unit_slope
from analysis.verify.requirements import Requirement
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter, VerificationProblem

T = np.linspace(0.0, 1.0, 101)


def _decay_run(x0, k):
    """``x(t) = x0 exp(-k t)``: one code path for floats and duals."""
    return [x0 * exp(-k * float(t)) for t in T]


class Decay:
    def __init__(self):
        self.calls = 0

    def __call__(self, p):
        self.calls += 1
        return SignalTrace(times=T, signals={"x": np.array(_decay_run(p["x0"], p["k"]))})


class DecaySensitivities:
    def __init__(self):
        self.calls = 0

    def __call__(self, p):
        from analysis.dual import variables

        self.calls += 1
        values, grads = split(_decay_run(*variables([p["x0"], p["k"]])), 2)
        return SignalTrace(times=T, signals={"x": values}), {"x": grads}


PARAMS = (Parameter(name="x0", low=1.0, high=3.0, nominal=2.0), Parameter(name="k", low=0.5, high=2.5, nominal=1.0))


def _problem(formula="always[0, 1] (x >= 0.1)", sensitivities=True):
    return VerificationProblem(name="decay", simulate=Decay(), parameters=PARAMS, horizon=1.0, signals=("x",),
                               requirements=(Requirement(name="floor", formula=formula),),
                               sensitivities=DecaySensitivities() if sensitivities else None)


@pytest.mark.parametrize("unit", [(0.4, 0.3), (-0.5, 0.7), (0.9, -0.6)])
def test_the_gradient_from_sensitivities_is_the_closed_form_with_one_simulation(unit):
    # robustness = x0 e^{-k} - 0.1 (the minimum at t = 1); dx0/du = 1, dk/du = 1.5 above nominal, 0.5 below
    problem = _problem()
    search = Search(problem=problem, budget=10, evaluator=evaluate)
    rho, grad = sensitivity_gradient(search, 0, np.array(unit))
    point = problem.point(unit)
    x0, k = point["x0"], point["k"]
    assert rho == pytest.approx(x0 * math.exp(-k) - 0.1, rel=1e-14)
    dk = 1.5 if unit[1] > 0 else 0.5
    assert grad == pytest.approx([math.exp(-k), -x0 * math.exp(-k) * dk], rel=1e-13)  # exact, not ~h^2
    assert search.used == 1 and problem.sensitivities.calls == 1 and problem.simulate.calls == 0
    assert search.evaluations[0].outcome.gradient_method == "sensitivities"


def test_the_unit_slope_follows_the_piecewise_linear_map_and_its_kinks():
    mid = Parameter(name="a", low=0.0, high=4.0, nominal=1.0)  # up 3, down 1
    assert unit_slope(mid, 0.5, 2.0) == 6.0 and unit_slope(mid, -0.5, 2.0) == 2.0
    assert unit_slope(mid, 0.0, -2.0) == -6.0 and unit_slope(mid, 0.0, 2.0) == 2.0  # the side a descent takes
    end = Parameter(name="b", low=0.0, high=325.0, nominal=0.0)  # p = 325 |u|
    assert unit_slope(end, 0.2, -1.0) == -325.0 and unit_slope(end, -0.2, -1.0) == 325.0
    assert unit_slope(end, 0.0, -1.0) == -325.0 and unit_slope(end, 0.0, 1.0) == 0.0  # nominal is a minimiser
    assert unit_slope(Parameter(name="c", low=2.0, high=2.0), 0.3, 5.0) == 0.0


def test_the_result_and_the_journal_say_which_gradient_was_used():
    with_sens = verify(_problem(), budget=30, seed=0, method="whitebox")
    without = verify(_problem(sensitivities=False), budget=30, seed=0, method="whitebox")
    assert with_sens.gradients.startswith("sensitivities")
    assert without.gradients.startswith("central finite differences (the problem gives no sensitivities")
    assert with_sens.as_dict()["gradients"] == with_sens.gradients
    assert "gradients" not in verify(_problem(), budget=30, seed=0, method="guided").as_dict()
    gradients = [e for e in with_sens.evaluations if e.phase == "gradient"]
    assert gradients and all(e.outcome.gradient_method == "sensitivities" and e.outcome.gradient for e in gradients)
    assert all(not e.outcome.gradient_method for e in without.evaluations)
    # a journal line carries the gradient and reads back
    line = json.loads(json.dumps(gradients[0].as_dict()))
    assert Evaluation.from_dict(line) == gradients[0]


def test_a_requirement_whose_signal_has_no_sensitivity_falls_back_to_finite_differences_and_says_why():
    problem = VerificationProblem(
        name="decay", simulate=Decay(), parameters=PARAMS, horizon=1.0, signals=("x", "y"),
        requirements=(Requirement(name="floor", formula="always[0, 1] (y >= 0.1)"),),
        sensitivities=lambda p: (SignalTrace(times=T, signals={"x": np.zeros(T.size), "y": np.array(
            _decay_run(p["x0"], p["k"]))}), {"x": np.zeros((T.size, 2))}))
    problem = VerificationProblem(name="decay", simulate=lambda p: problem.sensitivities(p)[0],
                                  parameters=PARAMS, horizon=1.0, signals=("x", "y"),
                                  requirements=problem.requirements, sensitivities=problem.sensitivities)
    search, _ = falsify(problem, budget=25, seed=0, method="whitebox")
    notes = {e.outcome.gradient_method for e in search.evaluations if e.outcome.gradient_method}
    assert notes and all("none for floor" in n and "'y'" in n for n in notes)
    # the descent went on with central differences: a stencil of 2k = 4 points around a centre
    centre = next(e.unit for e in search.evaluations if e.phase == "gradient" and e.outcome.gradient_method)
    stencil = [e for e in search.evaluations if e.phase == "gradient" and not e.outcome.gradient_method
               and max(abs(a - b) for a, b in zip(e.unit, centre)) <= 2e-3 + 1e-12]
    assert len(stencil) == 4


def test_the_same_seed_gives_byte_identical_json_and_a_resumed_search_replays_it_without_simulating_again():
    journal = []
    first = verify(_problem("always[0, 1] (x >= 0.05)"), budget=40, seed=3, method="whitebox",
                   on_evaluation=journal.append)
    text = json.dumps(first.as_dict(evaluations=True), sort_keys=True)
    assert text == json.dumps(verify(_problem("always[0, 1] (x >= 0.05)"), budget=40, seed=3,
                                     method="whitebox").as_dict(evaluations=True), sort_keys=True)
    assert any(e.phase == "gradient" for e in journal) and len(journal) == 40
    # resumed from the journal's lines as the application stores them (read back from JSON, the later line of a
    # point winning): the same evaluations, byte-identical, and nothing simulated again
    cache = {}
    for e in journal:
        back = Evaluation.from_dict(json.loads(json.dumps(e.as_dict())))
        cache[back.unit] = back.outcome
    problem = _problem("always[0, 1] (x >= 0.05)")
    resumed = verify(problem, budget=40, seed=3, method="whitebox", cache=cache)
    assert json.dumps(resumed.as_dict(evaluations=True), sort_keys=True) == text
    explained = 1 if resumed.requirements[0].counterexample is not None else 0
    assert problem.sensitivities.calls == 0 and problem.simulate.calls == explained


def _corner_problem():
    """A discrete signal (a mode, like a gear): ``g = 1`` only where ``x0 > 2.8`` and ``k < 0.6``, a corner of the box
    of area 0.25 % of it; its sensitivity is 0 everywhere, so the robustness of ``g < 0.5`` (``+-0.5``) is flat."""
    def run(p):
        g = 1.0 if p["x0"] > 2.8 and p["k"] < 0.6 else 0.0
        return SignalTrace(times=T, signals={"g": np.full(T.size, g)})

    return VerificationProblem(name="corner", simulate=run, parameters=PARAMS, horizon=1.0, signals=("g",),
                               requirements=(Requirement(name="mode", formula="always[0, 1] (g < 0.5)"),),
                               sensitivities=lambda p: (run(p), {"g": np.zeros((T.size, 2))}))


def test_a_flat_robustness_restarts_with_a_group_that_reaches_a_corner_soon():
    # a zero gradient says nothing: the descent restarts with a group of the space-filling start (the vertex of the
    # next point's orthant, two surrogate steps, the point), so the corner is a vertex tried within the first
    # groups (the Sobol points' orthants are stratified: 4 groups of at most 4 simulations cover the 4 vertices,
    # plus the nominal point and its gradient).  The descent that restarted from bare Sobol points (one simulation
    # each) needed 25 simulations on seed 0.
    for seed in range(5):
        search, falsified = falsify(_corner_problem(), budget=200, seed=seed, method="whitebox")
        first = next(e.index + 1 for e in search.evaluations if e.violates(0))
        assert first <= 2 + 4 * 4, (seed, first)
        assert search.evaluations[first - 1].unit == (1.0, -1.0)
        assert {e.phase for e in search.evaluations[:first]} <= {"nominal", "gradient", "start", "surrogate"}


def test_the_group_restart_is_deterministic_and_resumes_from_the_journal():
    journal = []
    first = verify(_corner_problem(), budget=60, seed=2, method="whitebox", on_evaluation=journal.append)
    text = json.dumps(first.as_dict(evaluations=True), sort_keys=True)
    assert text == json.dumps(verify(_corner_problem(), budget=60, seed=2, method="whitebox")
                              .as_dict(evaluations=True), sort_keys=True)
    assert any(e.phase == "start" and e.outcome.gradient_method == "sensitivities" for e in journal)
    cache = {}
    for e in journal:
        back = Evaluation.from_dict(json.loads(json.dumps(e.as_dict())))
        cache[back.unit] = back.outcome
    calls = []
    problem = _corner_problem()
    simulate, sens = problem.simulate, problem.sensitivities
    problem = VerificationProblem(name="corner", simulate=lambda p: calls.append(1) or simulate(p),
                                  parameters=PARAMS, horizon=1.0, signals=("g",), requirements=problem.requirements,
                                  sensitivities=lambda p: calls.append(2) or sens(p))
    resumed = verify(problem, budget=60, seed=2, method="whitebox", cache=cache)
    assert json.dumps(resumed.as_dict(evaluations=True), sort_keys=True) == text
    assert calls.count(2) == 0
