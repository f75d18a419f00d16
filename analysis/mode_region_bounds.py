"""Bounds behind :func:`analysis.mode_region.mode_region_of_attraction`: the inner level set of the
Lyapunov function where the linear part dominates (the perturbation bound and its problems), and the time
bound from layers of the annulus (their rates, the sharpening of the layers by bisection, and the problems
the re-check runs again).

See :mod:`analysis.mode_region` for the method; it is the only user of these names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from fractions import Fraction
from typing import Any

import numpy as np

from analysis import exact
from analysis.certificate import enclose
from analysis.polynomial import Polynomial
from analysis.sublevel import SublevelCertificate, enclose_batch, partial_derivative
from analysis.mode_polynomials import ModePolynomials, coefficient_of, linear_part, quadratic_matrix

# Helpers shared with analysis.mode_region have public names but stay out of __all__: every new short string
# literal changes Hypothesis's pool of local constants, hence the fuzzing draws of the committed report.
__all__ = []


_SHARPEN_ROUNDS = 40
"""Rounds of refinement of the boxes that limit the entry-time bound."""

_SHARPEN_BOXES = 2_000
"""Boxes the refinement may add."""

_LAYERS = 32
"""Geometric layers of the annulus ``c_in <= V <= c`` of the entry-time bound."""

Matrix = list[list[Fraction]]


def _positive_definite(m: Matrix) -> bool:
    """Exactly ``m ≻ 0`` (:func:`analysis.exact.is_positive_definite`)."""
    return exact.is_positive_definite(m)


def _inverse_diagonal(m: Matrix) -> list[Fraction]:
    """Diagonal of ``m⁻¹`` (exact cofactors, :func:`analysis.exact.determinant`)."""
    det, n = exact.determinant(m), len(m)
    return [exact.determinant([[m[r][c] for c in range(n) if c != i] for r in range(n) if r != i]) / det if n > 1
            else 1 / m[0][0] for i in range(n)]


def _shifted(m: Matrix, mu: Fraction) -> Matrix:
    return [[x - (mu if i == j else 0) for j, x in enumerate(row)] for i, row in enumerate(m)]


def _sqrt_up(x: Fraction) -> Fraction:
    """A dyadic rational ``>= sqrt(x)``."""
    s = math.sqrt(float(x))
    while Fraction(s) ** 2 < x:
        s = math.nextafter(s, math.inf)
    return Fraction(s)


def _perturbation(polys: ModePolynomials, p: Matrix) -> list[list[Polynomial]]:
    """Entries of ``P·E(z) + E(z)ᵀ·P``, ``E = Df − A`` (exact; every entry vanishes at the origin)."""
    z, n = polys.variables, len(polys.variables)
    e = [[partial_derivative(polys.rates[z[i]], z[j]) - coefficient_of(polys.rates[z[i]], {z[j]: 1}) for j in range(n)]
         for i in range(n)]
    pe = [[sum((e[k][j] * p[i][k] for k in range(n)), Polynomial({})) for j in range(n)] for i in range(n)]
    return [[pe[i][j] + pe[j][i] for j in range(n)] for i in range(n)]


def _sigma_squared(entries: list[list[Polynomial]], r: Fraction) -> Fraction:
    """``Σ_ij (Σ_α |c_α| r^|α|)²``: a bound of the squared Frobenius norm on the cube ``|z_i| <= r``."""
    total = Fraction(0)
    for row in entries:
        for poly in row:
            b = sum((abs(c) * r ** sum(p for _, p in m) for m, c in poly.terms.items()), Fraction(0))
            total += b * b
    return total


def inner_data(polys: ModePolynomials, w: Polynomial, r_start: float) -> dict[str, Any] | str:
    """Search the rationals of the inner argument (module docstring, step 3); every claim is checked exactly."""
    z = polys.variables
    p = quadratic_matrix(w, z)
    a = linear_part(polys.rates, z)
    n = len(z)
    m = [[-sum(a[k][i] * p[k][j] + p[i][k] * a[k][j] for k in range(n)) for j in range(n)] for i in range(n)]
    mu = Fraction(0.9 * float(np.linalg.eigvalsh(np.array(m, dtype=float)).min()))
    while mu > 0 and not _positive_definite(_shifted(m, mu)):
        mu /= 2
    if not (mu > 0 and _positive_definite(p)):
        return "the quadratic W of the linearisation is not proven (P > 0, -(A'P + PA) > 0 failed exactly)"
    entries = _perturbation(polys, p)
    r = Fraction(float(r_start))
    for _ in range(200):
        if _sqrt_up(_sigma_squared(entries, r)) <= mu / 2:
            break
        r /= 2
    for _ in range(6):  # grow r back while the bound allows
        if _sqrt_up(_sigma_squared(entries, r * Fraction(5, 4))) > mu / 2:
            break
        r *= Fraction(5, 4)
    sigma = _sqrt_up(_sigma_squared(entries, r))
    if not sigma < mu:
        return f"inner argument: no cube |z_i| <= r found on which the flow contracts (sigma = {float(sigma):.3g})"
    lam = Fraction(1.01 * float(np.linalg.eigvalsh(np.array(p, dtype=float)).max()))
    while not _positive_definite(_shifted([[-x for x in row] for row in p], -lam)):
        lam *= 2
    c_w = r * r / max(_inverse_diagonal(p))
    f0 = [coefficient_of(polys.rates[v], {}) for v in z]
    pf0 = sum((sum(p[i][k] * f0[k] for k in range(n)) ** 2 for i in range(n)), Fraction(0))
    rate = mu - sigma
    radius = Fraction(0) if pf0 == 0 else _sqrt_up(4 * pf0 / rate ** 2)
    return {"W": w, "r": r, "mu": mu, "sigma": sigma, "lambda_max": lam, "c_w": c_w,
            "kappa": Fraction(math.nextafter(float(rate / lam), 0.0)) if float(rate / lam) > 0 else Fraction(0),
            "epsilon": radius}


def inner_problems(polys: ModePolynomials, data: Mapping[str, Any]) -> list[str]:
    """Exact re-check of the inner argument's rationals (empty: it holds)."""
    z, n, w = polys.variables, len(polys.variables), data["W"]
    if any(a.kind != "var" or a.variable not in z for a in w.atoms) or any(
            sum(e for _, e in mono) != 2 for mono in w.terms):
        return ["W is not a quadratic form in the shifted coordinates"]
    p = quadratic_matrix(w, z)
    a = linear_part(polys.rates, z)
    m = [[-sum(a[k][i] * p[k][j] + p[i][k] * a[k][j] for k in range(n)) for j in range(n)] for i in range(n)]
    r, mu, sigma, lam, c_w = (data[k] for k in ("r", "mu", "sigma", "lambda_max", "c_w"))
    problems = []
    if not _positive_definite(p):
        problems.append("P is not positive definite")
    if not (mu > 0 and _positive_definite(_shifted(m, mu))):
        problems.append(f"-(A'P + PA) - mu I is not positive definite (mu = {mu})")
    if not (r > 0 and 0 <= sigma < mu and sigma ** 2 >= _sigma_squared(_perturbation(polys, p), r)):
        problems.append(f"sigma = {sigma} does not bound the perturbation on |z_i| <= {r} below mu")
    if not _positive_definite(_shifted([[-x for x in row] for row in p], -lam)):
        problems.append(f"lambda_max = {lam} is not above the eigenvalues of P")
    if not (c_w > 0 and all(c_w * d <= r * r for d in _inverse_diagonal(p))):
        problems.append(f"the ellipsoid W <= {c_w} is not inside the cube |z_i| <= {r}")
    f0 = [coefficient_of(polys.rates[v], {}) for v in z]
    pf0 = sum((sum(p[i][k] * f0[k] for k in range(n)) ** 2 for i in range(n)), Fraction(0))
    rate, eps, kappa = mu - sigma, data["epsilon"], data["kappa"]
    if not (eps >= 0 and (eps * rate / 2) ** 2 >= pf0):
        problems.append(f"epsilon = {eps} is below 2 |P f(x*)| / (mu - sigma)")
    if not (kappa >= 0 and kappa * lam <= rate):
        problems.append(f"kappa = {kappa} exceeds (mu - sigma)/lambda_max")
    return problems


