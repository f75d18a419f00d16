"""The yardstick of ``reconstruction_bounded``: the exact ZOH motion of the hidden points and the BDF's error on it.

Nothing here shares code with what the property judges (:mod:`visnav.estimator`,
:mod:`analysis.bdf`, the equation (13) and the camera screw of :mod:`visnav.model`):
every formula is written again from its definition, by another route.

* **The camera screw** ``(V_y, V_z, Ω_x)`` is derived from the cart's kinematics:
  the optical centre ``C = M + Dx (cos θ, sin θ) + R(θ + ϑ) (a, b)`` moves at
  ``Ċ = v (cos θ, sin θ) + Dx ω (−sin θ, cos θ) + (ω + ϖ) R'(φ) (a, b)``;
  projected on the camera's left and forward axes this is
  ``V_y = −v sin ϑ + Dx ω cos ϑ + a (ω + ϖ)``, ``V_z = v cos ϑ + Dx ω sin ϑ − b (ω + ϖ)``,
  and the camera turns about its downward ``x`` axis at ``Ω_x = −(ω + ϖ)``
  (:func:`camera_screw_zoh`).
* **The motion of a hidden point** is that of a fixed world point seen from
  the moving camera, ``ṗ = −V − Ω × p`` in camera coordinates ``p = (X z, Y z, z)``:
  ``ẋ = 0``, ``ẏ = −V_y + Ω_x z``, ``ż = −V_z − Ω_x y`` (linear in ``p``; (13) is this
  equation divided by the depth).  Under zero-order hold the joint rates are
  constant over a period and ``ϑ(t) = ϑ_k + ϖ (t − t_k)``; :func:`zoh_maps`
  integrates the affine map of every period with classical RK4 and
  :data:`FLOW_SUBSTEPS` substeps, the screw evaluated at the exact time of every
  stage, and :func:`zoh_flow` applies it (5e-15 from ``solve_ivp(DOP853,
  rtol=1e-13)`` on a period at the rate limits, depths 0.6–4 m; a test checks < 1e-12).
* **The specified BDF** (``docs/estimator.md``): the coefficients of
  ``Σ_{j=1}^{q} (1/j) ∇^j ψ_{k+1} = h F(ψ_{k+1})`` expanded with exact fractions
  (:func:`bdf_formula`), the histopolation weights from the cell means of a
  polynomial (:func:`histopolation_formula`), the period mean of the screw by
  Gauss–Legendre quadrature (:func:`period_mean_screw`), the Jacobian of the
  point's image rates by central differences of the rigid-motion rates.

:func:`zoh_reconstruction_reference` then gives, for a closed-loop run, the
exact features of every sample while the loop reconstructs (integrated from
the last measured image) and the error the specified BDF must make on that
motion to first order (``predicted``, see its docstring for the derivation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

from visnav.parameters import RobotGeometry

__all__ = [
    "FLOW_SUBSTEPS",
    "SCREW_MODEL_NAMES",
    "bdf_formula",
    "histopolation_formula",
    "camera_screw_zoh",
    "period_mean_screw",
    "image_rates",
    "zoh_maps",
    "zoh_flow",
    "ReconstructionReference",
    "zoh_reconstruction_reference",
]

FLOW_SUBSTEPS = 16
"""RK4 substeps per sampling period of :func:`zoh_flow` (local error ~ (ω h/16)^5 ≈ 1e-15 at 50 ms)."""

SCREW_MODEL_NAMES = ("end", "start", "mean", "histopolated")
"""The screw models ``docs/estimator.md`` specifies (written here again, not imported)."""

_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(8)


@lru_cache(maxsize=None)
def bdf_formula(order: int) -> tuple[tuple[float, ...], float]:
    """``(c_1 .. c_q, β)`` of ``ψ_{k+1} = Σ_j c_j ψ_{k+1−j} + β h F(ψ_{k+1})``.

    From ``Σ_{j=1}^{q} (1/j) ∇^j ψ_{k+1} = h F`` with ``∇^j = (1 − E^{-1})^j``:
    the coefficient of ``ψ_{k+1−i}`` is ``a_i = Σ_{j ≥ max(i, 1)} (1/j) C(j, i) (−1)^i``,
    so ``c_i = −a_i / a_0`` and ``β = 1 / a_0`` (exact fractions, then floats).
    BDF4: ``(48, −36, 16, −3)/25``, ``β = 12/25``.
    """
    if not 1 <= order <= 6:
        raise ValueError(f"order = {order!r}: expected an integer in 1..6 (the BDF orders the estimator accepts)")
    a = [sum((Fraction(1, j) * math.comb(j, i) * (-1) ** i for j in range(max(i, 1), order + 1)), Fraction(0))
         for i in range(order + 1)]
    return tuple(float(-a_i / a[0]) for a_i in a[1:]), float(1 / a[0])


@lru_cache(maxsize=None)
def histopolation_formula(cells: int) -> tuple[float, ...]:
    """Weights ``w_i`` with ``P(t_{k+1}) = Σ_{i<p} w_i P̄_{k−i}`` for a polynomial of degree ``p − 1``.

    ``P̄_{k−i}`` is the mean of ``P`` over the cell ``[t_{k−i}, t_{k+1−i}]``.  With
    ``s = (t − t_{k+1})/h`` the cell ``i`` is ``[−i−1, −i]`` and the mean of ``s^m`` over
    it is ``((−i)^{m+1} − (−i−1)^{m+1})/(m + 1)``; the weights are the first row of
    the inverse of that matrix (exact fractions).  ``(1)``, ``(3, −1)/2``, ``(11, −7, 2)/6``, ...
    """
    p = int(cells)
    if p < 1:
        raise ValueError(f"cells = {cells!r}: expected at least 1 period mean")
    m = [[Fraction((-i) ** (d + 1) - (-i - 1) ** (d + 1), d + 1) for d in range(p)] for i in range(p)]
    # solve M^T w = e_0 (the value at s = 0 is the coefficient of s^0): Gauss-Jordan on fractions
    a = [[m[i][d] for i in range(p)] + [Fraction(int(d == 0))] for d in range(p)]
    for col in range(p):
        pivot = next(r for r in range(col, p) if a[r][col] != 0)
        a[col], a[pivot] = a[pivot], a[col]
        a[col] = [x / a[col][col] for x in a[col]]
        for r in range(p):
            if r != col and a[r][col] != 0:
                a[r] = [x - a[r][col] * y for x, y in zip(a[r], a[col])]
    return tuple(float(row[p]) for row in a)


def camera_screw_zoh(pan: np.ndarray | float, v: float, omega: float, pan_rate: float,
                     geometry: RobotGeometry) -> np.ndarray:
    """``(V_y, V_z, Ω_x)`` of the camera at pan angle(s) ``pan`` [rad] under the joint rates ``(v, ω, ϖ)``.

    Returns an array of shape ``pan.shape + (3,)`` [m/s, m/s, rad/s] (derivation in the module docstring).
    """
    s, c = np.sin(pan), np.cos(pan)
    dx, a, b = geometry.pan_offset_m, geometry.camera_forward_m, geometry.camera_lateral_m
    turn = omega + pan_rate
    return np.stack(np.broadcast_arrays(-v * s + dx * omega * c + a * turn, v * c + dx * omega * s - b * turn,
                                        -turn + 0.0 * s), axis=-1)


def period_mean_screw(pan: np.ndarray | float, joint_rates: np.ndarray | Sequence[float], h: float,
                      geometry: RobotGeometry) -> np.ndarray:
    """Mean of the screw over ZOH period(s) (8-point Gauss–Legendre, exact to round-off here).

    ``pan`` of shape ``(K,)`` and ``joint_rates`` of shape ``(K, 3)`` give ``(K, 3)``; scalars give ``(3,)``.
    """
    rates = np.asarray(joint_rates, dtype=float)
    v, omega, pan_rate = (rates[..., i, None] for i in range(3))
    tau = 0.5 * h * (1.0 + _GAUSS_NODES)
    screws = camera_screw_zoh(np.asarray(pan, dtype=float)[..., None] + pan_rate * tau, v, omega, pan_rate, geometry)
    return 0.5 * np.einsum("j,...jc->...c", _GAUSS_WEIGHTS, screws)


def _point_rates(p: np.ndarray, screw: np.ndarray) -> np.ndarray:
    """``ṗ = −V − Ω × p`` for points ``p`` (rows ``x, y, z`` in the camera frame)."""
    v_y, v_z, w_x = screw
    out = np.empty_like(p)
    out[:, 0] = 0.0
    out[:, 1] = -v_y + w_x * p[:, 2]
    out[:, 2] = -v_z - w_x * p[:, 1]
    return out


def image_rates(psi: np.ndarray, screw: np.ndarray) -> np.ndarray:
    """``(Ẋ, Ẏ, ż)`` of image points ``psi`` (rows ``X, Y, z``) from the rigid motion ``ṗ`` of ``p = (Xz, Yz, z)``."""
    z = psi[:, 2]
    p = np.stack((psi[:, 0] * z, psi[:, 1] * z, z), axis=1)
    dp = _point_rates(p, screw)
    return np.stack(((dp[:, 0] - psi[:, 0] * dp[:, 2]) / z, (dp[:, 1] - psi[:, 1] * dp[:, 2]) / z, dp[:, 2]), axis=1)


def _image_rate_jacobian(psi: np.ndarray, screw: np.ndarray) -> np.ndarray:
    """``∂F/∂ψ`` per point, shape ``(n, 3, 3)``, by central differences (relative step 1e-6), in one evaluation."""
    n = psi.shape[0]
    step = 1e-6 * np.maximum(1.0, np.abs(psi))  # (n, 3)
    shifted = np.repeat(psi[None, :, :], 6, axis=0)  # +e_X, +e_Y, +e_z, -e_X, -e_Y, -e_z
    for col in range(3):
        shifted[col, :, col] += step[:, col]
        shifted[3 + col, :, col] -= step[:, col]
    rates = image_rates(shifted.reshape(6 * n, 3), screw).reshape(6, n, 3)
    return np.transpose((rates[:3] - rates[3:]) / (2.0 * step.T[:, :, None]), (1, 2, 0))


def zoh_maps(pan: np.ndarray, inputs: np.ndarray, h: float, geometry: RobotGeometry,
             substeps: int = FLOW_SUBSTEPS) -> np.ndarray:
    """The affine maps ``(y, z) -> M (y, z) + w`` of ZOH periods, rows ``(M11, M12, M21, M22, w1, w2)``.

    For fixed world points in camera coordinates ``p = (x, y, z)``,
    ``ṗ = −V(t) − Ω × p`` is affine in ``p``: ``x`` is constant and ``(y, z)``
    turns at the constant rate ``Ω_x = −(ω + ϖ)`` while shifted by
    ``−(V_y(t), V_z(t))``, with the screw of ``ϑ(t) = ϑ_k + ϖ t``.  Classical RK4
    with ``substeps`` equal substeps is run on the map itself (the same
    arithmetic as RK4 on every point), for all periods at once.

    Parameters
    ----------
    pan : ndarray, shape (K,)
        Pan angle at the start of every period [rad].
    inputs : ndarray, shape (K, 3)
        Joint rates ``(v, ω, ϖ)`` held over every period [m/s, rad/s, rad/s].
    h : float
        Period [s].

    Returns
    -------
    ndarray, shape (K, 6)
    """
    pan = np.asarray(pan, dtype=float).reshape(-1)
    v, omega, pan_rate = (np.asarray(inputs, dtype=float).reshape(-1, 3)[:, i] for i in range(3))
    dt = h / substeps
    times = (0.5 * dt) * np.arange(2 * substeps + 1)
    screws = camera_screw_zoh(pan[:, None] + pan_rate[:, None] * times[None, :], v[:, None], omega[:, None],
                              pan_rate[:, None], geometry)  # (K, 2 substeps + 1, 3)
    w_x = -(omega + pan_rate)

    def rate(m: list[np.ndarray], vy: np.ndarray, vz: np.ndarray) -> list[np.ndarray]:
        a, b, c, d, e, f = m  # y' = a y + b z + e, z' = c y + d z + f
        return [w_x * c, w_x * d, -w_x * a, -w_x * b, w_x * f - vy, -w_x * e - vz]

    one, zero = np.ones_like(pan), np.zeros_like(pan)
    m = [one, zero, zero, one, zero, zero]
    for j in range(substeps):
        s0, s1, s2 = screws[:, 2 * j], screws[:, 2 * j + 1], screws[:, 2 * j + 2]
        k1 = rate(m, s0[:, 0], s0[:, 1])
        k2 = rate([x + 0.5 * dt * k for x, k in zip(m, k1)], s1[:, 0], s1[:, 1])
        k3 = rate([x + 0.5 * dt * k for x, k in zip(m, k2)], s1[:, 0], s1[:, 1])
        k4 = rate([x + dt * k for x, k in zip(m, k3)], s2[:, 0], s2[:, 1])
        m = [x + dt / 6.0 * (q1 + 2.0 * q2 + 2.0 * q3 + q4) for x, q1, q2, q3, q4 in zip(m, k1, k2, k3, k4)]
    return np.stack(m, axis=1)


def _apply_map(psi: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Image points ``psi`` (rows ``X, Y, z``) moved by one period's map (row of :func:`zoh_maps`)."""
    a, b, c, d, e, f = m
    z = psi[:, 2]
    x, y = psi[:, 0] * z, psi[:, 1] * z
    y_new, z_new = a * y + b * z + e, c * y + d * z + f
    return np.stack((x / z_new, y_new / z_new, z_new), axis=1)


