"""The stability analysis of a scenario: what ``visnav analyse`` prints.

Assembles, for one scenario:

* the path-following law (10)–(12): linearisation by AD with an independent
  closed form, eigenvalue curves against ``k`` and ``v_coll``, the quadratic
  Lyapunov function of the linearisation (``control.lyap``), the
  machine-checked certificate ``V̇ ≤ 0`` (exact normal form + interval
  branch and bound), the region of attraction, the bounds along a bypass
  and the admissible range of ``k`` for the scenario's entry angles;
* beside them, the sum-of-squares study of the same loop
  (:func:`visnav.studies.path_following_sos.path_following_sos`): a certified
  invariant region larger than the hand-given ``V``'s, the bounds on ``|δ|``
  and ``|ω|`` along the bypass and the admissible ``k`` recomputed from its
  certificates (``sos="scan"``; ``"scenario"`` judges only the scenario's
  ``k``, ``"off"`` leaves the study out);
* the loops of the linearised controllers, broken at the angular velocity
  ω (path following, per obstacle), at the pan-rate input (16) and at each
  visual-servoing output channel (7) at the goal, continuous and sampled at
  ``T_e`` with zero-order hold and one sample of computation delay: gain,
  phase and delay margins with their crossover frequencies.

Each claim carries how it was obtained: ``proven`` (the interval
certificate), ``computed`` (linear algebra on the AD linearisation) or
``sampled`` (the entry angles come from a simulation of the scenario).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.linearise import quadratic_lyapunov
from analysis.lmi import common_quadratic_lyapunov_lmi
from analysis.margins import frequency_response_data, loop_model, loop_transfer, margins, sampled_loop_transfer

from visnav import model
from visnav.geometry import proximity
from visnav.parameters import PATH_CLEARANCE_M
from visnav.studies.goal_loops import PanTaskModel, VisualServoingModel, goal_loop_findings, pan_task_model, visual_servoing_model
from hybrid.jsonable import to_jsonable
from visnav.parameters import K_PATH_RANGE, Scenario
from visnav.scenario import validate_gains
from visnav.studies.path_following import (
    admissible_gains,
    certify_path_following,
    entry_bounds,
    path_following_closed_form_eigenvalues,
    path_following_model,
)

__all__ = ["Analysis", "analyse", "entry_angles_from_simulation", "DEFAULT_CLEARANCE_M", "SOS_CHOICES"]

DEFAULT_CLEARANCE_M = PATH_CLEARANCE_M
"""Default clearance the admissible gains must guarantee [m] (the scenario validator keeps d0 above it)."""

SOS_CHOICES = ("scan", "scenario", "off")
"""What :func:`analyse` asks of the SOS study: the gain scan too, the scenario's ``k`` only, or nothing."""

_K_CURVE = tuple(float(k) for k in np.geomspace(0.1, 100.0, 31))
_V_CURVE = tuple(float(v) for v in np.linspace(0.05, 0.6, 12))
_LAMBDA_CURVE = tuple(float(x) for x in np.geomspace(0.05, 40.0, 15))
"""Gains λ [1/s] of the goal-loop curves; 1/T = 20 1/s (the sampled loop's limit) lies inside."""
_RESPONSE_POINTS = 200
"""Log-spaced frequencies of the Bode/Nyquist data, 1e-3 rad/s to the Nyquist frequency π/T."""
_K_MARGIN_CURVE = tuple(float(k) for k in np.geomspace(0.1, 100.0, 13))


@dataclass(frozen=True, kw_only=True, slots=True)
class Analysis:
    """Result of :func:`analyse` (JSON-ready through :meth:`as_dict`)."""

    scenario: str
    data: dict[str, Any]

    def as_dict(self) -> dict[str, Any]:
        """The whole analysis as plain JSON types."""
        return to_jsonable({"scenario": self.scenario, **self.data})


