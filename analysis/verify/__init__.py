"""Verify your own switching system: the one module to import (with :mod:`hybrid` for the model).

Describe *what* to verify, then ask for the verdicts::

    from hybrid import HybridAutomaton, HybridSystem, Mode, Transition
    from hybrid.symbolic import coordinates, flow_map
    from analysis.verify import Parameter, Requirement, assert_verified, hybrid_problem, verify

    problem = hybrid_problem(name="room", system=room, initial={"T": Parameter(name="T0", low=19.5, high=20.5)},
                             horizon=120.0, requirements=(Requirement(name="comfort", formula="always[0, 120] ..."),))
    result = verify(problem, budget=120)          # or, in a test suite: assert_verified(problem)

The problem
    :class:`VerificationProblem` (any simulator), built for the two kinds of system the toolkit executes by
    :func:`hybrid_problem` (continuous time) and :func:`sampled_problem` (a sampled-data loop); a box of
    :class:`Parameter`; :class:`Requirement` in Signal Temporal Logic (``docs/stl.md``), :func:`min_dwell`
    for no chatter; :class:`Proof` for a certificate of your own; :class:`InvalidPoint` for a point outside
    your hypotheses; :class:`SignalTrace` for a simulator of your own.
The verdicts
    :func:`verify` gives a :class:`VerificationResult`, one :class:`RequirementVerdict` per requirement
    (proven, falsified with its :class:`Counterexample`, not falsified, incomplete); :func:`assert_verified`
    raises :class:`VerificationFailed` unless the verdict is a pass; :func:`load_problem` loads
    ``FILE.py:OBJECT`` as ``visnav verify`` does.

The modules behind it live in this package and stay importable for the finer pieces:
:mod:`~analysis.verify.verification` (the problem, parameters, proofs), :mod:`~analysis.verify.problems`
(problems of hybrid systems and sampled loops), :mod:`~analysis.verify.requirements`,
:mod:`~analysis.verify.signals` (input signals as parameters), :mod:`~analysis.verify.falsification` with
:mod:`~analysis.verify.falsification_search` and :mod:`~analysis.verify.falsification_book` (the searches),
:mod:`~analysis.verify.verdicts`, :mod:`~analysis.verify.testing` (the pytest entry) and
:mod:`~analysis.verify.loading` (a user's module).
"""

import importlib as _importlib
from typing import Any as _Any

# Loaded on first use: importing one module of this package (``analysis.verify.requirements`` from the
# case's scenario, say) must not load the executors behind the rest (tests/visnav/fuzzing/test_package.py).
_LAZY = {
    "SignalTrace": "",
    **dict.fromkeys(("DEFAULT_TIMEOUT_S", "METHODS"), "falsification"),
    "load_problem": "loading",
    **dict.fromkeys(("hybrid_problem", "sampled_problem"), "problems"),
    **dict.fromkeys(("Requirement", "min_dwell"), "requirements"),
    **dict.fromkeys(("VerificationFailed", "assert_verified"), "testing"),
    **dict.fromkeys(("Counterexample", "RequirementVerdict", "VerificationResult", "verify"), "verdicts"),
    **dict.fromkeys(("InvalidPoint", "Parameter", "Proof", "VerificationProblem"), "verification"),
}


def __getattr__(name: str) -> _Any:
    if name == "SignalTrace":
        from analysis.stl import SignalTrace as value
    elif name in _LAZY:
        value = getattr(_importlib.import_module(f".{_LAZY[name]}", __name__), name)
    else:
        raise AttributeError(f"module 'analysis.verify' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "VerificationProblem",
    "Parameter",
    "Requirement",
    "Proof",
    "InvalidPoint",
    "SignalTrace",
    "hybrid_problem",
    "sampled_problem",
    "min_dwell",
    "verify",
    "METHODS",
    "DEFAULT_TIMEOUT_S",
    "VerificationResult",
    "RequirementVerdict",
    "Counterexample",
    "assert_verified",
    "VerificationFailed",
    "load_problem",
]
