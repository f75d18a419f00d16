"""Monte-Carlo campaigns: sampling, classification, aggregation, executors, ``visnav sweep``.

Most runs use ``short.toml``: the paper scenario with a 6 s duration (about 0.02 s of
computation per sample, every run a timeout), so that whole campaigns take a second or two.
"""

import concurrent.futures as cf
import dataclasses
import json
import math
import multiprocessing
import os
import random
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import visnav.simulation
from analysis.campaigns import (
    CampaignOptionError,
    InlineExecutor,
    SchedulerUnavailableError,
    campaign_executor,
    wilson_interval,
)
from hybrid import DivergenceError
from visnav.app.cli import main
from visnav.app.cli_sweep import FLAGS, open_campaign_store
from visnav.closed_loop import desired_features
from visnav.perturbation import PerturbationError, Uniform
from visnav.scenario import load_scenario
from visnav.studies.campaign import (
    CAMPAIGN_OUTCOMES,
    QUANTILES,
    CampaignSpec,
    CampaignSpecError,
    SampleResult,
    run_campaign,
    run_sample,
    sample_scenario,
    summarise,
)

PAPER_TOML = Path(__file__).parents[3] / "visnav" / "scenarios" / "paper.toml"


@pytest.fixture(scope="module")
def short_toml(tmp_path_factory):
    text, count = re.subn(r"(?m)^duration_s = 120\.0.*$", "duration_s = 6.0", PAPER_TOML.read_text())
    assert count == 1
    # the paper's requirements look 90 s ahead, beyond a 6 s run: a campaign does not read them
    text = text[:text.index("[[requirements]]")] if "[[requirements]]" in text else text
    path = tmp_path_factory.mktemp("scenario") / "short.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def short_spec(short_toml):
    return CampaignSpec(scenario=load_scenario(str(short_toml)), samples=24, seed=11)


@pytest.fixture(scope="module")
def short_results(short_spec):
    """The reference: every sample run in this process, in index order."""
    return tuple(run_sample(short_spec, i) for i in range(short_spec.samples))


# ---------------------------------------------------------------------------------------------
# Specification
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("changes, message", [
    ({"samples": 0}, r"samples = 0: expected an integer >= 1; fix: give the number of scenarios"),
    ({"samples": 2.0}, r"samples = 2.0: expected an integer >= 1"),
    ({"seed": -1}, r"seed = -1: expected an integer >= 0; fix: give a non-negative integer seed"),
    ({"start_offset_m": -0.1}, r"start_offset_m = -0.1: expected a finite half-width >= 0; fix: use 0 to disable"),
    ({"target_heading_rad": math.inf}, r"target_heading_rad = inf: expected a finite half-width"),
    ({"obstacle_radius_m": 0.35}, r"obstacle_radius_m = 0.35: expected a half-width below the smallest obstacle "
                                  r"radius \(0.35 m\).*fix: use a value below 0.35"),
    ({"obstacle_height_m": 0.25}, r"obstacle_height_m = 0.25: expected heights of obstacles\[0\] 'low' \(0.3 ± 0.25 m\) "
                                  r"to stay low \(non-occluding\).*fix: use a half-width below 0.2 m"),
    ({"k_path_scale": Uniform(low=0.0, high=1.0)}, r"k_path_scale = \{'low': 0.0, 'high': 1.0\}: expected a factor "
                                                   r"range with low > 0"),
    ({"v_coll_scale": (0.5, 1.0)}, r"v_coll_scale = \(0.5, 1.0\): expected a Uniform"),
    ({"max_attempts": 0}, r"max_attempts = 0: expected an integer >= 1"),
])
def test_spec_validation_names_parameter_value_expectation_fix(paper, changes, message):
    values = {"scenario": paper, "samples": 10, "seed": 0, **changes}
    with pytest.raises(CampaignSpecError, match=message):
        CampaignSpec(**values)


def test_uniform_validation():
    with pytest.raises(PerturbationError, match=r"Uniform = \(2.0, 1.0\): expected low <= high; fix: swap"):
        Uniform(low=2.0, high=1.0)
    with pytest.raises(PerturbationError, match=r"Uniform.high = nan: expected a finite number"):
        Uniform(low=0.0, high=math.nan)
    assert Uniform(low=1.0, high=3.0).at(0.25) == 1.5


