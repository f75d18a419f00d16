"""An unbounded ``time-horizon`` (negative: SpaceEx's ``time-horizon = -1``) is read as ``math.inf``; zero, NaN,
infinities and text are refused naming the key; the STL formula and the export handle it explicitly."""

from __future__ import annotations

import math

import pytest

from hybrid.spaceex_config import forbidden_formula, parse_config
from hybrid.spaceex_export import spaceex_cfg
from hybrid.spaceex_import import load_spaceex
from hybrid.spaceex_syntax import SpaceExError
from pathlib import Path

BALL = Path(__file__).resolve().parents[1] / "data" / "spaceex" / "spaceexparser" / "bball" / "bball.xml"
BASE = 'system = "system"\ninitially = "10<=x<=10.2 & v==0"\nforbidden = "x >= 10.5"\n'


@pytest.mark.parametrize("value", ["-1", "-0.5", "-1e9"])
def test_a_negative_horizon_is_unbounded(value):
    cfg = parse_config(BASE + f"time-horizon = {value}\niter-max = -1\n", "u.cfg")
    assert cfg.horizon == math.inf and cfg.unbounded and "iter-max" in cfg.ignored
    assert not parse_config(BASE + "time-horizon = 8\n", "b.cfg").unbounded
    assert not parse_config(BASE, "n.cfg").unbounded  # no horizon at all: None, not unbounded


@pytest.mark.parametrize("value", ["0", "-0", "nan", "inf", "-inf", "soon"])
def test_a_horizon_that_is_neither_positive_nor_negative_and_finite_is_refused_naming_it(value):
    with pytest.raises(SpaceExError) as caught:
        parse_config(BASE + f"time-horizon = {value}\n", "u.cfg")
    text = str(caught.value)
    assert "u.cfg:4: time-horizon" in text and "time-horizon = -1 for an unbounded property" in text


def test_a_sampling_time_with_an_unbounded_horizon_is_checked_without_an_upper_bound():
    assert parse_config(BASE + "time-horizon = -1\nsampling-time = 0.05\n", "u.cfg").sampling_time == 0.05
    with pytest.raises(SpaceExError) as caught:
        parse_config(BASE + "time-horizon = -1\nsampling-time = 0\n", "u.cfg")
    assert "sampling-time" in str(caught.value) and "inf" not in str(caught.value)


def test_the_stl_formula_needs_a_finite_window():
    model = load_spaceex(BALL)
    cfg = parse_config(BASE + "time-horizon = -1\n", "u.cfg")
    with pytest.raises(SpaceExError, match="finite window"):
        forbidden_formula(model, cfg, cfg.horizon)
    assert forbidden_formula(model, cfg, 30.0).startswith("always[0, 30.0] not ")


def test_the_export_writes_an_unbounded_horizon_as_minus_one_and_reads_it_back():
    model = load_spaceex(BALL)
    box = {s: (1.0, 1.0) for s in model.system.state_names}
    text = spaceex_cfg(model.system, box, horizon=math.inf, forbidden="x >= 20")
    assert "time-horizon = -1" in text and "sampling-time" not in text
    assert parse_config(text, "e.cfg").unbounded
    for bad in (math.nan, -1.0, 0.0, -math.inf, True):
        with pytest.raises(SpaceExError, match="spaceex_cfg: horizon"):
            spaceex_cfg(model.system, box, horizon=bad)
