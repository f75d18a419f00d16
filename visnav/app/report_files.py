"""Write a built report to a folder: report.json, report.md, report.html and the figures (atomically)."""

from __future__ import annotations

import json
from pathlib import Path

from visnav.app.files import figures_png, write_png, write_text_atomic
from visnav.app.report import Report
from visnav.app.report_render import render_html, render_markdown

__all__ = ["report_json_text", "write_report"]

FIGURE_DIR = "figures"
"""Sub-folder of the figures, referenced by relative links from report.md."""


def report_json_text(report: Report) -> str:
    """``report.json``'s exact text: sorted keys, 1-space indent, trailing newline (byte-reproducible)."""
    return json.dumps(report.data, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


def write_report(report: Report, folder: Path) -> list[Path]:
    """Write the report into ``folder`` (which must exist and be writable); returns the paths written.

    Every file is written atomically (temporary file + rename), figures first,
    ``report.json`` last, so an interrupted write never leaves a report.json
    that points at missing figures.
    """
    figure_dir = folder / FIGURE_DIR
    figure_dir.mkdir(parents=True, exist_ok=True)
    png = figures_png(report.figures)
    written = list(write_png(figure_dir, png).values())
    paths = {stem: f"{FIGURE_DIR}/{stem}.png" for stem in png}
    for name, text in (("report.md", render_markdown(report.data, paths)),
                       ("report.html", render_html(report.data, png)),
                       ("report.json", report_json_text(report))):
        write_text_atomic(folder / name, text)
        written.append(folder / name)
    return written