def zoh_flow(psi: np.ndarray, pan: float, joint_rates: Sequence[float], h: float, geometry: RobotGeometry,
             substeps: int = FLOW_SUBSTEPS) -> np.ndarray:
    """The image points ``psi`` (rows ``X, Y, z``) one ZOH period of length ``h`` [s] later (:func:`zoh_maps`)."""
    return _apply_map(psi, zoh_maps(np.array([pan]), np.array([joint_rates]), h, geometry, substeps)[0])


@dataclass(frozen=True, kw_only=True, slots=True)
class ReconstructionReference:
    """The yardstick of one closed-loop run (arrays indexed by sample, then point, then ``X, Y, z``).

    Attributes
    ----------
    reference : ndarray, shape (K, n, 3)
        The measured features where the loop does not reconstruct; while it
        does, the exact ZOH motion integrated from the last measured image
        (:func:`zoh_flow`) [-, -, m].
    predicted : ndarray, shape (K, n, 3)
        First-order error of the specified BDF on that motion (0 where nothing is reconstructed).
    advanced : ndarray of bool, shape (K,)
        Samples whose estimate the loop's estimator produced by a step.
    truth_gap : float
        Largest ``|reference − recorded truth|`` over the advanced samples (normalised units and m):
        the exact ZOH motion against the projection the simulation records; round-off if (13) and the
        simulated world agree.
    bdf_steps : int
        BDF steps predicted (start-up steps excluded).
    """

    reference: np.ndarray
    predicted: np.ndarray
    advanced: np.ndarray
    truth_gap: float
    bdf_steps: int


