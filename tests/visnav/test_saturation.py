"""The saturated closed loop: applied commands clipped to [limits], the demand kept as signals, the variant verified."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest

from analysis.verify.verification import ProblemError
from visnav.app.cli import main
from visnav.closed_loop import DEMAND_RECORDS, clip_command
from visnav.fuzzing.closed_loop import BlendMonitor, simulate_variant
from visnav.fuzzing.variants import make_variant
from visnav.parameters import ActuatorLimits
from visnav.perturbation import apply_perturbation
from visnav.requirements import DEMAND_SIGNALS, demand_requirements, parsed_requirements, run_trace
from visnav.scenario import load_scenario
from visnav.verification import SATURATED, loop_variant, paper_box, paper_problem

#: The counterexample `visnav verify paper` finds to controls_within_limits (docs/verify.md): start heading
#: -0.1 rad and the tall obstacle 5 cm wider; its image starts 43.6 px from the target's (mu_occ = 0.82), and
#: the blend (19), dominated by the occlusion law, demands v = 0.80 m/s at t = 0 against v_max = 0.6.
COUNTEREXAMPLE = {"start.dtheta_rad": -0.1, "obstacles[1].dradius_m": 0.05}


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def point_scenario(scenario):
    perturbation, params = paper_box(scenario)
    drawn = apply_perturbation(scenario, perturbation, [COUNTEREXAMPLE.get(p.name, 0.0) for p in params],
                               source="test")
    assert drawn.scenario is not None, drawn.error
    return drawn.scenario


@pytest.fixture(scope="module")
def saturated_run(point_scenario):
    return simulate_variant(point_scenario, "resolved", saturate=True)


def _limits(scenario):
    lim = scenario.limits
    return np.array([lim.v_max_mps, lim.omega_max_radps, lim.pan_rate_max_radps])


def _demand(trace):
    return np.stack([trace.record(name) for name in DEMAND_RECORDS], axis=1)


# ---------------------------------------------------------------------------------------------
# The clipping and the plant
# ---------------------------------------------------------------------------------------------


def test_clip_command_saturates_each_component_to_its_own_limit():
    limits = ActuatorLimits(v_max_mps=0.6, omega_max_radps=1.2, pan_rate_max_radps=1.5)
    assert clip_command((0.8, -2.0, 1.5), limits) == (0.6, -1.2, 1.5)
    assert clip_command((-0.7, 0.3, -1.6), limits) == (-0.6, 0.3, -1.5)
    assert clip_command((0.1, -0.2, 0.3), limits) == (0.1, -0.2, 0.3)  # inside: unchanged, bit for bit
    v, omega, pan = clip_command((math.nan, math.inf, -math.inf), limits)
    assert math.isnan(v) and (omega, pan) == (1.2, -1.5)  # a NaN is not hidden as a limit


def test_the_applied_command_is_the_clipped_demand_sample_by_sample(point_scenario, saturated_run):
    trace = saturated_run.trace
    demand, applied, lim = _demand(trace), trace.inputs, _limits(point_scenario)
    assert np.array_equal(applied, np.clip(demand, -lim, lim))  # numpy's clip, not the loop's
    clipped = np.flatnonzero(np.any(np.abs(demand) > lim, axis=1))
    # the occlusion law demands v = 0.799 m/s at t = 0, above the limit until 0.2 s
    assert clipped.tolist() == [0, 1, 2, 3, 4]
    assert demand[0, 0] == pytest.approx(0.79891242, abs=1e-6) and applied[0, 0] == lim[0]
    assert np.all(np.abs(applied) <= lim) and saturated_run.metrics.within_actuator_limits


def test_the_recorded_demand_is_the_blend_19(point_scenario):
    """The demand records are (19) recomputed from the recorded µ and the pure controls at every sample
    (:class:`BlendMonitor`, eq. (18)-(19) written out in visnav.fuzzing.loop_mutants), clipped or not."""
    monitor = BlendMonitor(tolerance=1e-12)
    run = simulate_variant(point_scenario, "resolved", saturate=True, blend_monitor=monitor)
    assert monitor.samples == len(run.trace.times) and monitor.skipped == 0
    assert monitor.first_at is None and monitor.worst <= 1e-12


def _rk4_period(state, u, period, steps):
    """The cart and pan ``(v cos θ, v sin θ, ω, ϖ)`` under a constant input, integrated by classical RK4."""
    def f(s):
        return np.array([u[0] * math.cos(s[2]), u[0] * math.sin(s[2]), u[1], u[2]])

    s, h = np.array(state, dtype=float), period / steps
    for _ in range(steps):
        k1 = f(s)
        k2 = f(s + 0.5 * h * k1)
        k3 = f(s + 0.5 * h * k2)
        k4 = f(s + h * k3)
        s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s


def test_the_plant_moves_with_the_applied_command(point_scenario, saturated_run):
    """Each period re-integrated from the recorded state with the applied input held (RK4, 200 steps of 0.25 ms).

    RK4's error over one period is about h^4 T |v| ω^4 ~ 1e-16 m here and the round-off of 200 steps
    ~1e-13 m: 1e-10 m is a tolerance three orders above both.  The demand, held instead over the clipped
    samples, moves the robot 0.2 m/s x 50 ms = 1 cm further: the check tells them apart.
    """
    trace, period = saturated_run.trace, point_scenario.sampling_period_s
    for k in range(0, 200):
        expected = _rk4_period(trace.states[k], trace.inputs[k], period, 200)
        assert np.max(np.abs(expected - trace.states[k + 1])) < 1e-10, k
    demanded = _rk4_period(trace.states[0], _demand(trace)[0], period, 200)
    assert np.hypot(*(demanded[:2] - trace.states[1, :2])) > 5e-3


# ---------------------------------------------------------------------------------------------
# The signals and the two requirements
# ---------------------------------------------------------------------------------------------


def test_the_trace_carries_the_applied_and_the_demanded_command(point_scenario, saturated_run):
    variant = make_variant("resolved", point_scenario.envelopes, point_scenario.supervisor,
                           len(point_scenario.obstacles))
    signals = run_trace(point_scenario, saturated_run.trace, variant)
    post = np.flatnonzero(np.r_[np.diff(signals.times) != 0, True])  # a sample's own row is its last one
    assert post.size == len(saturated_run.trace.times)
    for i, (applied, demand) in enumerate(zip(("v_mps", "omega_radps", "pan_rate_radps"), DEMAND_SIGNALS)):
        assert np.array_equal(signals.signal(applied)[post], saturated_run.trace.inputs[:, i])
        assert np.array_equal(signals.signal(demand)[post], _demand(saturated_run.trace)[:, i])
    values = {p.name: p.formula for p in parsed_requirements(point_scenario)}
    applied = values["controls_within_limits"]
    assert applied.satisfied(signals) and applied.robustness(signals) == 0.0  # v held at the limit itself
    demand = values["demand_within_limits"]
    lim = _limits(point_scenario)
    margin = np.min(lim - np.abs(_demand(saturated_run.trace)))  # the formula's robustness, by numpy
    assert not demand.satisfied(signals)
    assert demand.robustness(signals) == pytest.approx(margin, abs=1e-12) and margin == pytest.approx(-0.1989, abs=1e-4)
    assert demand.explain(signals).time == 0.0


def test_demand_requirements_are_those_reading_the_demand(scenario):
    assert demand_requirements(scenario) == ("demand_within_limits",)


# ---------------------------------------------------------------------------------------------
# The variant in paper_problem and the CLI
# ---------------------------------------------------------------------------------------------


def test_the_saturated_variant_and_its_requirements(scenario):
    published = paper_problem(scenario)
    assert "demand_within_limits" not in published.requirement_names
    assert "controls_within_limits" in published.requirement_names
    assert "not verified here: demand_within_limits" in published.description
    assert published.simulate.saturate is False
    saturated = paper_problem(scenario, SATURATED)
    assert saturated.name == "paper~saturated" and saturated.simulate.saturate is True
    assert saturated.simulate.variant == "resolved"
    assert saturated.requirement_names == tuple(r.name for r in scenario.requirements)
    assert len(saturated.requirement_names) == len(published.requirement_names) + 1
    both = paper_problem(scenario, "paper+saturated")
    assert (both.name, both.simulate.variant, both.simulate.saturate) == ("paper~paper+saturated", "paper", True)
    assert loop_variant("paper") == ("paper", False) and loop_variant("saturated") == ("resolved", True)


def test_a_scenario_with_requirements_on_the_demand_only_needs_the_saturated_loop(scenario):
    import dataclasses

    only = dataclasses.replace(scenario, requirements=tuple(r for r in scenario.requirements
                                                            if r.name == "demand_within_limits"))
    with pytest.raises(ProblemError) as caught:
        paper_problem(only)
    assert "every requirement of scenario 'paper' reads the demand" in caught.value.render()
    assert "variant 'saturated'" in caught.value.render()
    assert paper_problem(only, SATURATED).requirement_names == ("demand_within_limits",)


@pytest.mark.parametrize("name", ["saturate", "bogus+saturated", "saturated+saturated", "paper+", "+saturated",
                                  "", 3, None])
def test_an_unknown_variant_is_refused_naming_the_known_ones(name):
    with pytest.raises(ProblemError) as caught:
        loop_variant(name)
    text = caught.value.render()
    assert "variant" in text and "saturated" in text and "paper" in text and repr(name) in text


def test_the_cli_refuses_an_unknown_variant_with_exit_2(tmp_path, capsys):
    code = main(["verify", "paper", "--variant", "saturation", "--out", str(tmp_path / "v")])
    err = capsys.readouterr().err
    assert code == 2 and "--variant" in err and "'saturation'" in err and "saturated" in err
    assert "Traceback" not in err


def test_a_quick_verification_of_the_saturated_loop(tmp_path):
    """The two limit requirements over the box with 40 simulations: the applied command is never over a limit,
    the demand is (the counterexample, replayed from its file, still violates it)."""
    out = tmp_path / "v"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(["verify", "paper", "--variant", "saturated", "--budget", "40", "--requirement",
                     "controls_within_limits", "--requirement", "demand_within_limits", "--json", "--out", str(out)])
    data = json.loads(stdout.getvalue())
    verdicts = {r["name"]: r for r in data["requirements"]}
    assert code == 1 and data["problem"] == "paper~saturated"
    assert verdicts["controls_within_limits"]["verdict"] == "not_falsified"
    assert verdicts["controls_within_limits"]["robustness"] >= 0.0
    cx = verdicts["demand_within_limits"]["counterexample"]
    assert verdicts["demand_within_limits"]["verdict"] == "falsified" and cx["robustness"] < 0.0
    with contextlib.redirect_stdout(io.StringIO()) as replayed:
        again = main(["replay", cx["file"], "--json"])
    assert again == 1 and json.loads(replayed.getvalue())["robustness"] == pytest.approx(cx["robustness"], abs=0)