def test_perturbation_declares_every_draw_in_order(paper):
    spec = CampaignSpec(scenario=paper, samples=3, seed=0, obstacle_radius_m=0.02)
    moves = spec.perturbation().moves
    assert len(moves) == 3 + 4 * len(paper.obstacles) + 3 + 3
    assert [m.label for m in moves[:3]] == ["start.dx_m", "start.dy_m", "start.dtheta_rad"]
    assert moves[5].field == "obstacles[0].radius_m" and moves[5].draw.half_width == 0.02
    assert [m.field for m in moves[-3:]] == ["gains.k_path", "gains.lambda_vs", "gains.v_coll_mps"]
    assert moves[-3].change == "factor" and moves[-3].draw == spec.k_path_scale


def test_default_perturbation_ranges_keep_the_paper_gains_valid(paper):
    """k and v_coll at the ends of the default factor ranges pass the scenario rules (k range, v_coll <= v_max)."""
    from visnav.parameters import K_PATH_RANGE
    from visnav.scenario import validate_gains

    spec = CampaignSpec(scenario=paper, samples=1, seed=0)
    for k_factor in (spec.k_path_scale.low, spec.k_path_scale.high):
        for v_factor in (spec.v_coll_scale.low, spec.v_coll_scale.high):
            gains = dataclasses.replace(paper.gains, k_path=paper.gains.k_path * k_factor,
                                        v_coll_mps=paper.gains.v_coll_mps * v_factor)
            validate_gains(gains, paper.limits, source="paper")
            assert K_PATH_RANGE[0] <= gains.k_path <= K_PATH_RANGE[1] and gains.v_coll_mps <= paper.limits.v_max_mps


def test_spec_hash_identifies_the_campaign(paper):
    spec = CampaignSpec(scenario=paper, samples=10, seed=0)
    assert spec.spec_hash() == CampaignSpec(scenario=paper, samples=10, seed=0).spec_hash()
    assert spec.spec_hash() != CampaignSpec(scenario=paper, samples=10, seed=1).spec_hash()
    assert spec.spec_hash() != CampaignSpec(scenario=paper, samples=11, seed=0).spec_hash()
    assert spec.spec_hash() != CampaignSpec(scenario=paper, samples=10, seed=0, obstacle_offset_m=0.1).spec_hash()


# ---------------------------------------------------------------------------------------------
# Sampling
# ---------------------------------------------------------------------------------------------


def test_sample_depends_on_seed_and_index_only(paper):
    small = CampaignSpec(scenario=paper, samples=5, seed=7)
    large = CampaignSpec(scenario=paper, samples=500, seed=7)
    assert sample_scenario(small, 3) == sample_scenario(large, 3)
    assert sample_scenario(small, 3) != sample_scenario(small, 2)
    assert sample_scenario(small, 3) != sample_scenario(CampaignSpec(scenario=paper, samples=5, seed=8), 3)


def test_draws_come_from_the_spawned_seed_sequence(paper):
    spec = CampaignSpec(scenario=paper, samples=10, seed=5)
    drawn = sample_scenario(spec, 6)
    assert drawn.attempts == 1
    n_slots = 3 + 4 * len(paper.obstacles) + 3 + 3
    u = np.random.default_rng(np.random.SeedSequence(5).spawn(7)[6]).random(n_slots)
    params = dict(drawn.parameters)
    assert params["start.dx_m"] == pytest.approx(0.2 * (2 * u[0] - 1), abs=1e-15)
    assert params["obstacles[1].dheight_m"] == pytest.approx(0.1 * (2 * u[3 + 4 + 3] - 1), abs=1e-15)
    assert params["gains.k_path"] == pytest.approx(paper.gains.k_path * (0.75 + 0.5 * u[-3]), rel=1e-15)
    assert drawn.scenario.start.x_m == pytest.approx(paper.start.x_m + params["start.dx_m"], abs=1e-15)
    assert drawn.scenario.gains.k_path == params["gains.k_path"]


