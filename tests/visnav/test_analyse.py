"""`visnav analyse`: the JSON contract, the margins' second route, the certificate re-checked."""

import json
import math

import pytest

from analysis.certificate import recheck
from analysis.margins import loop_model, loop_transfer, margins, margins_by_sweep, sampled_loop_transfer
from analysis.polynomial import normal_form
from visnav.analyse import _vs_loop, analyse
from visnav.cli import main
from visnav.scenario import load_scenario
from visnav.stability import lyapunov_rate_symbolic, path_following_closed_form_eigenvalues, path_following_model


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def result(paper):
    return analyse(paper).as_dict()


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
    vs = _vs_loop(paper)
    np.testing.assert_allclose(vs.plant_b @ vs.controller_d, paper.gains.lambda_vs * np.eye(3), atol=1e-9)


def test_cli_analyse_json_and_bad_clearance(capsys):
    assert main(["analyse", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path_following"]["lyapunov"]["certified"] is True
    assert main(["analyse", "--clearance", "0.7"]) == 2
    assert "clearance_m = 0.7" in capsys.readouterr().err


def test_analysis_is_deterministic(paper, result):
    assert json.dumps(analyse(paper).as_dict(), sort_keys=True) == json.dumps(result, sort_keys=True)
