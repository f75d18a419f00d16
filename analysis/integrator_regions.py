"""Linear stability of the integrators of :mod:`analysis.integrators`: regions, loci, A(α) angles.

Applied to the test equation ``y' = λ y`` with ``z = h λ``, every scheme of
:data:`analysis.integrators.FIXED_STEP_SCHEMES` becomes a linear recurrence
whose characteristic polynomial is

    π(ζ, z) = Σ_k z^k p_k(ζ)

(:class:`StabilityPolynomial`).  The scheme is stable at ``z`` when every
root ``ζ`` of ``π(·, z)`` lies in the closed unit disc (those on the circle
simple); the stability region is the set of such ``z``.  Its boundary lies on
the *boundary locus* ``{z : π(e^{iθ}, z) = 0}`` (:func:`boundary_locus`),
which for a linear multistep method is the closed curve
``z(θ) = ρ(e^{iθ}) / σ(e^{iθ})``.

* Euler: ``ζ = 1 + z``; RK4: ``ζ = R(z) = 1 + z + z²/2 + z³/6 + z⁴/24``.
* ABM4 in PECE mode (AB4 predictor, 3-step Adams–Moulton corrector, ``f``
  evaluated after the correction), ``y_{n+1} = y_n + (z/24)(9 y^P + 19 y_n −
  5 y_{n−1} + y_{n−2})`` with ``y^P = y_n + (z/24)(55 y_n − 59 y_{n−1} + 37
  y_{n−2} − 9 y_{n−3})``: quadratic in ``z``.
* BDF of order ``m``: ``π = ρ(ζ) − z β ζ^m`` with the exact coefficients of
  :func:`analysis.bdf.bdf_coefficients_exact` (orders above 6 are accepted
  here, to show their instability).

A(α) angle (:func:`a_alpha`)
----------------------------
The BDF region is the exterior of its locus.  ``A(α)``-stability means the
sector ``|arg(−z)| < α`` lies in it, so ``α`` is the smallest angle
``|arg(−z(θ))|`` reached by a locus point with ``Re z < 0`` (90° if the locus
stays in the closed right half plane).  The minimum is bracketed on a grid of
:data:`A_ALPHA_GRID` values of θ and refined by Brent's bounded method
(:func:`scipy.optimize.minimize_scalar`, ``xatol`` = :data:`A_ALPHA_XATOL`).
Precision: at an interior minimum ``θ*`` the angle is stationary, so an error
``δ`` in ``θ*`` changes it by ``O(δ²)``: ``δ = 1e-12`` leaves ``1e-24`` rad, and
the result is limited by the rounding of ``arg`` (about ``1e-15`` rad,
``6e-14`` °).  An independent second route solves the tangency condition
``Im(z'(θ)/z(θ)) = 0`` (the ray from the origin touches the locus) with Brent's
root finder; both are reported and agree to about ``1e-12`` °, four orders of
magnitude inside what comparing with the published four-figure values needs.

Examples
--------
>>> round(a_alpha(4).alpha_deg, 4)  # published to three decimals, truncated: 73.351
73.3517
>>> round(real_stability_interval(stability_polynomial("rk4")), 4)
-2.7853
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from analysis.bdf import bdf_characteristic_roots, bdf_coefficients_exact
from analysis.integrators import UnknownSchemeError

__all__ = [
    "PUBLISHED_A_ALPHA_DEG",
    "A_ALPHA_GRID",
    "A_ALPHA_XATOL",
    "ROOT_TOLERANCE",
    "StabilityPolynomial",
    "AAlpha",
    "ZeroStability",
    "stability_polynomial",
    "max_root_modulus",
    "is_stable",
    "boundary_locus",
    "a_alpha",
    "zero_stability",
    "real_stability_interval",
    "stability_grid",
    "first_unstable_step",
]

PUBLISHED_A_ALPHA_DEG = {1: 90.0, 2: 90.0, 3: 86.032, 4: 73.351, 5: 51.839, 6: 17.839}
"""A(α) angles of BDF1–6 [deg] (Hairer & Wanner, *Solving ODEs II*, §V.2, Table 2.3, three decimals)."""
A_ALPHA_GRID = 20001
"""Points of the θ grid on ``(0, π]`` that brackets the minimum of ``|arg(−z(θ))|``."""
A_ALPHA_XATOL = 1e-12
"""Absolute tolerance on θ of the bounded Brent refinement [rad]."""
ROOT_TOLERANCE = 1e-9
"""A root counts as inside the closed unit disc when its modulus is at most ``1 + ROOT_TOLERANCE``."""


@dataclass(frozen=True, kw_only=True, slots=True)
class StabilityPolynomial:
    """``π(ζ, z) = Σ_k z^k p_k(ζ)`` of a scheme applied to ``y' = λ y``, ``z = h λ``.

    Attributes
    ----------
    scheme : str
    coefficients : tuple of tuple of float
        ``coefficients[k]`` holds ``p_k`` with the highest power of ζ first;
        every ``p_k`` has ``degree + 1`` entries.
    degree : int
        Degree in ζ (the number of steps of a multistep method, 1 for a
        one-step method).
    """

    scheme: str
    coefficients: tuple[tuple[float, ...], ...]
    degree: int

    def in_zeta(self, z: complex | np.ndarray) -> np.ndarray:
        """Coefficients in ζ (highest power first) at ``z``; shape ``(..., degree + 1)``."""
        z_arr = np.asarray(z, dtype=complex)
        powers = np.stack([z_arr ** k for k in range(len(self.coefficients))], axis=-1)
        return powers @ np.array(self.coefficients, dtype=complex)


@dataclass(frozen=True, kw_only=True, slots=True)
class AAlpha:
    """The measured A(α) angle of one BDF order.

    Attributes
    ----------
    order : int
    alpha_deg : float
        α by minimising ``|arg(−z(θ))|`` over the locus in ``Re z < 0`` [deg].
    alpha_tangency_deg : float
        α from the tangency condition (second route) [deg].
    theta_star : float or None
        Locus parameter of the tangency point [rad] (``None`` when α = 90°).
    z_star : complex or None
        The tangency point ``z(θ*)`` (upper half plane).
    published_deg : float
        :data:`PUBLISHED_A_ALPHA_DEG`.
    error_deg : float
        ``alpha_deg − published_deg``.
    """

    order: int
    alpha_deg: float
    alpha_tangency_deg: float
    theta_star: float | None
    z_star: complex | None
    published_deg: float
    error_deg: float


@dataclass(frozen=True, kw_only=True, slots=True)
class ZeroStability:
    """Roots of ``ρ(ζ)`` of a BDF (the scheme at ``z = 0``).

    Attributes
    ----------
    order : int
    roots : tuple of complex
        Sorted by decreasing modulus (``ζ = 1`` is always one of them).
    max_parasitic_modulus : float
        Largest modulus of the roots other than the principal ``ζ = 1``.
    zero_stable : bool
        All roots in the closed unit disc, the principal one simple.
    """

    order: int
    roots: tuple[complex, ...]
    max_parasitic_modulus: float
    zero_stable: bool


def _fraction_poly(values: Sequence[Fraction]) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def stability_polynomial(scheme: str) -> StabilityPolynomial:
    """:class:`StabilityPolynomial` of ``"euler"``, ``"rk4"``, ``"abm4"`` or ``"bdf<m>"`` (any ``m >= 1``).

    Raises
    ------
    analysis.integrators.UnknownSchemeError
        Any other name (the adaptive references have no fixed polynomial).
    """
    if scheme == "euler":
        coeffs: tuple[tuple[float, ...], ...] = ((1.0, -1.0), (0.0, -1.0))
    elif scheme == "rk4":
        coeffs = ((1.0, -1.0), (0.0, -1.0), (0.0, -0.5), (0.0, -1.0 / 6.0), (0.0, -1.0 / 24.0))
    elif scheme == "abm4":
        p0 = (1.0, -1.0, 0.0, 0.0, 0.0)
        p1 = tuple(-c / 24.0 for c in (0.0, 9.0 + 19.0, -5.0, 1.0, 0.0))
        p2 = tuple(-9.0 * c / 576.0 for c in (0.0, 55.0, -59.0, 37.0, -9.0))
        coeffs = (p0, p1, p2)
    elif isinstance(scheme, str) and scheme.startswith("bdf") and scheme[3:].isdigit() and int(scheme[3:]) >= 1:
        order = int(scheme[3:])
        history, beta = bdf_coefficients_exact(order)
        rho = (Fraction(1),) + tuple(-c for c in history)
        sigma = (beta,) + (Fraction(0),) * order
        coeffs = (_fraction_poly(rho), _fraction_poly(tuple(-s for s in sigma)))
    else:
        raise UnknownSchemeError(
            f"scheme = {scheme!r}: a stability polynomial exists for 'euler', 'rk4', 'abm4' and 'bdf<m>' "
            f"(m >= 1); the adaptive references have none"
        )
    return StabilityPolynomial(scheme=scheme, coefficients=coeffs, degree=len(coeffs[0]) - 1)


def max_root_modulus(poly: StabilityPolynomial, z: complex | np.ndarray) -> np.ndarray:
    """Largest ``|ζ|`` over the roots of ``π(·, z)``, for every ``z`` (vectorised).

    Roots are the eigenvalues of batched companion matrices.  Where the leading
    coefficient vanishes (e.g. ``z = 1/β`` for a BDF) a root is at infinity and
    the result is ``inf``.

    Returns
    -------
    numpy.ndarray of float, shape of ``z``
    """
    z_arr = np.asarray(z, dtype=complex)
    shape = z_arr.shape
    c = poly.in_zeta(z_arr.reshape(-1))
    lead = c[:, 0]
    out = np.full(c.shape[0], np.inf)
    ok = np.abs(lead) > 1e-14 * np.max(np.abs(c), axis=1)
    m = poly.degree
    if m == 1:
        out[ok] = np.abs(c[ok, 1] / lead[ok])
    elif np.any(ok):
        monic = c[ok, 1:] / lead[ok, None]
        companion = np.zeros((monic.shape[0], m, m), dtype=complex)
        companion[:, 0, :] = -monic
        companion[:, np.arange(1, m), np.arange(m - 1)] = 1.0
        out[ok] = np.max(np.abs(np.linalg.eigvals(companion)), axis=1)
    return out.reshape(shape)


def is_stable(poly: StabilityPolynomial, z: complex | np.ndarray, tol: float = ROOT_TOLERANCE) -> np.ndarray:
    """Whether ``z`` lies in the stability region (roots in the closed unit disc, within ``tol``).

    Roots of modulus exactly one are not checked for simplicity: on the
    region's boundary the answer is "stable" within ``tol``.
    """
    return max_root_modulus(poly, z) <= 1.0 + tol


def boundary_locus(poly: StabilityPolynomial, points: int = 2048) -> np.ndarray:
    """The locus ``{z : π(e^{iθ}, z) = 0}``, ``θ`` on ``points`` equal steps of ``[0, 2π]``.

    Returns
    -------
    numpy.ndarray of complex, shape (points, K)
        ``K`` = degree of π in ``z`` (1 for a linear multistep method, 4 for
        RK4, 2 for ABM4 PECE): column ``k`` is the ``k``-th root in ``z``
        (roots sorted by argument, so the columns are not continuous curves
        for ``K > 1``).  The region's boundary is a subset of these points.
    """
    theta = np.linspace(0.0, 2.0 * math.pi, points)
    zeta = np.exp(1j * theta)
    # value of p_k at ζ for each k: shape (points, K + 1)
    pk = np.stack([np.polyval(np.array(p, dtype=complex), zeta) for p in poly.coefficients], axis=1)
    k_max = pk.shape[1] - 1
    if k_max == 1:
        return (-pk[:, 0] / pk[:, 1]).reshape(-1, 1)
    out = np.empty((points, k_max), dtype=complex)
    for i in range(points):
        roots = np.roots(pk[i, ::-1])
        roots = np.concatenate([roots, np.full(k_max - roots.size, np.nan + 0j)])
        out[i] = roots[np.argsort(np.angle(roots))]
    return out


def _bdf_locus(order: int):
    """``z(θ)`` and ``z'(θ)`` of the BDF locus as numpy callables (exact coefficients)."""
    poly = stability_polynomial(f"bdf{order}")
    rho = np.array(poly.coefficients[0])
    sigma = -np.array(poly.coefficients[1])
    d_rho, d_sigma = np.polyder(rho), np.polyder(sigma)

    def z(theta: np.ndarray | float) -> np.ndarray:
        zeta = np.exp(1j * np.asarray(theta, dtype=float))
        return np.polyval(rho, zeta) / np.polyval(sigma, zeta)

    def dz(theta: np.ndarray | float) -> np.ndarray:
        zeta = np.exp(1j * np.asarray(theta, dtype=float))
        r, s = np.polyval(rho, zeta), np.polyval(sigma, zeta)
        return 1j * zeta * (np.polyval(d_rho, zeta) * s - r * np.polyval(d_sigma, zeta)) / (s * s)

    return z, dz