def test_target_moves_with_the_goal_so_the_desired_image_is_unchanged(paper):
    spec = CampaignSpec(scenario=paper, samples=20, seed=1, target_offset_m=0.5, target_heading_rad=0.2)
    reference = np.array(desired_features(paper))
    moved = 0
    for i in range(spec.samples):
        scenario = sample_scenario(spec, i).scenario
        assert np.allclose(np.array(desired_features(scenario)), reference, rtol=0, atol=1e-12)
        moved += scenario.target.points_m != paper.target.points_m
    assert moved == spec.samples


def test_obstacles_keep_their_occlusion_class_and_the_papers_hypotheses(paper):
    spec = CampaignSpec(scenario=paper, samples=40, seed=2, obstacle_offset_m=0.3, obstacle_height_m=0.19)
    camera = paper.robot.camera_height_m
    for i in range(spec.samples):
        drawn = sample_scenario(spec, i)
        assert drawn.scenario is not None
        low, tall = drawn.scenario.obstacles
        assert 0 < low.height_m < camera <= tall.height_m
        gap = math.dist(low.center_m, tall.center_m) - low.radius_m - tall.radius_m
        assert gap >= 2 * paper.envelopes.d_plus_m


def test_draws_breaking_a_rule_are_redrawn_then_classified_invalid(paper):
    wide = CampaignSpec(scenario=paper, samples=30, seed=0, obstacle_offset_m=1.5, max_attempts=1)
    drawn = [sample_scenario(wide, i) for i in range(wide.samples)]
    invalid = [d for d in drawn if d.scenario is None]
    assert invalid and len(invalid) < wide.samples
    assert all("scenario 'paper#" in d.detail and "fix:" in d.detail for d in invalid)
    result = run_sample(wide, invalid[0].index)  # no simulation for an invalid draw
    assert result.outcome == "invalid_scenario" and result.detail == invalid[0].detail
    assert result.min_clearance_m is None and result.parameters == invalid[0].parameters
    retried = CampaignSpec(scenario=paper, samples=30, seed=0, obstacle_offset_m=1.5, max_attempts=50)
    again = sample_scenario(retried, invalid[0].index)
    assert again.scenario is not None and again.attempts > 1


def test_sample_index_out_of_range(paper):
    spec = CampaignSpec(scenario=paper, samples=3, seed=0)
    with pytest.raises(CampaignSpecError, match=r"index = 3: expected an integer in \[0, 3\)"):
        sample_scenario(spec, 3)


# ---------------------------------------------------------------------------------------------
# One sample
# ---------------------------------------------------------------------------------------------


def test_paper_sample_succeeds_with_its_metrics(paper):
    result = run_sample(CampaignSpec(scenario=paper, samples=1, seed=0), 0)
    assert result.outcome == "success" and result.success
    assert 0.15 < result.min_clearance_m < 0.4
    assert result.final_feature_error_px < paper.success_tolerance_px
    assert result.occlusion_duration_s > 10.0 and result.max_reconstruction_error_px < 0.1
    assert result.transitions >= 4 and result.steps > 1000 and result.within_actuator_limits is True


def test_short_samples_time_out(short_results, short_spec):
    assert {r.outcome for r in short_results} == {"timeout"}
    assert all(r.sim_time_s == pytest.approx(short_spec.scenario.duration_s, abs=0.051) for r in short_results)


def test_outcomes_are_the_run_vocabulary_without_timeout_diagnoses():
    assert CAMPAIGN_OUTCOMES == ("success", "collision", "timeout", "diverged", "invalid_scenario", "error")
    assert set(CAMPAIGN_OUTCOMES) <= set(visnav.simulation.OUTCOMES)


def test_a_diagnosed_timeout_is_stored_as_a_timeout(short_spec, monkeypatch):
    """Format version 1: ``stuck_in_loop`` and ``target_lost`` (visnav.simulation.classify_run) are timeouts."""
    reference = run_sample(short_spec, 0)
    for diagnosis in ("stuck_in_loop", "target_lost"):
        monkeypatch.setattr(visnav.simulation, "classify_run", lambda scenario, trace, metrics, d=diagnosis: d)
        assert run_sample(short_spec, 0) == reference  # outcome "timeout", metrics unchanged
    monkeypatch.setattr(visnav.simulation, "classify_run", lambda scenario, trace, metrics: "collision")
    assert run_sample(short_spec, 0).outcome == "collision"


