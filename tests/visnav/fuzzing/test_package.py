"""The package ``visnav.fuzzing``: names load on first use; ``replay`` stays the function."""

from __future__ import annotations

import subprocess
import sys


def test_every_exported_name_resolves_and_replay_is_the_function():
    code = ("import visnav.fuzzing.replay; import visnav.fuzzing as f; "
            "assert callable(f.replay) and f.replay.__module__ == 'visnav.fuzzing.replay', f.replay; "
            "from visnav.fuzzing import replay; assert replay is f.replay; "
            "missing = [n for n in f.__all__ if getattr(f, n, None) is None]; assert not missing, missing; "
            "print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_the_measurement_space_does_not_load_the_closed_loop():
    code = ("import sys; import visnav.fuzzing.space; "
            "print(sorted(m for m in ('visnav.fuzzing.closed_loop', 'scipy.integrate', 'hybrid.sampled') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"
