"""Write a built report to a folder: report.json, report.md, report.html and the figures (atomically)."""

from __future__ import annotations

import json
from pathlib import Path

from .io import figure_png_bytes, write_bytes_atomic, write_text_atomic
from .report import Report
from .report_render import render_html, render_markdown

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
    import matplotlib.pyplot as plt

    figure_dir = folder / FIGURE_DIR
    figure_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    png: dict[str, bytes] = {}
    for stem in sorted(report.figures):
        data = figure_png_bytes(report.figures[stem])
        plt.close(report.figures[stem])
        png[stem] = data
        path = figure_dir / f"{stem}.png"
        write_bytes_atomic(path, data)
        written.append(path)
    paths = {stem: f"{FIGURE_DIR}/{stem}.png" for stem in png}
    for name, text in (("report.md", render_markdown(report.data, paths)),
                       ("report.html", render_html(report.data, png)),
                       ("report.json", report_json_text(report))):
        write_text_atomic(folder / name, text)
        written.append(folder / name)
    return written