def test_divergence_and_errors_are_classified_not_raised(short_spec, monkeypatch):
    def diverge(scenario):
        raise DivergenceError(3.25, "NEAR|CLEAR", "NaN in the state")

    monkeypatch.setattr(visnav.simulation, "simulate", diverge)
    result = run_sample(short_spec, 0)
    assert result.outcome == "diverged" and "t = 3.25 s in mode 'NEAR|CLEAR': NaN in the state" in result.detail
    assert result.scenario_digest is not None and result.min_clearance_m is None

    def broken(scenario):
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(visnav.simulation, "simulate", broken)
    result = run_sample(short_spec, 1)
    assert result.outcome == "error" and result.detail == "LinAlgError: singular matrix"


def test_sample_result_round_trips_through_json(short_results):
    for result in short_results[:5]:
        assert SampleResult.from_dict(json.loads(json.dumps(result.as_dict()))) == result
    data = short_results[0].as_dict()
    data["steps"] = -1
    with pytest.raises(ValueError, match=r"field 'steps' = -1: expected an integer >= 0 or null"):
        SampleResult.from_dict(data)
    del data["steps"]
    with pytest.raises(ValueError, match=r"missing \['steps'\]"):
        SampleResult.from_dict(data)


# ---------------------------------------------------------------------------------------------
# Aggregation
# ---------------------------------------------------------------------------------------------


def test_wilson_interval_known_values():
    assert wilson_interval(0, 0) is None
    assert wilson_interval(10, 10) == (pytest.approx(0.722467, abs=1e-6), 1.0)
    assert wilson_interval(0, 10) == (0.0, pytest.approx(0.277533, abs=1e-6))
    lo, hi = wilson_interval(50, 100)
    assert (lo, hi) == (pytest.approx(0.403832, abs=1e-6), pytest.approx(0.596168, abs=1e-6))


def test_summary_is_independent_of_completion_order(short_spec, short_results):
    reference = json.dumps(summarise(short_spec, short_results).as_dict(), sort_keys=True)
    shuffled = list(short_results)
    random.Random(0).shuffle(shuffled)
    assert json.dumps(summarise(short_spec, shuffled).as_dict(), sort_keys=True) == reference


def test_summary_counts_quantiles_and_failures(short_spec, short_results):
    mixed = list(short_results)
    mixed[2] = SampleResult(index=2, outcome="invalid_scenario", detail="x")
    mixed[5] = SampleResult(index=5, outcome="diverged", detail="y")
    summary = summarise(short_spec, mixed[:20])
    assert summary.samples_done == 20 and not summary.complete
    assert dict(summary.counts) == {"success": 0, "collision": 0, "timeout": 18, "diverged": 1,
                                    "invalid_scenario": 1, "error": 0}
    assert summary.success_rate == 0.0 and summary.success_interval == wilson_interval(0, 20)
    assert dict(summary.failures)["diverged"] == (5,) and dict(summary.failures)["invalid_scenario"] == (2,)
    clearances = [r.min_clearance_m for r in mixed[:20] if r.outcome == "timeout"]
    assert [v for _, v in summary.clearance_quantiles_m] == pytest.approx(np.quantile(clearances, QUANTILES))
    assert summary.reconstruction_error_quantiles_px == ()  # no occlusion within 6 s
    with pytest.raises(ValueError, match="result index 3 appears twice"):
        summarise(short_spec, [short_results[3], short_results[3]])


# ---------------------------------------------------------------------------------------------
# Executors
# ---------------------------------------------------------------------------------------------


def test_run_campaign_in_process_gives_the_reference(short_spec, short_results):
    got = []
    with campaign_executor(workers=1) as backend:
        assert backend.kind == "inline" and backend.workers == 1
        count = run_campaign(short_spec, backend.executor, got.append, window=3)
    assert count == short_spec.samples
    assert got == list(short_results)  # in process, results arrive in index order
    # two worker processes: test_same_seed_gives_byte_identical_files_with_two_workers


def test_run_campaign_skips_done_indices(short_spec, short_results):
    got = []
    run_campaign(short_spec, InlineExecutor(), got.append, skip=range(0, 24, 2))
    assert [r.index for r in got] == list(range(1, 24, 2))
    assert got == [short_results[i] for i in range(1, 24, 2)]


