"""Cost of one reconstruction step: FeatureEstimator.advance (BDF4 + Newton) against solve_ivp.

Usage::

    python benchmarks/bench_bdf_step.py [--rounds N] [--budget-us B]

Both sides advance the same 4-point state ``ψ`` of equation (13) over one
sampling period ``h = 50 ms`` along an exactly known ZOH motion (the test
motion of ``tests/visnav/test_estimator.py``):

* ``FeatureEstimator.advance``: one BDF4 step (predictor, per-point 2×2 Newton,
  histopolated screw) in Python floats, timed call by call with
  ``time.perf_counter_ns`` (the ~60 ns timer overhead is included);
* ``scipy.integrate.solve_ivp(F, (0, h), ψ_k, method="BDF", rtol=1e-10,
  atol=1e-12)`` with a numpy ``F`` of (13) and the same (constant) screw.  ``F``
  is written out over all points at once (calling :func:`visnav.model.feature_depth_rate`
  on arrays costs 1.5× as much per evaluation and would flatter the estimator); the
  script checks it against :func:`visnav.model.feature_depth_rate`, the single
  definition of (13), before timing.

Prints the medians [µs] and their ratio; exits with status 1 if the median of
the BDF4 step exceeds the budget (20 µs by default).
"""

from __future__ import annotations

import argparse
import gc
import math
import statistics
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

from visnav.estimator import FeatureEstimator
from visnav.geometry import camera_pose, project_points, propagate_pose
from visnav.model import feature_depth_rate
from visnav.parameters import EstimatorSettings, RobotGeometry

GEOMETRY = RobotGeometry()
POINTS = ((5.0, 2.3, 0.3), (5.0, 2.7, 0.3), (5.0, 2.3, 0.7), (5.0, 2.7, 0.7))
H = 0.05
N_HISTORY = 10
N_STEPS = 300  # 15 s
BUDGET_US = 20.0


def commands(t: float) -> tuple[float, float, float]:
    return (0.2, 0.3 * math.sin(0.5 * t), -0.25 * math.cos(0.4 * t))


def features(pose):
    cx, cy, phi = camera_pose(*pose, GEOMETRY)
    return project_points(cx, cy, phi, GEOMETRY.camera_height_m, POINTS)


def motion():
    pose = (0.0, 0.0, 0.0, 0.0)
    poses, rates = [pose], []
    for k in range(N_HISTORY + N_STEPS):
        q = commands((k - N_HISTORY) * H)
        rates.append(q)
        pose = propagate_pose(pose, *q, H)
        poses.append(pose)
    return poses, rates


def fresh_estimator(poses, rates) -> FeatureEstimator:
    est = FeatureEstimator(GEOMETRY, EstimatorSettings(order=4, screw_model="histopolated"))
    est.observe(features(poses[0]))
    for k in range(1, N_HISTORY + 1):
        est.observe(features(poses[k]), poses[k - 1][3], rates[k - 1], H)
    est.start(require_full_history=True)
    return est


def rhs_numpy(t: float, psi: np.ndarray, screw: tuple[float, float, float]) -> np.ndarray:
    """Equation (13) for all points at once (numpy)."""
    v_y, v_z, w_x = screw
    x, y, z = psi[0::3], psi[1::3], psi[2::3]
    out = np.empty_like(psi)
    out[0::3] = x * (v_z / z + y * w_x)
    out[1::3] = (y * v_z - v_y) / z + (1.0 + y * y) * w_x
    out[2::3] = -v_z - z * y * w_x
    return out


def check_rhs_numpy(poses, rates) -> None:
    """``rhs_numpy`` is equation (13) as :mod:`visnav.model` defines it (to rounding), else ``RuntimeError``."""
    est = fresh_estimator(poses, rates)
    for k in range(N_HISTORY, N_HISTORY + N_STEPS, 10):
        screw = est.screw_for_step(poses[k][3], rates[k], H)
        points = features(poses[k])
        expected = np.array([feature_depth_rate(*point, *screw) for point in points]).reshape(-1)
        got = rhs_numpy(0.0, np.array(points, dtype=float).reshape(-1), screw)
        if not np.allclose(got, expected, rtol=1e-13, atol=1e-15):
            raise RuntimeError(f"rhs_numpy differs from visnav.model.feature_depth_rate at step {k}")


def bench_estimator(poses, rates, rounds: int) -> tuple[list[int], list[int]]:
    times, iterations = [], []
    clock = time.perf_counter_ns
    for _ in range(rounds):
        est = fresh_estimator(poses, rates)
        gc.disable()
        try:
            for k in range(N_HISTORY, N_HISTORY + N_STEPS):
                pan, q = poses[k][3], rates[k]
                t0 = clock()
                est.advance(pan, q, H)
                t1 = clock()
                times.append(t1 - t0)
                iterations.append(est.last_newton_iterations)
        finally:
            gc.enable()
    return times, iterations


def bench_solve_ivp(poses, rates, repetitions: int) -> list[int]:
    est = fresh_estimator(poses, rates)
    cases = []
    for k in range(N_HISTORY, N_HISTORY + N_STEPS, max(1, N_STEPS // repetitions)):
        screw = est.screw_for_step(poses[k][3], rates[k], H)
        cases.append((np.array(features(poses[k]), dtype=float).reshape(-1), screw))
    times = []
    clock = time.perf_counter_ns
    for psi, screw in cases[:repetitions]:
        t0 = clock()
        sol = solve_ivp(rhs_numpy, (0.0, H), psi, method="BDF", rtol=1e-10, atol=1e-12, args=(screw,))
        t1 = clock()
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        times.append(t1 - t0)
    return times


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=20, help="passes over the 300-step motion (default 20)")
    parser.add_argument("--ivp-repetitions", type=int, default=100, help="solve_ivp calls (default 100)")
    parser.add_argument("--budget-us", type=float, default=BUDGET_US, help="limit on the BDF4 step median [µs]")
    args = parser.parse_args(argv)
    poses, rates = motion()
    check_rhs_numpy(poses, rates)
    bench_estimator(poses, rates, 1)  # warm-up
    step_ns, iterations = bench_estimator(poses, rates, args.rounds)
    ivp_ns = bench_solve_ivp(poses, rates, args.ivp_repetitions)
    step_us = statistics.median(step_ns) / 1000.0
    ivp_us = statistics.median(ivp_ns) / 1000.0
    print(f"FeatureEstimator.advance (BDF4 + Newton, 4 points): median {step_us:8.2f} µs "
          f"over {len(step_ns)} steps (p10 {np.percentile(step_ns, 10) / 1000:.2f}, "
          f"p90 {np.percentile(step_ns, 90) / 1000:.2f}); Newton iterations per step: "
          f"max {max(iterations)}, mean {statistics.fmean(iterations):.2f}")
    print(f"solve_ivp(method='BDF', rtol=1e-10, atol=1e-12):    median {ivp_us:8.2f} µs over {len(ivp_ns)} calls")
    print(f"ratio solve_ivp / advance: {ivp_us / step_us:.0f}x")
    if step_us > args.budget_us:
        print(f"FAIL: the BDF4 step median {step_us:.2f} µs exceeds the budget of {args.budget_us:g} µs",
              file=sys.stderr)
        return 1
    print(f"OK: within the budget of {args.budget_us:g} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
