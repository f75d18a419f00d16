"""Stability of the path-following law (10)–(12): linearisation, Lyapunov bounds, admissible gains.

One symbolic source: the closed loop is *composed* in CasADi from the
path-frame kinematics :func:`visnav.model.path_error_rates` and the control
law :func:`visnav.model.path_following_omega` — the same functions the
simulation evaluates with floats — around an obstacle of radius ``R`` whose
envelope ξ0 has radius ``R + d0``, so ``ρ = R + d0 + δ``.  In closed loop
the curvature terms cancel and

    δ̇ = v sin α,    α̇ = −v (k δ + α + 2k sin α).

With ``V = k δ²/2 + (1 − cos α)`` (the candidate of the cited proof's
lineage), ``V̇ = −v (α sin α + 2k sin² α) ≤ 0`` on ``|α| ≤ π`` for
``k, v ≥ 0``, and ``V̇ = 0`` exactly on the line ``α = 0``.  LaSalle: on
that line ``α̇ = −v k δ``, so the largest invariant set in
``{V̇ = 0} ∩ {V < 2}`` is the origin; every sublevel set ``{V ≤ c}`` with
``c < 2`` (where ``|α| < π``) is positively invariant and attracted to it.

Along a bypass entered at ``(δ0, α0)`` with ``V0 = V(δ0, α0) < 2``:

* ``|δ(t)| ≤ δ_max = sqrt(2 V0 / k) = sqrt(δ0² + 2 (1 − cos α0)/k)``,
* ``|α(t)| ≤ α_max = arccos(1 − V0)``,
* ``|ω(t)| ≤ v (k δ_max + α_max + 2k sin(min(α_max, π/2)) + 1/(R + d0 − δ_max))``

(triangle inequality on (11)), so the robot stays at least ``d0 − δ_max``
from the obstacle and within the actuator limit when these bounds allow;
:func:`admissible_gains` turns that into the range of ``k``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from analysis.linearise import Linearisation, linearise

from visnav import model
from visnav.parameters import K_PATH_RANGE

__all__ = [
    "PathFollowingModel",
    "path_following_model",
    "path_following_closed_form_eigenvalues",
    "entry_bounds",
    "EntryBounds",
    "AdmissibleGains",
    "admissible_gains",
    "LyapunovCertificate",
    "lyapunov_rate_symbolic",
    "certify_path_following",
]


@dataclass(frozen=True, kw_only=True, slots=True)
class PathFollowingModel:
    """CasADi expressions of the path-following closed loop.

    Attributes
    ----------
    k, v, d_zero, radius, side : float
        Gain [1/m], speed [m/s], envelope offset d0 [m], obstacle radius R [m], bypass side ±1.
    delta, alpha : casadi.SX
        The error coordinates δ [m] and α [rad].
    rates : casadi.SX, shape (2, 1)
        ``(δ̇, α̇)`` composed from the kinematics and the control law.
    omega : casadi.SX
        The commanded ω [rad/s].
    lyapunov : casadi.SX
        ``V = k δ²/2 + 1 − cos α``.
    kappa : casadi.SX
        Free symbol standing for the curvature ``1/ρ`` in :attr:`lyapunov_rate`.
    lyapunov_rate : casadi.SX
        ``V̇ = ∇V · (δ̇, α̇)`` by automatic differentiation, with the curvature
        left as the free symbol ``κ`` (it cancels; the certificate proves it).
    function : casadi.Function
        ``F([δ, α]) -> (δ̇, α̇)``.
    """

    k: float
    v: float
    d_zero: float
    radius: float
    side: float
    delta: Any
    alpha: Any
    kappa: Any
    rates: Any
    omega: Any
    lyapunov: Any
    lyapunov_rate: Any
    function: Any

    def linearisation(self) -> Linearisation:
        """Linearisation at the equilibrium ``(δ, α) = (0, 0)`` (on the envelope ξ0)."""
        return linearise(self.function, (0.0, 0.0), state_names=("delta_m", "alpha_rad"),
                         name="path following (10)-(11)")

    def plant_and_gain(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Loop broken at ω: ``A_p, B_p`` of the kinematics at ω = ω* and the law's gain ``K``.

        ``A_p = ∂(δ̇, α̇)/∂(δ, α)`` with ω held at its equilibrium value, ``B_p =
        ∂(δ̇, α̇)/∂ω``, ``K = ∂ω/∂(δ, α)``; the closed loop is ``A_p + B_p K``.
        """
        x = ca.vertcat(self.delta, self.alpha)
        w = ca.SX.sym("omega")
        curvature = 1 / (self.radius + self.d_zero + self.delta)
        open_rates = ca.vertcat(*model.path_error_rates(self.v, w, self.alpha, curvature, self.side, ops=ca))
        omega_star = float(ca.DM(ca.substitute(self.omega, x, ca.DM.zeros(2))))
        at = {"x": ca.DM.zeros(2), "w": omega_star}
        f = ca.Function("loop_at_omega", [x, w], [ca.jacobian(open_rates, x), ca.jacobian(open_rates, w),
                                                  ca.jacobian(self.omega, x)])
        a_p, b_p, k = (np.array(m.full(), dtype=float) for m in f(at["x"], at["w"]))
        return a_p, b_p.reshape(2, 1), k.reshape(1, 2)


