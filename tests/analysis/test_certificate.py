"""Tests of analysis.certificate: the path-following Lyapunov certificate, re-checks, failures."""

from __future__ import annotations

import copy
import json
import math
import time
from decimal import Decimal, localcontext
from fractions import Fraction

import casadi as ca
import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.certificate import (
    Certificate,
    InvalidCertificate,
    InvalidRegion,
    InvalidSearchParameter,
    certify_nonpositive,
    covers,
    enclose,
    recheck,
    recheck_problems,
)
from analysis.polynomial import Atom, Polynomial, normal_form

NEAR_PI = math.pi - 1e-3


def path_following_vdot(k: float, v: float, *, flip: bool = False) -> Polynomial:
    """Normal form of V̇ for δ̇ = v sin α, α̇ = -v (k δ + α ± 2k sin α), V = k δ²/2 + 1 - cos α."""
    delta, alpha = ca.SX.sym("delta"), ca.SX.sym("alpha")
    sign = -1.0 if flip else 1.0
    flow = ca.vertcat(v * ca.sin(alpha), -v * (k * delta + alpha + sign * 2 * k * ca.sin(alpha)))
    lyapunov = k * delta**2 / 2 + (1 - ca.cos(alpha))
    vdot = ca.dot(ca.gradient(lyapunov, ca.vertcat(delta, alpha)), flow)
    return normal_form(vdot, [delta, alpha])


def region(alpha_max: float) -> dict[str, tuple[float, float]]:
    return {"delta": (-0.5, 0.5), "alpha": (-alpha_max, alpha_max)}


# --------------------------------------------------------------------------- the case study


@pytest.mark.parametrize("k, v", [(4.0, 0.1), (0.7, 0.3)])
@pytest.mark.parametrize("alpha_max", [NEAR_PI, math.pi])
def test_path_following_vdot_is_certified(k, v, alpha_max):
    poly = path_following_vdot(k, v)
    start = time.perf_counter()
    cert = certify_nonpositive(poly, region(alpha_max), split_at={"alpha": (0.0,)})
    elapsed = time.perf_counter() - start
    assert cert.certified and cert.status == "certified"
    assert elapsed < 2.0, f"certification took {elapsed:.3f} s"
    assert cert.variables == ("delta", "alpha")
    assert cert.region == ((-0.5, 0.5), (-alpha_max, alpha_max))
    assert all(u <= 0.0 for u in cert.upper_bounds) and len(cert.upper_bounds) == len(cert.boxes)
    assert cert.failed_boxes == () and cert.counterexample is None
    # the zero set alpha = 0 lies on the faces of the two boxes, whose bounds are exactly 0
    assert sorted(b[1] for b in cert.boxes) == [(-alpha_max, 0.0), (0.0, alpha_max)]
    assert cert.upper_bounds == (0.0, 0.0)
    assert covers(cert.region, cert.boxes)
    assert recheck(poly, cert, region=region(alpha_max))


def test_zero_set_inside_a_box_cannot_be_certified_without_split_at():
    """No enclosure of nonzero width around alpha = 0 has upper bound <= 0: split_at is needed."""
    poly = path_following_vdot(4.0, 0.1)
    box = {"delta": (-0.5, 0.5), "alpha": (-NEAR_PI, 2.0)}  # bisection never lands on alpha = 0
    cert = certify_nonpositive(poly, box, max_failures=1)
    assert not cert.certified and cert.status == "min_width" and cert.counterexample is None
    (failed,) = cert.failed_boxes
    assert failed[1][0] < 0.0 < failed[1][1] and failed[1][1] - failed[1][0] <= 1e-9
    assert failed[0] == (-0.5, 0.5)  # delta is never split: the polynomial does not depend on it
    assert certify_nonpositive(poly, box, split_at={"alpha": [0.0]}).certified


def test_certificate_rechecks_after_a_json_round_trip():
    poly = path_following_vdot(4.0, 0.1)
    cert = certify_nonpositive(poly, region(NEAR_PI), split_at={"alpha": (0.0,)})
    text = json.dumps(cert.as_dict())
    data = json.loads(text)
    assert data["format"] == "analysis.certificate/1"
    assert data["boxes"][0][1][0] == float.hex(cert.boxes[0][1][0])
    assert Certificate.from_dict(data) == cert
    assert recheck(poly, data)
    assert recheck(poly, data, region=region(NEAR_PI))
    assert not recheck(poly, data, region=region(math.pi))  # a different claim