def _layers(c_in: float, c: float) -> list[float]:
    """``_LAYERS + 1`` increasing levels from ``c_in`` to ``c`` (geometric: ``V̇`` is smallest near ``c_in``)."""
    ratio = c / c_in
    inner = [c_in * ratio ** (k / _LAYERS) for k in range(1, _LAYERS)]
    levels = [c_in] + [x for x in inner if c_in < x < c] + [c]
    return sorted(set(levels))


def _layer_rates(v: Polynomial, cert: SublevelCertificate, layers: Sequence[float]) -> list[float]:
    """Per layer the least ``−rate bound`` of the decreasing boxes whose ``V`` enclosure meets it (``inf``: none).

    ``V`` is enclosed box by box by :func:`analysis.certificate.enclose` (scalar, outward rounded): every
    point with ``V`` in a layer lies in a decreasing box whose enclosure meets the layer, so ``V̇`` is at
    most ``−m_k`` there.
    """
    picked = [(box, bound) for box, label, bound in zip(cert.boxes, cert.labels, cert.rate_bounds)
              if label == "decreasing" and bound is not None]
    if not picked:
        return [math.inf] * (len(layers) - 1)
    ivs = [enclose(v, dict(zip(cert.variables, box))) for box, _ in picked]
    vlo, vhi = np.array([iv.lo for iv in ivs]), np.array([iv.hi for iv in ivs])
    edges = np.array(layers, dtype=float)
    meets = (vlo[:, None] <= edges[None, 1:]) & (vhi[:, None] >= edges[None, :-1])
    speed = -np.array([bound for _, bound in picked], dtype=float)
    return np.where(meets, speed[:, None], np.inf).min(axis=0).tolist()