def path_following_model(*, k: float, v: float, d_zero: float, radius: float, side: int = 1) -> PathFollowingModel:
    """Compose the path-following closed loop symbolically (see the module docstring).

    Raises
    ------
    ValueError
        ``k < 0``, ``v <= 0``, ``d_zero <= 0``, ``radius <= 0`` or ``side`` not ±1, naming the value.
    """
    for name, value, ok, expected in (
        ("k", k, k >= 0, ">= 0 [1/m]"), ("v", v, v > 0, "> 0 [m/s]"),
        ("d_zero", d_zero, d_zero > 0, "> 0 [m]"), ("radius", radius, radius > 0, "> 0 [m]"),
    ):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and ok):
            raise ValueError(f"path_following_model: {name} = {value!r}; expected a finite number {expected}")
    if side not in (-1, 1):
        raise ValueError(f"path_following_model: side = {side!r}; expected +1 (obstacle on the left) or -1")
    delta, alpha, kappa = ca.SX.sym("delta"), ca.SX.sym("alpha"), ca.SX.sym("kappa")
    curvature = 1 / (radius + d_zero + delta)
    omega = model.path_following_omega(delta, alpha, curvature, side, v, k, ops=ca)
    rates = ca.vertcat(*model.path_error_rates(v, omega, alpha, curvature, side, ops=ca))
    x = ca.vertcat(delta, alpha)
    lyapunov = k * delta**2 / 2 + (1 - ca.cos(alpha))
    # V̇ for the certificate: the curvature kept as a free symbol κ, so that the normal form is a
    # polynomial in (δ, α, sin α, cos α, κ); a bound valid for every κ holds at κ = 1/ρ(δ).
    omega_k = model.path_following_omega(delta, alpha, kappa, side, v, k, ops=ca)
    rates_k = ca.vertcat(*model.path_error_rates(v, omega_k, alpha, kappa, side, ops=ca))
    lyapunov_rate = ca.jtimes(lyapunov, x, rates_k)
    return PathFollowingModel(
        k=float(k), v=float(v), d_zero=float(d_zero), radius=float(radius), side=float(side),
        delta=delta, alpha=alpha, kappa=kappa, rates=rates, omega=omega, lyapunov=lyapunov, lyapunov_rate=lyapunov_rate,
        function=ca.Function("path_following_closed_loop", [x], [rates]),
    )


def path_following_closed_form_eigenvalues(k: float, v: float) -> tuple[complex, complex]:
    """Eigenvalues of ``[[0, v], [−v k, −v (1 + 2k)]]``: ``v/2 (−(1 + 2k) ± sqrt(1 + 4k²))``.

    Independent check of the AD linearisation (the discriminant ``(1 + 2k)² − 4k = 1 + 4k²``
    is positive: both real and negative for ``k > 0``).
    """
    root = math.sqrt(1.0 + 4.0 * k * k)
    return (complex(0.5 * v * (-(1.0 + 2.0 * k) - root), 0.0), complex(0.5 * v * (-(1.0 + 2.0 * k) + root), 0.0))


@dataclass(frozen=True, kw_only=True, slots=True)
class EntryBounds:
    """What ``V`` guarantees along a bypass entered at ``(δ0, α0)`` with gain ``k``.

    Attributes
    ----------
    k, delta0, alpha0 : float
    v0 : float
        ``V(δ0, α0)``; the bounds hold when ``v0 < 2``.
    valid : bool
        ``v0 < 2``.
    delta_max_m, alpha_max_rad, omega_max_radps : float
        Bounds on ``|δ|``, ``|α|``, ``|ω|`` along the whole bypass.
    min_distance_m : float
        ``d0 − δ_max``: closest approach to the obstacle surface.
    """

    k: float
    delta0: float
    alpha0: float
    v0: float
    valid: bool
    delta_max_m: float
    alpha_max_rad: float
    omega_max_radps: float
    min_distance_m: float


