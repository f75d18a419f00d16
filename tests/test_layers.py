"""Imports go downward only (visnav -> analysis -> hybrid); library code never imports plotting."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize("package, forbidden", [
    ("hybrid", ("visnav", "analysis", "matplotlib")),
    ("analysis", ("visnav", "matplotlib")),
    ("visnav.simulation", ("matplotlib",)),
])
def test_import_does_not_pull_upper_layers(package, forbidden):
    code = (
        f"import sys, {package}; bad = [m for m in {forbidden!r} if m in sys.modules]; "
        "print(','.join(bad)); sys.exit(1 if bad else 0)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, f"{package} imported {proc.stdout.strip()}"