def _step_screw(model: str, k: int, order: int, pan: np.ndarray, inputs: np.ndarray, h: float,
                geometry: RobotGeometry, means: np.ndarray) -> np.ndarray:
    """The screw the specified model gives the BDF step over period ``k`` (``docs/estimator.md``).

    ``means``: the period means of every period (:func:`period_mean_screw`), shape ``(K, 3)``.
    """
    v, omega, pan_rate = (float(u) for u in inputs[k])
    if model == "end":
        return camera_screw_zoh(float(pan[k]) + pan_rate * h, v, omega, pan_rate, geometry)
    if model == "start":
        return camera_screw_zoh(float(pan[k]), v, omega, pan_rate, geometry)
    if model == "mean":
        return means[k]
    cells = min(order, min(order, k) + 1)  # the estimator keeps the means of the last `order` periods
    return sum((w * means[k - i] for i, w in enumerate(histopolation_formula(cells))), np.zeros(3))


def _intervals(reconstructing: np.ndarray) -> list[tuple[int, int]]:
    """``(s, e)``: reconstruction starts at sample ``s`` (measured) and steps at ``s + 1 .. e`` (``e`` included)."""
    out, k, n = [], 0, len(reconstructing)
    while k < n:
        if reconstructing[k]:
            e = k + 1
            while e < n and reconstructing[e]:
                e += 1
            out.append((k, min(e, n - 1)))
            k = e
        k += 1
    return out


