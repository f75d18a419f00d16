"""The committed ``reports/paper/`` is what the README's main job writes: regenerated and compared byte for byte.

A file of its own so that the suite's longest test (the full report, ~4 minutes) runs on one
worker while the quick-report tests of ``test_report.py`` run on another (``make test`` runs
pytest-xdist with ``--dist loadfile``).
"""

from __future__ import annotations

import json

import pytest

from visnav.app.verification_report import dependency_versions


def test_committed_paper_report_regenerates(tmp_path, report_tools):
    """reports/paper is the output of the README's main job; regenerating it must give the same bytes."""
    COMMITTED = report_tools.committed
    committed = json.loads((COMMITTED / "report.json").read_text())
    done = report_tools.run(tmp_path)  # the main job runs whatever the versions: it must complete
    report_tools.exit_is_the_verdicts(done, tmp_path)
    if committed["meta"]["versions"] != dependency_versions():
        differ = {k: (v, dependency_versions().get(k)) for k, v in committed["meta"]["versions"].items()
                  if dependency_versions().get(k) != v}
        pytest.skip(f"the report ran; its bytes are not compared: reports/paper was generated with other "
                    f"package versions {differ}: regenerate it with `make demo` on this machine")
    for name in ("report.json", "report.md"):  # byte for byte: every number rounded by visnav.app.precision
        assert (tmp_path / name).read_bytes() == (COMMITTED / name).read_bytes(), (
            f"{name} differs from reports/paper/{name}: the report changed; regenerate it with `make demo` and "
            "review the diff")
    assert report_tools.counterexamples(tmp_path) == report_tools.counterexamples(COMMITTED), (
        "reports/paper/counterexamples/ differs: regenerate it with `make demo` and review the diff")
    # every figure too: drawn from the numbers the rounding policy keeps (docs/report.md)
    pngs = sorted(p.name for p in (tmp_path / "figures").glob("*.png"))
    assert pngs == sorted(p.name for p in (COMMITTED / "figures").glob("*.png")), "the figures differ in name"
    differ = [name for name in pngs
              if (tmp_path / "figures" / name).read_bytes() != (COMMITTED / "figures" / name).read_bytes()]
    assert not differ, (f"reports/paper/figures/ differs in {differ}: regenerate it with `make demo` and review "
                        "the diff")
    # report.html embeds the figures: the same bytes once they and report.md are
    assert (tmp_path / "report.html").read_bytes() == (COMMITTED / "report.html").read_bytes()
