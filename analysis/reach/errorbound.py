"""The rounding errors of a long flowpipe, tracked in an eigenbasis so that they do not wrap.

The flowpipe (:mod:`analysis.reach.flowpipe`) maps its main zonotope by ``Φ = e^{A_aug δ}`` every step; each map
adds an error box ``e_k`` (the rounding of the products, :func:`~analysis.reach.zonotope.linear_map`).  The
accumulated error ``E_k = Σ_{j<k} Φ^{k−j} e_j`` kept as a zonotope that is mapped and box-reduced every step
*wraps*: its box grows like ``ρ(|Φ|)^k``, i.e. like ``e^{ρ(|A|) t}`` whatever the step.  For a lightly damped
oscillator of 48 states (the ARCH building, ``ρ(|A|) ≈ 54 /s``) the error reaches ``10⁶`` within a second.

This module bounds ``E_k`` without wrapping.  The coordinates split into ``F`` (rows of ``A_aug`` that are zero
but for the constant column: constants, clocks, constant inputs) and ``R`` (the rest).  On ``R`` it takes the
numerical eigenvectors ``V`` of ``Φ_RR`` (complex) and ``W ≈ V⁻¹``, and tracks a vector ``r`` of moduli with
``|(W_R E)_i| <= r_i`` (``i ∈ R``) and ``|E_i| <= r_i`` (``i ∈ F``).  In those coordinates ``Φ`` is nearly
diagonal, so ``r ← N r + |W| |e_k|`` with ``N >= |W Φ W⁻¹|`` (entrywise) barely grows: no wrapping, since the
moduli of complex eigen-coordinates are invariant under the rotations that make boxes wrap.

Everything is proven, not assumed:

* ``W V = I − R`` is computed with its rounding, and ``‖R‖∞ <= ρ < 1/2`` is required; then
  ``W⁻¹ = V (I − R)⁻¹`` and ``‖(I − R)⁻¹ − I‖∞ <= ρ / (1 − ρ)`` (Neumann series);
* ``N`` bounds ``|W_R Φ W_R⁻¹|`` by ``|T| + err_T`` with ``T = fl(W_R Φc_RR V)`` (rounding of both complex
  products with ``γ_{4(m+2)}``, a generous constant for complex dot products; Higham §3.6), the radius ``Φr``,
  and the ``ρ / (1 − ρ)`` term applied through ``‖·‖∞`` (a rank-one bound);
* ``|E| <= |V| r_R + ‖|V|‖ ρ/(1 − ρ) max r_R`` on ``R``, and ``r_F`` on ``F``.

The bound holds for every exact ``Φ ∈ [Φc ± Φr]``.  When ``Φ_RR`` is not safely diagonalisable (``ρ >= 1/2`` or a
condition number above ``10¹⁰``) no tracker is built and the flowpipe keeps its error zonotope.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .zonotope import gamma, upper

__all__ = ["ErrorTracker", "error_tracker", "MAX_CONDITION"]

MAX_CONDITION = 1e10
"""Largest ``‖|W|‖∞ ‖|V|‖∞`` accepted for the eigenbasis."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ErrorTracker:
    """The bound propagation of the module docstring (every array real and non-negative).

    Attributes
    ----------
    rest, free : ndarray of int
        Indices of ``R`` and ``F`` in the augmented coordinates (dimension ``N``).
    n_rr : ndarray, shape (|R|, |R|)
        ``>= |W_R Φ_RR W_R⁻¹|`` without the rank-one term; ``coupling`` is that term's factor.
    n_rf, n_fr, n_ff : ndarray
        ``>= |W_R Φ_RF|``, ``>= |Φ_FR|`` (times the bound of ``|W_R⁻¹|``), ``>= |Φ_FF|``.
    w_abs : ndarray, shape (|R|, |R|)
        ``>= |W_R|`` (maps a new error box into ``R``'s coordinates).
    v_abs : ndarray, shape (|R|, |R|)
        ``|V|``; ``v_row`` its row sums times ``ρ/(1 − ρ)`` (the inverse's correction).
    """

    rest: np.ndarray
    free: np.ndarray
    n_rr: np.ndarray
    coupling: float
    n_rf: np.ndarray
    n_fr: np.ndarray
    n_ff: np.ndarray
    w_abs: np.ndarray
    v_abs: np.ndarray
    v_row: np.ndarray

    def start(self) -> np.ndarray:
        """``r = 0`` (no error yet), shape ``(N,)``."""
        return np.zeros(self.rest.size + self.free.size)

    def _back(self, r: np.ndarray) -> np.ndarray:
        """``>= |W_R⁻¹ w|`` for ``|w| <= r_R``."""
        rr = r[: self.rest.size]
        peak = float(rr.max()) if rr.size else 0.0
        return upper(self.v_abs @ rr + self.v_row * peak, self.rest.size + 3)

    def box(self, r: np.ndarray) -> np.ndarray:
        """``>= |E|`` componentwise in the augmented coordinates, shape ``(N,)``."""
        out = np.zeros(r.size)
        out[self.rest] = self._back(r)
        out[self.free] = r[self.rest.size:]
        return out

    def step(self, r: np.ndarray, error: np.ndarray, box: np.ndarray | None = None) -> np.ndarray:
        """``r`` after one map by ``Φ`` and the addition of a new error box ``[-error, error]`` (augmented).

        ``box``: :meth:`box` of the same ``r`` when the caller has it (its ``R`` part is reused, not recomputed).
        """
        m = self.rest.size
        rr, rf = r[:m], r[m:]
        peak = float(rr.max()) if m else 0.0
        back = self._back(r) if box is None else box[self.rest]
        new_r = self.n_rr @ rr + self.coupling * peak + self.n_rf @ rf + self.w_abs @ error[self.rest]
        new_f = self.n_ff @ rf + self.n_fr @ back + error[self.free]
        return upper(np.concatenate([new_r, new_f]), 2 * r.size + 6)


