"""The guided and white-box searches (issue 29): first violations against Monte-Carlo on planted bugs whose
violating share is known in closed form, gradients against closed forms, determinism and resumption."""

from __future__ import annotations

import json
import math
import statistics

import numpy as np
import pytest

from analysis.verify.falsification import METHODS, evaluate, falsify
from analysis.verify.falsification_search import (central_gradient, folded, physical_vertex, simulations_to_violation,
                                                  space_filling, surrogate_minimum)
from analysis.verify.falsification import Search
from analysis.planted import VIOLATING_FRACTION, planted_problems
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter, VerificationProblem

SEEDS = range(5)


def _first(problem, method, budget, seed):
    search, _ = falsify(problem, budget=budget, seed=seed, method=method)
    count = simulations_to_violation(search)
    return budget + 1 if count is None else count  # not found: censored past the budget


def _geometric_median(p: float) -> int:
    """Monte-Carlo's median count to a first violation: its draws are independent, each violating with the
    share ``p`` of the box, so the count is geometric: the smallest n with 1 - (1 - p)^n >= 1/2."""
    return math.ceil(math.log(0.5) / math.log1p(-p))


@pytest.mark.parametrize("name", sorted(VIOLATING_FRACTION))
def test_guided_needs_no_more_simulations_than_monte_carlo_on_closed_form_planted_bugs(name):
    problem = planted_problems()[name]
    budget = 40
    for method in ("guided", "whitebox"):
        ours = statistics.median(_first(problem, method, budget, s) for s in SEEDS)
        mc = statistics.median(_first(problem, "monte-carlo", budget, s) for s in SEEDS)
        assert ours <= mc, (method, ours, mc)
        assert ours <= _geometric_median(VIOLATING_FRACTION[name]), (method, ours)


def test_the_closed_form_violating_shares_match_dense_sampling():
    # an independent route: 400,000 uniform draws (standard error <= 0.0006 at a share of 0.175)
    rng = np.random.default_rng(12)
    a, b = rng.uniform(-1, 1, (2, 400_000))
    assert ((a + np.minimum(b, 0)) < -0.9).mean() == pytest.approx(VIOLATING_FRACTION["line-corner"], abs=0.003)
    u = rng.uniform(-1, 1, (400_000, 4))
    assert (u.prod(axis=1) > 0.7).mean() == pytest.approx(VIOLATING_FRACTION["ramp-late"], abs=1.5e-4)


def test_the_space_filling_start_is_seeded_and_stratified():
    a, b = space_filling(3, 8, seed=4), space_filling(3, 8, seed=4)
    assert np.array_equal(a, b) and not np.array_equal(a, space_filling(3, 8, seed=5))
    assert a.shape == (8, 3) and np.all(np.abs(a) <= 1.0)
    # a scrambled Sobol net: each coordinate has one point in each eighth of [-1, 1]
    for column in a.T:
        assert sorted(np.floor((column + 1.0) * 4.0).astype(int).tolist()) == list(range(8))
    assert np.array_equal(space_filling(3, 4, seed=4, skip=4), a[4:])


def test_the_surrogate_minimum_is_the_vertex_of_a_linear_model_and_the_centre_of_a_quadratic():
    rng = np.random.default_rng(0)
    xs = rng.uniform(-1, 1, (5, 3))
    ys = xs @ np.array([2.0, -1.0, 0.5]) + 3.0  # exactly linear: the minimum over the box is (-1, 1, -1)
    assert surrogate_minimum(xs, ys).tolist() == [-1.0, 1.0, -1.0]
    xs = rng.uniform(-1, 1, (12, 2))
    ys = (xs[:, 0] - 0.3) ** 2 + 2.0 * (xs[:, 1] + 0.4) ** 2  # separable quadratic: minimiser (0.3, -0.4)
    assert surrogate_minimum(xs, ys) == pytest.approx([0.3, -0.4], abs=1e-9)
    assert surrogate_minimum(xs[:1], ys[:1]) is None


