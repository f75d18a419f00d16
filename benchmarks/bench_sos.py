"""The SOS analysis of the paper scenario's path following: time of each part, and what it finds.

Run: ``.venv/bin/python benchmarks/bench_sos.py [--repeats N] [--intervals]``.

Times (median of ``--repeats`` runs, wall clock, this machine, solver threads as configured) of the
three parts of :func:`visnav.studies.path_following_sos.path_following_sos` called one by one:

* region: the volume-heuristic SOS region, its branch-and-bound certificate and scalar re-check;
* bypass: the sets through the entry at the scenario's ``k`` and the tight re-checked bounds;
* gains: the scan of ``k`` over ``K_PATH_RANGE`` (13-point grid, 3 refinements of each edge);

their sum (the budget is 30 s), then the area ratio, the bounds beside the hand-given ``V``'s and
the simulation's, and the admissible gains both ways.  ``--intervals`` also times, once, the k-interval
certificates between the proven gains (``prove_intervals=True``).
"""

from __future__ import annotations

import argparse
import statistics
import time


def _simulated_bypass(scenario, obstacle_index: int = 0) -> tuple[float, float]:
    """Largest ``|δ|`` and ``|ω|`` of the simulated run while the supervisor follows the path (sampled)."""
    import numpy as np

    from visnav.geometry import proximity
    from visnav.simulation import simulate
    from visnav.supervisor import split_mode

    trace = simulate(scenario).trace
    start = [e for e in trace.events if split_mode(e.target)[0] == "AVOID"]
    end = [e for e in trace.events if split_mode(e.target)[0] == "LEAVE"]
    if not start or not end:
        return float("nan"), float("nan")
    memory = dict(start[0].memory)
    obstacle = scenario.obstacles[int(memory["obstacle"])]
    times = np.asarray(trace.times)
    mask = (times >= start[0].time) & (times <= end[0].time)
    deltas = [proximity(x, y, th, obstacle, int(memory["side"])).d_coll - scenario.envelopes.d_zero_m
              for x, y, th, _ in np.asarray(trace.states)[mask]]
    return float(np.max(np.abs(deltas))), float(np.max(np.abs(np.asarray(trace.inputs)[mask, 1])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--intervals", action="store_true", help="also time the k-interval certificates once")
    args = parser.parse_args()

    from visnav.parameters import PATH_CLEARANCE_M, K_PATH_RANGE
    from visnav.scenario import load_scenario
    from visnav.studies.loop_analysis import entry_angles_from_simulation
    from visnav.studies.path_following_sos import (
        certified_region,
        polynomial_loop,
        sos_admissible_gains,
        sos_entry_bounds,
    )

    scenario = load_scenario("paper")
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    angles = sorted({round(a, 12) for _, _, a in entry_angles_from_simulation(scenario)})
    radii = tuple(o.radius_m for o in scenario.obstacles)
    k, v, d0 = gains.k_path, gains.v_coll_mps, env.d_zero_m
    entry = (env.d_minus_m - d0 - v * scenario.sampling_period_s, env.d_minus_m - d0)
    times: dict[str, list[float]] = {"region": [], "bypass": [], "gains": []}
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        loop = polynomial_loop(k=k, v=v, d_zero=d0, radii=radii)
        region = certified_region(loop)
        t1 = time.perf_counter()
        bypass = [sos_entry_bounds(loop, delta_entry=entry, alpha0=a, recheck=True) for a in angles]
        t2 = time.perf_counter()
        scan = sos_admissible_gains(v=v, d_zero=d0, radii=radii, delta_entry=entry, entry_angles=angles,
                                    clearance=PATH_CLEARANCE_M, omega_max=limits.omega_max_radps, extra_gains=(k,))
        t3 = time.perf_counter()
        for name, dt in (("region", t1 - t0), ("bypass", t2 - t1), ("gains", t3 - t2)):
            times[name].append(dt)
    medians = {name: statistics.median(ts) for name, ts in times.items()}
    print(f"paper scenario: k = {k:g} 1/m, v = {v:g} m/s, d0 = {d0:g} m, radii {radii} m, entry delta in "
          f"[{entry[0]:.4g}, {entry[1]:.4g}] m, alpha0 {angles} rad; median of {args.repeats} runs")
    for name, value in medians.items():
        print(f"  {name:7s} {value:7.2f} s   (runs: {', '.join(f'{t:.2f}' for t in times[name])})")
    print(f"  total   {sum(medians.values()):7.2f} s   (budget 30 s)")
    print(f"region: {region.status}; area {region.area:.4g} m rad vs hand-given {region.hand_area:.4g} "
          f"(c* = {region.hand_level:g}): ratio {region.area_ratio:.3f}; {len(region.certificate.boxes)} boxes")
    sim_delta, sim_omega = _simulated_bypass(scenario)
    for b in bypass:
        cf = b.hand_closed_form["nominal"]
        print(f"bypass alpha0 = {b.alpha0:.4g} rad ({b.status}):")
        print(f"  hand V, closed form (visnav analyse): |delta| <= {cf['delta_max_m']:.4g} m, "
              f"|omega| <= {cf['omega_max_radps']:.4g} rad/s")
        for label, pair in (("hand V, branch and bound", b.hand), ("SOS sets", b.sos), ("all sets (reported)", b.combined)):
            print(f"  {label:26s}: |delta| <= {pair.delta_max_m:.4g} m (clearance >= {pair.min_distance_m:.4g} m), "
                  f"|omega| <= {pair.omega_max_radps:.4g} rad/s")
        print(f"  simulation (sampled)      : |delta| = {sim_delta:.4g} m, |omega| = {sim_omega:.4g} rad/s")
    hand = scan.hand
    print(f"admissible k (clearance >= {PATH_CLEARANCE_M:g} m, |omega| <= {limits.omega_max_radps:g} rad/s), "
          f"searched {K_PATH_RANGE}:")
    print(f"  hand V : {hand['interval']}  ({hand['finding']})")
    print(f"  SOS    : {scan.interval}, proven at {len(scan.proven_gains)} gains {[round(g, 4) for g in scan.proven_gains]}")
    print(f"  edges  : lower in {scan.lower_bracket}, upper in {scan.upper_bracket}")
    print(f"  finding: {scan.finding}")
    if args.intervals:
        t = time.perf_counter()
        proven = sos_admissible_gains(v=v, d_zero=d0, radii=radii, delta_entry=entry, entry_angles=angles,
                                      clearance=PATH_CLEARANCE_M, omega_max=limits.omega_max_radps,
                                      extra_gains=(k,), prove_intervals=True)
        print(f"with k-interval certificates ({time.perf_counter() - t:.2f} s): interval {proven.interval}, "
              f"every k proven: {proven.interval_proven}")
        for d in proven.intervals_proven:
            print(f"  [{d['k'][0]:.4g}, {d['k'][1]:.4g}]: {'proven' if d['proven'] else 'not proven'}")


if __name__ == "__main__":
    main()
