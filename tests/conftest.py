"""Test configuration: hypothesis profiles.

Hypothesis loads its built-in ``ci`` profile (derandomised, no deadline) by
itself when the ``CI`` environment variable is set; locally we use a fast
``dev`` profile.
"""

import os

from hypothesis import settings

settings.register_profile("dev", max_examples=40, deadline=None)
if not os.environ.get("CI"):
    settings.load_profile("dev")

LONGEST_FIRST = ("test_report_committed.py", "test_report.py")
"""Test files that take minutes (each regenerates a report): collected first, so that with
``--dist loadfile`` each starts at once on its own worker and the short files fill in around them,
instead of one of them starting last and running alone (the CI budget is 10 minutes)."""


def pytest_collection_modifyitems(session, config, items):
    """Move the items of :data:`LONGEST_FIRST` to the front, keeping every other order."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest keeps its order
