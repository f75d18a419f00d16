"""The stiffness study of equation (13): Jacobians, spectra, the reconstruction problem, the CLI."""

import dataclasses
import json

import numpy as np
import pytest

from analysis.integrators import FIXED_STEP_SCHEMES, REFERENCE_SCHEMES, integrate
from visnav import model
from visnav.app.cli import main
from visnav.estimator import mean_camera_screw
from visnav.parameters import EstimatorSettings
from visnav.scenario import load_scenario, scenario_digest
from visnav.simulation import simulate
from visnav.studies.stiffness import (
    QUICK_SETTINGS,
    REFERENCE_SETTINGS,
    StiffnessStudyError,
    StudySettings,
    histopolant_screw,
    jacobian_blocks,
    occlusion_window,
    orbit_problem,
    paper_metrics,
    random_scenarios,
    reconstruction_problem,
    replay_estimator,
    replay_zoh_rk4,
    spectrum_of_run,
    stiffness_study,
)


@pytest.fixture(scope="module")
def paper():
    scenario = load_scenario("paper")
    return scenario, simulate(scenario)


@pytest.fixture(scope="module")
def window(paper):
    return occlusion_window(paper[1])


@pytest.fixture(scope="module")
def screw(paper):
    return histopolant_screw(paper[1])


# --------------------------------------------------------------------------- ∂F/∂ψ


def _random_states(rng, k):
    psi = np.column_stack([rng.uniform(-0.3, 0.3, k), rng.uniform(-0.3, 0.3, k), rng.uniform(0.5, 8.0, k)])
    screws = rng.uniform(-0.8, 0.8, (k, 3))
    return psi, screws


def test_casadi_jacobian_equals_the_closed_form_and_finite_differences():
    rng = np.random.default_rng(3)
    psi, screws = _random_states(rng, 20)
    blocks = jacobian_blocks(psi, screws)[:, 0]
    for (x, y, z), s, block in zip(psi, screws, blocks):
        closed = np.array(model.feature_depth_rate_jacobian(x, y, z, *s))
        assert np.allclose(block, closed, rtol=1e-14, atol=1e-15)
        # central differences, step 1e-6: truncation O(1e-12 |F'''|), round-off O(1e-16/1e-6)
        fd = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1e-6
            fd[:, j] = (np.array(model.feature_depth_rate(*(psi_i := np.array([x, y, z]) + e), *s))
                        - np.array(model.feature_depth_rate(*(psi_i - 2 * e), *s))) / 2e-6
        assert np.allclose(block, fd, atol=1e-8)


def test_eigenvalues_match_the_closed_form_of_the_block():
    # X feeds neither Ẏ nor ż: λ_X = V_z/z + Y Ω_x, and the (Y, z) block has
    # trace V_z/z + Y Ω_x and determinant Ω_x V_y/z − 2 Y Ω_x V_z/z − 2 Y² Ω_x².
    rng = np.random.default_rng(5)
    psi, screws = _random_states(rng, 50)
    blocks = jacobian_blocks(psi, screws)[:, 0]
    for (x, y, z), (vy, vz, wx), block in zip(psi, screws, blocks):
        eig = np.linalg.eigvals(block)
        lam_x = vz / z + y * wx
        trace = vz / z + y * wx
        det = wx * vy / z - 2 * y * wx * vz / z - 2 * y * y * wx * wx
        pair = np.roots([1.0, -trace, det])
        expected = np.sort_complex(np.concatenate([[lam_x], pair]))
        assert np.allclose(np.sort_complex(eig), expected, atol=1e-12)


def test_problem_rhs_and_jacobian_are_the_model_s(window, screw):
    problem = reconstruction_problem(window, screw)
    t = float(window.times[10])
    y = np.array(window.psi[10])
    s = screw(t)
    expected = np.concatenate([model.feature_depth_rate(*y[3 * i : 3 * i + 3], *s) for i in range(window.n_points)])
    assert np.allclose(problem.f(t, y), expected, rtol=1e-15, atol=0)
    blocks = jacobian_blocks(y[None, :], np.array([s]))[0]
    jac = problem.jac(t, y)
    for i in range(window.n_points):
        assert np.allclose(jac[3 * i : 3 * i + 3, 3 * i : 3 * i + 3], blocks[i], rtol=1e-14, atol=1e-16)
    assert np.count_nonzero(jac) <= 9 * window.n_points  # block diagonal


# --------------------------------------------------------------------------- window and input


def test_occlusion_window_of_the_paper(paper, window):
    _, run = paper
    assert window.hidden[0] == False  # noqa: E712 - the last sample with every feature measured
    assert window.hidden[1:].all() and window.pans.size == 347  # 17.35 s of occlusion
    assert window.duration == pytest.approx(run.metrics.occlusion_duration_s, abs=1e-9)
    k = window.start_index
    assert window.psi[0][2] == run.trace.record("z0")[k]
    assert window.history_psi.shape == (7, 12) and np.array_equal(window.history_psi[-1], window.psi[0])


