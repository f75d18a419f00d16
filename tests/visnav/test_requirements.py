"""visnav.requirements: the STL trace of a closed-loop run and the paper's claims as requirements."""

from __future__ import annotations

import time

import numpy as np
import pytest

from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from visnav.fuzzing.closed_loop import simulate_variant
from visnav.fuzzing.properties import TOLERANCE
from visnav.fuzzing.variants import make_variant
from visnav.requirements import (
    MEMORY,
    SIGNAL_TABLE,
    UNBOUNDED,
    paper_requirements,
    parsed_requirements,
    requirement_values,
    run_trace,
    signal_catalogue,
    signal_descriptions,
)
from visnav.scenario import load_scenario
from visnav.simulation import dense_clearance, simulate

#: The requirements of paper.toml, in file order (the table of docs/requirements.md).
NAMES = (
    "no_collision", "task_success", "controls_within_limits", "demand_within_limits", "mu_in_unit_interval",
    "mu_coll_continuous",
    "mu_occ_continuous", "mu_coll_follows_eq2", "mu_occ_follows_eq3", "reconstruction_while_hidden",
    "reconstruction_error_px_bounded", "reconstruction_depth_error_bounded", "avoid_set_not_before",
    "avoid_set_not_after", "avoid_released_with_leave", "leave_implies_avoid", "leave_after_passing",
    "leave_set_without_occlusion_risk", "leave_set_not_after", "dL_latched_at_leave", "leave_released_not_before",
    "leave_released_not_after", "occlu_set_not_before", "occlu_set_not_after", "occlu_released_not_before",
    "occlu_released_not_after", "DL_latched_at_release", "occlusion_release_ends_not_before",
    "occlusion_release_ends_not_after", "approach_set_not_before", "approach_set_not_after",
    "approach_released_not_before", "approach_released_not_after", "side_latched",
)

#: Lower bounds of the robustness on the paper run where the margin means something (measured value in the
#: comment); the others hold with the margin of a 0/1 flag (0.5) or of the 1e-9 tolerance of an equality.
LOWER_BOUNDS = {
    "no_collision": 0.25,  # 0.2608 m: the minimum clearance along the exact trajectory
    "task_success": 1e-4,  # 0.0034 px: the run stops at the first sample below 1 px
    "controls_within_limits": 0.15,  # 0.156 rad/s below omega_max
    "demand_within_limits": 0.15,  # the same: the loop does not clip, the demand is the applied command
    "reconstruction_error_px_bounded": 0.015,  # max 0.00066 px per point against 0.017
    "reconstruction_depth_error_bounded": 0.11,  # max 0.00065 mm against 0.12
    "avoid_set_not_before": 0.004,  # AVOID set at d = 0.2959 m
    "occlu_set_not_before": 0.3,  # OCCLU set at d_occ = 39.63 px
    "occlu_set_not_after": 0.4,
    "occlusion_release_ends_not_before": 0.4,  # RELEASE -> CLEAR at d_occ = 84.96 px >= D_end = 84.53 px
    "occlusion_release_ends_not_after": 4.0,
    "leave_released_not_before": 0.003,  # LEAVE -> FAR at d = 0.6236 m >= 0.62 m
    "leave_released_not_after": 0.003,
    "approach_released_not_before": 0.001,  # APPROACH -> FAR at d = 0.6214 m >= 0.62 m
}

#: What the paper's logic as printed falsifies on the paper scenario (docs/requirements.md): requirement -> time [s]
#: of the deciding sample (STL explanation).
PAPER_FALSIFIES = {
    "mu_occ_continuous": 27.5,  # OCCLU reset at d_occ >= D0: mu_occ 1 -> 0 (question 8)
    "mu_coll_follows_eq2": 32.0,  # LEAVE set beyond d+: mu_coll = 1, "otherwise" (question 2)
    "task_success": 32.25,  # never released, the robot goes round the tall obstacle: stuck_in_loop
    "side_latched": 42.15,  # no latch: the side the controller reads flips during the avoidance
    "controls_within_limits": 42.25,  # |omega| = 1.95 rad/s > 1.2
    "demand_within_limits": 42.25,  # the same demand: the paper's loop does not clip
    "leave_released_not_after": 43.8,  # d_coll beyond the release band with LEAVE still set
    "reconstruction_error_px_bounded": 60.25,  # during the second, uncontrolled occlusion
    "reconstruction_depth_error_bounded": 60.25,
}

