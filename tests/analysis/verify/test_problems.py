"""STL traces of hybrid executions (both sides of every jump) and problem constructors."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.verify.problems import hybrid_problem, sampled_problem, trace_from_sampled, trace_from_trajectory
from analysis.verify.requirements import Requirement
from analysis.verify.verification import Parameter, ProblemError
from hybrid import HybridAutomaton, HybridSystem, Mode, Transition, simulate_continuous
from hybrid.examples import bouncing_ball, thermostat
from hybrid.sampled import Plant, simulate_sampled


def test_every_jump_of_a_bouncing_ball_is_two_samples_at_one_time():
    model = bouncing_ball()
    traj = simulate_continuous(model.system, model.x0, duration=2.0)
    trace = trace_from_trajectory(traj)
    times, jumps, h, v = trace.times, trace.jumps, trace.signal("h"), trace.signal("v")
    assert traj.events
    for e in traj.events:
        after = np.nonzero((times == e.time) & (jumps == e.jump))[0]
        before = np.nonzero((times == e.time) & (jumps == e.jump - 1))[0]
        assert after.size >= 1 and before.size >= 1
        assert before.max() + 1 == after.min()  # adjacent samples, in (t, j) order
        assert v[before.max()] == pytest.approx(e.state_before[1], abs=1e-12)
        assert v[after.min()] == pytest.approx(e.state_after[1], abs=1e-12)
    assert np.all(np.diff(times) >= 0) and np.all(np.diff(jumps) >= 0)
    assert np.all(h >= -1e-9)


def test_an_instantaneous_cycle_at_the_start_keeps_the_initial_state_and_every_mode_it_visits():
    system = _zero_band_thermostat()
    traj = simulate_continuous(system, (20.0,), duration=5.0)
    assert traj.termination == "zeno"
    trace = trace_from_trajectory(traj)
    modes = trace.label("mode")
    assert modes[0] == "off" and trace.jumps[0] == 0
    assert list(modes[:4]) == ["off", "on", "off", "on"]
    assert list(trace.jumps) == list(range(trace.n))
    assert np.all(trace.times == 0.0)


def _zero_band_thermostat() -> HybridSystem:
    a = HybridAutomaton(
        name="t0", variables=("T",), initial_mode="off",
        modes=(Mode(name="off", invariant=lambda v, m: v[0] - 20.0), Mode(name="on", invariant=lambda v, m: 20.0 - v[0])),
        transitions=(Transition(name="heat_on", source="off", target="on", guard=lambda v, m: 20.0 - v[0]),
                     Transition(name="heat_off", source="on", target="off", guard=lambda v, m: v[0] - 20.0)))
    return HybridSystem(automaton=a, state_names=("T",),
                        flows={"off": lambda t, x, m: (-0.1 * (x[0] - 10),), "on": lambda t, x, m: (-0.1 * (x[0] - 30),)})


def test_a_uniform_sample_period_adds_grid_points_inside_segments():
    room = thermostat()
    traj = simulate_continuous(room.system, (20.0,), duration=30.0)
    trace = trace_from_trajectory(traj, sample_period=0.5)
    inner = np.diff(trace.times)
    assert inner.max() <= 0.5 + 1e-12
    # the temperature at the grid points is the dense output, within the solver's tolerance of the closed form
    t = trace.times
    off = (np.array(trace.label("mode")) == "off") & (t < traj.events[0].time)
    assert np.allclose(trace.signal("T")[off], 10 + 10 * np.exp(-0.1 * t[off]), atol=1e-7)


class _Hold:
    record_names = ("u_rec",)

    def initial_state(self, t, x):
        return None

    def measure(self, t, x, c):
        return (x[0],), c

    def control(self, t, x, c, v, mode, memory):
        u = 1.0 if mode == "up" else -1.0
        return (u,), c, (u,)


def _relay():
    a = HybridAutomaton(
        name="relay", variables=("y",), initial_mode="up",
        modes=(Mode(name="up"), Mode(name="down")),
        transitions=(Transition(name="top", source="up", target="down", guard=lambda v, m: v[0] - 1.0),
                     Transition(name="bottom", source="down", target="up", guard=lambda v, m: -1.0 - v[0])))
    plant = Plant(state_names=("x",), input_names=("u",), derivative=lambda x, u: (u[0],),
                  exact_flow=lambda x, u, dt: (x[0] + u[0] * dt,))
    return a, plant, _Hold()


def test_a_sampled_run_gets_one_pre_jump_sample_per_jump_with_held_inputs():
    a, plant, ctl = _relay()
    run = simulate_sampled(a, plant, ctl, (0.0,), period=0.25, duration=6.0)
    trace = trace_from_sampled(run)
    assert trace.n == run.times.size + len(run.events)
    for e in run.events:
        rows = np.nonzero(trace.times == run.times[e.sample])[0]
        assert [trace.label("mode")[r] for r in rows] == [e.source, e.target]
        before, after = rows
        assert trace.signal("x")[before] == trace.signal("x")[after]  # the plant is continuous
        assert trace.signal("u")[before] == run.inputs[e.sample - 1, 0]  # the input held over the last period
        assert trace.signal("u")[after] == run.inputs[e.sample, 0]


def test_sampled_problem_verifies_the_relay_band():
    problem = sampled_problem(
        name="relay", build=lambda p: _relay(), initial={"x": Parameter(name="x0", low=-0.5, high=0.5)},
        period=0.25, horizon=6.0,
        requirements=(Requirement(name="band", formula="always[0, 6] (abs(x) <= 1.25)"),))
    trace = problem.simulate(problem.nominal())
    # x ramps at 1/s, the relay turns at |x| >= 1 on a 0.25 s grid: |x| <= 1 + 0 exactly on this grid
    assert problem.parsed[0].formula.robustness(trace) == pytest.approx(0.25, abs=1e-12)


def test_hybrid_problem_refuses_an_initial_set_that_misses_a_state():
    with pytest.raises(ProblemError) as info:
        hybrid_problem(name="room", system=thermostat().system, initial={}, horizon=10.0,
                       requirements=(Requirement(name="r", formula="always[0, 1] (T > 0)"),))
    assert "missing: ['T']" in str(info.value)


def test_hybrid_problem_refuses_a_formula_on_a_signal_the_system_does_not_have():
    with pytest.raises(ValueError) as info:
        hybrid_problem(name="room", system=thermostat().system, initial={"T": 20.0}, horizon=10.0,
                       requirements=(Requirement(name="r", formula="always[0, 1] (Temp > 0)"),))
    text = str(info.value)
    assert "Temp" in text and "T" in text and "^" in text


def test_structural_checks_of_a_symbolic_system_are_proven_with_the_options_passed_through():
    """hybrid_problem(check_box=...) of a symbolic model: PROVEN claims; method, rates, timeout passed through."""
    import dataclasses
    import pickle

    from analysis.verify.problems import StructuralChecks
    from hybrid import Box

    problem = hybrid_problem(name="room", system=thermostat().system, initial={"T": 20.0}, horizon=10.0,
                             check_box=Box(bounds={"T": (15.0, 25.0)}),
                             requirements=(Requirement(name="r", formula="always[0, 1] (T > 0)"),))
    checks = problem.structural
    assert isinstance(checks, StructuralChecks)
    assert (checks.method, checks.rates, checks.timeout_s) == ("auto", None, 5.0)
    report = checks()
    assert {c.status for c in report.claims.values()} == {"proven"} and report.solver.startswith("z3")
    sampled = dataclasses.replace(checks, method="sampled", samples=40)()
    assert sampled.claim("nondeterminism") == "sampled" and sampled.zeno is None
    # declared rate bounds reach the Zeno dwell bounds: a slower room dwells longer
    slow = dataclasses.replace(checks, rates={"T": 0.1}, timeout_s=2.0)()
    assert slow.zeno.min_dwell_s > report.zeno.min_dwell_s
    # the options themselves pickle (the checks pickle whenever their model and box do)
    options = StructuralChecks(model="model", method="smt", rates={"T": 0.1}, timeout_s=2.0)
    assert pickle.loads(pickle.dumps(options)) == options
