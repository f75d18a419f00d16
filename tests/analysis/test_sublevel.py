"""analysis.sublevel: branch and bound on sublevel sets, hand cases, soundness, re-check of tampered certificates."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.certificate import enclose
from analysis.polynomial import Atom, Polynomial
from analysis.sublevel import (
    BoundCertificate,
    Reciprocal,
    SublevelCertificate,
    SublevelError,
    bound_on_sublevel,
    certify_sublevel,
    enclose_batch,
    lie_derivative,
    partial_derivative,
    recheck_bound,
    recheck_sublevel,
)
from hybrid.errors import ParameterError

X, Y = Polynomial.atom("x"), Polynomial.atom("y")
D, A = Polynomial.atom("delta"), Polynomial.atom("alpha")
S, C = Polynomial.atom(Atom.sin("alpha")), Polynomial.atom(Atom.cos("alpha"))
BOX = {"x": (-2.0, 2.0), "y": (-2.0, 2.0)}
V = X**2 + Y**2
VDOT = lie_derivative(V, {"x": -X + Y, "y": -X - Y})  # = -2 x^2 - 2 y^2


@pytest.fixture(scope="module")
def certificate() -> SublevelCertificate:
    return certify_sublevel(V, VDOT, BOX, rho_out=1.0, rho_in=0.01)


def test_lie_derivative_of_the_hand_case():
    assert VDOT == -2 * X**2 - 2 * Y**2


def test_hand_case_is_certified_with_its_precise_claim(certificate):
    c = certificate
    assert c.certified and c.status == "certified"
    assert set(c.labels) <= {"outside", "inside", "decreasing"} and "decreasing" in c.labels
    assert c.max_rate is not None and c.max_rate < 0
    # dV/dt = -2V: the rate bound is at best -2 rho_in, and entering {V <= 0.01} takes at least ln(100)/2
    assert c.entry_time_bound >= (1.0 - 0.01) / (2 * 0.01)
    assert "positively invariant" in c.claim and "enters {V <= 0.01}" in c.claim
    assert {(name, side) for name, side, _ in c.faces} == {("x", "lo"), ("x", "hi"), ("y", "lo"), ("y", "hi")}
    assert recheck_sublevel(V, VDOT, c, region=BOX) == ()


def test_certificate_survives_json_exactly(certificate):
    data = json.loads(json.dumps(certificate.as_dict()))
    assert recheck_sublevel(V, VDOT, data) == ()
    assert SublevelCertificate.from_dict(data).boxes == certificate.boxes


def test_a_wrong_derivative_is_not_certified():
    wrong = 2 * X**2 - 2 * Y**2  # positive along the x axis
    c = certify_sublevel(V, wrong, BOX, rho_out=1.0, rho_in=0.01)
    assert not c.certified and c.status == "counterexample"
    point = c.counterexample["point"]
    assert wrong.evaluate_at(point) > 0 and 0.01 <= V.evaluate_at(point) <= 1.0
    assert recheck_sublevel(V, wrong, c) != ()


def test_a_set_that_reaches_the_box_is_refused():
    c = certify_sublevel(V, VDOT, {"x": (-0.5, 0.5), "y": (-2.0, 2.0)}, rho_out=1.0, rho_in=0.01)
    assert not c.certified and c.status == "reaches_boundary"


def test_nonstrict_zero_on_a_line_needs_the_split_and_strict_fails():
    # V = delta^2/2 + 1 - cos alpha along delta' = sin alpha, alpha' = -delta - alpha: dV/dt = -alpha sin alpha
    v = 0.5 * D**2 + 1 - C
    rate = lie_derivative(v, {"delta": S, "alpha": -D - A})
    assert rate == -A * S
    region = {"delta": (-1.5, 1.5), "alpha": (-3.0, 3.0)}
    nonstrict = certify_sublevel(v, rate, region, rho_out=1.0, rho_in=0.05, strict=False, split_at={"alpha": (0.0,)})
    assert nonstrict.certified and recheck_sublevel(v, rate, nonstrict) == ()
    strict = certify_sublevel(v, rate, region, rho_out=1.0, rho_in=0.05, strict=True, split_at={"alpha": (0.0,)},
                              max_boxes=3000)
    assert not strict.certified  # dV/dt = 0 on alpha = 0, across the annulus


ARITHMETIC = pytest.mark.parametrize("arithmetic", ["scalar", "batched"])


@ARITHMETIC
def test_recheck_passes_in_both_arithmetics(certificate, arithmetic):
    assert recheck_sublevel(V, VDOT, certificate, arithmetic=arithmetic) == ()


@ARITHMETIC
def test_recheck_rejects_a_removed_box(certificate, arithmetic):
    data = certificate.as_dict()
    k = data["labels"].index("decreasing")
    for key in ("boxes", "labels", "rate_bounds"):
        del data[key][k]
    assert any("do not cover" in p for p in recheck_sublevel(V, VDOT, data, arithmetic=arithmetic))


@ARITHMETIC
def test_recheck_rejects_a_changed_bound_or_level(certificate, arithmetic):
    data = certificate.as_dict()
    k = data["labels"].index("decreasing")
    data["rate_bounds"][k] = float.hex(-1e3)  # a rate bound the box does not have
    assert any("does not hold" in p for p in recheck_sublevel(V, VDOT, data, arithmetic=arithmetic))
    data = certificate.as_dict()
    data["rho_out"] = float.hex(3.9)  # the set would reach the faces
    assert recheck_sublevel(V, VDOT, data, arithmetic=arithmetic) != ()
    data = certificate.as_dict()
    data["faces"][0][2] = data["faces"][0][2][1:]
    assert any("face" in p for p in recheck_sublevel(V, VDOT, data, arithmetic=arithmetic))
    assert recheck_sublevel(V, VDOT + 3 * X**2, certificate, arithmetic=arithmetic) != ()  # another V̇


@ARITHMETIC
def test_bound_over_a_disc_and_its_recheck(arithmetic):
    b = bound_on_sublevel(X, BOX, sets=[(V, 1.0)], tolerance=1e-3)
    assert b.certified and 1.0 <= b.bound <= 1.0 + 2e-3 and b.status == "converged"
    assert b.attained is not None and b.attained <= 1.0 <= b.bound
    assert recheck_bound(X, [(V, 1.0)], json.loads(json.dumps(b.as_dict())), arithmetic=arithmetic) == ()
    assert BoundCertificate.from_dict(b.as_dict()).bound == b.bound
    lowered = b.as_dict()
    lowered["bound"] = float.hex(0.9)
    assert recheck_bound(X, [(V, 1.0)], lowered, arithmetic=arithmetic) != ()
    removed = b.as_dict()
    k = removed["labels"].index("bounded")
    for key in ("boxes", "labels", "uppers"):
        del removed[key][k]
    assert any("do not cover" in p for p in recheck_bound(X, [(V, 1.0)], removed, arithmetic=arithmetic))
    assert recheck_bound(X, [(V, 2.0)], b, arithmetic=arithmetic) != ()  # a different set


def test_decision_mode_and_absolute_bounds():
    b = bound_on_sublevel(X * Y, BOX, sets=[(V, 1.0)], absolute=True, good_enough=0.6)
    assert b.certified and 0.5 <= b.bound <= 0.6 and b.status in ("decided", "converged")


def test_reciprocal_auxiliary_variable():
    kappa = Polynomial.atom("kappa")
    aux = (Reciprocal(name="kappa", of="x", offset=(2.0, 3.0)),)
    b = bound_on_sublevel(kappa, {"x": (-1.0, 1.0)}, aux=aux, tolerance=1e-4)
    assert b.certified and 1.0 <= b.bound <= 1.0 + 2e-4  # 1/(2 + x) is largest at x = -1, offset 2
    assert recheck_bound(kappa, [], b, aux=aux) == ()
    assert recheck_bound(kappa, [], b, aux=(Reciprocal(name="kappa", of="x", offset=(1.0, 3.0)),)) != ()


def test_parameters_have_no_faces():
    k = Polynomial.atom("k")
    rate = lie_derivative(V, {"x": -k * X, "y": -k * Y})
    c = certify_sublevel(V, rate, {**BOX, "k": (0.5, 2.0)}, rho_out=1.0, rho_in=0.01, parameters=("k",))
    assert c.certified and {name for name, _, _ in c.faces} == {"x", "y"}
    assert "for every value of the parameters k in [0.5, 2]" in c.claim
    assert recheck_sublevel(V, rate, c) == ()
    failing = certify_sublevel(V, rate, {**BOX, "k": (-0.5, 2.0)}, rho_out=1.0, rho_in=0.01, parameters=("k",))
    assert not failing.certified


def test_partial_derivative_through_the_atoms():
    p = 3 * D * C**3 * S + 2 * A * C**2 - S
    dp = partial_derivative(p, "alpha")
    for a in (-2.0, 0.3, 1.1):
        h = 1e-6
        numeric = (p.evaluate_at({"delta": 0.7, "alpha": a + h}) - p.evaluate_at({"delta": 0.7, "alpha": a - h})) / (2 * h)
        assert dp.evaluate_at({"delta": 0.7, "alpha": a}) == pytest.approx(numeric, rel=1e-6, abs=1e-8)


TRIG = 3 * D * C**3 * S - 5 * A * C**2 + 0.1 * S**4 - D**2 * C + 1


@settings(max_examples=60, deadline=None)
@given(st.floats(-3, 3), st.floats(0, 2), st.floats(-3, 3), st.floats(0, 2),
       st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1)), min_size=3, max_size=3))
def test_batched_enclosures_contain_the_function(d0, dw, a0, aw, fractions):
    lo, hi = np.array([[d0, a0]]), np.array([[d0 + dw, a0 + aw]])
    elo, ehi = enclose_batch(TRIG, {"delta": (0, 0), "alpha": (0, 0)}, lo, hi)
    scalar = enclose(TRIG, {"delta": (d0, d0 + dw), "alpha": (a0, a0 + aw)})
    for fd, fa in fractions:
        value = TRIG.evaluate_at({"delta": d0 + fd * dw, "alpha": a0 + fa * aw})
        assert elo[0] <= value <= ehi[0]
        assert scalar.lo <= value <= scalar.hi


def test_exact_zeros_stay_exact():
    # -alpha sin(alpha) on alpha in [0, 1]: the upper end must be exactly 0, not an ulp above
    lo, hi = enclose_batch(-A * S, {"alpha": (0, 0)}, np.array([[0.0]]), np.array([[1.0]]))
    assert hi[0] == 0.0 and lo[0] < 0.0


@pytest.mark.parametrize(("call", "parameter"), [
    (lambda: certify_sublevel(V, VDOT, {"x": (1.0, -1.0), "y": (-1.0, 1.0)}, rho_out=1.0), "region['x']"),
    (lambda: certify_sublevel(V, VDOT, BOX, rho_out=1.0, rho_in=1.0), "rho_in"),
    (lambda: certify_sublevel(V, VDOT, BOX, rho_out=math.nan), "rho_out"),
    (lambda: certify_sublevel(V, VDOT, BOX, rho_out=1.0, max_boxes=0), "max_boxes"),
    (lambda: certify_sublevel(V, VDOT, {"x": (-1.0, 1.0)}, rho_out=1.0), "polynomial"),
    (lambda: bound_on_sublevel(X, BOX, tolerance=0.0), "tolerance"),
    (lambda: lie_derivative(V, {"x": X}), "rates"),
])
def test_bad_inputs(call, parameter):
    with pytest.raises(SublevelError) as info:
        call()
    assert isinstance(info.value, ParameterError) and info.value.parameter == parameter