#: Which requirements catch which supervisor mutant in closed loop on the paper scenario.
MUTANT_CATCHERS = {
    "drop_dl_latch": {"task_success", "mu_coll_follows_eq2"},
    "reset_avoid_on_leave": {"controls_within_limits", "demand_within_limits", "mu_coll_continuous",
                             "mu_coll_follows_eq2", "avoid_released_with_leave", "leave_implies_avoid"},
    "no_hysteresis": {"leave_released_not_before", "approach_released_not_before"},
    "no_release_phase": {"mu_occ_continuous"},
    "raw_pan": set(),  # |pan| never reaches pi here: the run is the resolved one, sample for sample
    "equal_priority": set(),  # the pan crosses zero with mu_occ > 0: the tie is never enabled here
}


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def resolved(scenario):
    return simulate(scenario)


@pytest.fixture(scope="module")
def trace(scenario, resolved):
    return run_trace(scenario, resolved.trace, resolved.loop.supervisor)


@pytest.fixture(scope="module")
def values(scenario, trace):
    return dict(requirement_values(scenario, trace))


def _variant_trace(scenario, name):
    run = simulate_variant(scenario, name)
    variant = make_variant(name, scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    return run, run_trace(scenario, run.trace, variant.model, latches_obstacle=variant.latches_obstacle)


@pytest.fixture(scope="module")
def paper_variant(scenario):
    return _variant_trace(scenario, "paper")


# ---------------------------------------------------------------------------------------------
# The catalogue
# ---------------------------------------------------------------------------------------------


def test_catalogue_lists_every_signal_of_the_trace_once(scenario, trace):
    signals, labels = signal_catalogue(scenario)
    assert len(set(signals)) == len(signals)
    assert set(trace.names) == {*signals, "time", "jumps"}
    assert set(trace.label_names) == set(labels) == {"mode"}
    assert {"d_coll_0_m", "d_coll_1_m", *MEMORY, "d_minus", "D_plus", "hysteresis"} <= set(signals)
    assert set(labels["mode"]) == set(resolved_modes(scenario))
    described = signal_descriptions(scenario)
    assert set(described) == {*signals, "time", "jumps"}
    assert all(unit and meaning for unit, meaning in described.values())
    assert set(SIGNAL_TABLE) <= set(signals)


def resolved_modes(scenario):
    from visnav.supervisor import build_supervisor

    return build_supervisor(scenario.envelopes, scenario.supervisor, len(scenario.obstacles)).automaton.mode_names


def test_paper_requirements_are_the_scenario_tables(scenario):
    requirements = paper_requirements(scenario)
    assert all(isinstance(r, Requirement) for r in requirements)
    assert tuple(r.name for r in requirements) == NAMES
    assert all(r.description for r in requirements)
    assert [p.name for p in parsed_requirements(scenario)] == list(NAMES)


# ---------------------------------------------------------------------------------------------
# The trace on the hybrid time domain
# ---------------------------------------------------------------------------------------------


def test_one_pre_jump_row_per_supervisor_jump(resolved, trace):
    sampled = resolved.trace
    events = sampled.events
    assert len(events) == 11 and trace.n == len(sampled.times) + len(events)
    repeated = np.flatnonzero(np.diff(trace.times) == 0)  # row r and r + 1 are the two sides of a jump
    assert repeated.size == len(events)
    modes = trace.label("mode")
    jumps = trace.signal("jumps")
    for r, e in zip(repeated, events):
        assert trace.times[r] == trace.times[r + 1] == e.time
        assert (modes[r], modes[r + 1]) == (e.source, e.target)
        assert jumps[r + 1] == e.jump and jumps[r] == e.jump - 1
    # the rows that are not pre-jump rows are the samples, in order, with their modes and jump counters
    post = np.setdiff1d(np.arange(trace.n), repeated)
    assert np.array_equal(trace.times[post], sampled.times)
    assert [modes[r] for r in post] == [sampled.mode_names[i] for i in sampled.modes]
    assert np.array_equal(jumps[post], sampled.jumps)
    # two jumps at one instant (5.9 s and 27.7 s): one row per intermediate mode
    assert [modes[r] for r in np.flatnonzero(trace.times == 5.9)] == ["APPROACH|CLEAR", "AVOID|CLEAR", "ARMED|CLEAR"]


def test_every_row_of_a_sample_carries_its_measurements(resolved, trace):
    sampled = resolved.trace
    repeated = np.flatnonzero(np.diff(trace.times) == 0)
    for name in ("d_nearest_m", "d_occ_px", "pan_wrapped_rad", "feature_error_px", "clearance_m", "d_coll_0_m"):
        x = trace.signal(name)
        assert np.array_equal(x[repeated], x[repeated + 1]), name
    post = np.setdiff1d(np.arange(trace.n), repeated)
    assert np.array_equal(trace.signal("d_coll_1_m")[post], np.minimum(sampled.signal("d_coll_1_m"), UNBOUNDED))
    # no occluder in view: +inf becomes UNBOUNDED; everything is finite
    assert sampled.signal("d_occ_px").max() == np.inf and trace.signal("d_occ_px").max() == UNBOUNDED
    # before the jumps, the controller's input is the one held until the instant
    for r in repeated:
        k = int(np.searchsorted(sampled.times, trace.times[r]))
        if trace.signal("jumps")[r] == sampled.jumps[k - 1]:  # the first row of the instant
            assert trace.signal("omega_radps")[r] == sampled.input("omega_radps")[k - 1]


def test_mu_at_every_jump_is_the_fuzz_property_definition(resolved, trace):
    """Both sides of every jump: µ of the source mode with the memory before, of the target with the memory after."""
    sampled, model = resolved.trace, resolved.loop.supervisor
    repeated = np.flatnonzero(np.diff(trace.times) == 0)
    memory = model.automaton.initial_memory()
    worst = 0.0
    for r, e in zip(repeated, sampled.events):
        v = sampled.signals[e.sample]
        before = model.risk(e.source, v, memory)  # as check_mu_continuity: j.memory_before
        memory = dict(e.memory)
        after = model.risk(e.target, v, memory)
        assert (trace.signal("mu_coll")[r], trace.signal("mu_occ")[r]) == before
        assert (trace.signal("mu_coll")[r + 1], trace.signal("mu_occ")[r + 1]) == after
        worst = max(worst, abs(before[0] - after[0]), abs(before[1] - after[1]))
    assert worst <= TOLERANCE  # the fuzz property's tolerance, stricter than the requirement's 1e-9
    f = {p.name: p.formula for p in parsed_requirements(resolved.scenario)}["mu_coll_continuous"]
    # the formula measures exactly these jumps: its robustness at each jump row is 1e-9 - |dmu_coll|
    inner = f.tree.arg  # the implication under always
    from analysis.stl.semantics import _Robustness

    rho = _Robustness(trace).value(inner)
    dmu = np.abs(np.diff(trace.signal("mu_coll")))[repeated]
    assert np.allclose(rho[repeated + 1], 1e-9 - dmu, rtol=0, atol=1e-18)


def test_clearance_and_reconstruction_errors(scenario, resolved, trace):
    m = resolved.metrics
    assert trace.signal("clearance_m").min() == dense_clearance(scenario, resolved.trace) == m.min_clearance_m
    assert np.all(trace.signal("clearance_m") <= trace.signal("d_nearest_m") + 1e-12)  # math vs numpy round-off
    px, mm = trace.signal("recon_error_px"), trace.signal("depth_error_mm")
    off = trace.signal("reconstructing") < 0.5
    assert np.all(px[off] == 0.0) and np.all(mm[off] == 0.0)
    # max over points <= the norm over all points that the metrics report
    assert 0.0 < px.max() <= m.max_reconstruction_error_px and 0.0 < mm.max() <= m.max_depth_error_mm


def test_without_clipping_the_demand_is_the_applied_command(resolved, trace):
    """The paper's loop records no demand: the demand signals are the inputs, row for row (pre-jump rows too)."""
    assert "v_demand_mps" not in resolved.trace.record_names
    for applied, demand in (("v_mps", "v_demand_mps"), ("omega_radps", "omega_demand_radps"),
                            ("pan_rate_radps", "pan_rate_demand_radps")):
        assert np.array_equal(trace.signal(applied), trace.signal(demand)), demand


def test_memory_and_flags(trace):
    leave, avoid = trace.signal("leave"), trace.signal("avoid")
    assert set(np.unique(leave)) == set(np.unique(avoid)) == {0.0, 1.0}
    dl = trace.signal("dL")[leave > 0.5]
    assert dl.min() == dl.max() == pytest.approx(0.46424023714946117)
    assert np.array_equal(np.unique(trace.signal("side")), [-1.0, 0.0, 1.0])


def test_conversion_is_fast(scenario, resolved):
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        out = run_trace(scenario, resolved.trace, resolved.loop.supervisor)
        best = min(best, time.perf_counter() - start)
    assert isinstance(out, SignalTrace) and best < 0.05


# ---------------------------------------------------------------------------------------------
# The requirements on the paper run, on the paper's logic as printed, on the mutants
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_every_requirement_holds_on_the_paper_run(values, name):
    value = values[name]
    assert value.satisfied and value.robustness > 0.0, value
    assert value.robustness >= LOWER_BOUNDS.get(name, 1e-9 * (1 - 1e-6))


def test_the_paper_logic_as_printed_is_falsified(scenario, paper_variant):
    run, trace = paper_variant
    assert run.outcome == "stuck_in_loop"
    values = dict(requirement_values(scenario, trace))
    falsified = {n for n, v in values.items() if not v.satisfied}
    assert falsified == {n for n, v in values.items() if v.robustness < 0}
    assert falsified == set(PAPER_FALSIFIES)
    formulas = {p.name: p.formula for p in parsed_requirements(scenario)}
    for name, when in PAPER_FALSIFIES.items():
        assert formulas[name].explain(trace).time == pytest.approx(when), name
    # the first violation: mu_occ jumps from 1 to 0 when the as-written OCCLU is reset at d_occ >= D0
    assert values["mu_occ_continuous"].robustness == -0.5
    jump = np.flatnonzero((np.diff(trace.times) == 0) & (np.abs(np.diff(trace.signal("mu_occ"))) > 0.5))
    assert trace.times[jump[0]] == 27.5 and trace.label("mode")[jump[0]] == "HELD|OCCLUDED"
    assert values["task_success"].robustness < -300.0  # the feature error stays above 300 px


@pytest.mark.parametrize("mutant", sorted(MUTANT_CATCHERS))
def test_mutants_in_closed_loop_are_caught_by(scenario, resolved, mutant):
    run, trace = _variant_trace(scenario, mutant)
    values = dict(requirement_values(scenario, trace))
    caught = {n for n, v in values.items() if not v.satisfied or v.robustness <= 0}
    assert caught == MUTANT_CATCHERS[mutant]
    if not caught:  # not caught because nothing differs on this scenario
        assert np.array_equal(run.trace.states, resolved.trace.states)


def test_a_jump_at_the_start_has_its_pre_jump_row(scenario):
    """Started inside d+ of the low obstacle: FAR -> APPROACH at t = 0, before any input was applied."""
    import dataclasses

    from visnav.parameters import Pose

    near = dataclasses.replace(scenario, start=Pose(x_m=1.05, y_m=0.35), duration_s=0.5, requirements=())
    result = simulate(near)
    assert result.trace.events[0].time == 0.0
    trace = run_trace(near, result.trace, result.loop.supervisor)
    assert trace.times[:2].tolist() == [0.0, 0.0] and trace.jumps[:2].tolist() == [0, 1]
    assert trace.label("mode")[:2] == ("FAR|CLEAR", "APPROACH|CLEAR")
    assert trace.signal("v_mps")[0] == 0.0 and trace.signal("v_mps")[1] == result.trace.input("v_mps")[0]
    assert trace.signal("mu_coll")[0] == trace.signal("mu_coll")[1] == 0.0  # d = 0.55 m is beyond d0
    assert trace.signal("side")[0] == 0.0 and trace.signal("side")[1] == 1.0  # latched at the jump


def test_docs_describe_every_signal_and_requirement(scenario):
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "requirements.md").read_text(encoding="utf-8")
    signals, _ = signal_catalogue(scenario)
    assert [name for name in signals if f"`{name}`" not in text] == []
    assert [name for name in NAMES if f"| `{name}` |" not in text] == []


def test_a_variant_object_gives_its_model_and_latch(scenario, paper_variant):
    run, expected = paper_variant
    variant = make_variant("paper", scenario.envelopes, scenario.supervisor, len(scenario.obstacles))
    trace = run_trace(scenario, run.trace, variant)
    for name in ("side", "obstacle", "mu_coll", "mu_occ", "d_coll_m", "leave"):
        assert np.array_equal(trace.signal(name), expected.signal(name)), name
    assert trace.label("mode") == expected.label("mode")
