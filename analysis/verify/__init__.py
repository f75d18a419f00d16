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

from analysis.verify.falsification import DEFAULT_TIMEOUT_S, METHODS
from analysis.verify.loading import load_problem
from analysis.verify.problems import hybrid_problem, sampled_problem
from analysis.verify.requirements import Requirement, min_dwell
from analysis.stl import SignalTrace
from analysis.verify.testing import VerificationFailed, assert_verified
from analysis.verify.verdicts import Counterexample, RequirementVerdict, VerificationResult, verify
from analysis.verify.verification import InvalidPoint, Parameter, Proof, VerificationProblem

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
