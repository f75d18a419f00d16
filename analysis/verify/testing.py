"""Verification in a test suite: :func:`assert_verified` fails a test with the shrunk counterexample.

Use it in pytest (or any runner) on the user's own problem::

    from analysis.verify.testing import assert_verified
    from mypackage.thermostat import problem

    def test_thermostat_requirements():
        assert_verified(problem)

The budget follows the active hypothesis profile (``max_examples``: the
``ci`` profile in CI, a small ``dev`` one locally), unless given.  On
failure the :class:`VerificationFailed` message lists each falsified
requirement with its robustness, the point (parameter values), the instant
and the atom that decide it, and the command that reproduces the search and
writes the counterexample file for ``visnav replay``.
"""

from __future__ import annotations

from analysis.verify.falsification import DEFAULT_TIMEOUT_S
from analysis.verify.verdicts import VerificationResult, verify
from analysis.verify.verification import VerificationProblem

__all__ = ["VerificationFailed", "assert_verified", "profile_budget"]


class VerificationFailed(AssertionError):
    """The verdict is not a pass (falsified, diverged, incomplete, a model error); ``result`` is the
    :class:`VerificationResult`."""

    def __init__(self, message: str, result: VerificationResult) -> None:
        super().__init__(message)
        self.result = result


def profile_budget() -> int:
    """The active hypothesis profile's ``max_examples`` (the budget in simulations)."""
    from hypothesis import settings

    return int(settings().max_examples)


def _message(problem: VerificationProblem, result: VerificationResult, budget: int, seed: int) -> str:
    source = problem.source or "<module>:<object>"
    lines = [f"{problem.name}: {result.verdict} ({result.simulations} simulations, seed {seed})"]
    for r in result.requirements:
        if r.counterexample is None:
            continue
        cx = r.counterexample
        point = ", ".join(f"{k}={v!r}" for k, v in cx.point.items())
        lines += [
            f"  requirement {r.name} FALSIFIED: robustness {cx.robustness:.6g} at t = {cx.time:.6g} s "
            f"({cx.atom} = {cx.atom_value:.6g})",
            f"    formula: {' '.join(r.formula.split())}",
            f"    counterexample ({cx.how}): {point}",
            f"    reproduce: visnav verify {source} --seed {seed} --budget {budget} "
            f"--method {result.method} --out out/verify/{problem.name}   (then: visnav replay "
            f"out/verify/{problem.name}/counterexamples/{r.name}.json"
            f"{'' if source == 'paper' else f' --problem {source}'})",
        ]
    for d in (*result.errors[:1], *result.diverged[:3], *result.ended_early[:3]):
        lines.append(f"  {d['status']} at {dict(d['point'])}: {d['detail']}")
    for r in result.requirements:
        if r.verdict == "incomplete":
            lines.append(f"  requirement {r.name} INCOMPLETE: {r.undecided} runs ended before deciding it "
                         f"({r.undecided_reasons[0] if r.undecided_reasons else 'ended early'})")
    if result.errors and result.errors[0].get("traceback"):
        lines.append("  the model's code raised; its traceback:\n" + str(result.errors[0]["traceback"]).rstrip())
    return "\n".join(lines)


def assert_verified(
    problem: VerificationProblem,
    *,
    budget: int | None = None,
    seed: int = 0,
    method: str = "guided",
    timeout_s: float | None = DEFAULT_TIMEOUT_S,
) -> VerificationResult:
    """Verify ``problem``; raise :class:`VerificationFailed` unless every requirement holds.

    Parameters
    ----------
    budget : int or None
        Simulations; ``None`` takes :func:`profile_budget`.
    seed : int
        The search's seed (the same seed, the same counterexample).
    method : str
        :data:`analysis.verify.falsification.METHODS`.
    timeout_s : float or None
        Wall-clock limit of each simulation [s]; a simulation past it makes the verdict incomplete.

    Returns
    -------
    VerificationResult
        When the verdict is a pass (:data:`analysis.verify.verdicts.PASSES`): every requirement proven or not
        falsified, every simulation complete.
    """
    budget = profile_budget() if budget is None else budget
    result = verify(problem, budget=budget, seed=seed, method=method, timeout_s=timeout_s)
    if not result.passed:
        raise VerificationFailed(_message(problem, result, budget, seed), result)
    return result
