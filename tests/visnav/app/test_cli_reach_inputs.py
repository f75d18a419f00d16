"""``visnav reach`` on SpaceEx models with bounded non-deterministic inputs (issue 28 item 4).

Yardsticks (closed forms, not the engine):

* the lag ``ẋ = −x + u``, ``u(t) ∈ [−0.1, 0.1]``, ``x(0) = 0``: ``|x(t)| <= 0.1 (1 − e^{−t})`` with equality for
  ``u ≡ ±0.1``, so over 5 s ``max x = 0.1 (1 − e^{−5}) = 0.099326``.  ``x >= 0.105`` is never reached (slack
  0.00567); ``x >= 0.099`` is reached (at ``t = ln 100 = 4.61`` s by ``u ≡ 0.1``): the flowpipe must meet it and
  nothing may be proven.  With the input dropped (``u ≡ 0``) ``x ≡ 0``, so ``x >= 0.05`` would be "proven": it
  must be met, which shows the input is in the flowpipe.
* the stiff lag ``ẋ = −5000 x + u``, ``|u| <= 1``, ``x(0) = 0`` over 0.1 s: ``max x = (1 − e^{−500})/5000 = 2·10⁻⁴``.
  The default step 10⁻⁴ s gives ``‖A_aug‖ δ = 5001·10⁻⁴ = 0.5``.  The former input term over-approximated the
  input's reach set by up to ``e^κ`` (``e^{0.5} = 1.65``: 3.3·10⁻⁴, so ``x <= 2.5·10⁻⁴`` needed the input ladder's
  third choice ``κ = 0.1``); the sub-stepped input set (analysis.reach.input_step, docs/reachability.md) and the
  re-check's own sub-steps are within about 10 % of it, so the default step proves ``x <= 2.5·10⁻⁴``.
* the unstable ``ẋ = x + u``, ``u ∈ [0.5, 1]``, ``x(0) = 0``: the reach set at ``t`` is
  ``[0.5 (e^t − 1), e^t − 1]``, so a segment ``[t, t + δ]`` (``δ`` = 20 s / 1000) holds at least
  ``[0.5 (e^t − 1), e^{t+δ} − 1]``, of box radius above the engine's size limit 10⁶ once
  ``e^t (e^δ − 0.5) > 2·10⁶ + 0.5``: the flowpipe (a superset) blows up by that segment (inconclusive, exit 5), and
  not much earlier (‖A_aug‖δ = 0.04: its wrapping is a few percent, far from the factor 1.5 that would move the
  blow-up ``ln 1.5 = 0.4`` s earlier).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest


HEAD = '<?xml version="1.0"?>\n<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2">\n'
PARAMS = "".join(f'<param name="{p}" type="real" local="false" d1="1" d2="1" dynamics="any"/>\n' for p in "xu")


def _xml(flow: str, low: float, high: float) -> str:
    return (HEAD + '<component id="c">\n' + PARAMS + f'<location id="1" name="a"><invariant>{low!r} &lt;= u &amp; '
            f"u &lt;= {high!r}</invariant><flow>x' == {flow}</flow></location>\n</component>\n</sspaceex>\n")


def _model(tmp_path: Path, flow: str, low: float, high: float, forbidden: str, horizon: float,
           initially: str = "x==0", extra: str = "") -> tuple[str, str]:
    (tmp_path / "m.xml").write_text(_xml(flow, low, high))
    (tmp_path / "m.cfg").write_text(f'system = "c"\ninitially = "{initially}"\nforbidden = "{forbidden}"\n'
                                    f"time-horizon = {horizon!r}\n{extra}")
    return str(tmp_path / "m.xml"), str(tmp_path / "m.cfg")


LAG_MAX = 0.1 * (1.0 - math.exp(-5.0))


def test_a_bound_that_holds_with_a_margin_is_proven_with_the_inputs(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-x + u", -0.1, 0.1, "x >= 0.105", 5.0)
    code, out, err = cli("reach", "--problem", xml, "--config", cfg, "--json")
    assert code == 0, out + err
    data = json.loads(out)
    assert data["inputs"] == [{"name": "u", "low": -0.1, "high": 0.1,
                               "signal": "any measurable signal within the bounds"}]
    (req,) = data["requirements"]
    assert req["status"] == "proven" and "re-checked with the inputs" in req["reason"]
    # a lower bound of the true slack 0.105 - 0.099326, and not far below it (step 0.005 s: e^0.01 wrapping)
    assert 0.105 - LAG_MAX - 1e-3 < req["margin"] <= 0.105 - LAG_MAX + 1e-12
    assert data["starts"][0]["flowpipe"]["inputs"], "the saved flowpipe carries B and U (the re-check reads them)"


def test_an_unsafe_set_just_inside_the_reach_set_is_not_proven(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-x + u", -0.1, 0.1, "x >= 0.099", 5.0)
    assert 0.099 < LAG_MAX  # the yardstick: u = 0.1 reaches it
    code, out, err = cli("reach", "--problem", xml, "--config", cfg)
    assert code == 1, out + err
    assert "unsafe set met" in out and "proven " not in out
    assert "inputs (any signal within the bounds): u in [-0.1, 0.1]" in out


def test_the_input_is_not_dropped(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-x + u", -0.1, 0.1, "x >= 0.05", 5.0)  # u = 0 would keep x = 0
    code, out, err = cli("reach", "--problem", xml, "--config", cfg, "--json")
    assert code == 1, out + err
    assert json.loads(out)["requirements"][0]["status"] == "met"


def test_without_a_step_the_default_step_proves_the_stiff_lag(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-5000*x + u", -1.0, 1.0, "x >= 0.00025", 0.1)
    code, out, err = cli("reach", "--problem", xml, "--config", cfg, "--json")
    assert code == 0, out + err
    data = json.loads(out)
    assert data["steps_chosen"] == ""  # ‖A‖·10⁻⁴ = 0.5 <= 3.9: the first choice keeps the default step
    # a lower bound of the true slack 5·10⁻⁵, within 10 % of the reach set 2·10⁻⁴ (measured 3.71·10⁻⁵)
    assert 0.00025 - 1.1 * 2e-4 < data["requirements"][0]["margin"] <= 0.00025 - 2e-4 + 1e-12


def test_an_explicit_step_is_used_alone(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-5000*x + u", -1.0, 1.0, "x >= 0.00025", 0.1)
    code, out, err = cli("reach", "--problem", xml, "--config", cfg, "--json", "--time-step", "0.0001")
    data = json.loads(out)
    assert data["time_step"] == 0.0001 and data["steps_chosen"] == "" and data["options"] == {}
    assert code == 0, out + err  # the former input term (e^0.5 · 2e-4 = 3.3e-4 > 2.5e-4) met it


def test_a_flowpipe_that_blows_up_is_inconclusive_naming_where(tmp_path, cli):
    xml, cfg = _model(tmp_path, "x + u", 0.5, 1.0, "x >= 1e12", 20.0)
    code, out, err = cli("reach", "--problem", xml, "--config", cfg)
    assert code == 5, out + err
    assert "INCONCLUSIVE" in out
    found = [line for line in out.splitlines() if "blew up at t = " in line]
    assert found and "in mode 'a'" in found[0], out
    t = float(found[0].split("blew up at t = ")[1].split()[0])
    delta = 20.0 / 1000
    latest = math.log((2e6 + 0.5) / (math.exp(delta) - 0.5))  # 15.16: the exact set's radius passes 1e6 after it
    assert latest - math.log(1.5) < t <= latest + delta + 1e-9


def test_out_writes_the_figures_and_the_inputs(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-x + u", -0.1, 0.1, "x >= 0.105", 5.0)
    out_dir = tmp_path / "out"
    code, out, err = cli("reach", "--problem", xml, "--config", cfg, "--out", out_dir)
    assert code == 0, out + err
    assert (out_dir / "figures" / "sets_x.png").stat().st_size > 1000
    assert json.loads((out_dir / "reach.json").read_text())["inputs"][0]["name"] == "u"


def test_a_flow_with_an_input_times_a_state_is_bad_input(tmp_path, cli):
    xml, cfg = _model(tmp_path, "-x*u", 0.5, 1.0, "x >= 2", 1.0, initially="x==1")
    code, out, err = cli("reach", "--problem", xml, "--config", cfg)
    assert code == 2 and "affine" in err and "Traceback" not in err, err


def _switching_xml(low: float, high: float) -> str:
    """Two locations ``ẋ = −x + u`` and ``ẋ = −2x + u`` switching at any time (no guard, no reset)."""
    inv = f"<invariant>{low!r} &lt;= u &amp; u &lt;= {high!r}</invariant>"
    labels = "".join(f'<param name="{n}" type="label" local="false"/>\n' for n in ("go", "back"))
    return (HEAD + '<component id="c">\n' + PARAMS + labels
            + f'<location id="1" name="slow">{inv}<flow>x\' == -x + u</flow></location>\n'
            + f'<location id="2" name="fast">{inv}<flow>x\' == -2*x + u</flow></location>\n'
            + '<transition source="1" target="2"><label>go</label></transition>\n'
            + '<transition source="2" target="1"><label>back</label></transition>\n</component>\n</sspaceex>\n')


@pytest.mark.parametrize("bound, code, status", [(0.105, 0, "proven"), (0.099, 1, "met")])
def test_arbitrary_switching_is_reached_as_its_relaxation(tmp_path, cli, bound, code, status):
    # yardstick: for x >= 0, ẋ <= −x + 0.1 in either location, so every switched run has x(t) <= 0.1 (1 − e^{−t})
    # (with equality staying in 'slow' under u = 0.1); by symmetry |x| <= LAG_MAX over 5 s.  The hybrid loop never
    # ends (every guard holds at once); the relaxation ẋ ∈ conv{−x, −2x} + u holds every run
    (tmp_path / "m.xml").write_text(_switching_xml(-0.1, 0.1))
    (tmp_path / "m.cfg").write_text(f'system = "c"\ninitially = "x==0 & loc(c)==slow"\nforbidden = "x >= {bound}"\n'
                                    "time-horizon = 5\n")
    got, out, err = cli("reach", "--problem", str(tmp_path / "m.xml"), "--config", str(tmp_path / "m.cfg"), "--json")
    assert got == code, out + err
    data = json.loads(out)
    (req,) = data["requirements"]
    assert req["status"] == status, req
    assert data["starts"][0]["flowpipe"]["schedule"]["relaxed_group"] == ["fast", "slow"] or \
        data["starts"][0]["flowpipe"]["schedule"]["relaxed_group"] == ["slow", "fast"]
    if status == "proven":
        assert "arbitrary-switching relaxation of 'slow' and 'fast'" in req["reason"] or \
            "arbitrary-switching relaxation of 'fast' and 'slow'" in req["reason"]
        # both margins are lower bounds of the true slack, and the re-check's is not far below it (step 5 ms)
        slack = bound - LAG_MAX
        assert 0.0 < req["margin"] <= slack + 1e-12 and 0.0 < req["recheck_margin"] <= slack + 1e-12
        assert req["margin"] > slack - 2e-3
