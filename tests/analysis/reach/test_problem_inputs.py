"""``problem_reach`` on SpaceEx problems with bounded non-deterministic inputs: the input route of ``visnav verify``.

Yardsticks: the lag ``ẋ = −a x + u``, ``u(t) ∈ [−0.1, 0.1]``, ``x(0) = 0`` reaches at most ``(0.1/a)(1 − e^{−a t})``
(closed form, ``u ≡ 0.1``); over 5 s that is 0.099326 for ``a = 1`` and 0.05 for ``a = 2``.  The platoon PLAD01-BND42
is published safe (ARCH-COMP AFF) and verify proves it on the same route: both commands make the same engine call
(:func:`analysis.spaceex_reach.input_flowpipe`) with the same step, so their margins are the same number.
"""

from __future__ import annotations

import math
from pathlib import Path

from analysis.reach.problem import problem_reach
from analysis.spaceex import spaceex_problem
from analysis.spaceex_route import problem_input_route

ROOT = Path(__file__).resolve().parents[3]
PLATOON = ROOT / "tests" / "data" / "spaceex" / "arch2017" / "Platoon" / "SpaceEx"
SPECS = ROOT / "tests" / "data" / "spaceex" / "arch2017" / "specs"
BALL = ROOT / "tests" / "data" / "spaceex" / "spaceexparser" / "bball" / "bball.xml"

HEAD = '<?xml version="1.0"?>\n<sspaceex xmlns="http://www-verimag.imag.fr/xml-namespaces/sspaceex" version="0.2">\n'
PARAMS = "".join(f'<param name="{p}" type="real" local="false" d1="1" d2="1" dynamics="any"/>\n' for p in "xu")
BOUND = "<invariant>-0.1 &lt;= u &amp; u &lt;= 0.1</invariant>"
TWO = (HEAD + '<component id="c">\n' + PARAMS + f'<location id="1" name="a">{BOUND}<flow>x\' == -x + u</flow>'
       f'</location>\n<location id="2" name="b">{BOUND}<flow>x\' == -2*x + u</flow></location>\n'
       "</component>\n</sspaceex>\n")


def _two(tmp_path: Path, forbidden: str):
    (tmp_path / "two.xml").write_text(TWO)
    (tmp_path / "two.cfg").write_text(f'system = "c"\ninitially = "x==0"\nforbidden = "{forbidden}"\n'
                                      "time-horizon = 5\n")
    return spaceex_problem(tmp_path / "two.xml", tmp_path / "two.cfg")


def test_every_location_is_a_start_and_each_flowpipe_takes_the_input(tmp_path):
    problem = _two(tmp_path, "x >= 0.105")  # no loc(...): both locations are initial
    result = problem_reach(problem)
    assert [m for m, _, _ in result.runs] == ["a", "b"]
    assert result.inputs == (("u", -0.1, 0.1),)
    (req,) = result.requirements
    assert req.status == "proven", req.reason
    worst = 0.1 * (1 - math.exp(-5.0))  # location a's closed form (b's is 0.05)
    assert 0.105 - worst - 1e-3 < req.margin <= 0.105 - worst + 1e-12
    tops = [max(float(s.hi[0]) for s in r.segments) for _, _, r in result.runs]
    # each flowpipe holds its closed-form maximum (a superset of the reach set) and is not far above it
    assert worst <= tops[0] < worst + 1e-3 and 0.05 * (1 - math.exp(-10.0)) <= tops[1] < 0.05 + 1e-3


def test_a_set_only_location_a_reaches_is_met(tmp_path):
    result = problem_reach(_two(tmp_path, "x >= 0.07"))  # a reaches 0.0993, b at most 0.05
    assert result.complete and result.requirements[0].status == "met"
    assert "mode 'a'" in result.requirements[0].reason


def test_the_json_is_deterministic_and_names_the_inputs(tmp_path):
    problem = _two(tmp_path, "x >= 0.105")
    first, second = problem_reach(problem).to_json(), problem_reach(problem).to_json()
    assert first == second and '"inputs": [{"high": 0.1, "low": -0.1, "name": "u"' in first


def test_a_problem_without_inputs_has_no_route_and_no_inputs_key(tmp_path):
    (tmp_path / "b.cfg").write_text('system = "system"\ninitially = "10<=x<=10.2 & v==0"\nforbidden = "x >= 10.5"\n'
                                    "time-horizon = 2\n")
    problem = spaceex_problem(BALL, tmp_path / "b.cfg")
    assert problem_input_route(problem) is None
    assert '"inputs"' not in problem_reach(problem).to_json()


def test_the_platoon_is_proven_as_verify_proves_it():
    problem = spaceex_problem(PLATOON / "PLAD01-BND.xml", SPECS / "PLAD01-BND42.cfg")
    route = problem_input_route(problem)
    assert [i.name for i in route.inputs] == ["aL"] and route.signal_parameters[0] == "input_aL_0"
    result = problem_reach(problem)
    (req,) = result.requirements
    assert req.status == "proven" and result.time_step == 0.02 and result.steps_chosen == ""
    proof = problem.proofs["safe"]()
    assert proof.proven and "step 0.02 s" in proof.evidence
    assert req.margin == proof.margin  # one engine call for both commands: the same flowpipe


def test_the_recheck_is_given_the_inputs(tmp_path, monkeypatch):
    # a re-check without the inputs would re-check the input-free system (the saved tube holds its runs too) and
    # pass: only what it is given shows that the proof covers the inputs
    import analysis.reach.problem as module

    seen = []
    original = module.recheck_flowpipe

    def spy(saved, system, initial, fragment, **kwargs):
        seen.append((system, kwargs.get("inputs")))
        return original(saved, system, initial, fragment, **kwargs)

    monkeypatch.setattr(module, "recheck_flowpipe", spy)
    problem = _two(tmp_path, "x >= 0.105")
    assert problem_reach(problem).requirements[0].status == "proven"
    route = problem_input_route(problem)
    assert len(seen) == 2 and all(system is not None and inputs is not None for system, inputs in seen)
    for system, inputs in seen:
        assert type(system).__name__ == "HybridSystem"  # read again by the re-checker, as verify's proof does
        assert {m: (i.matrix, i.bounds) for m, i in inputs.items()} == {"a": ([[1.0]], ([-0.1], [0.1])),
                                                                       "b": ([[1.0]], ([-0.1], [0.1]))}
    assert set(route.matrices) == {"a", "b"}