def entry_angles_from_simulation(scenario: Scenario) -> tuple[tuple[str, float, float], ...]:
    """``(obstacle, δ, α)`` where each bypass of the simulated run reaches full path following.

    The supervisor enters ``AVOID`` (µ_coll = 1) on crossing ``d−``; the angle
    there is the entry angle of the Lyapunov analysis.  Sampled: one run.
    """
    from visnav.simulation import simulate
    from visnav.supervisor import split_mode

    result = simulate(scenario)
    trace = result.trace
    out = []
    for event in trace.events:
        before, after = split_mode(event.source)[0], split_mode(event.target)[0]
        if before == "APPROACH" and after == "AVOID":
            k = int(np.searchsorted(trace.times, event.time))
            x, y, theta, _ = trace.states[k]
            memory = dict(event.memory)
            obstacle = scenario.obstacles[int(memory["obstacle"])]
            prox = proximity(x, y, theta, obstacle, int(memory["side"]))
            out.append((obstacle.name, prox.d_coll - scenario.envelopes.d_zero_m, prox.alpha))
    return tuple(out)


def _margin_pair(lm: Any, period: float, **where: Any) -> dict[str, Any]:
    continuous = margins(loop_transfer(lm, **where))
    sampled = margins(sampled_loop_transfer(lm, period, delay_samples=1, **where))
    return {"continuous": continuous.as_dict(), "sampled": sampled.as_dict()}


def _vs_loop(vs: VisualServoingModel) -> Any:
    """Visual-servoing loop at the goal in task space: ė = M q̇, q̇ = −λ J_r⁻¹ e.

    ``M = E G = ∂ė_VS/∂q̇`` by AD of the symbolic model (the projection
    composed with the kinematics); it equals ``C L* J_r = J_r`` (checked in
    the goal findings), so the three channels are decoupled integrators of
    gain λ_VS — computed, not assumed.
    """
    jr_inv = np.array(model.reduced_jacobian_inverse(vs.goal[3], *vs.offsets), dtype=float)
    m = vs.input_matrix()
    return loop_model(np.zeros((3, 3)), m, np.eye(3), None, vs.lambda_vs * jr_inv,
                      input_names=("v", "omega", "pan_rate"), output_names=("e_Vy", "e_Vz", "e_Wx"))


def _pan_loop(pan: PanTaskModel) -> Any:
    """Pan loop at the goal (base at rest): ``ϑ̇ = ϖ``, ``e_gc = c ϑ``, ``ϖ = −K e_gc``; ``c, K`` by AD."""
    c, gain = pan.loop_gains()
    return loop_model([[0.0]], [[1.0]], [[c]], None, [[gain]], input_names=("pan_rate",), output_names=("e_gc",))


def _omega_loop(scenario: Scenario, k: float, radius: float) -> Any:
    env, v = scenario.envelopes, scenario.gains.v_coll_mps
    a_p, b_p, gain = path_following_model(k=k, v=v, d_zero=env.d_zero_m, radius=radius).plant_and_gain()
    return loop_model(a_p, b_p, np.eye(2), None, -gain, input_names=("omega",), output_names=("delta", "alpha"))


def _margin_curve(gains: Sequence[float], build: Any, period: float, **where: Any) -> dict[str, Any]:
    """Headline margins of the loops ``build(g)`` for each gain ``g``, continuous and sampled."""
    keys = ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "gain_crossover_frequency", "closed_loop_stable")
    out: dict[str, Any] = {"continuous": {k: [] for k in keys}, "sampled": {k: [] for k in keys}}
    for g in gains:
        pair = _margin_pair(build(g), period, **where)
        for kind in ("continuous", "sampled"):
            for key in keys:
                out[kind][key].append(pair[kind][key])
    for kind in ("continuous", "sampled"):
        stable = out[kind]["closed_loop_stable"]
        out[kind]["stable_gain_range"] = _stable_range(gains, stable)
    out["sampled"]["stability_limit"] = _sampled_stability_limit(gains, out["sampled"]["closed_loop_stable"], build,
                                                                 period, **where)
    return out


