"""The package ``hybrid``: every exported name resolves; the executors load on first use only."""

from __future__ import annotations

import subprocess
import sys

import hybrid


def test_every_exported_name_resolves():
    for name in hybrid.__all__:
        assert getattr(hybrid, name) is not None, name
    assert hybrid.simulate_continuous.__module__ == "hybrid.continuous"
    assert hybrid.settle.__module__ == "hybrid.sampled"
    assert set(hybrid.__all__) <= set(dir(hybrid))


def test_an_unknown_name_is_an_attribute_error():
    try:
        hybrid.no_such_name  # noqa: B018
    except AttributeError as err:
        assert "no_such_name" in str(err)
    else:  # pragma: no cover
        raise AssertionError("expected AttributeError")


def test_a_structural_check_does_not_load_the_integrators():
    code = ("import sys; import hybrid; from hybrid import check, decide; "
            "print(sorted(m for m in ('scipy.integrate', 'scipy.optimize', 'hybrid.continuous', 'hybrid.sampled') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"