def test_a_scenario_without_occlusion_is_refused(paper):
    scenario = dataclasses.replace(paper[0], obstacles=())
    with pytest.raises(StiffnessStudyError, match=r"no feature is ever hidden.*use a scenario whose tall obstacle"):
        occlusion_window(simulate(scenario))


def test_histopolant_means_equal_the_exact_zoh_means(paper, screw):
    _, run = paper
    trace = run.trace
    h = trace.period
    g = run.scenario.robot
    nodes, weights = np.polynomial.legendre.leggauss(4)  # exact for degree <= 7 (the spline has 6)
    for k in range(150, 560, 37):
        t0 = float(trace.times[k])
        ts = t0 + 0.5 * h * (nodes + 1.0)
        mean = 0.5 * sum(w * np.array(screw(t)) for w, t in zip(weights, ts))
        exact = mean_camera_screw(float(trace.states[k, 3]), *map(float, trace.inputs[k]), h, g)
        assert np.allclose(mean, exact, rtol=0, atol=1e-12)


def test_histopolant_casadi_form_equals_the_numeric_one(screw, window):
    import casadi as ca

    t = ca.MX.sym("t")
    f = ca.Function("T", [t], [screw.casadi(t)])
    for time in np.linspace(window.times[0], window.times[-1], 7):
        assert np.allclose(np.array(f(time)).reshape(-1), screw(float(time)), rtol=0, atol=1e-12)


def test_orbit_exact_solution_satisfies_the_ode(paper):
    problem, exact = orbit_problem(paper[0])
    for t in (0.0, 3.3, 7.1, 11.9):
        dt = 1e-5  # central difference: error O(dt² |ψ'''|) ~ 1e-10
        derivative = (exact(t + dt) - exact(t - dt)) / (2 * dt)
        assert np.allclose(derivative, problem.f(t, exact(t)), atol=1e-8)
    assert np.all(exact(problem.t1)[2::3] > 0.5)  # the target stays in front of the camera


# --------------------------------------------------------------------------- the measured claims


def test_equation_13_is_far_from_stiff_along_the_paper_run(paper):
    spec = spectrum_of_run(paper[1])
    h = spec.period
    # measured max |h λ| = 0.0021: the explicit schemes' real intervals start at -1.28 (ABM4)
    assert h * spec.spectral_radius.max() < 0.01
    assert np.all(spec.stiffness_ratio >= 1.0)
    assert spec.depths.min() > 4.0


def test_what_limits_the_reconstruction(window, screw):
    """Truncation of BDF4 << sampling floor of the smooth input; RK4 on the exact ZOH screw removes it."""
    problem = reconstruction_problem(window, screw)
    scheme, rtol, atol = REFERENCE_SETTINGS
    reference = integrate(problem, scheme, rtol=rtol, atol=atol, t_eval=window.times).y
    truth, hidden, f = window.psi, window.hidden, window.focal_px
    floor = paper_metrics(reference, truth, hidden, f)
    bdf4 = integrate(problem, "bdf4", h=window.period).y
    truncation = paper_metrics(bdf4, reference, hidden, f)
    assert 5e-4 < floor[0] < 2e-3  # measured 9.8e-4 px: the O(h²) ZOH-vs-smooth-input error
    assert truncation[0] < 1e-3 * floor[0]  # measured 5.6e-8 px
    est = paper_metrics(replay_estimator(window, EstimatorSettings(order=4)), truth, hidden, f)
    assert est[0] == pytest.approx(floor[0], rel=0.05)  # the estimator sits on the same floor
    end = paper_metrics(replay_estimator(window, EstimatorSettings(order=4, screw_model="end")), truth, hidden, f)
    assert end[0] > 1000 * est[0]  # the held screw: 3.8 px
    zoh = paper_metrics(replay_zoh_rk4(window, 1), truth, hidden, f)
    assert zoh[0] < 1e-7 and zoh[1] < 1e-7  # measured 1.2e-9 px / 8.6e-10 mm


# --------------------------------------------------------------------------- random scenarios, settings


def test_random_scenarios_are_seeded(paper):
    base = paper[0]
    first = random_scenarios(base, 3, seed=7)
    assert first == random_scenarios(base, 3, seed=7)
    assert first != random_scenarios(base, 3, seed=8)
    assert [s.name for s in first] == ["paper-random-7-0", "paper-random-7-1", "paper-random-7-2"]
    low = [o for o in first[0].obstacles if o.name == "low"][0]
    assert low == [o for o in base.obstacles if o.name == "low"][0]  # only occluders move


