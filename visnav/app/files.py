"""Atomic file output used by the CLI and report rendering (never by library code)."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

__all__ = [
    "OutputError", "prepare_output_dir", "write_bytes_atomic", "write_text_atomic", "figure_png_bytes",
    "figures_png", "write_png", "write_figures",
]


class OutputError(OSError):
    """An output folder or file cannot be written."""


def prepare_output_dir(path: str | os.PathLike[str]) -> Path:
    """Create ``path`` if needed and check that it is a writable folder."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"--out {str(folder)!r}: exists and is not a folder; choose a folder path")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"--out {str(folder)!r}: cannot create the folder ({err.strerror}); choose a writable path") from err
    if not folder.is_dir():
        raise OutputError(f"--out {str(folder)!r}: exists and is not a folder; choose a folder path")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"--out {str(folder)!r}: folder is not writable; choose a writable path")
    return folder


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """UTF-8 text version of :func:`write_bytes_atomic`."""
    write_bytes_atomic(path, text.encode("utf-8"))


def figure_png_bytes(figure: object, dpi: int = 120) -> bytes:
    """PNG bytes of a matplotlib figure (deterministic metadata)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})  # type: ignore[attr-defined]
    return buffer.getvalue()


def figures_png(figures: dict[str, object]) -> dict[str, bytes]:
    """PNG bytes of each figure (:func:`figure_png_bytes`), by stem; the figures are closed."""
    import matplotlib.pyplot as plt

    out: dict[str, bytes] = {}
    for stem in sorted(figures):
        out[stem] = figure_png_bytes(figures[stem])
        plt.close(figures[stem])  # type: ignore[arg-type]
    return out


def write_png(folder: Path, png: dict[str, bytes]) -> dict[str, Path]:
    """Write each image as ``folder/<stem>.png`` (atomically, sorted by stem); the paths by stem."""
    written: dict[str, Path] = {}
    for stem in sorted(png):
        path = Path(folder) / f"{stem}.png"
        write_bytes_atomic(path, png[stem])
        written[stem] = path
    return written


def write_figures(folder: Path, figures: dict[str, object]) -> dict[str, Path]:
    """Render (:func:`figures_png`) and write (:func:`write_png`) matplotlib figures."""
    return write_png(folder, figures_png(figures))
