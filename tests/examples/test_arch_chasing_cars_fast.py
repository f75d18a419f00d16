"""CC's float fast path (examples/arch/chasing_cars.py, :func:`simulate_floats`, taken on plain float inputs) against
the generic path it stands in for: the same closed forms run through the dual-aware code on the same floats (inputs
held in object arrays, which select the generic path), and the value part of the dual run (:func:`sensitivities_cars`).
The fast path promises the same floating-point operations in the same order, so the comparison is exact (no
tolerance): every sample time, every signal value and every mode."""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from analysis.dual import variables
from analysis.verify.signals import PiecewiseConstantInput

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "arch" / "chasing_cars.py"


@pytest.fixture(scope="module")
def cc():
    spec = importlib.util.spec_from_file_location("arch_chasing_cars_fast_under_test", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _signals(cc, rng, throttle_points, brake_points):
    throttle = PiecewiseConstantInput(name="throttle", low=0.0, high=1.0, control_points=throttle_points,
                                      span=cc.HORIZON)
    brake = PiecewiseConstantInput(name="brake", low=0.0, high=1.0, control_points=brake_points, span=cc.HORIZON)
    point = {}
    for item in (throttle, brake):
        for name in item.parameter_names:  # corners as well as interior values: saturated throttle / brake runs
            point[name] = float(rng.choice([0.0, 1.0])) if rng.random() < 0.2 else float(rng.uniform(0.0, 1.0))
    return throttle.signal(point), brake.signal(point)


def _generic(signal):
    """The same signal with its values in an object array: :func:`simulate_cars` then runs the generic code."""
    return dataclasses.replace(signal, values=signal.values.astype(object))


def _assert_same(fast, reference):
    assert fast.keys() == reference.keys()
    assert fast["modes"] == reference["modes"]
    for name in ("time", *(f"y{i}" for i in range(1, 6)), *(f"v{i}" for i in range(1, 6))):
        a, b = np.asarray(fast[name], dtype=float), np.asarray(reference[name], dtype=float)
        assert a.shape == b.shape and a.tobytes() == b.tobytes(), name  # bit for bit (signed zeros included)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_fast_path_is_bit_identical_to_the_generic_path(cc, sign):
    rng = np.random.default_rng(29 if sign > 0 else 92)
    events = 0
    for throttle_points, brake_points in ((7, 3), (7, 3), (7, 3), (1, 1), (12, 5), (25, 10)):
        throttle, brake = _signals(cc, rng, throttle_points, brake_points)
        horizon = float(rng.choice([cc.HORIZON, 37.3]))
        fast = cc.simulate_cars(throttle, brake, horizon, keeping_sign=sign)
        reference = cc.simulate_cars(_generic(throttle), _generic(brake), horizon, keeping_sign=sign)
        _assert_same(fast, reference)
        events += sum(a != b for a, b in zip(fast["modes"], fast["modes"][1:]))
    assert events >= 100  # the runs switch modes (and so exercise event location), not only flow


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_fast_path_gives_the_values_of_the_dual_path(cc, sign):
    rng = np.random.default_rng(7 if sign > 0 else 8)
    for _ in range(2):
        throttle, brake = _signals(cc, rng, 7, 3)
        duals = variables([*throttle.values.tolist(), *brake.values.tolist()])
        dual_throttle = dataclasses.replace(throttle, values=np.array(duals[:7], dtype=object))
        dual_brake = dataclasses.replace(brake, values=np.array(duals[7:], dtype=object))
        trace, sens = cc.sensitivities_cars(dual_throttle, dual_brake, keeping_sign=sign)
        fast = cc.simulate_cars(throttle, brake, keeping_sign=sign)
        assert trace.times.tobytes() == np.asarray(fast["time"]).tobytes()
        for name in cc.OUTPUTS:
            assert trace.signal(name).tobytes() == np.ascontiguousarray(fast[name]).tobytes(), name
            assert sens[name].shape == (trace.n, 10)
        assert tuple(zip(*(trace.label(f"mode{i}") for i in range(2, 6)))) == fast["modes"]
