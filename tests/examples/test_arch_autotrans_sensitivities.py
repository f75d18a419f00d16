"""The sensitivities of AT (examples/arch/autotrans.py): forward-mode dual numbers through the model's own code,
against finely resolved central differences of the plain simulation at random points of the box (where no shift
moves within the stencil), the same trace as the plain run, and the white-box search using them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from analysis.verify.falsification import falsify

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "arch" / "autotrans.py"


@pytest.fixture(scope="module")
def at():
    spec = importlib.util.spec_from_file_location("arch_autotrans_sensitivities_under_test", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("seed", range(3))
def test_the_sensitivities_match_central_differences_of_the_plain_simulation(at, seed):
    problem = at.problems()["AT6a"]  # 30 s: every control point acts on the run
    rng = np.random.default_rng(seed)
    point = problem.point(rng.uniform(-0.9, 0.9, problem.dimension))
    trace, sens = problem.trace_sensitivities(point)
    plain = problem.trace(point)
    for name in ("speed", "rpm", "gear"):  # the same run: bit-identical samples
        assert np.array_equal(trace.signal(name), plain.signal(name))
    assert not np.any(sens["gear"])  # the gear is discrete
    checked = 0
    for j, parameter in enumerate(problem.parameters):
        # h = 1e-6 of the range: the central difference's truncation (h^2 |x'''|) is negligible, its round-off
        # ~ eps |rpm| / h ~ 1e-8 rpm per %; the tables are piecewise linear, so a stage crossing a breakpoint within
        # +-h makes the two one-sided slopes differ: there the sensitivity (the branch the float run takes) must
        # lie between them; elsewhere it must equal the central difference
        h = 1e-6 * (parameter.high - parameter.low)
        up, down = dict(point), dict(point)
        up[parameter.name] += h
        down[parameter.name] -= h
        t_up, t_down = problem.trace(up), problem.trace(down)
        if not (np.array_equal(t_up.signal("gear"), plain.signal("gear"))
                and np.array_equal(t_down.signal("gear"), plain.signal("gear"))):
            continue  # a shift moved by a tick within the stencil: the map is discontinuous there
        checked += 1
        for name in ("speed", "rpm"):
            s = sens[name][:, j]
            scale = max(1e-9, float(np.max(np.abs(s))))
            forward = (t_up.signal(name) - plain.signal(name)) / h
            backward = (plain.signal(name) - t_down.signal(name)) / h
            central = (forward + backward) / 2
            tol = 1e-5 * scale
            close = np.abs(s - central) <= tol
            between = (s >= np.minimum(forward, backward) - tol) & (s <= np.maximum(forward, backward) + tol)
            assert np.all(close | between), (name, parameter.name, np.max(np.abs(s - central)), scale)
            assert np.mean(close) >= 0.95  # kinks are met at a few samples, not along the run
    assert checked >= 8


def test_a_throttle_on_a_later_segment_does_not_move_the_earlier_samples(at):
    problem = at.problems()["AT1"]
    trace, sens = problem.trace_sensitivities(problem.nominal())
    j = [p.name for p in problem.parameters].index("throttle_3")  # starts at 3 * 30 / 7 = 12.86 s
    before = trace.times < 3 * 30 / 7 - 1e-9
    assert not np.any(sens["speed"][before, j]) and np.any(sens["speed"][~before, j] > 0)


def test_the_white_box_search_takes_its_gradients_from_the_sensitivities_and_says_so(at):
    problem = at.problems()["AT1"]
    journal = []
    search, falsified = falsify(problem, budget=40, seed=0, method="whitebox", on_evaluation=journal.append)
    assert 0 in falsified and "sensitivities" in falsified[0][1]
    gradients = [e for e in journal if e.phase == "gradient"]
    assert gradients and all(e.outcome.gradient_method == "sensitivities" for e in gradients)
    # one simulation per gradient: no finite-difference stencil around any centre
    assert len(gradients) == len({e.unit for e in gradients})
    fd_problem = problem.without_sensitivities()
    _, fd_falsified = falsify(fd_problem, budget=40, seed=0, method="whitebox")
    assert fd_problem.sensitivities is None and all("sensitivities" not in how for _, how in fd_falsified.values())