def _sampled_stability_limit(gains: Sequence[float], stable: Sequence[bool], build: Any, period: float,
                             **where: Any) -> float | None:
    """Largest gain keeping the sampled closed loop stable, by bisection between grid points (rel. 1e-10).

    ``None`` when the sampled loop is stable on the whole grid or unstable at its first point.
    """
    last_ok = None
    for i, ok in enumerate(stable):
        if ok:
            last_ok = i
        elif last_ok is not None:
            lo, hi = gains[last_ok], gains[i]
            while hi - lo > 1e-10 * hi:
                mid = math.sqrt(lo * hi)
                if margins(sampled_loop_transfer(build(mid), period, delay_samples=1, **where)).closed_loop_stable:
                    lo = mid
                else:
                    hi = mid
            return lo
    return None


def _stable_range(gains: Sequence[float], stable: Sequence[bool]) -> list[float] | None:
    """``[lowest, highest]`` grid gain with a stable closed loop (``None`` when none; sampled: a grid, not a bound)."""
    ok = [g for g, s in zip(gains, stable) if s]
    return [min(ok), max(ok)] if ok else None


def _sos_study(scenario: Scenario, entries: Sequence[tuple[str, float, float]], angles: Sequence[float],
               clearance_m: float, sos: str) -> dict[str, Any] | None:
    """The SOS study of the path-following loop as JSON (``None`` for ``sos="off"``).

    The entry angles are the hand analysis's: the simulated ones, or ``α0 = 0`` when the run bypasses
    no obstacle (``entry_angles_source`` says which).
    """
    if sos == "off":
        return None
    from visnav.studies.path_following_sos import path_following_sos

    study = path_following_sos(scenario, entry_angles=angles, clearance_m=clearance_m, scan=sos == "scan")
    source = ("sampled: one simulation of the scenario" if entries else
              "assumed: the simulated run bypasses no obstacle, alpha0 = 0")
    return {**study.as_dict(), "entry_angles_source": source, "scan": sos == "scan"}


def analyse(scenario: Scenario, *, clearance_m: float = DEFAULT_CLEARANCE_M, sos: str = "scan") -> Analysis:
    """The analysis of ``scenario`` (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
    clearance_m : float
        Clearance [m] the admissible gains must guarantee.
    sos : str
        One of :data:`SOS_CHOICES`: the SOS study with its gain scan (about 20 s on the paper
        scenario), at the scenario's ``k`` only (about 10 s), or left out.

    A scenario from :func:`visnav.scenario.load_scenario` is already valid; the gains
    of one built in Python (``dataclasses.replace``) are checked by the same rules,
    :func:`visnav.scenario.validate_gains` (``k`` in
    :data:`visnav.parameters.K_PATH_RANGE`, ``v_coll <= v_max``).

    Raises
    ------
    ValueError
        A clearance that is negative or not smaller than ``d0``; ``sos`` not one of :data:`SOS_CHOICES`.
    visnav.scenario.ScenarioError
        (a ``ValueError``) gains or limits that break a scenario rule.
    """
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    if not (0.0 <= clearance_m < env.d_zero_m):
        raise ValueError(
            f"analyse: clearance_m = {clearance_m!r}; expected 0 <= clearance < d0 = {env.d_zero_m} m "
            "(the path-following envelope itself)"
        )
    if sos not in SOS_CHOICES:
        raise ValueError(f"analyse: sos = {sos!r}; expected one of {list(SOS_CHOICES)} (the SOS study with its "
                         "gain scan, at the scenario's k only, or none)")
    validate_gains(gains, limits, source=scenario.name)
    period = scenario.sampling_period_s
    path_following = _path_following_section(scenario, clearance_m, sos)
    loops, responses, goal, lambda_curves, margin_curves = _loop_section(scenario)

    data: dict[str, Any] = {
        "path_following": path_following,
        "goal": goal.as_dict(),
        "eigenvalues_vs_lambda": lambda_curves,
        "margins": loops,
        "margins_vs_gains": margin_curves,
        "frequency_responses": responses,
        "sampling_period_s": period,
    }
    return Analysis(scenario=scenario.name, data=data)