def _layer_time(layers: Sequence[float], rates: Sequence[float]) -> Fraction | None:
    """``Σ (ρ_{k+1} − ρ_k)/m_k`` exactly (layers no box meets take no time); ``None`` if some ``m_k <= 0``."""
    total = Fraction(0)
    for k, m in enumerate(rates):
        if math.isinf(m):
            continue
        if not m > 0:
            return None
        total += (Fraction(layers[k + 1]) - Fraction(layers[k])) / Fraction(m)
    return total


def _float_up(x: Fraction) -> float:
    y = float(x)
    return y if Fraction(y) >= x else math.nextafter(y, math.inf)


def _children(v: Polynomial, rate: Polynomial, cert: SublevelCertificate, lo: np.ndarray, hi: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bisect boxes along their relatively widest side; label the halves as :func:`certify_sublevel` would.

    Returns the halves (``2N`` boxes: lower halves then upper halves), their labels, rate bounds and
    per parent whether both halves have a claim (else the parent is kept).
    """
    region = dict(zip(cert.variables, cert.region))
    widths = np.array([b - a for a, b in cert.region])
    j = np.argmax((hi - lo) / widths, axis=1)
    rows = np.arange(lo.shape[0])
    mid = 0.5 * lo[rows, j] + 0.5 * hi[rows, j]
    upper_lo, lower_hi = lo.copy(), hi.copy()
    upper_lo[rows, j], lower_hi[rows, j] = mid, mid
    clo, chi = np.vstack((lo, upper_lo)), np.vstack((lower_hi, hi))
    vlo, vhi = enclose_batch(v, region, clo, chi)
    top = cert.rho_out + 1e-9 * max(1.0, cert.rho_out)
    bottom = cert.rho_in - 1e-9 * max(1.0, cert.rho_in)
    labels = np.where(vlo > top, "outside", np.where(vhi < bottom, "inside", "decreasing")).astype(object)
    whi = enclose_batch(rate, region, clo, chi)[1]
    bound = whi + 1e-9 * np.abs(whi)
    ok = (labels != "decreasing") | (bound < 0.0)
    n = lo.shape[0]
    return clo, chi, labels, np.where(labels == "decreasing", bound, np.nan), ok[:n] & ok[n:]


def _layer_contributions(v: Polynomial, cert: SublevelCertificate, lo: np.ndarray, hi: np.ndarray,
                         rates: np.ndarray, layers: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per layer ``Δρ_k/m_k`` and ``m_k`` over the decreasing boxes given, and which boxes meet which layer."""
    vlo, vhi = enclose_batch(v, dict(zip(cert.variables, cert.region)), lo, hi)
    meets = (vlo[:, None] <= layers[None, 1:]) & (vhi[:, None] >= layers[None, :-1])
    m = np.where(meets, -rates[:, None], np.inf).min(axis=0)
    return np.where(np.isfinite(m), np.diff(layers) / np.where(np.isfinite(m), m, 1.0), 0.0), m, meets


def sharpen_layers(v: Polynomial, rate: Polynomial, cert: SublevelCertificate) -> SublevelCertificate:
    """The same certificate with the boxes that limit the layered entry-time bound bisected (sharper rates)."""
    lo = np.array([[a for a, _ in b] for b in cert.boxes])
    hi = np.array([[b for _, b in box] for box in cert.boxes])
    labels = np.array(cert.labels, dtype=object)
    rates = np.array([np.nan if r is None else r for r in cert.rate_bounds])
    layers, limit = np.array(_layers(cert.rho_in, cert.rho_out)), lo.shape[0] + _SHARPEN_BOXES
    history: list[float] = []
    for _ in range(_SHARPEN_ROUNDS):
        dec = np.nonzero(labels == "decreasing")[0]
        contrib, m, meets = _layer_contributions(v, cert, lo[dec], hi[dec], rates[dec], layers)
        history.append(float(contrib.sum()))
        if lo.shape[0] >= limit or (len(history) > 3 and not history[-1] < 0.99 * history[-4]):
            break
        hot = contrib >= 0.25 * contrib.max()
        pick = dec[(meets[:, hot] & (-rates[dec][:, None] <= 2.0 * m[hot][None, :])).any(axis=1)]
        pick = pick[: max(0, limit - lo.shape[0])]
        clo, chi, clab, crate, ok = _children(v, rate, cert, lo[pick], hi[pick])
        keep = np.ones(lo.shape[0], dtype=bool)
        keep[pick[ok]] = False
        both = np.concatenate((ok, ok))
        lo, hi = np.vstack((lo[keep], clo[both])), np.vstack((hi[keep], chi[both]))
        labels, rates = np.concatenate((labels[keep], clab[both])), np.concatenate((rates[keep], crate[both]))
    known = rates[labels == "decreasing"]
    max_rate = float(known.max()) if known.size else None
    entry = None if max_rate is None else float(np.nextafter((cert.rho_out - cert.rho_in) / -max_rate, np.inf))
    claim = cert.claim
    if cert.entry_time_bound is not None and entry is not None:
        claim = claim.replace(f"within {cert.entry_time_bound:.6g} time units", f"within {entry:.6g} time units")
    return replace(cert, boxes=tuple(tuple(zip(a.tolist(), b.tolist())) for a, b in zip(lo, hi)),
                   labels=tuple(str(x) for x in labels),
                   rate_bounds=tuple(None if x != "decreasing" else float(r) for x, r in zip(labels, rates)),
                   max_rate=max_rate, entry_time_bound=entry, claim=claim,
                   method=cert.method + "; decreasing boxes that limit the layered entry-time bound bisected further")


def time_bound(v: Polynomial, cert: SublevelCertificate) -> dict[str, Any]:
    """The layered entry-time bound (never above the certificate's own ``(c − c_in)/m``)."""
    layers = _layers(cert.rho_in, cert.rho_out)
    rates = _layer_rates(v, cert, layers)
    exact = _layer_time(layers, rates)
    bound = cert.entry_time_bound if exact is None else min(_float_up(exact), cert.entry_time_bound)
    return {"layers": [float.hex(x) for x in layers],
            "rates": [None if math.isinf(m) else float.hex(m) for m in rates], "bound": bound}


def time_problems(v: Polynomial, cert: SublevelCertificate, data: Mapping[str, Any], claimed: Any) -> list[str]:
    """Re-check of the layered entry-time bound from the sublevel certificate's boxes (empty: it holds)."""
    if not isinstance(claimed, (int, float)) or isinstance(claimed, bool) or not claimed > 0:
        return [f"time bound {claimed!r} is not a positive number"]
    if cert.entry_time_bound is not None and claimed >= cert.entry_time_bound:
        return []
    layers = [float.fromhex(x) for x in data["layers"]]
    rates = [math.inf if m is None else float.fromhex(m) for m in data["rates"]]
    if (len(rates) != len(layers) - 1 or layers[0] != cert.rho_in or layers[-1] != cert.rho_out
            or any(b <= a for a, b in zip(layers, layers[1:]))):
        return ["the time layers do not partition [rho_in, rho_out]"]
    actual = _layer_rates(v, cert, layers)
    problems = [f"time layer {k}: rate {m!r} exceeds the boxes' {a!r}" for k, (m, a) in enumerate(zip(rates, actual))
                if m > a]
    exact = _layer_time(layers, rates)
    if exact is None or Fraction(claimed) < exact:
        problems.append(f"time bound {claimed!r} is below the layered sum {None if exact is None else float(exact)}")
    return problems
