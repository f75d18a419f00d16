"""The supervisors the fuzzer can drive, by name: the resolved automaton, the paper as written, the mutants.

:data:`VARIANTS` lists the names :func:`make_variant` accepts (``visnav fuzz
--variant NAME``): :data:`RESOLVED` (:mod:`visnav.supervisor`), :data:`PAPER`
(:mod:`visnav.fuzzing.paper_logic`) and the planted defects of
:mod:`visnav.fuzzing.mutants`.
"""

from __future__ import annotations

import functools

from visnav.fuzzing.mutants import MUTANTS, RESOLVED, SupervisorVariant, build_variant
from visnav.fuzzing.paper_logic import PAPER, paper_variant
from visnav.fuzzing.space import MeasurementSpace
from visnav.parameters import Envelopes, SupervisorSettings

__all__ = ["RESOLVED", "PAPER", "VARIANTS", "make_variant", "variant_for", "variant_flags"]

VARIANTS = (RESOLVED, PAPER, *MUTANTS)
"""Names accepted by :func:`make_variant`."""


@functools.lru_cache(maxsize=64)
def make_variant(
    name: str, envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int
) -> SupervisorVariant:
    """``"resolved"``, ``"paper"`` (as written) or a mutant of :data:`visnav.fuzzing.mutants.MUTANTS` (cached).

    Raises
    ------
    KeyError
        Unknown name; the message lists :data:`VARIANTS`.
    """
    if name == PAPER:
        return paper_variant(envelopes, settings, n_obstacles)
    if name not in VARIANTS:
        raise KeyError(f"unknown supervisor variant {name!r}; known: {', '.join(VARIANTS)}")
    return build_variant(name, envelopes, settings, n_obstacles)


def variant_for(name: str, space: MeasurementSpace) -> SupervisorVariant:
    """:func:`make_variant` for the envelopes, settings and obstacle count of ``space``."""
    return make_variant(name, space.envelopes, space.settings, space.n_obstacles)


def variant_flags(variant: SupervisorVariant, mode: str) -> tuple[int, int, int]:
    """``(AVOID, LEAVE, OCCLU)`` of ``mode`` in ``variant``."""
    f = variant.model.flags(mode)
    return f["AVOID"], f["LEAVE"], f["OCCLU"]