# --------------------------------------------------------------------------- tampering


def certified_data(alpha_lo: float = -NEAR_PI) -> tuple[Polynomial, dict]:
    poly = path_following_vdot(4.0, 0.1)
    box = {"delta": (-0.5, 0.5), "alpha": (alpha_lo, NEAR_PI)}
    cert = certify_nonpositive(poly, box, split_at={"alpha": (0.0, 1.0)})  # three boxes
    assert len(cert.boxes) == 3
    return poly, json.loads(json.dumps(cert.as_dict()))


def test_removing_a_box_fails_the_recheck():
    poly, data = certified_data()
    data["boxes"].pop(1)
    data["upper_bounds"].pop(1)
    assert recheck_problems(poly, data) == ("the boxes do not cover the region",)
    assert not recheck(poly, data)


def test_a_box_whose_bound_is_positive_fails_the_recheck():
    poly, data = certified_data()
    tampered = copy.deepcopy(data)
    # stretch one box across alpha = 0 (the cover still holds) and claim a bound of -1
    lo_box = next(b for b in tampered["boxes"] if float.fromhex(b[1][1]) == 0.0)
    lo_box[1][1] = float.hex(0.5)
    tampered["upper_bounds"] = [float.hex(-1.0)] * len(tampered["upper_bounds"])
    problems = recheck_problems(poly, tampered)
    assert len(problems) == 1 and "upper bound is" in problems[0] and "> 0" in problems[0]
    assert not recheck(poly, tampered)


def test_an_enlarged_region_fails_the_recheck():
    poly, data = certified_data()
    data["region"][1][0] = float.hex(-math.pi)
    assert recheck_problems(poly, data) == ("the boxes do not cover the region",)


def test_other_inconsistencies_fail_the_recheck():
    poly, data = certified_data()
    not_claimed = dict(data, certified=False)
    assert "does not claim certification" in recheck_problems(poly, not_claimed)[0]
    other_poly = poly + Polynomial.atom("theta")
    assert "the polynomial depends on ['theta']" in recheck_problems(other_poly, data)[0]
    flipped = path_following_vdot(4.0, 0.1, flip=True)
    assert not recheck(flipped, data)
    malformed = copy.deepcopy(data)
    malformed["boxes"][0] = [[float.hex(1.0), float.hex(0.0)], malformed["boxes"][0][1]]
    assert "is malformed" in recheck_problems(poly, malformed)[0]
    assert "unreadable certificate" in recheck_problems(poly, {"format": "nope"})[0]
    assert not recheck(poly, "certificate")  # type: ignore[arg-type]


# --------------------------------------------------------------------------- failures


@pytest.mark.parametrize("poly", [
    path_following_vdot(4.0, 0.1, flip=True),  # sign of the k term flipped
    path_following_vdot(-1.0, 0.1),  # k < 0
], ids=["flipped", "negative-k"])
def test_positive_function_is_not_certified_and_gives_a_counterexample(poly):
    cert = certify_nonpositive(poly, region(NEAR_PI), split_at={"alpha": (0.0,)})
    assert not cert.certified and cert.status == "counterexample"
    point = cert.counterexample_point()
    assert set(point) == {"delta", "alpha"}
    assert poly.evaluate_at(point) > 0.0
    lo, hi = cert.counterexample_bounds
    assert 0.0 < lo <= poly.evaluate_at(point) <= hi
    assert len(cert.failed_boxes) == 1
    box = dict(zip(cert.variables, cert.failed_boxes[0]))
    assert all(box[name][0] <= point[name] <= box[name][1] for name in point)
    assert not recheck(poly, cert)
    data = json.loads(json.dumps(cert.as_dict()))
    assert Certificate.from_dict(data).counterexample == cert.counterexample


