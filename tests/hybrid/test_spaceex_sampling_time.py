"""``sampling-time`` of a SpaceEx ``.cfg``: read as the flowpipe's step, checked, ignored where it is no step."""

from __future__ import annotations

import pytest

from hybrid.spaceex_config import parse_config
from hybrid.spaceex_syntax import SpaceExError

BASE = 'system = "system"\ninitially = "10<=x<=10.2 & v==0"\nforbidden = "x >= 10.5"\ntime-horizon = 8\n'


def test_a_sampling_time_is_read_as_written():
    cfg = parse_config(BASE + "sampling-time = 0.05\n", "a.cfg")
    assert cfg.sampling_time == 0.05 and "sampling-time" not in cfg.ignored
    assert parse_config(BASE + "sampling-time = 8\n", "a.cfg").sampling_time == 8.0  # the horizon itself: one step
    assert parse_config(BASE, "a.cfg").sampling_time is None


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "-inf", "8.000001", "1e3", "fast", ""])
def test_a_bad_sampling_time_is_an_error_naming_it(value):
    with pytest.raises(SpaceExError) as caught:
        parse_config(BASE + f"sampling-time = {value}\n", "a.cfg")
    text = caught.value.render() if hasattr(caught.value, "render") else str(caught.value)
    assert "a.cfg:5: sampling-time" in text and "time-horizon = 8.0" in text and "remove the line" in text


def test_without_a_horizon_only_positive_and_finite_are_checked():
    cfg = parse_config('forbidden = "x >= 1"\nsampling-time = 100\n', "b.cfg")
    assert cfg.sampling_time == 100.0 and cfg.horizon is None
    with pytest.raises(SpaceExError, match="sampling-time"):
        parse_config('sampling-time = 0\n', "b.cfg")


@pytest.mark.parametrize("scenario", ["stc", '"stc"', "simu", "STC"])
def test_in_the_step_free_scenarios_it_is_ignored_unchecked(scenario):
    """SpaceEx's stc adapts its steps (sampling-time is where it starts), simu samples a simulation: the ARCH
    gearbox GRBX01-MES01.cfg (stc) has sampling-time = 1 over a horizon of 0.5 s and still loads."""
    cfg = parse_config(BASE + f"scenario = {scenario}\nsampling-time = 100\n", "c.cfg")
    assert cfg.sampling_time is None and "sampling-time" in cfg.ignored
    supp = parse_config(BASE + "scenario = supp\nsampling-time = 0.5\n", "c.cfg")
    assert supp.sampling_time == 0.5 and "sampling-time" not in supp.ignored