def a_alpha(order: int) -> AAlpha:
    """Measure the A(α) angle of the BDF of ``order`` (1–6) from its boundary locus.

    See the module docstring for the method and its precision.

    Raises
    ------
    analysis.bdf.BdfOrderError
        ``order`` outside 1–6 (BDF7 and above are not zero-stable, so they
        have no A(α) angle).
    """
    from scipy.optimize import brentq, minimize_scalar

    from analysis.bdf import validate_order

    order = validate_order(order)
    z, dz = _bdf_locus(order)
    theta = np.linspace(0.0, math.pi, A_ALPHA_GRID)[1:]
    values = z(theta)
    left = values.real < 0.0
    published = PUBLISHED_A_ALPHA_DEG[order]
    if not np.any(left):
        return AAlpha(order=order, alpha_deg=90.0, alpha_tangency_deg=90.0, theta_star=None, z_star=None,
                      published_deg=published, error_deg=90.0 - published)

    def angle(t: float) -> float:
        value = complex(z(t))
        return abs(math.atan2(-value.imag, -value.real))

    angles = np.where(left, np.abs(np.angle(-values)), np.inf)
    i = int(np.argmin(angles))
    lo, hi = float(theta[max(i - 2, 0)]), float(theta[min(i + 2, theta.size - 1)])
    best = minimize_scalar(angle, bounds=(lo, hi), method="bounded", options={"xatol": A_ALPHA_XATOL})
    theta_star = float(best.x)

    def tangency(t: float) -> float:  # d/dθ arg z(θ) = Im(z'/z)
        return float((complex(dz(t)) / complex(z(t))).imag)

    theta_tan = brentq(tangency, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    alpha = math.degrees(angle(theta_star))
    return AAlpha(
        order=order,
        alpha_deg=alpha,
        alpha_tangency_deg=math.degrees(angle(theta_tan)),
        theta_star=theta_star,
        z_star=complex(z(theta_star)),
        published_deg=published,
        error_deg=alpha - published,
    )


def zero_stability(order: int) -> ZeroStability:
    """Roots of ``ρ`` for the BDF of any ``order >= 1`` (BDF7: a root of modulus 1.0222 > 1)."""
    roots = bdf_characteristic_roots(order)
    principal = int(np.argmin(np.abs(roots - 1.0)))
    parasitic = np.delete(roots, principal)
    max_parasitic = float(np.max(np.abs(parasitic))) if parasitic.size else 0.0
    return ZeroStability(
        order=order,
        roots=tuple(complex(r) for r in roots),
        max_parasitic_modulus=max_parasitic,
        zero_stable=bool(max_parasitic < 1.0 - 1e-12),
    )


def real_stability_interval(poly: StabilityPolynomial, search: float = 1e3) -> float:
    """Left end ``x* < 0`` of the stability interval ``[x*, 0]`` on the negative real axis.

    The smallest ``r`` at which ``−r`` leaves the region (scan on a geometric
    grid, then bisection to 1e-13 relative); ``-inf`` if the axis is stable up
    to ``−search`` (an A(0)-stable method such as BDF).
    """
    radii = np.geomspace(1e-6, search, 4000)
    stable = is_stable(poly, -radii, tol=1e-14)
    bad = np.flatnonzero(~stable)
    if bad.size == 0:
        return -math.inf
    j = int(bad[0])
    lo, hi = (0.0 if j == 0 else float(radii[j - 1])), float(radii[j])
    while hi - lo > 1e-13 * hi:
        mid = 0.5 * (lo + hi)
        if bool(is_stable(poly, -mid, tol=1e-14)):
            lo = mid
        else:
            hi = mid
    return -lo


def stability_grid(
    poly: StabilityPolynomial, re: np.ndarray, im: np.ndarray
) -> np.ndarray:
    """``max |ζ|`` on the grid ``re[j] + i im[i]``: shape ``(im.size, re.size)`` (for contouring at 1)."""
    zz = np.asarray(re, dtype=float)[None, :] + 1j * np.asarray(im, dtype=float)[:, None]
    return max_root_modulus(poly, zz)


def _outermost_per_direction(lam: np.ndarray, width: float) -> np.ndarray:
    """For each bin of ``arg λ`` of the given width [rad], the eigenvalue of largest modulus."""
    bins = np.floor(np.angle(lam) / width).astype(np.int64)
    order = np.lexsort((-np.abs(lam), bins))
    first = np.concatenate([[True], bins[order][1:] != bins[order][:-1]])
    return lam[order][first]


def _all_stable(poly: StabilityPolynomial, z: np.ndarray) -> bool:
    return bool(np.all(is_stable(poly, z)))


def first_unstable_step(
    poly: StabilityPolynomial,
    eigenvalues: np.ndarray,
    h_min: float,
    h_max: float,
    *,
    points: int = 200,
    rtol: float = 1e-6,
    direction_bin: float = 1e-3,
) -> float:
    """Smallest step ``h`` in ``[h_min, h_max]`` at which some ``h λ`` leaves the stability region.

    Only eigenvalues with ``Re λ <= 0`` count (for ``Re λ > 0`` the exact
    solution grows too, and no scheme is "stable" in the sense of the
    region).  Along one direction ``arg λ`` the eigenvalue of largest modulus
    leaves first (all of them scale with ``h``), so the search runs on the
    outermost eigenvalue of every ``direction_bin``-wide bin of directions;
    the result is then checked on the whole set (and bisected on it if a
    bin hid an earlier exit).  Scans ``points`` geometric steps, then bisects
    the first failure to ``rtol``.

    Returns
    -------
    float
        The step, or ``inf`` if every ``h λ`` stays inside up to ``h_max``
        (``nan`` if there is no eigenvalue with ``Re λ <= 0``).
    """
    lam = np.asarray(eigenvalues, dtype=complex).reshape(-1)
    lam = lam[lam.real <= 0.0]
    if lam.size == 0:
        return math.nan
    lam = np.where(lam.imag < 0, lam.conjugate(), lam)  # regions of real schemes are symmetric
    reduced = _outermost_per_direction(lam, direction_bin)

    def search(values: np.ndarray, lo_bound: float) -> float:
        steps = np.geomspace(lo_bound, h_max, points)
        for j, h in enumerate(steps):
            if not _all_stable(poly, h * values):
                if j == 0:
                    return float(lo_bound)
                lo, hi = float(steps[j - 1]), float(h)
                while hi - lo > rtol * hi:
                    mid = 0.5 * (lo + hi)
                    if _all_stable(poly, mid * values):
                        lo = mid
                    else:
                        hi = mid
                return hi
        return math.inf

    found = search(reduced, h_min)
    check = min(found, h_max) * (1.0 - 2.0 * rtol)
    if check > h_min and not _all_stable(poly, check * lam):
        found = search(lam, h_min)
    return found
