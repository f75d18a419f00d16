"""Unbounded time by the arbitrary-switching relaxation (analysis.reach.relaxed_induction), end to end from SpaceEx.

The toy: ``x' = -x + u`` in ``slow``, ``x' = -2x + u`` in ``fast``, ``u(t) ∈ [-0.1, 0.1]``, a dwell clock ``t``
(switch when ``t >= 1``, ``t <= 2`` in each, ``t := 0``), ``x(0) = 0``.  Yardstick (closed form, any switching):
for ``x >= 0`` both flows give ``ẋ <= -x + 0.1``, so ``|x(t)| <= 0.1 (1 - e^{-t}) < 0.1`` for all ``t``: ``x >= 0.15``
is never reached (slack at least 0.05); ``x >= 0.05`` is reached (2 s in ``slow`` under ``u = 0.1``:
``0.1 (1 - e^{-2}) = 0.0865``).
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

import pytest

from analysis.reach.model import affine_model
from analysis.reach.recheck_projection import recheck_projection
from analysis.reach.relaxed import NoGroup
from analysis.reach.relaxed_induction import clock_free
from analysis.spaceex import spaceex_problem
from analysis.spaceex_reach import input_reach_model

HEAD = '<?xml version="1.0"?>\n<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2">\n'


def _xml(slow_flow: str = "-x + u") -> str:
    params = "".join(f'<param name="{p}" type="real" local="false" d1="1" d2="1" dynamics="any"/>\n' for p in "xtu")
    labels = "".join(f'<param name="{n}" type="label" local="false"/>\n' for n in ("go", "back"))
    inv = "<invariant>t &lt;= 2 &amp; -0.1 &lt;= u &amp; u &lt;= 0.1</invariant>"
    return (HEAD + '<component id="c">\n' + params + labels
            + f'<location id="1" name="slow">{inv}<flow>x\' == {slow_flow} &amp; t\' == 1</flow></location>\n'
            + f'<location id="2" name="fast">{inv}<flow>x\' == -2*x + u &amp; t\' == 1</flow></location>\n'
            + '<transition source="1" target="2"><label>go</label><guard>t &gt;= 1</guard>'
              '<assignment>t := 0</assignment></transition>\n'
            + '<transition source="2" target="1"><label>back</label><guard>t &gt;= 1</guard>'
              '<assignment>t := 0</assignment></transition>\n</component>\n</sspaceex>\n')


def _problem(tmp_path, forbidden: str, slow_flow: str = "-x + u"):
    (tmp_path / "m.xml").write_text(_xml(slow_flow))
    (tmp_path / "m.cfg").write_text(f'system = "c"\ninitially = "x==0 & t==0 & loc(c)==slow"\n'
                                    f'forbidden = "{forbidden}"\ntime-horizon = -1\n')
    return spaceex_problem(tmp_path / "m.xml", tmp_path / "m.cfg")


def test_a_bound_the_relaxation_keeps_is_proven_for_all_time(tmp_path):
    proof = _problem(tmp_path, "x >= 0.15").proofs["safe"]()
    assert proof.holds and proof.rechecked and proof.proven, proof.evidence
    assert "the clocks t projected out" in proof.evidence and "re-checked: the projection exactly" in proof.evidence
    assert "all time t >= 0 (unbounded)" in proof.assumptions
    # a lower bound of the true slack 0.05 (sup |x| = 0.1 over all time, approached by staying in slow under u = 0.1
    # for the relaxation; measured 0.0192: the relaxation's disturbance zonotope at step 0.083 s)
    assert 0.0 < proof.margin <= 0.15 - 0.1 + 1e-12


def test_a_bound_that_is_reached_is_not_proven(tmp_path):
    proof = _problem(tmp_path, "x >= 0.05").proofs["safe"]()
    assert not proof.proven
    assert "the relaxation's induction does not hold" in proof.evidence


def test_an_unstable_relaxation_is_not_proven(tmp_path):
    proof = _problem(tmp_path, "x >= 0.15", slow_flow="x + u").proofs["safe"]()  # x' = x + u grows without bound
    assert not proof.proven


def _model(tmp_path, slow_flow: str = "-x + u"):
    problem = _problem(tmp_path, "x >= 0.15", slow_flow)
    build = problem.simulate.build
    zero, inputs = input_reach_model(build.system, build.input_flows, build.inputs)
    return zero, inputs


def test_the_projection_drops_the_clock_and_its_recheck_catches_a_changed_flow(tmp_path):
    zero, inputs = _model(tmp_path)
    cf = clock_free(affine_model(zero), inputs)
    assert cf.clocks == ("t",) and cf.model.state_names == ("x",)
    assert recheck_projection(zero, cf.model, cf.kept, inputs, cf.inputs) == ""
    slow = cf.model.modes["slow"]
    bad = replace(cf.model, modes={**cf.model.modes, "slow": replace(slow, a=((Fraction(-1, 2),),))})
    assert "differs" in recheck_projection(zero, bad, cf.kept, inputs, cf.inputs)


def test_a_clock_read_by_a_flow_is_refused(tmp_path):
    zero, inputs = _model(tmp_path, slow_flow="-x + u + 0.01*t")
    with pytest.raises(NoGroup, match="reads a clock"):
        clock_free(affine_model(zero), inputs)
