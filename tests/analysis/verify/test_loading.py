"""Loading a user's problem from their own module or file."""

from __future__ import annotations

import textwrap

import pytest

from analysis.verify.loading import ProblemLoadError, load_problem, split_spec
from analysis.verify.verification import VerificationProblem

GOOD = '''
import numpy as np
from analysis.verify.requirements import Requirement
from analysis.stl import SignalTrace
from analysis.verify.verification import Parameter, VerificationProblem

def simulate(p):
    t = np.linspace(0.0, 2.0, 41)
    return SignalTrace(times=t, signals={"x": p["x0"] * np.exp(-t)})

def make(scale=1.0):
    return VerificationProblem(name="decay", simulate=simulate,
        parameters=(Parameter(name="x0", low=0.5 * scale, high=2.0 * scale),), horizon=2.0, signals=("x",),
        requirements=(Requirement(name="positive", formula="always[0, 2] (x > 0)"),))

problem = make()
number = 3
'''


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


@pytest.mark.parametrize("spec, expected", [("a.b:obj", ("a.b", "obj")), ("a/b.py:p", ("a/b.py", "p")),
                                            ("a/b.py", ("a/b.py", "problem")), ("C:\\x.py", ("C:\\x.py", "problem"))])
def test_split_spec(spec, expected):
    assert split_spec(spec) == expected


def test_a_problem_object_and_a_factory_load_from_a_file_outside_the_repository(tmp_path):
    path = _write(tmp_path, "mysys.py", GOOD)
    p = load_problem(f"{path}:problem")
    assert isinstance(p, VerificationProblem) and p.name == "decay" and p.source == f"{path}:problem"
    q = load_problem(f"{path}:make", {"scale": 2.0})
    assert q.parameters[0].high == 4.0
    assert load_problem(str(path)).name == "decay"  # OBJECT defaults to `problem`


def test_a_module_that_does_not_import_shows_the_users_traceback(tmp_path):
    path = _write(tmp_path, "broken.py", "import math\n\ndef f():\n    return 1 / 0\n\nf()\n")
    with pytest.raises(ProblemLoadError) as info:
        load_problem(f"{path}:problem")
    tb = info.value.user_traceback
    assert "ZeroDivisionError" in tb and str(path) in tb and "line 4" in tb
    assert "analysis/verify/loading.py" not in tb  # the toolkit's own frames are left out


def test_missing_file_module_object_and_wrong_type_are_named(tmp_path):
    path = _write(tmp_path, "mysys.py", GOOD)
    with pytest.raises(ProblemLoadError, match="existing .py file"):
        load_problem(f"{tmp_path}/nope.py:problem")
    with pytest.raises(ProblemLoadError, match="importable module"):
        load_problem("no_such_module_xyz:problem")
    with pytest.raises(ProblemLoadError) as info:
        load_problem(f"{path}:problme")
    assert "problem" in info.value.fix and "make" in info.value.fix
    with pytest.raises(ProblemLoadError, match="found int"):
        load_problem(f"{path}:number")
    with pytest.raises(ProblemLoadError, match="no options"):
        load_problem(f"{path}:problem", {"scale": 1.0})


def test_a_bad_formula_in_the_users_module_is_a_formula_error_with_a_caret(tmp_path):
    path = _write(tmp_path, "badf.py", GOOD.replace("always[0, 2] (x > 0)", "always[2, 0] (x > 0)"))
    with pytest.raises(ValueError) as info:
        load_problem(f"{path}:problem")
    assert "^" in str(info.value) and "positive" in str(info.value)
