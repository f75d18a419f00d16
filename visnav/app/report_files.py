"""Write a built report to a folder: report.json, report.md, report.html, the figures and the counterexamples.

Every file is written atomically; the counterexample files (``counterexamples/NAME.json``,
re-run by ``visnav replay``) sit next to the report, where its links point.
"""

from __future__ import annotations

import json
from pathlib import Path

from visnav.app.files import figures_png, write_png, write_text_atomic
from visnav.app.report import Report
from visnav.app.report_render import render_html, render_markdown
from visnav.app.verification_report import COUNTEREXAMPLE_DIR

__all__ = ["FIGURE_DIR", "report_json_text", "write_report"]

FIGURE_DIR = "figures"
"""Sub-folder of the figures, referenced by relative links from report.md."""


def report_json_text(report: Report) -> str:
    """``report.json``'s exact text: sorted keys, 1-space indent, trailing newline (byte-reproducible)."""
    return json.dumps(report.data, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


def _write_files(report: Report, folder: Path) -> list[Path]:
    """The report's own files (counterexamples), and the removal of stale counterexample files of an earlier run."""
    from visnav.app.cli_verify import is_verification_counterexample

    written = []
    for relative in sorted(report.files):
        path = folder / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, report.files[relative])
        written.append(path)
    stale_dir = folder / COUNTEREXAMPLE_DIR
    if stale_dir.is_dir():
        for path in sorted(stale_dir.glob("*.json")):
            if path not in written and is_verification_counterexample(path.read_text(errors="replace")):
                path.unlink()
    return written


def write_report(report: Report, folder: Path) -> list[Path]:
    """Write the report into ``folder`` (which must exist and be writable); returns the paths written.

    Every file is written atomically (temporary file + rename), figures and
    counterexample files first, ``report.json`` last, so an interrupted write
    never leaves a report.json that points at missing files.  Counterexample
    files of an earlier report in the same folder that this one does not have
    are removed (its links would otherwise be wrong).
    """
    figure_dir = folder / FIGURE_DIR
    figure_dir.mkdir(parents=True, exist_ok=True)
    png = figures_png(report.figures)
    written = list(write_png(figure_dir, png).values())
    written += _write_files(report, folder)
    paths = {stem: f"{FIGURE_DIR}/{stem}.png" for stem in png}
    for name, text in (("report.md", render_markdown(report.data, paths)),
                       ("report.html", render_html(report.data, png)),
                       ("report.json", report_json_text(report))):
        write_text_atomic(folder / name, text)
        written.append(folder / name)
    return written