def _free_rows(a_aug: np.ndarray) -> np.ndarray:
    last = a_aug.shape[0] - 1
    others = np.delete(a_aug, last, axis=1)
    return np.nonzero(~np.any(others != 0.0, axis=1))[0]


def error_tracker(a_aug: np.ndarray, phi_c: np.ndarray, phi_r: np.ndarray) -> ErrorTracker | None:
    """The tracker of ``Φ ∈ [phi_c ± phi_r]`` (``a_aug``: the augmented matrix, to find ``F``), or ``None``.

    Parameters
    ----------
    a_aug : ndarray, shape (N, N)
        ``A_aug`` as floats (only its zero pattern is used).
    phi_c, phi_r : ndarray, shape (N, N)
        The enclosure of ``e^{A_aug δ}``.
    """
    size = phi_c.shape[0]
    free = _free_rows(np.asarray(a_aug, dtype=float))
    rest = np.setdiff1d(np.arange(size), free)
    m = rest.size
    if m == 0 or not np.all(np.isfinite(phi_c)):
        return None
    p_rr = phi_c[np.ix_(rest, rest)]
    try:
        _, v = np.linalg.eig(p_rr)
        w = np.linalg.inv(v)
    except np.linalg.LinAlgError:
        return None
    v_abs, w_abs0 = np.abs(v), np.abs(w)
    if not (np.all(np.isfinite(v_abs)) and np.all(np.isfinite(w_abs0))):
        return None
    if float(np.abs(w_abs0).sum(axis=1).max() * v_abs.sum(axis=1).max()) > MAX_CONDITION:
        return None
    g = gamma(4 * (m + 2))
    resid = np.abs(np.eye(m) - w @ v) + g * (w_abs0 @ v_abs)
    rho = float(upper(resid.sum(axis=1).max(), 2 * m + 4))
    if not rho < 0.5:
        return None
    kappa = float(upper(rho / (1.0 - rho), 4))
    t = w @ p_rr @ v
    err_t = upper(2 * g * (w_abs0 @ np.abs(p_rr) @ v_abs) + w_abs0 @ phi_r[np.ix_(rest, rest)] @ v_abs, 4 * m + 8)
    n_rr = upper(np.abs(t) + err_t, 2)
    coupling = float(upper(n_rr.sum(axis=1).max() * kappa, 4))
    p_rf = phi_c[np.ix_(rest, free)]
    n_rf = upper(w_abs0 @ (np.abs(p_rf) + phi_r[np.ix_(rest, free)]) * (1.0 + 2 * g), 2 * m + 4)
    n_fr = upper(np.abs(phi_c[np.ix_(free, rest)]) + phi_r[np.ix_(free, rest)], 2)
    n_ff = upper(np.abs(phi_c[np.ix_(free, free)]) + phi_r[np.ix_(free, free)], 2)
    w_abs = upper(w_abs0 * (1.0 + 2 * g), 2)
    v_row = upper(v_abs.sum(axis=1) * kappa, m + 2)
    return ErrorTracker(rest=rest, free=free, n_rr=n_rr, coupling=coupling, n_rf=n_rf, n_fr=n_fr, n_ff=n_ff,
                        w_abs=w_abs, v_abs=v_abs, v_row=v_row)
