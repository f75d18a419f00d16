"""Problems of affine systems simulate in closed form; batches of points give the traces one by one gives."""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from analysis.verify.loading import load_problem
from analysis.verify.problems import hybrid_problem, trace_from_trajectory
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter, VerificationProblem
from hybrid.continuous import simulate_continuous
from hybrid.examples import thermostat

THERMOSTAT = str(Path(__file__).resolve().parents[3] / "examples" / "thermostat.py") + ":problem"


@pytest.fixture(scope="module")
def problem():
    return load_problem(THERMOSTAT)


def numerical(problem):
    return dataclasses.replace(problem.simulate, options={"closed_form": False})


def switch_times(trace) -> np.ndarray:
    return np.asarray(trace.times)[np.flatnonzero(np.diff(np.asarray(trace.jumps)) > 0) + 1]


def test_the_thermostat_problem_runs_in_closed_form_and_agrees_with_rk45(problem):
    point = {"T0": 20.3, "rate": 0.17}
    exact, rk = problem.simulate(point), numerical(problem)(point)
    assert exact.times.size == rk.times.size and exact.termination == rk.termination == "end_time"
    a, b = switch_times(exact), switch_times(rk)
    assert a.size == b.size > 100
    # independent yardstick: T(t) = T∞ + (T0 - T∞) e^{-kt} from 20.3 °C (off: cools to 19.5, then 20.5 <-> 19.5)
    k, t, T, on, expected = 0.17, 0.0, 20.3, False, []
    for _ in range(a.size):
        target, rest = (20.5, 30.0) if on else (19.5, 10.0)
        t += math.log((T - rest) / (target - rest)) / k
        expected.append(t)
        T, on = target, not on
    assert np.max(np.abs(a - expected)) < 1e-10
    assert np.max(np.abs(b - expected)) < 1e-6  # RK45 at rtol 1e-10, accumulated over ~200 flows
    assert np.max(np.abs(exact.signals["T"] - rk.signals["T"])) < 1e-6
    for req in problem.parsed:
        ra, rb = float(req.formula.robustness(exact)), float(req.formula.robustness(rk))
        assert (ra >= 0) == (rb >= 0) and ra == pytest.approx(rb, abs=1e-6)


def test_without_a_sample_period_the_trace_stays_the_solvers_steps():
    model = thermostat()
    kwargs = dict(name="room", system=model.system, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
                  horizon=30.0, requirements=(Requirement(name="r", formula="always[0, 30] (T <= 22)"),), reach=False)
    stepped = hybrid_problem(**kwargs).simulate({"T0": 20.0})
    sampled = hybrid_problem(**kwargs, sample_period=0.5).simulate({"T0": 20.0})
    # RK45's steps are short (rtol 1e-10): many more samples than the closed form's one step per flow
    assert stepped.times.size > 3 * switch_times(stepped).size + 10
    assert sampled.times.size == pytest.approx(30.0 / 0.5 + 2 * switch_times(sampled).size, abs=4)


def test_traces_of_a_batch_are_the_traces_one_by_one_in_any_executor(problem):
    rng = np.random.default_rng(5)
    points = [problem.point(rng.random(problem.dimension)) for _ in range(4)]
    alone = [problem.trace(p) for p in points]
    for batch in (problem.traces(points), problem.traces(points, cf.ThreadPoolExecutor(2))):
        assert len(batch) == len(alone)
        for a, b in zip(alone, batch):
            assert a.times.tobytes() == b.times.tobytes() and a.jumps.tobytes() == b.jumps.tobytes()
            assert a.signals["T"].tobytes() == b.signals["T"].tobytes() and a.labels == b.labels



def room(point):
    """A module-level (picklable) simulator: the reference thermostat from ``T0``, in closed form."""
    model = thermostat(T0=point["T0"])
    run = simulate_continuous(model.system, model.x0, duration=30.0, closed_form=True)
    return trace_from_trajectory(run, system=model.system, sample_period=0.5)


def test_a_picklable_simulator_runs_its_batch_in_a_process_pool():
    problem = VerificationProblem(name="room", simulate=room, parameters=(Parameter(name="T0", low=19.5, high=20.5),),
                                  horizon=30.0, signals=("T",), labels={"mode": ("off", "on")},
                                  requirements=(Requirement(name="r", formula="always[0, 30] (T <= 22)"),))
    points = [{"T0": 19.6}, {"T0": 20.0}, {"T0": 20.4}]
    alone = [problem.trace(p) for p in points]
    with cf.ProcessPoolExecutor(2) as pool:
        pooled = problem.traces(points, pool)
    assert [t.times.tobytes() for t in pooled] == [t.times.tobytes() for t in alone]
    assert [t.signals["T"].tobytes() for t in pooled] == [t.signals["T"].tobytes() for t in alone]
    assert len({t.signals["T"].tobytes() for t in pooled}) == 3


def test_a_zero_band_thermostat_ends_in_zeno_at_the_analytic_time_on_both_paths():
    zero = load_problem(THERMOSTAT.replace(":problem", ":zero_band"))
    point = {"T0": 20.3, "rate": 0.1}
    exact, rk = zero.simulate(point), numerical(zero)(point)
    assert exact.termination == rk.termination == "zeno"
    # off from 20.3 °C: T reaches the setpoint 20 °C at t = ln(10.3 / 10) / 0.1, and both guards hold there
    t_z = math.log(10.3 / 10.0) / 0.1
    assert float(exact.times[-1]) == pytest.approx(t_z, abs=1e-11)
    assert float(rk.times[-1]) == pytest.approx(t_z, abs=1e-8)
    for req in zero.parsed:
        assert (float(req.formula.robustness(exact)) >= 0) == (float(req.formula.robustness(rk)) >= 0)