def entry_bounds(*, k: float, v: float, d_zero: float, radius: float, delta0: float, alpha0: float) -> EntryBounds:
    """Bounds on ``δ``, ``α``, ``ω`` along a bypass from the Lyapunov sublevel set (module docstring)."""
    v0 = k * delta0 * delta0 / 2.0 + 1.0 - math.cos(alpha0)
    valid = v0 < 2.0 and k > 0
    if not valid:
        return EntryBounds(k=k, delta0=delta0, alpha0=alpha0, v0=v0, valid=False, delta_max_m=math.inf,
                           alpha_max_rad=math.pi, omega_max_radps=math.inf, min_distance_m=-math.inf)
    delta_max = math.sqrt(2.0 * v0 / k)
    alpha_max = math.acos(1.0 - v0)
    rho_min = radius + d_zero - delta_max
    omega = (v * (k * delta_max + alpha_max + 2.0 * k * math.sin(min(alpha_max, math.pi / 2)) + 1.0 / rho_min)
             if rho_min > 0 else math.inf)
    return EntryBounds(k=k, delta0=delta0, alpha0=alpha0, v0=v0, valid=True, delta_max_m=delta_max,
                       alpha_max_rad=alpha_max, omega_max_radps=omega, min_distance_m=d_zero - delta_max)


@dataclass(frozen=True, kw_only=True, slots=True)
class AdmissibleGains:
    """Gains ``k`` that keep every bypass clear of the obstacle and within the ω limit.

    Attributes
    ----------
    interval : tuple of (float, float) or None
        ``[k_min, k_max]`` admissible for *every* entry angle (``None``: empty).
    per_angle : tuple of (float, (float, float) or None)
        ``(α0, interval)`` per entry angle.
    clearance_m, omega_max_radps, delta0_m : float
        The requirements and the entry offset used.
    k_searched : (float, float)
        The range of ``k`` scanned.
    limits : tuple of dict
        Per entry angle, which requirement binds: the grid ``k`` range that
        guarantees the clearance alone (``clearance_k``, or ``None``), and the
        smallest guaranteed ``|ω|`` bound over the grid (``best_omega_bound_radps``
        at ``best_omega_k``).  An empty admissible set is explained by them.
    finding : str
    """

    interval: tuple[float, float] | None
    per_angle: tuple[tuple[float, tuple[float, float] | None], ...]
    clearance_m: float
    omega_max_radps: float
    delta0_m: float
    k_searched: tuple[float, float]
    limits: tuple[dict[str, Any], ...]
    finding: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {
            "interval": None if self.interval is None else list(self.interval),
            "per_angle": [{"alpha0_rad": a, "interval": None if i is None else list(i)} for a, i in self.per_angle],
            "clearance_m": self.clearance_m,
            "omega_max_radps": self.omega_max_radps,
            "delta0_m": self.delta0_m,
            "k_searched": list(self.k_searched),
            "limits": [dict(d) for d in self.limits],
            "finding": self.finding,
        }


def _admissible(k: float, *, v: float, d_zero: float, radius: float, delta0: float, alpha0: float,
                clearance: float, omega_max: float) -> bool:
    b = entry_bounds(k=k, v=v, d_zero=d_zero, radius=radius, delta0=delta0, alpha0=alpha0)
    return b.valid and b.min_distance_m >= clearance and b.omega_max_radps <= omega_max


