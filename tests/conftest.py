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
