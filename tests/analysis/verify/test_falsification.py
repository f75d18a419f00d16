"""Falsification and verdicts on small problems whose answers are known in closed form."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.verify.falsification import FalsificationError, SimulationFailed, evaluate, falsify, monte_carlo_unit
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verdicts import verify
from analysis.verify.verification import InvalidPoint, Parameter, Proof, VerificationProblem
from hybrid.errors import DivergenceError

T = np.linspace(0.0, 1.0, 21)


class Counting:
    """``x(t) = a + b t`` with a call counter (module-level class: picklable, deterministic)."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, p):
        self.calls += 1
        if p.get("invalid", 0.0) > 0.5:
            raise InvalidPoint("invalid > 0.5 breaks the hypothesis")
        if p.get("diverge", 0.0) > 0.7:
            raise DivergenceError(0.5, "m", "blew up")
        return SignalTrace(times=T, signals={"x": p["a"] + p["b"] * T})


def _problem(simulate, formulas, extra=(), proofs=None):
    params = (Parameter(name="a", low=-1.0, high=1.0, nominal=0.5), Parameter(name="b", low=-1.0, high=1.0, nominal=0.0),
              *extra)
    reqs = tuple(Requirement(name=n, formula=f) for n, f in formulas.items())
    return VerificationProblem(name="line", simulate=simulate, parameters=params, horizon=1.0, signals=("x",),
                               requirements=reqs, proofs=proofs or {})


def test_the_nominal_point_is_simulated_first_and_the_budget_is_respected():
    sim = Counting()
    problem = _problem(sim, {"pos": "always[0, 1] (x > -5)"})
    search, falsified = falsify(problem, budget=17, seed=3)
    assert search.evaluations[0].phase == "nominal" and search.evaluations[0].unit == (0.0, 0.0)
    assert search.used == 17 == sim.calls
    assert falsified == {}


def test_a_violation_is_found_shrunk_and_its_robustness_is_the_closed_form():
    # min over t of a + b t is a + min(b, 0); the requirement x > 0.8 is violated wherever a + min(b,0) < 0.8,
    # i.e. almost everywhere except near a = 1: the nominal point (a = 0.5) already violates it.
    problem = _problem(Counting(), {"high": "always[0, 1] (x > 0.8)", "never": "always[0, 1] (x > -3)"})
    result = verify(problem, budget=30, seed=0)
    high = result.requirement("high")
    assert high.verdict == "falsified"
    cx = high.counterexample
    a, b = cx.point["a"], cx.point["b"]
    assert cx.robustness == pytest.approx(a + min(b, 0.0) - 0.8, abs=1e-12)
    assert cx.unit == (0.0, 0.0)  # the nominal point violates it: nothing to shrink
    never = result.requirement("never")
    assert never.verdict == "not_falsified"
    assert never.robustness == pytest.approx(-1.0 - 1.0 + 3.0, abs=1e-9)  # the polish reaches the corner a=b=-1
    assert result.verdict == "falsified"


def test_hypothesis_finds_a_corner_violation_the_nominal_point_does_not_show_and_shrinks_it():
    # violated only where a + min(b, 0) < -0.9: a small corner of the box
    problem = _problem(Counting(), {"corner": "always[0, 1] (x >= -0.9)"})
    result = verify(problem, budget=60, seed=0)
    r = result.requirement("corner")
    assert r.nominal_robustness == pytest.approx(0.5 + 0.9)
    assert r.verdict == "falsified"
    cx = r.counterexample
    assert cx.point["a"] + min(cx.point["b"], 0.0) < -0.9
    assert cx.robustness < 0


def test_the_same_seed_gives_the_same_json_and_another_seed_other_points():
    def run(seed):
        return json.dumps(verify(_problem(Counting(), {"c": "always[0, 1] (x >= -0.9)"}), budget=25, seed=seed)
                          .as_dict(evaluations=True), sort_keys=True)

    assert run(4) == run(4)
    assert run(4) != run(5)


