"""The re-check's own check of a clock-free projection (:func:`analysis.reach.relaxed_induction.clock_free`).

A projection is sound for the relaxation's induction when every run of the original, restricted to the kept
states, is a run of the projection.  :func:`recheck_projection` checks that from the original system read again,
exactly (rationals), with its own code: every kept state's flow row in every mode is the projection's row and reads
no dropped state; every transition keeps the kept states (identity rows, zero offsets); every halfspace of the
projection's invariants and guards is a halfspace of the original's on kept states only (the projection may drop
constraints, never add one); the projection's input matrix is the original's kept rows with the same bounds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any

from .model import affine_model
from .recheck_inputs import model_inputs

__all__ = ["recheck_projection"]


def _restricted(polys: Sequence[Any], kept: Sequence[int]) -> set[tuple[tuple[Fraction, ...], Fraction]]:
    """The original's halfspaces that read kept states only, restricted to them."""
    n = None
    out = set()
    for p in polys:
        for h in p.halfspaces:
            n = len(h.normal)
            if all(h.normal[j] == 0 for j in range(n) if j not in kept):
                out.add((tuple(h.normal[j] for j in kept), Fraction(h.offset)))
    return out


def _weaker(projected: Sequence[Any], original: Sequence[Any], kept: Sequence[int], where: str) -> str:
    if len(projected) != len(original):
        return f"{where}: {len(projected)} polyhedra in the projection, {len(original)} in the model"
    for p, o in zip(projected, original):
        allowed = _restricted((o,), kept)
        extra = [h for h in p.halfspaces if (tuple(h.normal), Fraction(h.offset)) not in allowed]
        if extra:
            return f"{where}: the projection adds the halfspace {extra[0].text or extra[0].normal}"
    return ""


def _flows(model: Any, projected: Any, kept: Sequence[int]) -> str:
    n = len(model.state_names)
    for name, mode in model.modes.items():
        mine = projected.modes.get(name)
        if mine is None or mode.smooth is not None or mine.smooth is not None:
            return f"mode {name!r}: missing or not affine in the projection"
        for r, i in enumerate(kept):
            if any(mode.a[i][j] != 0 for j in range(n) if j not in kept):
                return f"mode {name!r}: the flow of {model.state_names[i]!r} reads a dropped state"
            if tuple(mode.a[i][j] for j in kept) != tuple(mine.a[r]) or mode.c[i] != mine.c[r]:
                return f"mode {name!r}: the flow of {model.state_names[i]!r} differs in the projection"
        why = _weaker(mine.invariant, mode.invariant, kept, f"mode {name!r} invariant")
        if why:
            return why
    return ""


def _transitions(model: Any, projected: Any, kept: Sequence[int]) -> str:
    n = len(model.state_names)
    mine = {t.name: t for t in projected.transitions}
    for t in model.transitions:
        p = mine.get(t.name)
        if p is None or (p.source, p.target) != (t.source, t.target):
            return f"transition {t.name!r}: missing or with other ends in the projection"
        for i in kept:
            if any(t.r_matrix[i][j] != (1 if i == j else 0) for j in range(n)) or t.r_offset[i] != 0:
                return f"transition {t.name!r} changes the kept state {model.state_names[i]!r}"
        size = len(kept)
        if any(p.r_matrix[r][c] != (1 if r == c else 0) for r in range(size) for c in range(size)) or any(p.r_offset):
            return f"transition {t.name!r}: the projection's reset is not the identity"
        why = _weaker(p.guard, t.guard, kept, f"transition {t.name!r} guard")
        if why:
            return why
    if len(mine) != len(model.transitions):
        return "the projection has other transitions than the model"
    return ""


def recheck_projection(system: Any, projected: Any, kept: Sequence[int], inputs: Mapping[str, Any] | None,
                       projected_inputs: Mapping[str, Any] | None) -> str:
    """``""`` when ``projected`` is a sound projection of ``system`` on the states ``kept`` (see the module), else
    the first reason it is not.

    Parameters
    ----------
    system : HybridSystem
        The original (input-free) symbolic system, read again here.
    projected : AffineHybridModel
        The projection the relaxation's flowpipes were computed on.
    kept : sequence of int
        The original indices of the projection's states, in order.
    inputs, projected_inputs : mapping {mode: ModeInput} or None
    """
    model = affine_model(system)
    kept = tuple(kept)
    if tuple(model.state_names[i] for i in kept) != tuple(projected.state_names):
        return "the projection's states are not the kept states of the model"
    why = _flows(model, projected, kept) or _transitions(model, projected, kept)
    if why:
        return why
    full = model_inputs(inputs, len(model.state_names))
    mine = model_inputs(projected_inputs, len(kept))
    if set(full) != set(mine):
        return "the projection's inputs are not the model's modes"
    for mode, spec in full.items():
        if tuple(spec.matrix[i] for i in kept) != tuple(mine[mode].matrix) or \
                (spec.low, spec.high) != (mine[mode].low, mine[mode].high):
            return f"mode {mode!r}: the projection's input differs from the model's kept rows"
    return ""
