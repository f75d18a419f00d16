"""Events located per second: ``hybrid.simulate_continuous`` against a hand-written solve_ivp loop.

Usage::

    python benchmarks/bench_events.py [--rounds N]

Both sides do the same job on the reference models of :mod:`hybrid.examples`,
with the same solver (RK45), the same tolerances (rtol 1e-10, atol 1e-12) and
the same number of events:

* bouncing ball (e = 0.8, from 1 m at rest): every impact up to the 53rd,
  where the executor's Zeno test stops the run (the last flight lasts 8 µs);
* thermostat (19 °C / 21 °C hysteresis): every switch over 2000 s.

The hand-written loop is the straightforward correct one: one ``solve_ivp``
call per flow with a terminal event (direction set so that a guard sitting on
zero after the reset does not fire again), the reset applied to the event
state, and a restart.  The executor additionally checks the guards at three
interior points of every step (``sign_checks=3``), the invariants, and the
priorities; the run with ``sign_checks=0`` is printed too.

Prints per model the median time of each side, events per second and the
ratio; the event times of both sides are compared (max relative difference).
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time

import numpy as np
from scipy.integrate import solve_ivp

from hybrid import simulate_continuous
from hybrid.examples import bouncing_ball, thermostat

RTOL, ATOL = 1e-10, 1e-12


def ball_loop(g: float, e: float, h0: float, v0: float, n_events: int, t_end: float) -> list[float]:
    """Hand-written bouncing-ball event loop with solve_ivp."""

    def hit(t, y):
        return y[0]

    hit.terminal = True
    hit.direction = -1
    t, y = 0.0, [h0, v0]
    times: list[float] = []
    while len(times) < n_events and t < t_end:
        sol = solve_ivp(lambda _t, s: [s[1], -g], (t, t_end), y, method="RK45", rtol=RTOL, atol=ATOL, events=hit)
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        h, v = sol.y_events[0][0]
        y = [h, -e * v]
        times.append(t)
    return times


def thermostat_loop(ambient: float, heater: float, rate: float, low: float, high: float, T0: float,
                    t_end: float) -> list[float]:
    """Hand-written thermostat event loop with solve_ivp."""

    def too_cold(t, y):
        return y[0] - low

    def too_hot(t, y):
        return y[0] - high

    too_cold.terminal, too_cold.direction = True, -1
    too_hot.terminal, too_hot.direction = True, 1
    heating = False
    t, y = 0.0, [T0]
    times: list[float] = []
    while t < t_end:
        target = heater if heating else ambient
        sol = solve_ivp(lambda _t, s: [-rate * (s[0] - target)], (t, t_end), y, method="RK45", rtol=RTOL,
                        atol=ATOL, events=too_hot if heating else too_cold)
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        y = [float(sol.y_events[0][0][0])]
        heating = not heating
        times.append(t)
    return times


def interleaved_medians(contenders: list, rounds: int) -> tuple[list[float], list[object]]:
    """Median wall time of each contender, the contenders alternating within every round."""
    samples: list[list[float]] = [[] for _ in contenders]
    results: list[object] = [None] * len(contenders)
    for _ in range(rounds):
        for k, fn in enumerate(contenders):
            gc.collect()
            start = time.perf_counter()
            results[k] = fn()
            samples[k].append(time.perf_counter() - start)
    return [statistics.median(s) for s in samples], results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()

    ball = bouncing_ball(restitution=0.8, h0=1.0, v0=0.0)
    ours_ball = lambda checks: simulate_continuous(  # noqa: E731
        ball.system, ball.x0, duration=10.0, rtol=RTOL, atol=ATOL, sign_checks=checks, dense=False)
    trajectory = ours_ball(3)
    n_ball = len(trajectory.events)
    hand_ball = lambda: ball_loop(9.81, 0.8, 1.0, 0.0, n_ball, 10.0)  # noqa: E731

    thermo = thermostat()
    horizon = 2000.0
    ours_thermo = lambda checks: simulate_continuous(  # noqa: E731
        thermo.system, thermo.x0, duration=horizon, rtol=RTOL, atol=ATOL, sign_checks=checks, dense=False)
    hand_thermo = lambda: thermostat_loop(10.0, 30.0, 0.1, 19.0, 21.0, thermo.x0[0], horizon)  # noqa: E731

    print(f"events located per second, median of {args.rounds} interleaved rounds (RK45, rtol {RTOL:g}, atol {ATOL:g})")
    for name, ours, hand in (("bouncing ball", ours_ball, hand_ball), ("thermostat", ours_thermo, hand_thermo)):
        (t_ours, t_ours0, t_hand), (traj, _, times) = interleaved_medians(
            [lambda: ours(3), lambda: ours(0), hand], args.rounds)
        ours_times = np.array([e.time for e in traj.events])  # type: ignore[attr-defined]
        hand_times = np.array(times)  # type: ignore[arg-type]
        n = min(len(ours_times), len(hand_times))
        diff = float(np.max(np.abs(ours_times[:n] - hand_times[:n]) / hand_times[:n]))
        events = len(ours_times)
        print(f"\n{name}: {events} events (hand loop {len(hand_times)}), max relative difference of event times {diff:.2e}")
        print(f"  hybrid.simulate_continuous  {t_ours * 1e3:8.2f} ms  {events / t_ours:9.0f} events/s")
        print(f"    with sign_checks=0        {t_ours0 * 1e3:8.2f} ms  {events / t_ours0:9.0f} events/s")
        print(f"  hand-written solve_ivp loop {t_hand * 1e3:8.2f} ms  {len(hand_times) / t_hand:9.0f} events/s")
        print(f"  speed ratio (hand / ours)   {t_hand / t_ours:8.2f}x   (sign_checks=0: {t_hand / t_ours0:.2f}x)")


if __name__ == "__main__":
    main()