def _path_following_section(scenario: Scenario, clearance_m: float, sos: str) -> dict[str, Any]:
    """The ``"path_following"`` part of :func:`analyse`: linearisation, Lyapunov certificates, entry states and
    bounds, admissible gains, the switched family and the SOS study."""
    env, gains, limits = scenario.envelopes, scenario.gains, scenario.limits
    k, v = gains.k_path, gains.v_coll_mps
    radii = [o.radius_m for o in scenario.obstacles] or [1.0]
    pf = path_following_model(k=k, v=v, d_zero=env.d_zero_m, radius=radii[0])
    lin = pf.linearisation()
    closed_form = path_following_closed_form_eigenvalues(k, v)
    lyap = quadratic_lyapunov(lin.jacobian)
    k_curve = [[[e.real, e.imag] for e in path_following_model(k=kk, v=v, d_zero=env.d_zero_m,
                                                               radius=radii[0]).linearisation().eigenvalues]
               for kk in _K_CURVE]
    v_curve = [[[e.real, e.imag] for e in path_following_model(k=k, v=vv, d_zero=env.d_zero_m,
                                                               radius=radii[0]).linearisation().eigenvalues]
               for vv in _V_CURVE]
    k_range = K_PATH_RANGE
    certificate = certify_path_following(
        k_range=k_range, v_range=(0.0, limits.v_max_mps),
        delta_range=(-env.d_zero_m, env.d_zero_m),
        curvature_range=(1.0 / (max(radii) + 2.0 * env.d_zero_m), 1.0 / min(radii)),
    )
    entries = entry_angles_from_simulation(scenario)
    delta0 = env.d_minus_m - env.d_zero_m
    angles = sorted({round(a, 12) for _, _, a in entries}) or [0.0]
    admissible = admissible_gains(
        v=v, d_zero=env.d_zero_m, radius=min(radii), delta0=delta0, entry_angles=angles,
        clearance=clearance_m, omega_max=limits.omega_max_radps, k_range=k_range,
    )
    bounds = [entry_bounds(k=k, v=v, d_zero=env.d_zero_m, radius=min(radii), delta0=delta0, alpha0=a)
              for a in angles]
    family = [path_following_model(k=k, v=v * s, d_zero=env.d_zero_m, radius=radii[0]).linearisation().jacobian
              for s in (0.25, 0.5, 1.0)]
    switched = common_quadratic_lyapunov_lmi(family, ["v_coll/4", "v_coll/2", "v_coll"])
    sos_study = _sos_study(scenario, entries, angles, clearance_m, sos)
    return {
        "parameters": {"k": k, "v_coll_mps": v, "d_zero_m": env.d_zero_m, "radius_m": radii[0]},
        "equilibrium": {"delta_m": 0.0, "alpha_rad": 0.0, "residual_norm": float(np.linalg.norm(lin.residual))},
        "jacobian": lin.jacobian.tolist(),
        "eigenvalues": [[e.real, e.imag] for e in lin.eigenvalues],
        "eigenvalues_closed_form": [[e.real, e.imag] for e in sorted(closed_form, key=lambda z: z.real)],
        "modes": [m.as_dict() for m in lin.modes],
        "hurwitz": lin.hurwitz,
        "finding": lin.finding,
        "claim": "computed",
        "eigenvalues_vs_k": {"k": list(_K_CURVE), "eigenvalues": k_curve},
        "eigenvalues_vs_v_coll": {"v_coll_mps": list(_V_CURVE), "eigenvalues": v_curve},
        "quadratic_lyapunov": lyap.as_dict(),
        "lyapunov": {**certificate.as_dict(), "claim": "proven" if certificate.certified else "not proven"},
        "entry_states": [{"obstacle": n, "delta_m": d, "alpha_rad": a, "claim": "sampled"} for n, d, a in entries],
        "entry_bounds": [
            {"alpha0_rad": b.alpha0, "delta0_m": b.delta0, "V0": b.v0, "valid": b.valid,
             "delta_max_m": b.delta_max_m, "alpha_max_rad": b.alpha_max_rad,
             "omega_max_radps": b.omega_max_radps, "min_distance_m": b.min_distance_m}
            for b in bounds
        ],
        "admissible_k": None if admissible.interval is None else list(admissible.interval),
        "admissible": admissible.as_dict(),
        "switched": {**switched.as_dict(), "claim": "proven" if switched.proven else "not proven",
                     "family": "path-following linearisation at v_coll/4, v_coll/2, v_coll (the blend ramps v)"},
        "sos": sos_study,
    }


