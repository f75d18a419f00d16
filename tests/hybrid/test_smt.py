"""hybrid.smt: the one solver call (incremental core, default solver on "unknown") and the term builders."""

from __future__ import annotations

from fractions import Fraction

import pytest

import z3  # z3-solver is a required dependency: its absence is a failure, not a skip

from hybrid import smt  # noqa: E402
from hybrid.smt import all_of, any_of, check_sat, combine, compare, context, fresh_context, rational, to_float  # noqa: E402


class _Undecided:
    """A session that answers "unknown" to everything (what the SMT core says on arithmetic it cannot settle)."""

    def __init__(self) -> None:
        self.depth = 0
        self.asked = 0

    def set(self, *args):
        pass

    def push(self):
        self.depth += 1

    def pop(self):
        self.depth -= 1

    def add(self, *constraints):
        pass

    def check(self):
        self.asked += 1
        return z3.unknown

    def reason_unknown(self):
        return "incomplete"


def test_an_unknown_from_the_core_goes_to_the_default_solver_whose_answer_counts(monkeypatch):
    with fresh_context():
        x = z3.Real("x", context())
        fake = _Undecided()
        monkeypatch.setattr(smt, "_session", lambda: fake)
        sat = check_sat([compare("==", combine("mul", x, x), rational(2.0)), compare(">", x, rational(0.0))], 1.0)
        assert fake.asked == 1 and fake.depth == 0  # asked once, its scope popped
        assert sat.status == "sat"
        value = to_float(sat.model.eval(x, model_completion=True))
        assert value == pytest.approx(2.0 ** 0.5, rel=1e-12)
        unsat = check_sat([compare("<", combine("mul", x, x), rational(-1.0))], 1.0)
        assert unsat.status == "unsat" and fake.asked == 2


def test_the_incremental_core_forgets_each_question_after_answering_it():
    with fresh_context():
        x = z3.Real("x", context())
        assert check_sat([compare(">", x, rational(1.0)), compare("<", x, rational(0.0))], 1.0).status == "unsat"
        again = check_sat([compare(">", x, rational(1.0))], 1.0)  # the contradictory bound above is gone
        assert again.status == "sat" and to_float(again.model.eval(x, model_completion=True)) > 1.0


def test_each_decision_has_its_own_session_and_the_outer_one_comes_back():
    with fresh_context():
        outer = smt._session()
        with fresh_context():
            inner = smt._session()
            assert inner is not outer
        assert smt._session() is outer


def test_the_builders_give_the_terms_of_z3s_own_operators():
    with fresh_context():
        ctx = context()
        x, y = z3.Real("x", ctx), z3.Real("y", ctx)
        pairs = [
            (compare(">=", x, y), x >= y), (compare(">", x, y), x > y), (compare("<=", x, y), x <= y),
            (compare("<", x, y), x < y), (compare("==", x, y), x == y), (compare("!=", x, y), x != y),
            (combine("add", x, y), x + y), (combine("sub", x, y), x - y), (combine("mul", x, y), x * y),
            (compare(">=", x, 0), x >= 0),  # a Python number goes through z3's coercion
            (all_of([x > 0, y > 0, x < y]), z3.And(x > 0, y > 0, x < y)),
            (any_of([x > 0, y > 0]), z3.Or(x > 0, y > 0)),
        ]
        for ours, theirs in pairs:
            s = z3.Solver(ctx=ctx)
            s.add(ours != theirs if z3.is_arith(ours) else z3.Xor(ours, theirs))
            assert s.check() == z3.unsat, (ours, theirs)
        assert z3.is_true(z3.simplify(all_of([])))
        assert z3.is_false(z3.simplify(any_of([])))


def test_numerals_come_back_as_the_nearest_float():
    with fresh_context():
        for value in (0.1, -3.75, 1e-300, 123456789.125, 0.0):
            assert to_float(rational(value)) == value
        third = z3.Q(1, 3, context())
        assert to_float(z3.simplify(third)) == float(Fraction(1, 3))
