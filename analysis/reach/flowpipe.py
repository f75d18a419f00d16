"""The flowpipe of one mode's affine dynamics ``ẋ = A x + B u + c``, ``u(t) ∈ U``, with zonotopes.

The state is augmented with a constant coordinate ``x_{n+1} = s`` (flow 0; ``s`` a power of two
chosen by the engine, so the scaling is exact), so the affine flow becomes the linear flow of
``A_aug = [[A, c/s], [0, 0]]`` exactly, and ``e^{A_aug δ}`` carries the constant's effect (no
separate input term for ``c``).  The non-deterministic input enters as the
zero-centred zonotope ``B U₀`` (the centre of ``U`` is moved into ``c``, exactly, in rationals).

Algorithm (Girard, HSCC 2005, with the wrapping-free sum of Girard, Le Guernic and Maler, HSCC 2006):

* first segment, over local time ``[0, δ]``:
  ``Q₀ = CH(X, Φ X) ⊕ box(F |X|) ⊕ V`` with ``Φ = e^{A_aug δ}`` (an interval matrix,
  :func:`analysis.reach.series.exp_enclosure`), the interpolation error bound ``F |X|``,
  ``F = Σ_{k>=2} c_k (|A_aug|δ)^k/k!`` with ``c_k = max_τ (τ − τ^k)`` (``c_2 = 1/4``)
  (:func:`analysis.reach.series.bloating_matrices`) and the input zonotope ``V`` holding the input's reach set
  ``R(δ) = {∫₀^δ e^{As} B u(s) ds}`` from 0, computed through sub-steps (:mod:`analysis.reach.input_step`; since
  ``0 ∈ U₀``, ``R(τ) ⊆ R(δ)`` for ``τ <= δ``, so ``V`` covers every local time of the first segment too);
* segment ``k``: ``R_k = Φ^k Q₀ ⊕ Σ_{j<k} Φ^j V``.  ``Φ^k Q₀`` is mapped step by step and never
  reduced (no wrapping); the input sum is accumulated and reduced but never mapped again;
  the rounding errors of every map are collected in an error zonotope ``E`` that is mapped and
  reduced (its wrapping only concerns numbers of the size of the rounding), or, when ``ρ(|Φ|) > 1`` would make
  that box grow like ``ρ(|Φ|)^k``, bounded in an eigenbasis (:mod:`analysis.reach.errorbound`): the errors of
  ``Φ^k Q₀`` and those of the mapped input ``Φ^j V`` alike (the latter wrapped to ``10⁶`` within 1.08 s on the
  48-state building with its input, BLDF01).

Each segment holds every state reached from ``X`` at local times ``[kδ, (k+1)δ]`` under any
measurable input with values in ``U``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .errorbound import ErrorTracker, error_tracker
from .input_step import input_step_set
from .input_sum import add_in_place
from .series import MatrixEnclosure, bloating_matrices, exp_enclosure
from .zonotope import (
    UNIT_ROUNDOFF,
    Zonotope,
    box_generators,
    linear_map,
    magnitude,
    reduce_order,
    upper,
    with_error,
)

__all__ = ["ModeDynamics", "mode_dynamics", "first_segment", "segments", "ERROR_ORDER"]

ERROR_ORDER = 3
"""Order (generators per dimension) kept in the rounding-error zonotope."""
INPUT_STEP_ORDER = 2
"""Order kept in the one-step input set ``V`` (mapped every step): its smallest generators are boxed."""


@dataclass(frozen=True, kw_only=True, slots=True)
class ModeDynamics:
    """The discretised dynamics of one mode, in augmented coordinates (dimension ``n + 1``).

    Attributes
    ----------
    mode : str
    step : float
        ``δ`` [s].
    phi : MatrixEnclosure
        Contains ``e^{A_aug δ}``.
    deviation : ndarray, shape (n+1, n+1)
        ``F >= 0``: ``|x(t) − ((1 − t/δ) x0 + (t/δ) Φ x0)| <= F |x0|`` for ``t ∈ [0, δ]`` (the first segment).
    input_step : Zonotope or None
        ``V``: every state change a full step of input can cause (zero centre); ``None`` without input.
    tracker : ErrorTracker or None
        Bounds the accumulated rounding errors in an eigenbasis (:mod:`analysis.reach.errorbound`) instead of
        the error zonotope; built only when the zonotope would wrap (``ρ(|Φ|) > 1``) and the basis is proven.
    """

    mode: str
    step: float
    phi: MatrixEnclosure
    deviation: np.ndarray
    input_step: Zonotope | None
    tracker: ErrorTracker | None = None


def mode_dynamics(mode: str, a: list[list[Fraction]], c: list[Fraction], step: float,
                  input_matrix: list[list[Fraction]] | None = None,
                  input_set: Zonotope | None = None) -> ModeDynamics:
    """The :class:`ModeDynamics` of ``ẋ = A x + B u + c``.

    Parameters
    ----------
    a : n × n Fractions
    c : n Fractions
    step : float
        ``δ > 0`` [s].
    input_matrix : n × p Fractions, or None
    input_set : Zonotope of dimension p, or None
        ``U``; only its generators are used: the caller moves ``B`` times its centre into ``c``
        (exactly) beforehand.  ``c`` is in the scaled augmented coordinates (see the engine).
    """
    n = len(c)
    centred = None
    if input_matrix is not None and input_set is not None:
        centred = Zonotope(center=np.zeros(input_set.dimension), generators=input_set.generators)
    aug = [list(row) + [c[i]] for i, row in enumerate(a)] + [[Fraction(0)] * (n + 1)]
    delta = Fraction(step)
    phi = exp_enclosure(aug, delta)
    deviation, _ = bloating_matrices(aug, delta, corrected=True)
    input_step = None
    if centred is not None:
        bc = np.array([[float(q) for q in row] for row in input_matrix])
        br = np.array([[float(upper(float(abs(q - Fraction(float(q)))), 1)) for q in row] for row in input_matrix])
        bu, err = linear_map(centred, bc, br)
        bu = with_error(bu, err)  # symmetric: still centred on 0
        top = reduce_order(input_step_set(a, bu, step), INPUT_STEP_ORDER).generators
        gens = np.vstack([top, np.zeros((1, top.shape[1]))])
        input_step = Zonotope(center=np.zeros(n + 1), generators=gens)
    tracker = None
    abs_phi = np.abs(phi.center)
    if np.all(np.isfinite(abs_phi)) and float(np.max(np.abs(np.linalg.eigvals(abs_phi)))) > 1.0 + 1e-9:
        tracker = error_tracker(np.array([[float(q) for q in row] for row in aug]), phi.center, phi.radius)
    return ModeDynamics(mode=mode, step=step, phi=phi, deviation=deviation, input_step=input_step, tracker=tracker)


def first_segment(dyn: ModeDynamics, start: Zonotope) -> Zonotope:
    """``Q₀``: every state reached from ``start`` (augmented) at local times ``[0, δ]``."""
    image, err_map = linear_map(start, dyn.phi.center, dyn.phi.radius)
    mean_c = (start.center + image.center) * 0.5
    half_c = (start.center - image.center) * 0.5
    mean_g = (start.generators + image.generators) * 0.5
    half_g = (start.generators - image.generators) * 0.5
    rounding = 2.0 * UNIT_ROUNDOFF * (np.abs(mean_c) + np.abs(half_c) + np.abs(mean_g).sum(axis=1)
                                      + np.abs(half_g).sum(axis=1))
    dim = start.dimension
    bloat = dyn.deviation @ magnitude(start)
    error = upper(err_map + rounding + bloat, 2 * start.order + dim + 6)
    parts = [mean_g, half_c.reshape(-1, 1), half_g, box_generators(error)]
    if dyn.input_step is not None:
        parts.append(dyn.input_step.generators)
    return Zonotope.of_arrays(mean_c, np.hstack(parts))


def segments(dyn: ModeDynamics, start: Zonotope, order: int, input_order: int | None = None) -> Iterator[Zonotope]:
    """``R_0, R_1, ...`` (augmented zonotopes), one per step of local time ``[kδ, (k+1)δ]``; endless.

    The caller stops the iteration (horizon, invariant, size limits).  The input sum keeps ``input_order``
    (default ``order``) generators per dimension, box included, each generator in its slot
    (:func:`analysis.reach.input_sum.add_in_place`: consecutive segments stay column-aligned for the union of a
    zonotope jump set).
    """
    main = first_segment(dyn, start)
    dim = start.dimension
    error = Zonotope(center=np.zeros(dim), generators=np.zeros((dim, 0)))
    mapped_input = dyn.input_step
    input_error = Zonotope(center=np.zeros(dim), generators=np.zeros((dim, 0)))
    input_gens, input_box = np.zeros((dim, 0)), np.zeros(dim)
    input_sum = Zonotope(center=np.zeros(dim), generators=input_gens)
    input_limit = ((order if input_order is None else input_order) - 1) * dim
    phi_c, phi_r = dyn.phi.center, dyn.phi.radius
    tracker = dyn.tracker
    bound = tracker.start() if tracker is not None else None
    bound_in = tracker.start() if tracker is not None else None
    while True:
        if tracker is not None:
            error_box = tracker.box(bound)
            error = Zonotope.of_arrays(np.zeros(dim), box_generators(error_box))
        yield Zonotope.of_arrays(main.center, np.hstack([main.generators, error.generators, input_sum.generators]))
        main, e_main = linear_map(main, phi_c, phi_r)
        if tracker is not None:  # no wrapping: the errors' moduli in the eigenbasis (errorbound.py)
            bound = tracker.step(bound, e_main, error_box)
        else:
            error, e_error = linear_map(error, phi_c, phi_r)
            error = reduce_order(with_error(error, upper(e_main + e_error, 2)), ERROR_ORDER)
        if mapped_input is not None:
            if tracker is not None:  # the input's rounding errors, bounded without wrapping as the main ones
                box_in = tracker.box(bound_in)
                input_error = Zonotope.of_arrays(np.zeros(dim), box_generators(box_in))
            input_gens, input_box = add_in_place(
                input_gens, input_box, np.hstack([mapped_input.generators, input_error.generators]), input_limit)
            input_sum = Zonotope.of_arrays(np.zeros(dim), np.hstack([input_gens, box_generators(input_box)]))
            mapped_input, e_in = linear_map(mapped_input, phi_c, phi_r)
            if tracker is not None:
                bound_in = tracker.step(bound_in, e_in, box_in)
            else:
                input_error, e_ie = linear_map(input_error, phi_c, phi_r)
                input_error = reduce_order(with_error(input_error, upper(e_in + e_ie, 2)), ERROR_ORDER)