def _random_scenarios_as_first_written(base, count, seed):
    """The study's draws before they became a visnav.perturbation.Perturbation: the reference they keep."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        obstacles = []
        for o in base.obstacles:
            if o.occludes(base.robot.camera_height_m):
                dx, dy = rng.uniform(-0.3, 0.3, size=2)
                o = dataclasses.replace(o, center_m=(o.center_m[0] + float(dx), o.center_m[1] + float(dy)),
                                        radius_m=o.radius_m * float(rng.uniform(0.85, 1.25)))
            obstacles.append(o)
        start = dataclasses.replace(base.start, y_m=base.start.y_m + float(rng.uniform(-0.3, 0.3)),
                                    theta_rad=base.start.theta_rad + float(rng.uniform(-0.1, 0.1)))
        gains = dataclasses.replace(base.gains, lambda_gc=base.gains.lambda_gc * float(rng.uniform(0.75, 1.5)),
                                    k_path=base.gains.k_path * float(rng.uniform(0.75, 1.25)),
                                    v_coll_mps=float(rng.uniform(0.15, 0.3)))
        out.append(dataclasses.replace(base, name=f"{base.name}-random-{seed}-{i}", obstacles=tuple(obstacles),
                                       start=start, gains=gains))
    return tuple(out)


@pytest.mark.parametrize("seed", [0, 1, 7, 123456])
def test_random_scenarios_are_exactly_the_studys_draws(paper, seed):
    """Bit for bit (repr of every float) the scenarios of the study's original formulas."""
    base = paper[0]
    assert repr(random_scenarios(base, 6, seed)) == repr(_random_scenarios_as_first_written(base, 6, seed))


@pytest.mark.parametrize("changes, message", [
    ({"seed": 1.5}, r"StudySettings.seed = 1.5: expected an integer"),
    ({"random_scenarios": -1}, r"StudySettings.random_scenarios = -1: expected an integer >= 0"),
    ({"order_steps": (0.1,)}, r"StudySettings.order_steps = \(0.1,\): expected at least two positive"),
    ({"pareto_steps": (0.1, -0.05)}, r"StudySettings.pareto_steps = \(0.1, -0.05\): expected at least two"),
    ({"timing_repeats": 0}, r"StudySettings.timing_repeats = 0: expected an integer >= 1"),
])
def test_bad_settings(changes, message):
    with pytest.raises(StiffnessStudyError, match=message):
        StudySettings(**changes)


def test_pareto_steps_must_be_multiples_of_the_sampling_period(paper):
    settings = StudySettings(pareto_steps=(0.075, 0.0375))
    with pytest.raises(StiffnessStudyError, match=r"the coarsest step 0.075 is not a multiple of the sampling period"):
        stiffness_study(paper[0], settings, result=paper[1])


# --------------------------------------------------------------------------- the whole study and the CLI


@pytest.fixture(scope="module")
def quick_study(paper):
    scenario, run = paper
    return stiffness_study(scenario, dataclasses.replace(QUICK_SETTINGS, random_scenarios=0), result=run)


def test_cli_json_is_complete_and_deterministic(paper, quick_study, capsys):
    assert main(["stiffness", "--quick", "--random", "0", "--json"]) == 0
    printed = capsys.readouterr().out
    d = json.loads(printed)
    expected = quick_study.as_dict()
    expected["scenario_digest"] = scenario_digest(paper[0])
    assert printed == json.dumps(expected, sort_keys=True) + "\n"  # same scenario and seed: same bytes
    assert "timing" not in d
    assert set(d["a_alpha_deg"]) == {str(q) for q in range(1, 7)}
    assert d["max_a_alpha_error_deg"] < 0.01
    for scheme in FIXED_STEP_SCHEMES:
        assert abs(d["observed_order"][scheme] - d["accuracy"]["verification"]["schemes"][scheme]
                   ["theoretical_order"]) < 0.1
    assert d["max_stiffness_ratio"] >= 1.0
    for scheme in FIXED_STEP_SCHEMES + REFERENCE_SCHEMES:
        row = d["reconstruction"][scheme]
        assert row["max_error_px"] > 0 and row["max_depth_error_mm"] > 0
    assert d["answer"]["stiff"] is False


def test_figures_render(quick_study):
    from visnav.app.figures_stiffness import stiffness_figures

    figures = stiffness_figures(quick_study)
    assert set(figures) == {"stiffness_regions", "stiffness_error_vs_step", "stiffness_error_vs_time",
                            "stiffness_ratio"}
    assert all(len(fig.axes) >= 1 for fig in figures.values())
    reproducible = stiffness_figures(quick_study, reproducible=True)
    assert set(reproducible) == {"stiffness_regions", "stiffness_error_vs_step", "stiffness_error_vs_evaluations",
                                 "stiffness_ratio"}
    ax = reproducible["stiffness_error_vs_evaluations"].axes[0]
    accuracy = {**quick_study.plots["paper_accuracy"], **quick_study.plots["reference_accuracy"]}
    plotted = {tuple(line.get_xdata()) for line in ax.get_lines()}
    assert tuple(accuracy["bdf4"]["evaluations"]) in plotted  # the x axis is the evaluation count


def test_cli_bad_input_exits_2(capsys):
    assert main(["stiffness", "--scenario", "nowhere", "--json"]) == 2
    assert "nowhere" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["stiffness", "--random", "-1"])
    assert info.value.code == 2
    assert "negative" in capsys.readouterr().err