def admissible_gains(
    *,
    v: float,
    d_zero: float,
    radius: float,
    delta0: float,
    entry_angles: Sequence[float],
    clearance: float,
    omega_max: float,
    k_range: tuple[float, float] = K_PATH_RANGE,
    grid: int = 2000,
) -> AdmissibleGains:
    """The set of ``k`` whose Lyapunov bounds guarantee clearance and the ω limit, per entry angle.

    The predicate of :func:`entry_bounds` is scanned on a log grid of ``k`` and
    every boundary refined by bisection to 1e-9 relative; the reported
    interval is the intersection over the entry angles (the admissible set of
    one angle is an interval on the grid in practice; several pieces would be
    reported as their hull with a note in ``finding``).
    """
    if not entry_angles:
        raise ValueError("admissible_gains: entry_angles is empty; give at least one entry angle [rad]")
    ks = np.geomspace(k_range[0], k_range[1], grid)
    per_angle = []
    limits = []
    pieces_note = ""
    for alpha0 in entry_angles:
        bounds = [entry_bounds(k=float(k), v=v, d_zero=d_zero, radius=radius, delta0=delta0, alpha0=alpha0)
                  for k in ks]
        clear = [float(k) for k, b in zip(ks, bounds) if b.valid and b.min_distance_m >= clearance]
        omegas = [(b.omega_max_radps, float(k)) for k, b in zip(ks, bounds) if b.valid]
        best = min(omegas) if omegas else (math.inf, math.nan)
        limits.append({"alpha0_rad": float(alpha0),
                       "clearance_k": [min(clear), max(clear)] if clear else None,
                       "best_omega_bound_radps": best[0], "best_omega_k": best[1]})
        def ok(k: float, a: float = alpha0) -> bool:
            return _admissible(k, v=v, d_zero=d_zero, radius=radius, delta0=delta0, alpha0=a,
                               clearance=clearance, omega_max=omega_max)

        flags = [ok(float(k)) for k in ks]
        if not any(flags):
            per_angle.append((float(alpha0), None))
            continue
        first = flags.index(True)
        last = len(flags) - 1 - flags[::-1].index(True)
        if not all(flags[first:last + 1]):
            pieces_note = " (the admissible set of some angle is not an interval: its hull is reported)"

        def refine(inside: float, outside: float) -> float:
            for _ in range(200):
                mid = math.sqrt(inside * outside)
                if ok(mid):
                    inside = mid
                else:
                    outside = mid
                if abs(outside - inside) <= 1e-9 * inside:
                    break
            return inside

        lo = float(ks[first]) if first == 0 else refine(float(ks[first]), float(ks[first - 1]))
        hi = float(ks[last]) if last == len(ks) - 1 else refine(float(ks[last]), float(ks[last + 1]))
        per_angle.append((float(alpha0), (lo, hi)))
    intervals = [i for _, i in per_angle]
    if any(i is None for i in intervals):
        interval = None
    else:
        lo = max(i[0] for i in intervals)  # type: ignore[index]
        hi = min(i[1] for i in intervals)  # type: ignore[index]
        interval = (lo, hi) if lo <= hi else None
    if interval is None:
        why = "; ".join(
            (f"alpha0 = {d['alpha0_rad']:.4g} rad: clearance alone needs k in [{d['clearance_k'][0]:.4g}, "
             f"{d['clearance_k'][1]:.4g}]" if d["clearance_k"] else f"alpha0 = {d['alpha0_rad']:.4g} rad: no k "
             "guarantees the clearance")
            + f", the smallest guaranteed |omega| bound is {d['best_omega_bound_radps']:.4g} rad/s "
            f"(at k = {d['best_omega_k']:.4g})"
            for d in limits
        )
        finding = (f"no k in [{k_range[0]:g}, {k_range[1]:g}] guarantees clearance >= {clearance:g} m and "
                   f"|omega| <= {omega_max:g} rad/s for every entry angle{pieces_note} ({why})")
    else:
        finding = (f"k in [{interval[0]:.6g}, {interval[1]:.6g}] 1/m guarantees clearance >= {clearance:g} m and "
                   f"|omega| <= {omega_max:g} rad/s for every entry angle{pieces_note}")
    return AdmissibleGains(
        interval=interval, per_angle=tuple(per_angle), clearance_m=float(clearance), omega_max_radps=float(omega_max),
        delta0_m=float(delta0), k_searched=(float(k_range[0]), float(k_range[1])), limits=tuple(limits),
        finding=finding,
    )