def test_zero_set_inside_boxes_exhausts_the_budget():
    x, y = Polynomial.atom("x"), Polynomial.atom("y")
    poly = -((x - y) ** 2)  # <= 0, but = 0 on the diagonal, which crosses box interiors
    unit = {"x": (0.0, 1.0), "y": (0.0, 1.0)}
    cert = certify_nonpositive(poly, unit, max_boxes=300, min_width=1e-3, max_failures=10**6)
    assert cert.status == "max_boxes" and not cert.certified
    assert cert.boxes_examined == 300 and cert.counterexample is None
    assert len(cert.failed_boxes) >= 1
    cert = certify_nonpositive(poly, {"x": (0.0, 1.0), "y": (0.0, 1.0)}, min_width=0.01, max_failures=3)
    assert cert.status == "min_width" and len(cert.failed_boxes) == 3
    assert all(hi - lo <= 0.01 for box in cert.failed_boxes for lo, hi in box)


def test_dependency_problem_is_resolved_by_bisection():
    x = Polynomial.atom("x")
    poly = x**2 - x - Fraction(1, 100)  # max -0.01 at the ends; naive enclosure on [0, 1] is [-1.01, 0.99]
    assert enclose(poly, {"x": (0.0, 1.0)}).hi > 0.9
    cert = certify_nonpositive(poly, {"x": (0.0, 1.0)})
    assert cert.certified and len(cert.boxes) > 5
    assert recheck(poly, json.loads(json.dumps(cert.as_dict())))
    assert not certify_nonpositive(poly + Fraction(1, 50), {"x": (0.0, 1.0)}).certified


def test_constants_and_degenerate_regions():
    box = {"x": (0.0, 1.0), "unused": (2.0, 2.0)}
    cert = certify_nonpositive(Polynomial.constant(-1), box)
    assert cert.certified and cert.boxes == (((0.0, 1.0), (2.0, 2.0)),)
    assert recheck(Polynomial.constant(-1), cert)
    cert = certify_nonpositive(Polynomial.constant(1), box)
    assert cert.status == "counterexample" and cert.counterexample == (0.5, 2.0)
    cert = certify_nonpositive(-Polynomial.atom("x") ** 2, {"x": (-1.0, 1.0)})
    assert cert.certified and len(cert.boxes) == 1


# --------------------------------------------------------------------------- covers


@st.composite
def tilings(draw):
    """A random tiling of [0, 1]^2 by recursive splits at random floats."""
    boxes = [((0.0, 1.0), (0.0, 1.0))]
    for _ in range(draw(st.integers(0, 25))):
        i = draw(st.integers(0, len(boxes) - 1))
        box = boxes.pop(i)
        d = draw(st.integers(0, 1))
        lo, hi = box[d]
        cut = draw(st.floats(lo, hi))
        boxes += [box[:d] + ((lo, cut),) + box[d + 1:], box[:d] + ((cut, hi),) + box[d + 1:]]
    return boxes


@given(tilings(), st.data())
def test_covers_accepts_tilings_and_rejects_a_missing_tile(boxes, data):
    unit = ((0.0, 1.0), (0.0, 1.0))
    assert covers(unit, boxes)
    assert covers(unit, boxes + [((0.2, 0.3), (0.1, 0.9))])  # overlaps are allowed
    fat = [i for i, b in enumerate(boxes) if all(lo < hi for lo, hi in b)]
    i = data.draw(st.sampled_from(fat))
    assert not covers(unit, boxes[:i] + boxes[i + 1:])


def test_covers_edge_cases():
    assert not covers(((0.0, 1.0),), [])
    assert covers(((0.5, 0.5),), [((0.0, 1.0),)])
    assert not covers(((0.0, 1.0),), [((0.0, 0.5),), ((0.5000001, 1.0),)])
    assert not covers(((0.0, 1.0), (0.0, 1.0)), [((0.0, 1.0),)])  # wrong dimension
    assert covers(((0.0, 1.0),), [((-5.0, 5.0),)])


# --------------------------------------------------------------------------- enclosure soundness

PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899862803")


def _reference_sin_cos(x: float) -> tuple[Fraction, Fraction]:
    with localcontext() as ctx:
        ctx.prec = 60
        r = Decimal(x)
        r -= (r / (2 * PI)).to_integral_value() * 2 * PI
        s = term = r
        c = cterm = Decimal(1)
        for k in range(1, 60):
            term = -term * r * r / ((2 * k) * (2 * k + 1))
            cterm = -cterm * r * r / ((2 * k - 1) * (2 * k))
            s, c = s + term, c + cterm
        return Fraction(s), Fraction(c)