def test_the_draws_do_not_depend_on_which_local_modules_are_imported(tmp_path, monkeypatch):
    # hypothesis mixes numbers from the source of every imported local module into its draws (with a small
    # probability per draw); a falsification must depend on its seed only, not on what else the process loaded
    def run():
        return json.dumps(verify(_problem(Counting(), {"c": "always[0, 1] (x >= -0.9)"}), budget=40, seed=2)
                          .as_dict(evaluations=True), sort_keys=True)

    before = run()
    constants = ", ".join(f"{-0.99 + 0.0173 * i!r}" for i in range(115))
    (tmp_path / "many_local_constants.py").write_text(f"VALUES = ({constants})\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib

    importlib.import_module("many_local_constants")
    assert run() == before


def test_a_resumed_search_reads_every_point_back_and_simulates_none():
    first = Counting()
    journal = []
    r1 = verify(_problem(first, {"c": "always[0, 1] (x >= -0.9)"}), budget=25, seed=1, on_evaluation=journal.append)
    cache = {e.unit: e.outcome for e in journal}
    again = Counting()
    r2 = verify(_problem(again, {"c": "always[0, 1] (x >= -0.9)"}), budget=25, seed=1, cache=cache)
    # the counterexample's trace is simulated again for its explanation; no search point is
    assert again.calls == (1 if r2.requirements[0].counterexample is not None else 0)
    assert json.dumps(r1.as_dict(evaluations=True)) == json.dumps(r2.as_dict(evaluations=True))


def test_invalid_and_diverged_points_are_counted_never_counterexamples():
    extra = (Parameter(name="invalid", low=0.0, high=1.0, nominal=0.0),
             Parameter(name="diverge", low=0.0, high=1.0, nominal=0.0))
    result = verify(_problem(Counting(), {"p": "always[0, 1] (x > -5)"}, extra=extra), budget=40, seed=0,
                    method="monte-carlo")
    assert result.invalid > 0 and "invalid > 0.5" in result.invalid_reasons[0]
    assert result.diverged and result.diverged[0]["status"] == "diverged"
    assert "blew up" in result.diverged[0]["detail"]
    assert result.verdict == "diverged"
    # the diverged runs did not decide p: never passed on them (issue 24)
    p = result.requirement("p")
    assert p.verdict == "incomplete" and p.undecided == len(result.diverged) and not result.passed


def test_a_crash_in_the_users_simulator_is_reported_with_their_traceback():
    def broken(p):
        return {"x": 1.0}["y"]

    problem = _problem(broken, {"p": "always[0, 1] (x > 0)"})
    outcome = evaluate(problem, (0.0, 0.0))  # a defect of the model: its own outcome, never "diverged"
    assert outcome.status == "error" and outcome.detail.startswith("KeyError")
    assert "KeyError" in outcome.traceback and "broken" in outcome.traceback
    result = verify(problem, budget=3, seed=0, method="monte-carlo")
    assert result.verdict == "error" and not result.passed
    assert result.requirement("p").verdict == "incomplete" and "broken" in result.errors[0]["traceback"]


def test_proofs_give_proven_only_when_rechecked_and_a_counterexample_overrides_them():
    good = Proof(holds=True, method="closed form", evidence="min a + min(b,0) = -2 > -5", rechecked=True)
    unchecked = Proof(holds=True, method="solver", evidence="feasible", rechecked=False)
    wrong = Proof(holds=True, method="bug", evidence="claims x > 0.8", rechecked=True)
    problem = _problem(Counting(), {"a": "always[0, 1] (x > -5)", "b": "always[0, 1] (x > -4)",
                                    "c": "always[0, 1] (x > 0.8)"},
                       proofs={"a": lambda: good, "b": lambda: unchecked, "c": lambda: wrong})
    result = verify(problem, budget=10, seed=0)
    assert [r.verdict for r in result.requirements] == ["proven", "not_falsified", "falsified"]
    only_a = verify(problem.with_requirements(problem.requirements[:1]), budget=3, seed=0)
    assert only_a.verdict == "proven"


@pytest.mark.parametrize("kwargs, parameter", [({"budget": 0}, "budget"), ({"budget": 2.5}, "budget"),
                                               ({"budget": 5, "method": "magic"}, "method"),
                                               ({"budget": 5, "seed": -1}, "seed")])
def test_bad_search_options_name_the_option(kwargs, parameter):
    with pytest.raises(FalsificationError) as info:
        falsify(_problem(Counting(), {"p": "always[0, 1] (x > 0)"}), **kwargs)
    assert info.value.parameter == parameter


def test_monte_carlo_draws_depend_only_on_seed_and_index_and_follow_the_distribution():
    problem = _problem(Counting(), {"p": "always[0, 1] (x > -5)"})
    assert monte_carlo_unit(problem, 7, 3) == monte_carlo_unit(problem, 7, 3)
    values = np.array([problem.point(monte_carlo_unit(problem, 0, i))["a"] for i in range(2000)])
    # uniform on [-1, 1]: mean 0 and standard deviation 1/sqrt(3); 2000 draws: standard error 0.013
    assert abs(values.mean()) < 0.05 and values.std() == pytest.approx(1 / 3**0.5, abs=0.03)


def test_guided_search_beats_or_matches_monte_carlo_on_a_narrow_well():
    # robustness min_t x = a + min(b, 0) + 0.05 - well: lowest near a = b = -1; a narrow region is negative
    formulas = {"well": "always[0, 1] (x > -1.97)"}
    guided = verify(_problem(Counting(), formulas), budget=40, seed=0, method="guided").requirement("well")
    mc = verify(_problem(Counting(), formulas), budget=40, seed=0, method="monte-carlo").requirement("well")
    assert guided.robustness <= mc.robustness
    assert guided.verdict == "falsified"


@pytest.mark.parametrize("low, high, nominal", [(0.0, 1.0, 0.0), (0.0, 1.0, 1.0), (-2.0, 3.0, 0.5), (1.0, 1.0, 1.0)])
def test_unit_coordinates_cover_the_interval_and_invert(low, high, nominal):
    p = Parameter(name="p", low=low, high=high, nominal=nominal)
    assert p.at(0.0) == nominal
    values = [p.at(u) for u in np.linspace(-1, 1, 201)]
    assert min(values) == low and max(values) == high
    for v in np.linspace(low, high, 7):
        assert p.at(p.unit_of(v)) == pytest.approx(v, abs=1e-12)
