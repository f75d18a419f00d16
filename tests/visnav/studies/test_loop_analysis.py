"""`visnav analyse`: the JSON contract, the margins' second route, the certificate re-checked."""

import json
import math

import pytest

from analysis.certificate import recheck
from analysis.margins import loop_model, loop_transfer, margins, margins_by_sweep, sampled_loop_transfer
from analysis.polynomial import normal_form
from visnav.studies.loop_analysis import _vs_loop, analyse
from visnav.studies.goal_loops import visual_servoing_model
from visnav.app.cli import main
from visnav.scenario import load_scenario
from visnav.studies.path_following import lyapunov_rate_symbolic, path_following_closed_form_eigenvalues, path_following_model


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def result(paper):
    # the SOS study at the scenario's k only (the scan is tested in test_path_following_sos and, byte for byte,
    # by the committed report)
    return analyse(paper, sos="scenario").as_dict()


def test_json_contract(result, paper):
    pf = result["path_following"]
    expected = sorted(path_following_closed_form_eigenvalues(paper.gains.k_path, paper.gains.v_coll_mps),
                      key=lambda z: z.real)
    for (re, im), want in zip(pf["eigenvalues"], expected):
        assert abs(complex(re, im) - want) <= 1e-12 * abs(want)
    assert pf["lyapunov"]["certified"] is True
    assert set(pf["lyapunov"]["region"]) == {"delta", "alpha", "kappa", "k", "v"}
    assert pf["admissible_k"] is None or (len(pf["admissible_k"]) == 2 and pf["admissible_k"][0] <= pf["admissible_k"][1])
    for name, pair in result["margins"].items():
        for kind in ("continuous", "sampled"):
            assert {"gain_margin_db", "phase_margin_deg", "delay_margin_s"} <= set(pair[kind]), (name, kind)
    assert {"pan", "omega@low", "omega@tall", "vs:e_Vy"} <= set(result["margins"])
    assert json.loads(json.dumps(result)) == result


def test_certificate_in_the_json_rechecks(result):
    expression, sym = lyapunov_rate_symbolic()
    poly = normal_form(expression, [sym[n] for n in ("delta", "alpha", "kappa", "k", "v")])
    saved = json.loads(json.dumps(result["path_following"]["lyapunov"]["certificate"]))
    assert recheck(poly, saved)
    saved["boxes"] = saved["boxes"][:-1]  # tampered: no longer covers the region
    assert not recheck(poly, saved)


def test_pan_and_vs_loops_match_their_closed_forms(result, paper):
    """Both loops are λ/s at the goal: PM 90°, crossover λ, delay margin π/(2λ); sampled: ω_c = (2/T) asin(λT/2)."""
    T = paper.sampling_period_s
    for name, lam in (("pan", paper.gains.lambda_gc), ("vs:e_Vy", paper.gains.lambda_vs), ("vs:e_Wx", paper.gains.lambda_vs)):
        c, s = result["margins"][name]["continuous"], result["margins"][name]["sampled"]
        assert c["phase_margin_deg"] == pytest.approx(90.0, abs=1e-6)
        assert c["gain_crossover_frequency"] == pytest.approx(lam, rel=1e-9)
        assert c["delay_margin_s"] == pytest.approx(math.pi / (2 * lam), rel=1e-9)
        assert s["gain_crossover_frequency"] == pytest.approx(2 / T * math.asin(lam * T / 2), rel=1e-9)
        assert s["gain_margin"] == pytest.approx(1 / (lam * T), rel=1e-9)