def test_interrupt_keeps_delivered_results_and_the_rest_resumes(short_spec, short_results):
    got = []

    def sink(result):
        got.append(result)
        if len(got) == 7:
            raise KeyboardInterrupt

    with campaign_executor(workers=2) as backend:
        with pytest.raises(KeyboardInterrupt):
            run_campaign(short_spec, backend.executor, sink, window=4)
    # the 7th result reached the sink; samples already running were waited for and delivered too
    assert 7 <= len(got) <= 7 + 4 and len({r.index for r in got}) == len(got)
    rest = []
    run_campaign(short_spec, InlineExecutor(), rest.append, skip={r.index for r in got})
    assert sorted(got + rest, key=lambda r: r.index) == list(short_results)


def test_dask_local_cluster_gives_the_reference(short_spec, short_results):
    got = []
    with campaign_executor(dask_local=2) as backend:
        assert backend.kind == "dask" and backend.workers == 2
        assert sum("Dask Worker" in p.name for p in multiprocessing.active_children()) == 2
        run_campaign(short_spec, backend.executor, got.append, window=backend.window)
    assert sorted(got, key=lambda r: r.index) == list(short_results)
    assert not [p for p in multiprocessing.active_children() if "Dask" in p.name]  # the cluster is shut down


def test_running_scheduler_gives_the_reference_and_one_without_workers_is_reported(short_spec, short_results):
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
                      dashboard_address=None) as cluster:
        got = []
        with campaign_executor(scheduler=cluster.scheduler_address, connect_timeout_s=5.0) as backend:
            assert backend.kind == "dask" and backend.workers == 1
            run_campaign(short_spec, backend.executor, got.append, window=backend.window)
        assert sorted(got, key=lambda r: r.index) == list(short_results)
    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", dashboard_address=None) as empty:
        start = time.perf_counter()
        with pytest.raises(SchedulerUnavailableError, match="the scheduler has no worker within the connect timeout "
                                                            "of 1 s; fix: start workers"):
            with campaign_executor(scheduler=empty.scheduler_address, connect_timeout_s=1.0):
                pass
        assert time.perf_counter() - start < 1.0 + 1.5


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_scheduler_not_listening_fails_within_the_timeout():
    address = f"tcp://127.0.0.1:{_free_port()}"
    start = time.perf_counter()
    with pytest.raises(SchedulerUnavailableError, match=re.escape(f"scheduler address '{address}': no Dask "
                                                                  "scheduler answered") + r".*within the connect "
                                                                  r"timeout of 1 s.*or raise connect_timeout_s"):
        with campaign_executor(scheduler=address, connect_timeout_s=1.0):
            pass
    assert time.perf_counter() - start < 1.0 + 1.5


def test_scheduler_that_accepts_but_never_answers_fails_within_the_timeout():
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        start = time.perf_counter()
        with pytest.raises(SchedulerUnavailableError, match="within the connect timeout of 1 s; fix: start one"):
            with campaign_executor(scheduler=address, connect_timeout_s=1.0):
                pass
        assert time.perf_counter() - start < 1.0 + 1.5


@pytest.mark.parametrize("options, message, flags", [
    ({"scheduler": "localhost:8786"}, r"scheduler address = 'localhost:8786': expected an address tcp://HOST:PORT",
     r"--scheduler = 'localhost:8786': expected an address tcp://HOST:PORT.*; fix: e.g. --scheduler tcp://"),
    ({"scheduler": "tcp://host:99999"}, r"expected an address tcp://HOST:PORT", r"--scheduler = 'tcp://host:99999'"),
    ({"workers": 0}, r"workers = 0: expected an integer >= 1", r"--workers = 0: expected an integer >= 1"),
    ({"workers": 2, "dask_local": 2}, r"dask_local = 2: expected one executor option, but workers and dask_local",
     r"--dask-local = 2: expected one executor option, but --workers and --dask-local"),
    ({"workers": 2, "connect_timeout_s": 0}, r"connect_timeout_s = 0: expected a positive number of seconds",
     r"--connect-timeout = 0: expected a positive number of seconds"),
])
def test_executor_options_are_validated(options, message, flags):
    """The library names its parameters; ``visnav sweep`` shows them as its flags (FLAGS)."""
    with pytest.raises(CampaignOptionError, match=message) as info:
        with campaign_executor(**options):
            pass
    assert "--" not in str(info.value)
    assert re.search(flags, info.value.render(FLAGS))


