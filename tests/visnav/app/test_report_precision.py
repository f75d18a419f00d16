"""The report prints only digits its computations defend: round-off never reaches its bytes.

Two checks of :mod:`visnav.app.precision` on the quick report of the paper scenario:

* every float the sections compute is moved by a few ulps (``np.nextafter``) before the policy rounds
  it: report.json, report.md and the figures must not change (a number printed with digits that
  round-off decides would);
* the report written by a process whose BLAS runs 2 threads (OpenBLAS splits LAPACK work and so
  changes the round-off) is byte-identical to the one of the console script (1 thread).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.app import precision
from visnav.app import report as report_module
from visnav.app import verification_report
from visnav.app.files import figures_png
from visnav.app.report import ReportOptions, build_report
from visnav.app.report_files import report_json_text
from visnav.app.report_render import render_markdown

ROOT = Path(__file__).resolve().parents[3]
ULPS = 3
"""How far every float is moved, in units in the last place (both ways)."""
PRE_ROUNDED = frozenset({"simulation", "analysis", "stiffness", "campaign"})
"""Sections whose numbers :mod:`visnav.app.report` rounds before it writes their claims."""


def _nudge(value: float, ulps: int) -> float:
    """``value`` moved by ``ulps`` units in the last place; an exact zero is kept (its ulp is a subnormal 5e-324:
    not a model of round-off, which leaves a zero computed by cancellation at ~1e-16 of the terms, what the
    absolute resolutions of the policy's kinds are for)."""
    x = float(value)
    if not np.isfinite(x) or x == 0.0:
        return x
    for _ in range(abs(ulps)):
        x = float(np.nextafter(x, np.inf if ulps > 0 else -np.inf))
    return x


def _nudge_tree(data: Any, path: str, ulps: int, moved: list[str]) -> Any:
    """Every float leaf moved by ``ulps`` (its path appended to ``moved``), except the counterexamples kept bit
    for bit (kind ``replay``: drawn, not computed)."""
    if isinstance(data, dict):
        return {k: _nudge_tree(v, f"{path}/{k}", ulps, moved) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_nudge_tree(v, path, ulps, moved) for v in data]
    if isinstance(data, float) and data != 0.0 and precision.kind_of(path) != "replay":
        moved.append(path)
        return _nudge(data, ulps)
    return data


def _leaf_differences(a: Any, b: Any, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _leaf_differences(a.get(k), b.get(k), f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _leaf_differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def _quick_report_nudged(ulps: int, monkeypatch: pytest.MonkeyPatch
                         ) -> tuple[str, str, dict[str, bytes], list[str]]:
    """The quick report built with every computed float moved by ``ulps`` before the policy rounds it; the
    documents, the figures and the paths of the floats moved."""
    real_section, real_value = precision.round_section, precision.round_value
    moved: list[str] = []

    def round_section(name: str, data: Any) -> dict[str, Any]:  # where a section's numbers are first rounded
        return real_section(name, _nudge_tree(data, name, ulps, moved))

    def assembled(name: str, data: Any) -> dict[str, Any]:  # the assembly rounds every section again:
        if name in PRE_ROUNDED:  # idempotent on what report.py rounded already (not nudged twice)
            return real_section(name, data)
        return round_section(name, data)

    def round_value(value: float, kind: Any) -> float:
        return real_value(_nudge(value, ulps) if kind != "replay" else value, kind)

    monkeypatch.setattr(report_module, "round_section", round_section)
    monkeypatch.setattr(verification_report, "round_section", assembled)
    for module in (report_module, verification_report):
        monkeypatch.setattr(module, "round_value", round_value)
    from visnav.scenario import load_scenario

    built = build_report(load_scenario("paper"), ReportOptions.for_mode(quick=True), source="paper")
    png = figures_png(built.figures)
    paths = {stem: f"figures/{stem}.png" for stem in png}
    monkeypatch.undo()
    return report_json_text(built), render_markdown(built.data, paths), png, moved


def test_a_few_ulps_do_not_change_the_rendered_report(monkeypatch):
    up = _quick_report_nudged(+ULPS, monkeypatch)
    down = _quick_report_nudged(-ULPS, monkeypatch)
    sections = {path.split("/")[0] for path in up[3]}
    assert len(up[3]) > 3000 and {"verification", "simulation", "analysis", "stiffness", "campaign"} <= sections
    differences = _leaf_differences(json.loads(up[0]), json.loads(down[0]))
    assert not differences, f"{len(differences)} leaves print round-off: {differences[:10]}"
    assert up[0] == down[0]
    assert up[1] == down[1], "report.md differs"
    assert sorted(up[2]) == sorted(down[2])
    for stem in up[2]:
        assert up[2][stem] == down[2][stem], f"figures/{stem}.png differs"


_TWO_THREADS = """
import ctypes, glob, os, sys
import numpy  # loaded with OPENBLAS_NUM_THREADS=2: the CLI's own setting (1) comes too late to change it
from visnav.app.entry import main
sys.argv = ["visnav", "report", "--scenario", "paper", "--quick", "--out", sys.argv[1]]
code = main()
libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), "..", "numpy.libs", "*openblas*"))
blas = ctypes.CDLL(libs[0]) if libs else None
if blas is not None:
    blas.scipy_openblas_get_corename64_.restype = ctypes.c_char_p
    print(f"blas-threads={blas.scipy_openblas_get_num_threads64_()}", file=sys.stderr)
    print(f"blas-core={blas.scipy_openblas_get_corename64_().decode()}", file=sys.stderr)
sys.exit(code)
"""


def test_two_blas_threads_write_the_same_report(tmp_path, report_tools):
    """A process whose BLAS runs 2 threads writes the bytes the console script (1 thread) writes."""
    from visnav.app.cli import REPORT_NUMERICS

    one = tmp_path / "one"
    done = report_tools.run(one, "--quick")
    report_tools.exit_is_the_verdicts(done, one)
    two = tmp_path / "two"
    env = {**os.environ, **REPORT_NUMERICS, "PYTHONHASHSEED": "7", "OPENBLAS_NUM_THREADS": "2",
           "OMP_NUM_THREADS": "2"}
    done = subprocess.run([sys.executable, "-c", _TWO_THREADS, str(two)], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=900)
    report_tools.exit_is_the_verdicts(done, two)
    if "blas-threads=" in done.stderr:  # numpy's OpenBLAS found: it did run 2 threads, on the pinned kernels
        assert "blas-threads=2" in done.stderr, done.stderr[-2000:]
        assert f"blas-core={REPORT_NUMERICS['OPENBLAS_CORETYPE']}" in done.stderr, done.stderr[-2000:]
    for name in ("report.json", "report.md", "report.html"):
        assert (one / name).read_bytes() == (two / name).read_bytes(), name
    assert report_tools.counterexamples(one) == report_tools.counterexamples(two)
    for png in sorted((one / "figures").glob("*.png")):
        assert png.read_bytes() == (two / "figures" / png.name).read_bytes(), png.name


def test_the_report_command_pins_its_numerics_before_numpy_loads():
    """``visnav report`` pins numpy's SIMD dispatch and OpenBLAS's kernels (visnav.app.cli.REPORT_NUMERICS); the
    command-line modules load no numpy before it does, and other commands are left alone."""
    from visnav.app.cli import REPORT_NUMERICS

    probe = ("import os, sys; import visnav.app.entry, visnav.app.cli as cli; loaded = 'numpy' in sys.modules; "
             "cli._pinned_report_numerics(sys.argv[1:]); "
             "print(loaded, os.environ.get('OPENBLAS_CORETYPE'), os.environ.get('NPY_DISABLE_CPU_FEATURES'))")
    env = {k: v for k, v in os.environ.items() if k not in REPORT_NUMERICS}
    for args, pinned in ((["report", "--quick"], True), (["simulate"], False)):
        done = subprocess.run([sys.executable, "-c", probe, *args], capture_output=True, text=True, env=env,
                              cwd=ROOT, timeout=120, check=True)
        expected = (f"False {REPORT_NUMERICS['OPENBLAS_CORETYPE']} {REPORT_NUMERICS['NPY_DISABLE_CPU_FEATURES']}"
                    if pinned else "False None None")
        assert done.stdout.strip() == expected, (args, done.stdout, done.stderr)
