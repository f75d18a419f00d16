"""Random switched linear families with a known answer, for testing and benchmarking LMI certificates.

:func:`planted_common_lyapunov`
    ``A_i = P⁻¹(S_i − Q_i)`` with ``S_i`` skew-symmetric and ``Q_i ≻ 0``: then
    ``A_iᵀP + PA_i = −2Q_i ≺ 0``, so ``V = xᵀPx`` is a common quadratic Lyapunov function by
    construction.
:func:`planted_no_common_lyapunov`
    Two Hurwitz modes ``[[−a, 0], [c, −b]]`` and ``[[−a, c], [0, −b]]`` (eigenvalues ``−a, −b``) whose
    average ``[[−a, c/2], [c/2, −b]]`` has the eigenvalue ``(−a − b + sqrt((a − b)² + c²))/2 > 0`` for
    ``c² > 4ab``, embedded with random stable blocks in a random basis, plus more Hurwitz modes.  A common
    quadratic Lyapunov function would also serve every convex combination, so none exists; the returned
    ``witness`` is that unstable average (an independent check of a certificate of absence).
"""

from __future__ import annotations

import numpy as np

__all__ = ["planted_common_lyapunov", "planted_no_common_lyapunov"]


def _random_spd(rng: np.random.Generator, n: int, condition: float) -> np.ndarray:
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return q @ np.diag(np.geomspace(1.0, condition, n)) @ q.T


def planted_common_lyapunov(rng: np.random.Generator, n: int, m: int, *, condition: float = 30.0
                            ) -> tuple[list[np.ndarray], np.ndarray]:
    """``m`` matrices ``(n, n)`` sharing the Lyapunov matrix ``P`` (returned), ``cond(P) = condition``."""
    p = _random_spd(rng, n, condition)
    p_inv = np.linalg.inv(p)
    family = []
    for _ in range(m):
        s = rng.standard_normal((n, n))
        q = _random_spd(rng, n, 10.0) * rng.uniform(0.2, 2.0)
        family.append(p_inv @ ((s - s.T) * rng.uniform(0.0, 3.0) - q))
    return family, p


def planted_no_common_lyapunov(rng: np.random.Generator, n: int, m: int) -> tuple[list[np.ndarray], np.ndarray]:
    """``m >= 2`` Hurwitz matrices ``(n, n)``, ``n >= 2``, with no common quadratic Lyapunov function, and the
    non-Hurwitz average of the first two (the witness)."""
    a, b = rng.uniform(0.5, 2.0, 2)
    c = 2.0 * np.sqrt(a * b) * rng.uniform(1.3, 4.0)
    blocks = [np.array([[-a, 0.0], [c, -b]]), np.array([[-a, c], [0.0, -b]])]
    blocks += [blocks[k % 2] + np.diag(-rng.uniform(0.0, 0.5, 2)) for k in range(m - 2)]
    t = np.linalg.qr(rng.standard_normal((n, n)))[0] @ np.diag(rng.uniform(0.5, 2.0, n))
    t_inv = np.linalg.inv(t)
    family = []
    for block in blocks:
        full = np.zeros((n, n))
        full[:2, :2] = block
        if n > 2:
            rest, _ = planted_common_lyapunov(rng, n - 2, 1, condition=5.0)
            full[2:, 2:] = rest[0]
            full[:2, 2:] = 0.3 * rng.standard_normal((2, n - 2))
        family.append(t @ full @ t_inv)
    return family, 0.5 * (family[0] + family[1])
