"""A run that ends early is never judged as if it were complete (issue 24, item 1), and a model's own
exception is its own verdict, never "diverged" (item 7).

Every expectation here comes from the model's closed form (the Zeno time of a bouncing ball, the instant
a unit-speed flow meets its invariant's end), never from the executor under test.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from analysis.verify.falsification import evaluate
from analysis.verify.problems import hybrid_problem
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace, parse_formula
from analysis.verify.testing import VerificationFailed, assert_verified
from analysis.verify.verdicts import verify
from analysis.verify.verification import Parameter, VerificationProblem
from hybrid.examples import bouncing_ball, bouncing_ball_zeno_time, deadlock


def _ball_problem(formula: str, horizon: float = 10.0, reach: bool | str = "auto") -> VerificationProblem:
    model = bouncing_ball(h0=4.905, restitution=0.5)
    return hybrid_problem(name="ball", system=model.system,
                          initial={"h": Parameter(name="h0", low=4.8, high=4.905, nominal=4.905), "v": 0.0},
                          horizon=horizon, requirements=(Requirement(name="r", formula=formula),), reach=reach)


def test_a_zeno_ball_is_incomplete_with_its_zeno_time_never_not_falsified():
    problem = _ball_problem("always[0, 10] (h >= -0.01)")
    outcome = evaluate(problem, (0.0, ))
    # closed form: t_Z = t1 + 2 e v1 / (g (1 - e)) = 3.0 s for h0 = 4.905 m, e = 0.5
    t_zeno = bouncing_ball_zeno_time(h0=4.905, restitution=0.5)
    assert outcome.status == "incomplete" and outcome.end == "zeno"
    assert outcome.end_time == pytest.approx(t_zeno, abs=1e-3) and outcome.satisfied == (None,)
    assert "Zeno" in outcome.detail
    result = verify(problem, budget=6, seed=0, method="monte-carlo")
    assert result.verdict == "incomplete" and not result.passed
    assert result.requirement("r").verdict == "incomplete" and result.requirement("r").undecided == 6
    assert result.ended_early and result.ended_early[0]["end"] == "zeno"
    with pytest.raises(VerificationFailed, match="INCOMPLETE"):
        assert_verified(problem, budget=4)


def test_a_violation_before_the_early_end_is_still_decided():
    # the ball rises to h0 = 4.905 m at most: "h < 4" is violated at t = 0, before the Zeno time
    problem = _ball_problem("always[0, 10] (h < 4)")
    outcome = evaluate(problem, (0.0,))
    assert outcome.status == "incomplete" and outcome.satisfied == (False,)
    result = verify(problem, budget=4, seed=0, method="monte-carlo")
    assert result.verdict == "falsified" and result.requirement("r").counterexample is not None


def test_a_requirement_whose_window_ends_before_the_early_end_is_decided():
    # 2 s < t_Z (2.97 s for h0 = 4.8, 3.0 s for 4.905): the prefix decides it
    searched = _ball_problem("always[0, 2] (h >= -0.01)", reach=False)
    assert evaluate(searched, (0.0,)).satisfied == (True,)
    assert verify(searched, budget=4, seed=0, method="monte-carlo").verdict == "not_falsified"
    # with reachability (the default) every run of the box is defined over the window [0, 2]: proven
    result = verify(_ball_problem("always[0, 2] (h >= -0.01)"), budget=4, seed=0, method="monte-carlo")
    assert result.verdict == "proven" and "reachability" in result.requirement("r").decided_by


def test_a_deadlock_ends_the_run_incomplete_at_the_invariants_end():
    model = deadlock()  # x' = 1, invariant x <= 1, no transition enabled there: stuck at t = 1 from x0 = 0
    problem = hybrid_problem(name="stuck", system=model.system, initial={"x": 0.0}, horizon=10.0,
                             requirements=(Requirement(name="r", formula="always[0, 10] (x < 5)"),))
    outcome = evaluate(problem, ())
    assert outcome.status == "incomplete" and outcome.end == "invariant_violated"
    assert outcome.end_time == pytest.approx(1.0, abs=1e-6) and "deadlock" in outcome.detail
    result = verify(problem, budget=1, seed=0)
    assert result.verdict == "incomplete"


def _trace_problem(simulate, formula: str = "always[0, 10] (x > 0)") -> VerificationProblem:
    return VerificationProblem(name="own", simulate=simulate, parameters=(Parameter(name="a", low=0, high=1),),
                               horizon=10.0, signals=("x",), requirements=(Requirement(name="r", formula=formula),))


def _short(point):
    t = np.linspace(0.0, 4.0, 41)  # the user's simulator stops at 4 s of a 10 s horizon and says nothing
    return SignalTrace(times=t, signals={"x": np.ones_like(t)})


def _final(point):
    t = np.linspace(0.0, 4.0, 41)
    return SignalTrace(times=t, signals={"x": np.ones_like(t)}, termination="final:goal")


def test_a_user_trace_shorter_than_the_horizon_is_incomplete_a_declared_final_stop_is_not():
    short = evaluate(_trace_problem(_short), (0.0,))
    assert short.status == "incomplete" and short.end == "short" and "before the horizon" in short.detail
    assert verify(_trace_problem(_short), budget=3, seed=0).verdict == "incomplete"
    final = evaluate(_trace_problem(_final), (0.0,))
    assert final.status == "ok" and final.end == "final:goal" and final.satisfied == (True,)


def _raises(point):
    raise ValueError("mu = 1.3 is outside [0, 1]")


def test_a_model_error_is_its_own_verdict_not_diverged():
    outcome = evaluate(_trace_problem(_raises), (0.0,))
    assert outcome.status == "error" and "ValueError" in outcome.detail and "_raises" in outcome.traceback
    result = verify(_trace_problem(_raises), budget=3, seed=0)
    assert result.verdict == "error" and not result.diverged


def _bad_str(point):
    class Weird(Exception):
        def __str__(self):
            raise RuntimeError("no text")
    raise Weird()


def test_an_exception_whose_text_raises_is_still_a_model_error():
    outcome = evaluate(_trace_problem(_bad_str), (0.0,))
    assert outcome.status == "error" and "could not be rendered" in outcome.detail


@pytest.mark.parametrize("formula, truth", [
    ("always[0, 2] (x > 0)", False),  # the known part already violates it
    ("always[0, 2] (x > -5)", None),  # holds on the known part, the window goes past the end
    ("eventually[0, 2] (x > 1.5)", True),  # reached on the known part
    ("eventually[0, 2] (x > 5)", None),
    ("always[0, 0.6] (x > 0)", True),  # window inside the known part
    ("not (always[0, 2] (x > 0))", True),
    ("(x > 0) until[0, 3] (x > 5)", False),  # the left side fails before the right one could hold
    ("historically (x > 0)", True),
])
def test_prefix_semantics_against_hand_truth(formula, truth):
    # samples at 0, 0.5, 1.0 s with x = 1, 2, -1; the run ended at 1.0 s (hand-derived truth for every continuation)
    trace = SignalTrace(times=[0.0, 0.5, 1.0], signals={"x": [1.0, 2.0, -1.0]})
    assert parse_formula(formula).prefix_satisfied(trace) is truth


def test_prefix_semantics_is_the_boolean_one_on_windows_inside_the_trace():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 10.0, 101)
    trace = SignalTrace(times=t, signals={"x": rng.normal(size=t.size)})
    for text in ("always[0, 2] (x > -2)", "eventually[1, 3] (x > 1)", "(x > -1) until[0, 4] (x > 1.5)",
                 "always[0, 5] eventually[0, 1] (x > 0)"):
        f = parse_formula(text)
        assert f.prefix_satisfied(trace) in (f.satisfied(trace), None)
        lo, hi = f.prefix_robustness(trace)
        assert lo <= f.robustness(trace) <= hi


ZENO_MODULE = textwrap.dedent('''
    from analysis.verify.problems import hybrid_problem
    from analysis.verify.requirements import Requirement
    from analysis.verify.verification import Parameter
    from hybrid.examples import bouncing_ball

    problem = hybrid_problem(
        name="ball", system=bouncing_ball(h0=4.905, restitution=0.5).system,
        initial={"h": Parameter(name="h0", low=4.8, high=4.905, nominal=4.905), "v": 0.0}, horizon=10.0,
        requirements=(Requirement(name="r", formula="always[0, 10] (h >= -0.01)"),))
''')


def test_cli_verify_of_a_zeno_model_exits_5_and_says_so(tmp_path):
    module = tmp_path / "ball.py"
    module.write_text(ZENO_MODULE)
    done = subprocess.run([sys.executable, "-m", "visnav.app.cli", "verify", f"{module}:problem", "--budget", "3",
                           "--out", str(tmp_path / "out")], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 5, done.stderr
    assert "INCOMPLETE" in done.stdout and "Zeno" in done.stdout
    assert math.isfinite(float(done.stdout.split("Zeno: the jumps accumulate at t = ")[1].split()[0]))


def _decay(point):
    t = np.linspace(0.0, 2.0, 21)
    return SignalTrace(times=t, signals={"x": point["x0"] * np.exp(-t)})


def test_a_parameter_of_the_box_is_a_constant_signal_of_the_formulas():
    problem = VerificationProblem(
        name="floor", simulate=_decay, horizon=2.0, signals=("x",),
        parameters=(Parameter(name="x0", low=1.0, high=2.0), Parameter(name="floor", low=0.05, high=0.3)),
        requirements=(Requirement(name="above", formula="always[0, 2] (x >= floor)"),))
    # closed form: min x = x0 e^-2 >= 0.1353 while floor reaches 0.3: violated at x0 = 1, floor = 0.3
    result = verify(problem, budget=30, seed=0, method="monte-carlo")
    assert result.verdict == "falsified"
    cx = result.requirement("above").counterexample
    assert cx.point["x0"] * math.exp(-2.0) < cx.point["floor"]
    assert cx.robustness == pytest.approx(cx.point["x0"] * math.exp(-2.0) - cx.point["floor"], abs=1e-12)


def test_the_first_violation_instant_is_where_the_violation_starts_not_where_it_is_worst():
    trace = SignalTrace(times=[0.0, 1.0, 2.0, 3.0, 4.0], signals={"x": [1.0, -0.1, 2.0, -5.0, 1.0]})
    f = parse_formula("always[0, 4] (x > 0)")
    assert f.first_violation(trace) == 1.0 and f.explain(trace).time == 3.0
    assert parse_formula("always[0, 4] (x > -1 and x > 0)").first_violation(trace) == 1.0
    assert parse_formula("always[0, 4] (x > -1 and x < 1.5)").first_violation(trace) == 2.0
    assert parse_formula("always[0, 4] (x > -10)").first_violation(trace) is None
