"""The supervisors the fuzzer can drive, by name: the resolved automaton, the paper as written, the mutants.

:data:`VARIANTS` lists the names :func:`make_variant` accepts (``visnav fuzz
--variant NAME``): :data:`RESOLVED` (:mod:`visnav.supervisor`), :data:`PAPER`
(:mod:`visnav.fuzzing.paper_logic`), the planted defects of
:mod:`visnav.fuzzing.mutants` and the closed-loop mutants of
:mod:`visnav.fuzzing.loop_mutants` (whose supervisor is the resolved one: the
signal properties hold on them by construction, the closed-loop properties
run the mutated loop).
"""

from __future__ import annotations

import dataclasses
import functools

from visnav.fuzzing.loop_mutants import LOOP_MUTANTS
from visnav.fuzzing.mutants import MUTANTS, RESOLVED, SupervisorVariant, build_variant
from visnav.fuzzing.paper_logic import PAPER, paper_variant
from visnav.fuzzing.space import MeasurementSpace
from visnav.parameters import Envelopes, SupervisorSettings

__all__ = ["RESOLVED", "PAPER", "VARIANTS", "make_variant", "variant_for", "variant_flags"]

VARIANTS = (RESOLVED, PAPER, *MUTANTS, *LOOP_MUTANTS)
"""Names accepted by :func:`make_variant`."""


@functools.lru_cache(maxsize=64)
def make_variant(
    name: str, envelopes: Envelopes, settings: SupervisorSettings, n_obstacles: int
) -> SupervisorVariant:
    """``"resolved"``, ``"paper"`` (as written), a mutant of :data:`visnav.fuzzing.mutants.MUTANTS` (cached),
    or the resolved supervisor under the name of a loop mutant (:data:`visnav.fuzzing.loop_mutants.LOOP_MUTANTS`).

    Raises
    ------
    KeyError
        Unknown name; the message lists :data:`VARIANTS`.
    """
    if name == PAPER:
        return paper_variant(envelopes, settings, n_obstacles)
    if name not in VARIANTS:
        raise KeyError(f"unknown supervisor variant {name!r}; known: {', '.join(VARIANTS)}")
    if name in LOOP_MUTANTS:  # the resolved supervisor; the mutant is in the loop (visnav.fuzzing.closed_loop)
        resolved = build_variant(RESOLVED, envelopes, settings, n_obstacles)
        return dataclasses.replace(resolved, name=name, description=f"the resolved supervisor in a loop where "
                                   f"{LOOP_MUTANTS[name]} (loop mutant)")
    return build_variant(name, envelopes, settings, n_obstacles)


def variant_for(name: str, space: MeasurementSpace) -> SupervisorVariant:
    """:func:`make_variant` for the envelopes, settings and obstacle count of ``space``."""
    return make_variant(name, space.envelopes, space.settings, space.n_obstacles)


def variant_flags(variant: SupervisorVariant, mode: str) -> tuple[int, int, int]:
    """``(AVOID, LEAVE, OCCLU)`` of ``mode`` in ``variant``."""
    f = variant.model.flags(mode)
    return f["AVOID"], f["LEAVE"], f["OCCLU"]