def test_the_physical_vertex_of_a_folded_coordinate_is_its_nominal_end():
    # a parameter whose nominal value is an end of its interval maps u and -u to one value: its vertices (in
    # the parameter's values) are u = 0 and |u| = 1, read back here through Parameter.at, not the search's code
    params = (Parameter(name="brake", low=0.0, high=325.0, nominal=0.0), Parameter(name="lift", low=-2.0, high=5.0,
              nominal=5.0), Parameter(name="throttle", low=0.0, high=100.0, nominal=50.0))
    problem = VerificationProblem(name="fold", simulate=Decay(), parameters=params, horizon=1.0, signals=("x",),
                                  requirements=(Requirement(name="floor", formula="always[0, 1] (x >= 0.1)"),))
    assert folded(problem).tolist() == [True, True, False]
    for point in ([0.3, -0.7, 0.2], [-0.2, 0.6, -0.01], [0.9, 0.1, -1.0]):
        vertex = physical_vertex(np.array(point), folded(problem))
        values = [p.at(u) for p, u in zip(params, vertex)]
        # each value is an end of its interval, the end nearest the point's own value
        for p, u, value in zip(params, point, values):
            assert value in (p.low, p.high)
            assert abs(value - p.at(u)) <= (p.high - p.low) / 2 + 1e-12


class Corner:
    """``x = sum (1 - p_i) + sum q_j`` with ``p_i`` ranging over [0, 1] about 0.5 and ``q_j`` over [0, 1] from
    their nominal 0 (folded): below 0.05 only in a simplex corner of the box, share 0.05^6 / 6! ≈ 2e-11."""

    def __call__(self, point):
        value = sum(1.0 - point[f"p{i}"] for i in range(3)) + sum(point[f"q{j}"] for j in range(3))
        return SignalTrace(times=np.array([0.0, 1.0]), signals={"x": np.full(2, value)})


def test_guided_reaches_a_corner_at_the_nominal_end_of_folded_coordinates():
    params = tuple(Parameter(name=f"p{i}", low=0.0, high=1.0, nominal=0.5) for i in range(3)) + tuple(
        Parameter(name=f"q{j}", low=0.0, high=1.0, nominal=0.0) for j in range(3))
    problem = VerificationProblem(name="corner", simulate=Corner(), parameters=params, horizon=1.0, signals=("x",),
                                  requirements=(Requirement(name="floor", formula="always[0, 1] (x >= 0.05)"),))
    counts = []
    for seed in SEEDS:
        search, falsified = falsify(problem, budget=200, seed=seed, method="guided")
        counts.append(simulations_to_violation(search))
        assert 0 in falsified, (seed, counts)
        # the counterexample read back in the parameters' values: in the corner by the closed form
        point = problem.point(falsified[0][0])
        assert sum(1.0 - point[f"p{i}"] for i in range(3)) + sum(point[f"q{j}"] for j in range(3)) < 0.05
    # Monte-Carlo's expected count is 1 / 2e-11; the vertices and the coordinate moves reach the corner at once
    assert max(counts) <= 60, counts


class Decay:
    """``x(t) = x0 exp(-k t)`` sampled on a fine grid that contains t = 1."""

    def __call__(self, p):
        t = np.linspace(0.0, 1.0, 101)
        return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-p["k"] * t)})


def _decay_problem():
    params = (Parameter(name="x0", low=1.0, high=3.0, nominal=2.0), Parameter(name="k", low=0.5, high=2.5, nominal=1.0))
    return VerificationProblem(name="decay", simulate=Decay(), parameters=params, horizon=1.0, signals=("x",),
                               requirements=(Requirement(name="floor", formula="always[0, 1] (x >= 0.1)"),))