def test_omega_loop_margins_agree_with_a_frequency_sweep(paper):
    T = paper.sampling_period_s
    pf = path_following_model(k=paper.gains.k_path, v=paper.gains.v_coll_mps, d_zero=paper.envelopes.d_zero_m,
                              radius=paper.obstacles[0].radius_m)
    import numpy as np

    a_p, b_p, gain = pf.plant_and_gain()
    lm = loop_model(a_p, b_p, np.eye(2), None, -gain, input_names=("omega",), output_names=("delta", "alpha"))
    for loop, w_max in ((loop_transfer(lm, at_input="omega"), 1e3), (sampled_loop_transfer(lm, T, at_input="omega"), math.pi / T)):
        a, b = margins(loop), margins_by_sweep(loop, w_min=1e-4, w_max=w_max)
        assert a.phase_margin_deg == pytest.approx(b.phase_margin_deg, rel=1e-6)
        assert a.gain_crossover_frequency == pytest.approx(b.gain_crossover_frequency, rel=1e-6)
        assert a.delay_margin_s == pytest.approx(b.delay_margin_s, rel=1e-6)
    vs = _vs_loop(visual_servoing_model(paper))
    np.testing.assert_allclose(vs.plant_b @ vs.controller_d, paper.gains.lambda_vs * np.eye(3), atol=1e-9)