def _loop_section(scenario: Scenario) -> tuple[dict[str, Any], dict[str, Any], Any, dict[str, Any], dict[str, Any]]:
    """The loops of :func:`analyse`: margins and frequency responses per loop, the goal-loop findings, the
    eigenvalues against the task gains and the margins against the gains."""
    k = scenario.gains.k_path
    period = scenario.sampling_period_s
    radii = [o.radius_m for o in scenario.obstacles] or [1.0]
    loops: dict[str, Any] = {}
    responses: dict[str, Any] = {}
    w = np.geomspace(1e-3, math.pi / period, _RESPONSE_POINTS)

    def add_loop(name: str, lm: Any, **where: Any) -> None:
        loops[name] = _margin_pair(lm, period, **where)
        responses[name] = {
            "continuous": frequency_response_data(loop_transfer(lm, **where), w, name=name).as_dict(),
            "sampled": frequency_response_data(sampled_loop_transfer(lm, period, delay_samples=1, **where), w,
                                               name=name).as_dict(),
        }

    for obstacle in scenario.obstacles:
        add_loop(f"omega@{obstacle.name}", _omega_loop(scenario, k, obstacle.radius_m), at_input="omega")
    pan = pan_task_model(scenario)
    vs = visual_servoing_model(scenario)
    add_loop("pan", _pan_loop(pan), at_input="pan_rate")
    vs_lm = _vs_loop(vs)
    for channel in ("e_Vy", "e_Vz", "e_Wx"):
        add_loop(f"vs:{channel}", vs_lm, at_output=channel)
    goal = goal_loop_findings(scenario, vs=vs, pan=pan)
    first = scenario.obstacles[0].radius_m if scenario.obstacles else radii[0]
    lambda_curves = {
        "lambda": list(_LAMBDA_CURVE),
        "vs_task_eigenvalues": [[[e.real, e.imag] for e in visual_servoing_model(scenario, lambda_vs=g)
                                 .task_linearisation().eigenvalues] for g in _LAMBDA_CURVE],
        "pan_eigenvalues": [[[e.real, e.imag] for e in pan_task_model(scenario, lambda_gc=g)
                             .pan_linearisation().eigenvalues] for g in _LAMBDA_CURVE],
    }
    margin_curves = {
        "omega_vs_k": {"k": list(_K_MARGIN_CURVE), "loop": "omega@" + (scenario.obstacles[0].name
                                                                        if scenario.obstacles else "none"),
                       **_margin_curve(_K_MARGIN_CURVE, lambda g: _omega_loop(scenario, g, first), period,
                                       at_input="omega")},
        "pan_vs_lambda_gc": {"lambda_gc": list(_LAMBDA_CURVE),
                             **_margin_curve(_LAMBDA_CURVE, lambda g: _pan_loop(pan_task_model(scenario, lambda_gc=g)),
                                             period, at_input="pan_rate")},
        "vs_vs_lambda_vs": {"lambda_vs": list(_LAMBDA_CURVE), "channel": "e_Vy",
                            **_margin_curve(_LAMBDA_CURVE,
                                            lambda g: _vs_loop(visual_servoing_model(scenario, lambda_vs=g)),
                                            period, at_output="e_Vy")},
    }
    return loops, responses, goal, lambda_curves, margin_curves