def zoh_reconstruction_reference(
    true: np.ndarray, pan: np.ndarray, inputs: np.ndarray, reconstructing: np.ndarray, h: float,
    geometry: RobotGeometry, order: int, screw_model: str,
) -> ReconstructionReference:
    """The exact hidden motion of a sampled run and the specified BDF's first-order error on it.

    The loop observes every sample while it does not reconstruct, starts at a
    sample ``s`` (measured) and steps at ``s + 1, ...`` up to and including the
    sample where it stops; the first measurement after a stop restarts the
    history.  A reconstruction starting with ``m < q`` measured states in its
    history takes ``q − m`` exact start-up steps (error < 1e-10), then BDF steps.

    **Error of the specified method** (the derivation of the bound).  Let ``ψ``
    be the exact ZOH motion and ``T_{k+1}`` the screw of the specified model.
    Inserted in the BDF-q formula it leaves the local defect
    ``δ_{k+1} = ψ_{k+1} − Σ_j c_j ψ_{k+1−j} − β h F(ψ_{k+1}, T_{k+1})``; the
    estimate ``ψ̃`` satisfies the formula exactly, so ``e = ψ̃ − ψ`` obeys
    ``e_{k+1} = Σ_j c_j e_{k+1−j} + β h (F(ψ̃_{k+1}) − F(ψ_{k+1})) − δ_{k+1}`` and, to first
    order, ``(I − β h A_{k+1}) e_{k+1} = Σ_j c_j e_{k+1−j} − δ_{k+1}`` with ``A = ∂F/∂ψ``
    at ``(ψ_{k+1}, T_{k+1})``, from ``e = 0`` on the measured history.  The defect
    is ``O(h^{q+1})`` (BDF truncation, error constant ``C_{q+1}``) plus the screw
    model's: ``O(h³)`` per step for the histopolated screw (the ZOH input is not
    smooth inside a period), ``O(h²)`` for a held or mean screw (half a period of
    input shift); the zero-stable recurrence (``q ≤ 6``) sums them over the
    horizon, ``|e_k| ≤ Γ Σ_j |δ_j|``, so the global error is
    ``O(h^{min(q, 2)})`` times the hiding time with the histopolated screw and
    ``O(h)`` with the others.  ``predicted`` is that recurrence evaluated on the
    run's own motion (the exact ``Γ``, not an estimate of it); what it leaves out
    is second order, ``≲ L' |e|² H`` (relative ``|e|/z ≤ 1e-3`` for errors below a
    pixel), plus the Newton tolerance (1e-12) and the start-up (1e-10).

    Parameters
    ----------
    true : ndarray, shape (K, n, 3)
        Recorded true features ``(X, Y, z)`` at every sample [-, -, m].
    pan : ndarray, shape (K,)
        Pan angle at every sample [rad].
    inputs : ndarray, shape (K, 3)
        Joint rates held over the period starting at every sample [m/s, rad/s, rad/s].
    reconstructing : ndarray of bool, shape (K,)
        Whether the loop reconstructs after the sample's control.
    h : float
        Sampling period [s].
    geometry : RobotGeometry
    order : int
        BDF order ``q`` (1–6).
    screw_model : str
        One of :data:`SCREW_MODEL_NAMES`.

    Raises
    ------
    ValueError
        Unknown screw model or order.
    """
    if screw_model not in SCREW_MODEL_NAMES:
        raise ValueError(f"screw_model = {screw_model!r}: expected one of {', '.join(SCREW_MODEL_NAMES)}")
    c, beta = bdf_formula(order)
    ref = np.array(true, dtype=float, copy=True)
    err = np.zeros_like(ref)
    advanced = np.zeros(len(ref), dtype=bool)
    means = period_mean_screw(pan, inputs, h, geometry)
    maps = zoh_maps(pan, inputs, h, geometry)
    gap, steps, fresh = 0.0, 0, 0  # fresh: first sample of the measured history
    for s, e in _intervals(np.asarray(reconstructing, dtype=bool)):
        history = min(order, s - fresh + 1)
        for k in range(s, e):  # the step over period k gives sample k + 1
            ref[k + 1] = _apply_map(ref[k], maps[k])
            advanced[k + 1] = True
            gap = max(gap, float(np.max(np.abs(ref[k + 1] - true[k + 1]))))
            if history < order:  # exact start-up step
                history += 1
                continue
            screw = _step_screw(screw_model, k, order, pan, inputs, h, geometry, means)
            hist = sum(cj * ref[k - j] for j, cj in enumerate(c))
            defect = ref[k + 1] - hist - beta * h * image_rates(ref[k + 1], screw)
            rhs = sum(cj * err[k - j] for j, cj in enumerate(c)) - defect
            lhs = np.eye(3) - beta * h * _image_rate_jacobian(ref[k + 1], screw)
            err[k + 1] = np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
            steps += 1
        fresh = e + 1
    return ReconstructionReference(reference=ref, predicted=err, advanced=advanced, truth_gap=gap, bdf_steps=steps)