@pytest.mark.parametrize("unit", [(0.4, 0.3), (-0.5, 0.7), (0.9, -0.6)])
def test_the_gradient_of_the_robustness_matches_the_closed_form(unit):
    # robustness = min_t x0 e^{-k t} - 0.1 = x0 e^{-k} - 0.1 (x0, k > 0: the minimum is at t = 1, a grid point);
    # unit coordinates map piecewise linearly: dx0/du = 1 (either side: nominal 2 in [1, 3]), dk/du = 1.5 above
    # the nominal k = 1 and 0.5 below it
    problem = _decay_problem()
    search = Search(problem=problem, budget=10, evaluator=evaluate)
    rho, grad = central_gradient(search, 0, np.array(unit))
    point = problem.point(unit)
    x0, k = point["x0"], point["k"]
    assert rho == pytest.approx(x0 * math.exp(-k) - 0.1, rel=1e-12)
    dk = 1.5 if unit[1] > 0 else 0.5
    expected = [math.exp(-k) * 1.0, -x0 * math.exp(-k) * dk]
    # central differences of half-width h = 2e-3 err by h^2/6 |f'''| <= 1e-6 |f| here (a smooth exponential),
    # far below the tolerance; the stencil stays on one side of the kink at u = 0
    assert grad == pytest.approx(expected, rel=1e-5)
    assert search.used == 5  # the centre and 2k stencil points: one batch


class Bowl:
    """A constant signal, a non-separable convex quadratic of the parameters: its minimum 0.05 is at
    ``x0 = 1.6, k = 1.2``, inside the box and off every vertex and grid a start could hit."""

    def __call__(self, p):
        a, b = p["x0"] - 1.6, p["k"] - 1.2
        value = a * a + b * b + 0.5 * a * b + 0.05
        return SignalTrace(times=np.array([0.0, 1.0]), signals={"x": np.full(2, value)})


@pytest.mark.parametrize("method", ["whitebox", "guided"])
def test_the_local_searches_reach_an_interior_minimum_in_closed_form(method):
    problem = VerificationProblem(name="bowl", simulate=Bowl(), parameters=_decay_problem().parameters, horizon=1.0,
                                  signals=("x",), requirements=(Requirement(name="floor", formula="always[0, 1] (x >= 0.01)"),))
    result = verify(problem, budget=120, seed=0, method=method).requirement("floor")
    assert result.verdict == "not_falsified"
    # the closed-form minimum is 0.05 - 0.01 = 0.04; no search can go below it, and both reach it within 1e-4
    assert 0.04 - 1e-12 <= result.robustness <= 0.04 + 1e-4


class Counted:
    """Counts the calls of a simulator."""

    def __init__(self, simulate):
        self.simulate, self.calls = simulate, 0

    def __call__(self, point):
        self.calls += 1
        return self.simulate(point)


@pytest.mark.parametrize("method", METHODS)
def test_the_same_seed_gives_byte_identical_json_and_a_resumed_search_replays_it(method):
    ramp = planted_problems()["ramp-late"]

    def problem(counter):
        return VerificationProblem(name=ramp.name, simulate=counter, parameters=ramp.parameters, horizon=ramp.horizon,
                                   signals=ramp.signals, requirements=ramp.requirements)

    journal = []
    first = verify(problem(Counted(ramp.simulate)), budget=30, seed=3, method=method, on_evaluation=journal.append)
    again = verify(problem(Counted(ramp.simulate)), budget=30, seed=3, method=method)
    other = verify(problem(Counted(ramp.simulate)), budget=30, seed=4, method=method)
    text = json.dumps(first.as_dict(evaluations=True), sort_keys=True)
    assert text == json.dumps(again.as_dict(evaluations=True), sort_keys=True)
    assert text != json.dumps(other.as_dict(evaluations=True), sort_keys=True)
    # resumed from the first half of the journal: the same points in the same order, byte-identical, and only
    # the second half simulated (plus the counterexample's explanation run, when there is one)
    half = {e.unit: e.outcome for e in journal[: len(journal) // 2]}
    counter = Counted(ramp.simulate)
    resumed = verify(problem(counter), budget=30, seed=3, method=method, cache=half)
    assert json.dumps(resumed.as_dict(evaluations=True), sort_keys=True) == text
    explained = 1 if resumed.requirements[0].counterexample is not None else 0
    assert counter.calls == len(journal) - len(half) + explained