def test_run_campaign_window_is_validated(short_spec):
    with pytest.raises(CampaignOptionError, match=r"window = 0: expected an integer >= 1"):
        run_campaign(short_spec, InlineExecutor(), print, window=0)


def test_run_campaign_in_index_order(short_spec, short_results):
    got = []
    with campaign_executor(workers=2) as backend:
        run_campaign(short_spec, backend.executor, got.append, window=4, order="index", skip={5})
    assert got == [r for r in short_results if r.index != 5]


# ---------------------------------------------------------------------------------------------
# visnav sweep
# ---------------------------------------------------------------------------------------------


def sweep_args(short_toml, out, *extra):
    return ["sweep", "--scenario", str(short_toml), "--samples", str(SWEEP_N), "--seed", "4", "--out", str(out), *extra]


SWEEP_N = 60


@pytest.fixture(scope="module")
def reference_run(short_toml, tmp_path_factory):
    """An uninterrupted ``visnav sweep`` in this process (1 worker)."""
    out = tmp_path_factory.mktemp("reference")
    assert main(sweep_args(short_toml, out, "--workers", "1", "--json")) == 0
    return out


def _start_sweep(short_toml, out, *extra):
    return subprocess.Popen([sys.executable, "-m", "visnav.app.cli", *sweep_args(short_toml, out, *extra)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_lines(path, count, proc, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and path.read_bytes().count(b"\n") >= count:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.01)
    raise AssertionError(f"{path} did not reach {count} lines")


def test_sweep_output_and_summary(reference_run, capsys):
    summary = json.loads((reference_run / "summary.json").read_text())
    assert summary["summary"]["complete"] and summary["summary"]["samples_done"] == SWEEP_N
    assert summary["summary"]["counts"]["timeout"] == SWEEP_N
    assert summary["campaign"]["seed"] == 4 and summary["campaign"]["samples"] == SWEEP_N
    lines = (reference_run / "results.jsonl").read_text().splitlines()
    assert [json.loads(line)["result"]["index"] for line in lines[1:]] == list(range(SWEEP_N))


def test_same_seed_gives_byte_identical_files_with_two_workers(short_toml, reference_run, tmp_path, capsys):
    assert main(sweep_args(short_toml, tmp_path, "--workers", "2", "--json")) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["executor"] == "process pool, 2 workers" and out["ran"] == SWEEP_N and out["scenarios_per_s"] > 0
    for name in ("results.jsonl", "summary.json"):
        assert (tmp_path / name).read_bytes() == (reference_run / name).read_bytes()


@pytest.mark.parametrize("workers", ["1", "2"])
def test_sigkill_halfway_then_resume_equals_uninterrupted(short_toml, reference_run, tmp_path, capsys, workers):
    proc = _start_sweep(short_toml, tmp_path, "--workers", workers)
    results = tmp_path / "results.jsonl"
    _wait_for_lines(results, 1 + 20, proc)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    stored = results.read_bytes().count(b"\n") - 1
    assert 20 <= stored < SWEEP_N  # really halfway
    assert main(sweep_args(short_toml, tmp_path, "--workers", workers, "--json")) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["resumed"] >= 20 and out["resumed"] + out["ran"] == SWEEP_N
    for name in ("results.jsonl", "summary.json"):
        assert (tmp_path / name).read_bytes() == (reference_run / name).read_bytes()


def test_sigint_flushes_reports_and_resumes(short_toml, reference_run, tmp_path, capsys):
    proc = _start_sweep(short_toml, tmp_path, "--workers", "2")
    results = tmp_path / "results.jsonl"
    _wait_for_lines(results, 1 + 15, proc)
    start = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert time.monotonic() - start < 10
    assert proc.returncode == 130 and "Traceback" not in err
    stored = int(re.search(r"interrupted: (\d+) of 60 samples are stored in", err)[1])
    assert "rerun the same command to resume" in err
    store, report = open_campaign_store(results, CampaignSpec(scenario=load_scenario(str(short_toml)), samples=SWEEP_N,
                                                              seed=4))
    with store:
        assert report.bad_lines == () and len(store.done) == stored < SWEEP_N  # flushed, nothing cut
    assert main(sweep_args(short_toml, tmp_path, "--workers", "1")) == 0
    assert (tmp_path / "summary.json").read_bytes() == (reference_run / "summary.json").read_bytes()
    assert (tmp_path / "results.jsonl").read_bytes() == (reference_run / "results.jsonl").read_bytes()


def test_corrupted_results_file_is_reported_repaired_and_completed(short_toml, reference_run, tmp_path, capsys):
    lines = (reference_run / "results.jsonl").read_text().splitlines(keepends=True)
    damaged = lines[:10] + ["{not json\n"] + lines[11:30] + [lines[30][:50]]  # a bad middle line and a cut last one
    (tmp_path / "results.jsonl").write_text("".join(damaged))
    assert main(sweep_args(short_toml, tmp_path, "--workers", "1")) == 0
    err = capsys.readouterr().err
    assert "results.jsonl: line 11: not valid JSON" in err
    assert "line 31: not valid JSON" in err and "the write was cut" in err
    assert "kept 28 valid results and rewrote the file without the 2 bad line(s)" in err
    assert (tmp_path / "summary.json").read_bytes() == (reference_run / "summary.json").read_bytes()


def test_resume_with_other_options_is_refused(short_toml, reference_run, tmp_path, capsys):
    (tmp_path / "results.jsonl").write_bytes((reference_run / "results.jsonl").read_bytes())
    args = sweep_args(short_toml, tmp_path, "--workers", "1")
    args[args.index("--seed") + 1] = "5"
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "belongs to another campaign" in err and "seed 4 in the file, 5 now" in err and "fix:" in err


def test_sweep_bad_input_exits_2(short_toml, tmp_path, capsys):
    assert main(["sweep", "--scenario", "nowhere", "--out", str(tmp_path)]) == 2
    assert "nowhere" in capsys.readouterr().err
    blocker = tmp_path / "plain-file"
    blocker.write_text("")
    assert main(["sweep", "--scenario", str(short_toml), "--samples", "2", "--out", str(blocker / "sub")]) == 2
    assert "--out" in capsys.readouterr().err
    address = f"tcp://127.0.0.1:{_free_port()}"
    start = time.perf_counter()
    code = main(["sweep", "--scenario", str(short_toml), "--samples", "2", "--out", str(tmp_path / "s"),
                 "--scheduler", address, "--connect-timeout", "1"])
    assert code == 2 and time.perf_counter() - start < 1.0 + 2.0
    err = capsys.readouterr().err
    assert f"--scheduler '{address}': no Dask scheduler answered" in err and "connect timeout of 1 s" in err
    assert "or raise --connect-timeout" in err and "connect_timeout_s" not in err
    with pytest.raises(SystemExit) as info:
        main(["sweep", "--workers", "2", "--dask-local", "2"])
    assert info.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


def test_sweep_help_lists_the_options():
    proc = subprocess.run([sys.executable, "-m", "visnav.app.cli", "sweep", "--help"], capture_output=True, text=True,
                          env={**os.environ, "COLUMNS": "200"})
    assert proc.returncode == 0
    for option in ("--scenario", "--samples", "--seed", "--out", "--workers", "--dask-local", "--scheduler",
                   "--connect-timeout", "--no-worker-timeout", "--json", "--progress"):
        assert option in proc.stdout


def test_cf_executor_interface_is_what_run_campaign_needs():
    future = InlineExecutor().submit(divmod, 7, 2)
    assert isinstance(future, cf.Future) and future.result() == (3, 1)
    failed = InlineExecutor().submit(divmod, 1, 0)
    assert isinstance(failed.exception(), ZeroDivisionError)


def test_progress_bar_on_request(short_toml, tmp_path, capsys):
    args = ["sweep", "--scenario", str(short_toml), "--samples", "3", "--out", str(tmp_path), "--workers", "1"]
    assert main([*args, "--progress"]) == 0
    err = capsys.readouterr().err
    assert "\rsweep [" in err and "] 3/3 " in err and err.endswith("\n")
    (tmp_path / "summary.json").unlink()
    assert main(args) == 0  # complete already: nothing to run, the summary is written again
    captured = capsys.readouterr()
    assert captured.err == "" and "none needed (every sample was already stored)" in captured.out
    assert (tmp_path / "summary.json").exists()