def test_cli_analyse_json_and_bad_clearance(capsys):
    assert main(["analyse", "--json", "--sos", "off"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path_following"]["lyapunov"]["certified"] is True
    assert out["path_following"]["sos"] is None
    assert main(["analyse", "--sos", "off"]) == 0
    assert "SOS study                   left out (--sos off)" in capsys.readouterr().out
    assert main(["analyse", "--clearance", "0.7"]) == 2
    assert "clearance_m = 0.7" in capsys.readouterr().err


def test_analysis_is_deterministic(paper, result):
    assert json.dumps(analyse(paper, sos="scenario").as_dict(), sort_keys=True) == json.dumps(result, sort_keys=True)


def test_the_sos_study_sits_beside_the_hand_analysis_and_beats_it(result, paper):
    """Same entry, same hand-given V: the SOS bounds are certified and tighter, the region larger."""
    pf = result["path_following"]
    sos = pf["sos"]
    assert sos["scan"] is False and sos["entry_angles_source"].startswith("sampled")
    assert [e["alpha_rad"] for e in pf["entry_states"]] == pytest.approx(sos["entry_angles_rad"], abs=1e-12)
    region = sos["region"]
    assert region["status"] == "proven" and region["area_ratio"] > 1.0
    assert region["area_ratio"] == pytest.approx(region["area_m_rad"] / region["hand_area_m_rad"], rel=1e-12)
    for hand, bypass in zip(pf["entry_bounds"], sos["bypass"]):
        # one hand-given bound, computed once: the SOS study quotes exactly what the hand analysis reports
        assert bypass["hand_closed_form"]["nominal"]["delta_max_m"] == hand["delta_max_m"]
        assert bypass["hand_closed_form"]["nominal"]["omega_max_radps"] == hand["omega_max_radps"]
        best = bypass["combined"]
        assert bypass["status"] == "proven" and best["rechecked"] is True
        assert best["delta_max_m"] < hand["delta_max_m"] and best["omega_max_radps"] < hand["omega_max_radps"]
        assert best["min_distance_m"] == pytest.approx(paper.envelopes.d_zero_m - best["delta_max_m"], abs=1e-12)
    judged = sos["admissible"]["evaluations"]
    assert [e["k"] for e in judged] == [paper.gains.k_path]
    ok = judged[0]["delta_max_m"] <= paper.envelopes.d_zero_m - 0.1 and judged[0]["omega_max_radps"] <= 1.2
    assert (judged[0]["verdict"] == "proven admissible") == ok
    assert {c["status"] for c in sos["claims"]} <= {"proven", "sampled", "not proven", "computed"}


def test_a_bad_sos_choice_is_refused(paper):
    with pytest.raises(ValueError, match=r"^analyse: sos = 'all'; expected one of \['scan', 'scenario', 'off'\]"):
        analyse(paper, sos="all")


def test_speeds_and_gains_out_of_range_are_refused(paper):
    """Hand-built gains go through the scenario rule (visnav.scenario.validate_gains), with its message."""
    import dataclasses

    from visnav.scenario import ScenarioError, validate_gains

    fast = dataclasses.replace(paper, gains=dataclasses.replace(paper.gains, v_coll_mps=0.9))
    stiff = dataclasses.replace(paper, gains=dataclasses.replace(paper.gains, k_path=5e3))
    for scenario, message in ((fast, r"gains.v_coll_mps = 0.9: expected at most limits.v_max_mps = 0.6 m/s.*"
                                     r"fix: lower gains.v_coll_mps"),
                              (stiff, r"gains.k_path = 5000.0: expected a gain in \[0.001, 1000\] 1/m")):
        with pytest.raises(ScenarioError, match=r"^scenario 'paper': " + message) as info:
            analyse(scenario)
        with pytest.raises(ScenarioError) as same:
            validate_gains(scenario.gains, scenario.limits, source=scenario.name)
        assert str(info.value) == str(same.value)


def test_the_certified_k_range_is_the_case_models_constant():
    import inspect

    from visnav.parameters import K_PATH_RANGE
    from visnav.studies import loop_analysis, path_following

    assert inspect.signature(path_following.admissible_gains).parameters["k_range"].default is K_PATH_RANGE
    assert loop_analysis.K_PATH_RANGE is K_PATH_RANGE


def test_sampled_margins_against_gains_follow_the_closed_form(result, paper):
    """Integrator λ/s under ZOH + one sample of delay: L(z) = λT/(z(z − 1)).

    Gain margin 1/(λT) (closed loop z² − z + gλT stable iff gλT < 1); crossover
    ω_c = (2/T) asin(λT/2) and phase margin 90° − (3/2) ω_c T (from arg L = −90° − 3ωT/2).
    """
    T = paper.sampling_period_s
    for key, gains_key in (("pan_vs_lambda_gc", "lambda_gc"), ("vs_vs_lambda_vs", "lambda_vs")):
        curve = result["margins_vs_gains"][key]
        for lam, gm_db, pm, wc in zip(curve[gains_key], curve["sampled"]["gain_margin_db"],
                                      curve["sampled"]["phase_margin_deg"],
                                      curve["sampled"]["gain_crossover_frequency"]):
            assert gm_db == pytest.approx(-20 * math.log10(lam * T), abs=1e-8), (key, lam)
            if lam * T < 2:
                w = 2 / T * math.asin(lam * T / 2)
                assert wc == pytest.approx(w, rel=1e-9)
                assert pm == pytest.approx(90 - math.degrees(1.5 * w * T), abs=1e-7)
        assert min(curve["sampled"]["gain_margin_db"]) < 0 < max(curve["sampled"]["gain_margin_db"])
        # z² − z + λT: a root leaves the unit circle at λT = 1
        assert curve["sampled"]["stability_limit"] == pytest.approx(1 / T, rel=1e-9)
        for c_pm in curve["continuous"]["phase_margin_deg"]:
            assert c_pm == pytest.approx(90.0, abs=1e-6)


def test_boundary_poles_of_the_omega_loop_are_explained_not_reported_as_a_gain_margin(result):
    """The loop opened at ω has poles ±j v/ρ: no −340 dB 'gain margin', a note instead."""
    c = result["margins"]["omega@low"]["continuous"]
    assert c["gain_margin_db"] is None or c["gain_margin_db"] > 0
    assert any("poles on the imaginary axis" in note for note in c["notes"])


def test_cli_analyse_out_writes_json_and_figures(tmp_path, capsys):
    assert main(["analyse", "--out", str(tmp_path)]) == 0
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == ["analysis.json", "analysis_bode.png", "analysis_eigenvalues_vs_gains.png",
                       "analysis_margins_vs_gains.png", "analysis_nyquist.png"]
    saved = json.loads((tmp_path / "analysis.json").read_text())
    assert saved["goal"]["closed_loop"]["hurwitz"] is False
    for name in written[1:]:
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "wrote" in capsys.readouterr().out
