"""The report's rounding policy (:mod:`visnav.app.precision`): outward bounds, floors, idempotence, every kind used."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.app.precision import (
    KINDS,
    RULES,
    TEXT_RULES,
    Precision,
    kind_of,
    number_text,
    quantise_for_figure,
    round_numbers_in_text,
    round_tree,
    round_value,
)

FINITE = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
DIGITS_KINDS = sorted(k for k, p in KINDS.items() if p.digits is not None)


def _significant_digits(x: float) -> int:
    """Significant digits of the shortest decimal of ``x`` (an independent count: the string, not decimal)."""
    mantissa = repr(abs(x)).split("e")[0].replace(".", "").lstrip("0").rstrip("0")
    return len(mantissa)


@settings(max_examples=400, deadline=None)
@given(x=FINITE, kind=st.sampled_from(DIGITS_KINDS))
def test_rounding_keeps_the_digits_and_is_idempotent(x, kind):
    p = KINDS[kind]
    r = round_value(x, kind)
    assert round_value(r, kind) == r  # a rounded report rounds to itself (sections and the assembly both round)
    if p.floor and abs(x) <= p.floor:
        assert r == p.floor
        return
    if r != 0.0:
        assert _significant_digits(r) <= p.digits
    # within one step of x, measured in exact rational arithmetic (not the decimal module the code uses)
    exponent = math.floor(math.log10(abs(x))) if x != 0 else 0
    step = max(Fraction(10) ** (exponent - p.digits + 2), Fraction(p.resolution))  # one decade of slack
    assert abs(Fraction(r) - Fraction(x)) <= step


@settings(max_examples=400, deadline=None)
@given(x=FINITE)
def test_proven_bounds_are_rounded_outward(x):
    """An upper bound never prints below the proven value, a lower bound never above; both within one step."""
    up, down = round_value(x, "bound_up"), round_value(x, "bound_down")
    assert up >= x and down <= x
    assert Fraction(up) - Fraction(down) <= Fraction(abs(x)) * Fraction(2, 1000) + Fraction(1, 10**300)


def test_roundoff_and_truncation_floors_read_at_most():
    assert round_value(0.0, "roundoff") == round_value(3.05e-16, "roundoff") == 1e-12
    assert round_value(2.4e-12, "roundoff") == 3e-12  # up: still an upper bound
    assert round_value(1.39e-10, "truncation_px") == round_value(1.48e-10, "truncation_px") == 1e-8
    assert round_value(0.10090656752426588, "truncation_px") == 0.1
    assert round_value(5.5647620316463647e-08, "truncation_px") == 6e-8


def test_machine_noise_disappears():
    """The differences measured between two SIMD/BLAS variants of the same run print the same."""
    pairs = [("input", 5.9238725918903485, 5.923872591890348),
             ("linear_algebra", -0.050000000000002695, -0.04999999999999895),
             ("linear_algebra", -1.1890488593735427e-15, 0.0),
             ("margin", 18.220222169093134, 18.220222169093084),
             ("sdp", 72224.78226194467, 72224.78521964807),
             ("time", 13.950000000000001, 13.95),
             ("simulation", 9.999999717180685e-10, 1e-09),
             ("error_px", 0.0009789827640288777, 0.0009789827639181074),
             ("truncation_mm", 2.738005400340894e-06, 2.738007176021801e-06)]
    for kind, a, b in pairs:
        assert number_text(a, kind) == number_text(b, kind), (kind, a, b)


def test_negative_zero_and_non_finite_values():
    assert math.copysign(1.0, round_value(-0.0, "computed")) == 1.0
    assert math.copysign(1.0, round_value(-1e-15, "linear_algebra")) == 1.0
    assert round_value(math.inf, "sdp") == math.inf and math.isnan(round_value(math.nan, "computed"))
    assert round_value(0.1 + 0.2, "replay") == 0.1 + 0.2  # kept bit for bit


def test_numbers_in_text_are_rounded_names_and_integers_kept():
    """A polynomial's coefficients to 4 significant digits of the largest one (a noise-level one prints 0);
    names (x2) and integer exponents kept."""
    text = "-0.053721509873867035*sin(alpha)^4 + 0.19494002684950829*x2^3 - 6.306091755628586e-06*delta"
    assert round_numbers_in_text(text, "sdp") == "-0.0537*sin(alpha)^4 + 0.1949*x2^3 - 0*delta"
    # two SDP solutions of one machine and another (measured): the same text
    assert (round_numbers_in_text("1.264e-05*sin(alpha)^4 + 16.38*sin(alpha)^3*cos(alpha)", "sdp")
            == round_numbers_in_text("9.775e-06*sin(alpha)^4 + 16.38*sin(alpha)^3*cos(alpha)", "sdp"))
    # the level of a certified set rounds down (a smaller set of the certified family), box bounds unchanged
    claim = "S = {x in B : V(x) <= %s} with B = delta in [-0.5, 0.5] x alpha in [-2.98451, 2.98451]"
    assert (round_numbers_in_text(claim % "0.999999969", "certified_level")
            == round_numbers_in_text(claim % "0.999999973", "certified_level") == claim % "0.999999")


def test_the_documentation_lists_every_kind():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[3] / "docs" / "report.md").read_text()
    for kind, p in KINDS.items():
        assert f"| `{kind}` | {'bit for bit' if p.digits is None else p.digits} |" in doc, kind


def test_every_rule_names_a_kind_and_every_kind_says_why():
    for _, kind in RULES + TEXT_RULES:
        assert kind in KINDS
    for p in KINDS.values():
        assert len(p.why) > 40
    assert RULES[-1] == ("*", "computed")  # nothing escapes the policy
    assert kind_of("analysis/path_following/sos/bypass/combined/delta_max_m") == "bound_up"
    assert kind_of("analysis/path_following/sos/bypass/combined/min_distance_m") == "bound_down"
    assert kind_of("stiffness/reconstruction/bdf6/truncation_error_px") == "truncation_px"
    assert kind_of("fuzzing/variants/paper/counterexamples/x/state") == "replay"


def test_bad_precision_is_refused():
    with pytest.raises(ValueError, match="direction"):
        Precision(kind="x", digits=3, why="w", direction="sideways")
    with pytest.raises(ValueError, match="digits"):
        Precision(kind="x", digits=0, why="w")


def test_round_tree_uses_the_path():
    data = {"bypass": [{"combined": {"delta_max_m": 0.25011559591320137, "min_distance_m": 0.24988440408679863}}],
            "lyapunov": "0.123456789*delta^2"}
    out = round_tree(data, "analysis/path_following/sos")
    assert out["bypass"][0]["combined"] == {"delta_max_m": 0.2502, "min_distance_m": 0.2498}
    assert out["lyapunov"] == "0.1235*delta^2"
    assert round_tree(out, "analysis/path_following/sos") == out


def test_figures_are_drawn_from_quantised_values():
    x = np.array([1.0000000000000002, 0.1 + 0.2, -3.14159265358979, 0.0, np.inf])
    q = quantise_for_figure({"a": x, "b": [0.30000000000000004]})
    assert np.array_equal(q["a"][:4], [1.0, 0.3, -3.14159, 0.0]) and np.isinf(q["a"][4])
    assert q["b"] == [0.3]
