"""visnav.fuzzing.registry: every property named, documented and budgeted."""

from __future__ import annotations

import pytest

from visnav.fuzzing.registry import PROPERTIES, budget, property_names


def test_registry_documents_every_property():
    assert property_names("scenario") == ("no_collision", "classified_outcome", "closed_loop_continuity",
                                          "reconstruction_bounded", "blend_weights")
    for p in PROPERTIES.values():
        assert p.summary and p.summary.endswith(".") and len(p.doc) > 100, p.name
        assert p.ci_examples >= 15


def test_budgets():
    assert budget("mu_range") == PROPERTIES["mu_range"].ci_examples == 120
    assert budget("mu_range", "dev") == 24 and budget("closed_loop_continuity", "dev") == 5
    with pytest.raises(ValueError, match="budget profile 'z'"):
        budget("mu_range", "z")
