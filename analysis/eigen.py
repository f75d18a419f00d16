"""Eigenvalues with what they mean in time: damping ratio, natural frequency, time constant.

The one place that turns a matrix's spectrum into :class:`EigenMode` s, shared by
:mod:`analysis.linearise` (a CasADi function's linearisation) and :mod:`analysis.equilibria` (a
hybrid mode's equilibrium).

Examples
--------
>>> [(m.real, m.time_constant_s) for m in eigen_modes([[-2.0, 0.0], [0.0, -0.5]])]
[(-2.0, 0.5), (-0.5, 2.0)]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hybrid.jsonable import to_jsonable

__all__ = ["EigenMode", "eigen_modes"]


@dataclass(frozen=True, kw_only=True, slots=True)
class EigenMode:
    """One eigenvalue of a linearisation and what it means in time.

    Attributes
    ----------
    real, imag : float
        The eigenvalue ``λ`` [1/s].
    damping_ratio : float
        ``−Re λ / |λ|`` (1 for a real stable pole, ``nan`` for ``λ = 0``).
    natural_frequency_radps : float
        ``|λ|`` [rad/s].
    time_constant_s : float
        ``−1 / Re λ`` [s] (``inf`` when ``Re λ = 0``; negative means growth).
    """

    real: float
    imag: float
    damping_ratio: float
    natural_frequency_radps: float
    time_constant_s: float

    def as_dict(self) -> dict[str, float | None]:
        """JSON-ready view: every field, ``None`` for non-finite numbers."""
        return to_jsonable(self)


def eigen_modes(matrix: np.ndarray) -> tuple[EigenMode, ...]:
    """Eigenvalues of a square matrix with damping, natural frequency and time constant.

    Sorted by real part, then imaginary part (deterministic order).
    """
    values = np.linalg.eigvals(np.asarray(matrix, dtype=float))
    out = []
    for lam in sorted(values, key=lambda z: (round(z.real, 12), round(z.imag, 12))):
        magnitude = abs(lam)
        damping = -lam.real / magnitude if magnitude > 0 else math.nan
        tau = -1.0 / lam.real if lam.real != 0 else math.inf
        out.append(EigenMode(real=float(lam.real), imag=float(lam.imag), damping_ratio=float(damping),
                             natural_frequency_radps=float(magnitude), time_constant_s=float(tau)))
    return tuple(out)