@dataclass(frozen=True, kw_only=True, slots=True)
class LyapunovCertificate:
    """The machine-checked claim ``V̇ ≤ 0`` for the path-following law.

    Attributes
    ----------
    certified : bool
    region : Mapping[str, tuple[float, float]]
        The box: ``delta``, ``alpha``, ``kappa`` (curvature 1/ρ), ``k``, ``v``.
    normal_form : str
        ``V̇`` as an exact polynomial in the atoms (the δ and κ terms cancel).
    depends_on : tuple of str
        Variables the normal form still depends on.
    certificate : analysis.certificate.Certificate
        The boxes and their bounds (re-checkable with :func:`analysis.certificate.recheck`).
    zero_set : str
        Where ``V̇ = 0``.
    lasalle : str
        The invariance argument.
    region_of_attraction : str
        The certified sublevel set.
    """

    certified: bool
    region: Any
    normal_form: str
    depends_on: tuple[str, ...]
    certificate: Any
    zero_set: str
    lasalle: str
    region_of_attraction: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (the certificate's boxes in ``float.hex`` for exact re-checking)."""
        return {
            "candidate": "V = k delta^2/2 + (1 - cos alpha)",
            "certified": self.certified,
            "region": {name: list(bounds) for name, bounds in self.region.items()},
            "normal_form": self.normal_form,
            "depends_on": list(self.depends_on),
            "method": self.certificate.method,
            "boxes": len(self.certificate.boxes),
            "zero_set": self.zero_set,
            "lasalle": self.lasalle,
            "region_of_attraction": self.region_of_attraction,
            "certificate": self.certificate.as_dict(),
        }


def lyapunov_rate_symbolic(*, side: int = 1) -> tuple[Any, dict[str, Any]]:
    """``V̇`` composed from the model with ``δ, α, κ, k, v`` all symbolic.

    Returns
    -------
    expression : casadi.SX
    symbols : dict of name -> casadi.SX
    """
    names = ("delta", "alpha", "kappa", "k", "v")
    sym = {n: ca.SX.sym(n) for n in names}
    delta, alpha, kappa, k, v = (sym[n] for n in names)
    omega = model.path_following_omega(delta, alpha, kappa, side, v, k, ops=ca)
    rates = ca.vertcat(*model.path_error_rates(v, omega, alpha, kappa, side, ops=ca))
    lyapunov = k * delta**2 / 2 + (1 - ca.cos(alpha))
    return ca.jtimes(lyapunov, ca.vertcat(delta, alpha), rates), sym


def certify_path_following(
    *,
    k_range: tuple[float, float],
    v_range: tuple[float, float],
    delta_range: tuple[float, float],
    curvature_range: tuple[float, float],
    alpha_range: tuple[float, float] = (-math.pi, math.pi),
) -> LyapunovCertificate:
    """Certify ``V̇ ≤ 0`` on a box by interval branch and bound on the exact normal form.

    ``V̇`` is built by AD from the same model functions the simulation uses,
    with the gain, the speed and the curvature as symbols; its exact
    polynomial normal form (``analysis.polynomial``) is bounded by outward-rounded
    interval arithmetic on boxes split at ``α = 0``, where ``V̇ = 0``
    (``analysis.certificate``).
    """
    from analysis.certificate import certify_nonpositive
    from analysis.polynomial import normal_form

    for name, (lo, hi) in (("k_range", k_range), ("v_range", v_range)):
        if not (0.0 <= lo <= hi and math.isfinite(hi)):
            raise ValueError(f"certify_path_following: {name} = {(lo, hi)}; expected 0 <= lower <= upper < inf")
    expression, sym = lyapunov_rate_symbolic()
    order = ("delta", "alpha", "kappa", "k", "v")
    poly = normal_form(expression, [sym[n] for n in order])
    region = {"delta": tuple(delta_range), "alpha": tuple(alpha_range), "kappa": tuple(curvature_range),
              "k": tuple(k_range), "v": tuple(v_range)}
    split = {"alpha": (0.0,)} if alpha_range[0] < 0.0 < alpha_range[1] else None
    certificate = certify_nonpositive(poly, region, split_at=split)
    depends = tuple(n for n in order if poly.depends_on(("var", n)) or poly.depends_on(("sin", n))
                    or poly.depends_on(("cos", n)))
    return LyapunovCertificate(
        certified=certificate.certified,
        region=region,
        normal_form=str(poly),
        depends_on=depends,
        certificate=certificate,
        zero_set="V̇ = 0 exactly where sin α = 0: the line α = 0 (and α = ±π, outside every sublevel set V < 2)",
        lasalle=("on α = 0, α̇ = −v k δ, so a solution staying in {V̇ = 0} has δ = 0: the largest invariant set "
                 "in {V̇ = 0} ∩ {V < 2} is the origin, which attracts every solution starting in {V < 2} "
                 "(k > 0, v > 0)"),
        region_of_attraction=("{(δ, α): k δ²/2 + 1 − cos α < 2} ∩ {|α| < π}, within the certified δ range: "
                              "every sublevel set V ≤ c < 2 is positively invariant"),
    )