@st.composite
def polynomials(draw):
    atoms = [Atom.var("x"), Atom.sin("x"), Atom.cos("x"), Atom.var("y"), Atom.sin("y")]
    terms = {}
    for _ in range(draw(st.integers(1, 5))):
        powers = {}
        for atom in draw(st.lists(st.sampled_from(atoms), max_size=3)):
            powers[atom] = powers.get(atom, 0) + draw(st.integers(1, 3))
        terms[tuple(powers.items())] = Fraction(draw(st.integers(-50, 50)), draw(st.integers(1, 7)))
    return Polynomial(terms)


@given(polynomials(), st.floats(-4.0, 4.0), st.floats(0.0, 2.0), st.floats(-4.0, 4.0), st.floats(0.0, 2.0),
       st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_enclosure_contains_high_precision_values(poly, x0, wx, y0, wy, tx, ty):
    box = {"x": (x0, x0 + wx), "y": (y0, y0 + wy)}
    px, py = min(x0 + tx * wx, x0 + wx), min(y0 + ty * wy, y0 + wy)
    sx, cx = _reference_sin_cos(px)
    sy, cy = _reference_sin_cos(py)
    values = {Atom.var("x"): Fraction(px), Atom.sin("x"): sx, Atom.cos("x"): cx,
              Atom.var("y"): Fraction(py), Atom.sin("y"): sy, Atom.cos("y"): cy}
    exact = poly.evaluate(values)
    iv = enclose(poly, box)
    assert Fraction(iv.lo) - Fraction(1, 10**40) <= exact <= Fraction(iv.hi) + Fraction(1, 10**40)


# --------------------------------------------------------------------------- errors


def test_invalid_arguments_raise():
    poly = path_following_vdot(4.0, 0.1)
    with pytest.raises(InvalidRegion, match=r"depends on \['alpha'\], which the region does not bound"):
        certify_nonpositive(poly, {"delta": (-1.0, 1.0)})
    with pytest.raises(InvalidRegion, match=r"expected finite bounds with lo <= hi"):
        certify_nonpositive(poly, {"alpha": (1.0, -1.0)})
    with pytest.raises(InvalidRegion, match=r"expected finite bounds"):
        certify_nonpositive(poly, {"alpha": (-math.inf, 1.0)})
    with pytest.raises(InvalidRegion, match=r"expected a pair \(lo, hi\) of numbers"):
        certify_nonpositive(poly, {"alpha": 1.0})
    with pytest.raises(InvalidRegion, match=r"expected a non-empty mapping"):
        certify_nonpositive(poly, {})
    with pytest.raises(InvalidRegion, match=r"split_at names 'beta', which is not a region variable"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, split_at={"beta": (0.0,)})
    with pytest.raises(InvalidRegion, match=r"expected a sequence of numbers"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, split_at={"alpha": ("a",)})
    with pytest.raises(InvalidRegion, match=r"expected a sequence of numbers"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, split_at={"alpha": None})
    with pytest.raises(InvalidRegion, match=r"split_at = 0.0: expected a mapping"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, split_at=0.0)
    with pytest.raises(InvalidSearchParameter, match=r"max_boxes = 0: expected an integer >= 1"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, max_boxes=0)
    with pytest.raises(InvalidSearchParameter, match=r"max_failures = 0: expected an integer >= 1"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, max_failures=0)
    with pytest.raises(InvalidSearchParameter, match=r"min_width = -1.0: expected a finite width >= 0"):
        certify_nonpositive(poly, {"alpha": (-1.0, 1.0)}, min_width=-1.0)
    with pytest.raises(TypeError, match=r"expected an analysis.polynomial.Polynomial"):
        certify_nonpositive("x", {"alpha": (-1.0, 1.0)})
    with pytest.raises(InvalidCertificate, match=r"format = 'x': expected 'analysis.certificate/1'"):
        Certificate.from_dict({"format": "x"})
    with pytest.raises(InvalidCertificate, match=r"certificate key 'boxes' is missing or malformed"):
        Certificate.from_dict({"format": "analysis.certificate/1", "variables": ["a"], "region": [["0x0p+0", "0x1p+0"]]})
    with pytest.raises(InvalidCertificate, match=r"key 'region' is missing or malformed"):
        Certificate.from_dict({"format": "analysis.certificate/1", "variables": ["a"], "region": [[0.0, 1.0]]})
