"""The sensitivities of CC (examples/arch/chasing_cars.py): the closed forms on dual numbers with the event times'
implicit-function derivatives (saltation), against central differences of the plain simulation at random points
where the discrete path (every sample, every mode) stays the same within the stencil."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from analysis.verify.falsification import falsify

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "arch" / "chasing_cars.py"


@pytest.fixture(scope="module")
def cc():
    spec = importlib.util.spec_from_file_location("arch_chasing_cars_sensitivities_under_test", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _labels(trace):
    return {name: trace.label(name) for name in trace.label_names}


@pytest.mark.parametrize("seed", [1, 2])
def test_the_sensitivities_through_the_events_match_central_differences(cc, seed):
    problem = cc.problems()["CC1"]
    point = problem.point(np.random.default_rng(seed).uniform(-0.9, 0.9, problem.dimension))
    trace, sens = problem.trace_sensitivities(point)
    plain = problem.trace(point)
    assert np.array_equal(trace.times, plain.times) and _labels(trace) == _labels(plain)
    events = sum(a != b for name in trace.label_names for a, b in zip(trace.label(name), trace.label(name)[1:]))
    assert events >= 10  # mode switches whose times depend on the inputs: their derivatives are in the samples
    checked = 0
    for j, parameter in enumerate(problem.parameters):
        h = 1e-5  # truncation ~h^2 (closed forms, smooth between events); the event times are located to 1e-12 s,
        up, down = dict(point), dict(point)  # which errs by ~1e-12 / h = 1e-7 in the differences
        up[parameter.name] += h
        down[parameter.name] -= h
        t_up, t_down = problem.trace(up), problem.trace(down)
        if t_up.n != plain.n or t_down.n != plain.n or _labels(t_up) != _labels(plain) \
                or _labels(t_down) != _labels(plain):
            continue  # an event appeared or vanished within the stencil: no derivative there
        checked += 1
        for name in ("y1", "y4", "y5", "v5"):
            s = sens[name][:, j]
            fd = (t_up.signal(name) - t_down.signal(name)) / (2 * h)
            assert np.max(np.abs(s - fd)) <= 1e-6 * max(1.0, float(np.max(np.abs(s)))), (name, parameter.name)
    assert checked >= 6


def test_the_white_box_search_on_cc1_uses_the_sensitivities(cc):
    search, falsified = falsify(cc.problems()["CC1"], budget=30, seed=0, method="whitebox")
    assert 0 in falsified
    assert any(e.outcome.gradient_method == "sensitivities" for e in search.evaluations)
