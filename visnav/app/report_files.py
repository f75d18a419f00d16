"""Write a built report to a folder: report.json, report.md, report.html, the figures and the counterexamples.

A report replaces its folder whole (:func:`write_report`), so that the folder never mixes two runs:

1. every document and figure is rendered in memory (nothing is touched yet);
2. the files are written into a hidden sibling folder ``.NAME.partial-PID-XXXXXXXX`` (beside the
   folder ``NAME``, on the same file system), each atomically;
3. the two folders are exchanged in one atomic step (Linux ``renameat2(RENAME_EXCHANGE)``), and the
   old report, now under the partial name, is deleted.

An interruption at any point (Ctrl-C, an error, ``kill -9``) leaves ``NAME`` holding the complete
old report or the complete new one; what remains of the other is a sibling whose name says
``partial``, removed by the next write beside it.  Where the file system cannot exchange two
folders, the old one is renamed to ``.NAME.previous-PID-XXXXXXXX`` and the new one renamed in
(Ctrl-C is held back between the two renames; on an error the old one is put back); only a hard
kill between those two renames leaves ``NAME`` missing, the old report then complete in
``.NAME.previous-…`` (deleted by the next report that is swapped in).

Since the folder is replaced whole, it must hold a report and nothing else: ``report.json``,
``report.md``, ``report.html``, ``figures/*.png``, ``counterexamples/*.json`` (verification
counterexamples), partial files of ours (and a file browser's ``.DS_Store``).  Anything else, ``--out`` being the current folder (or
holding it), a mount point or a folder whose parent is not writable is refused with an
:class:`~visnav.app.files.OutputError` (:func:`check_report_folder`, called before the report is
built).  The counterexample files (``counterexamples/NAME.json``, re-run by ``visnav replay``) sit
next to the report, where its links point; the new folder keeps the old folder's mode.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import re
import secrets
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from visnav.app.files import (
    sigint_deferred,
    OutputError,
    clean_partial_files,
    figures_png,
    folder_mode,
    is_partial_name,
    output_error,
    partial_prefix,
    write_bytes_atomic,
    write_text_atomic,
)
from visnav.app.report import Report
from visnav.app.report_render import render_html, render_markdown
from visnav.app.verification_report import COUNTEREXAMPLE_DIR

__all__ = ["FIGURE_DIR", "REPORT_FILES", "report_json_text", "check_report_folder", "write_report"]

FIGURE_DIR = "figures"
"""Sub-folder of the figures, referenced by relative links from report.md."""

REPORT_FILES = ("report.md", "report.html", "report.json")
"""The documents, in the order they are written (report.json last)."""

_PREVIOUS = ".previous-"
"""Mark of the old report moved aside where the folders cannot be exchanged atomically."""

_MOST_LISTED = 5
"""Foreign entries named in the refusal (the others counted)."""

_DESKTOP_FILES = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
"""What a file browser writes into a folder it shows: not data, not refused (the swap drops it)."""


def report_json_text(report: Report) -> str:
    """``report.json``'s exact text: sorted keys, 1-space indent, trailing newline (byte-reproducible)."""
    return json.dumps(report.data, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


# --------------------------------------------------------------------------- the folder


def _legacy_partial(name: str, suffix: str) -> bool:
    """An earlier version's temporary file ``.X<suffix>.XXXXXXXX`` of a file ``X<suffix>``."""
    target = name[1:-9]
    return len(name) > 10 and name[-9] == "." and target.endswith(suffix) and is_partial_name(name, {target})


def _is_counterexample(path: str) -> bool:
    from visnav.app.cli_verify import is_verification_counterexample

    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            return is_verification_counterexample(handle.read(4096))
    except OSError:
        return False


def _foreign_entries(real: Path) -> list[str]:
    """What ``real`` holds that no report wrote (relative paths; a folder ends with ``/``)."""
    foreign: list[str] = []
    with os.scandir(real) as listing:
        entries = sorted(listing, key=lambda e: e.name)
    for entry in entries:
        name, is_dir = entry.name, entry.is_dir(follow_symlinks=False)
        if is_partial_name(name, set(REPORT_FILES)) or name in _DESKTOP_FILES:
            continue
        if name in REPORT_FILES and entry.is_file(follow_symlinks=False):
            continue
        if name in (FIGURE_DIR, COUNTEREXAMPLE_DIR) and is_dir:
            suffix = ".png" if name == FIGURE_DIR else ".json"
            with os.scandir(entry.path) as inner:
                for item in sorted(inner, key=lambda e: e.name):
                    if (is_partial_name(item.name) or _legacy_partial(item.name, suffix)
                            or item.name in _DESKTOP_FILES):
                        continue
                    ours = item.is_file(follow_symlinks=False) and item.name.endswith(suffix) and (
                        name == FIGURE_DIR or _is_counterexample(item.path))
                    if not ours:
                        foreign.append(f"{name}/{item.name}" + ("/" if item.is_dir(follow_symlinks=False) else ""))
            continue
        foreign.append(name + ("/" if is_dir else ""))
    return foreign


def check_report_folder(folder: str | os.PathLike[str]) -> Path:
    """Check that a report can replace ``folder`` (module docstring); return its real path.

    Raises
    ------
    OutputError
        ``folder`` is a file, the current folder or one holding it, a mount point, holds files that
        are not part of a report, or its parent is not writable: the message says what to change.
    """
    given = Path(folder)
    label = f"--out {str(given)!r}"
    real = Path(os.path.realpath(given))
    parent = real.parent
    if os.path.lexists(real) and not real.is_dir():
        raise OutputError(f"{label}: exists and is not a folder; choose a folder path")
    try:
        here: Path | None = Path(os.path.realpath(os.getcwd()))
    except OSError:  # the current folder was deleted: it cannot be this one
        here = None
    if here is not None and (here == real or real in here.parents):
        raise OutputError(f"{label} is the current folder or holds it; the report replaces the whole folder: "
                          "run visnav from outside it, or choose another --out")
    if real.is_dir():
        try:
            foreign = _foreign_entries(real)
            mount = real == parent or os.stat(real).st_dev != os.stat(parent).st_dev
        except OSError as err:
            raise output_error(real, err, "read the folder") from err
        if foreign:
            listed = ", ".join(foreign[:_MOST_LISTED]) + (
                f" and {len(foreign) - _MOST_LISTED} more" if len(foreign) > _MOST_LISTED else "")
            raise OutputError(f"{label} holds {len(foreign)} file(s) that are not part of a visnav report ({listed}); "
                              "the report replaces the whole folder, so that it never mixes two runs: move them "
                              "away, or choose an empty or new folder")
        if mount:
            raise OutputError(f"{label} is a mount point; the report is written beside the folder and swapped in, "
                              f"which cannot cross file systems: give a folder inside it (e.g. {str(given / 'report')!r})")
    if parent.is_dir() and not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{label}: its parent folder {str(parent)!r} is not writable; the report is written beside "
                          "the folder and swapped in: make the parent writable, or choose another --out")
    return real


# --------------------------------------------------------------------------- the swap


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100
_renameat2: Any = None


def _exchange(first: Path, second: Path) -> bool:
    """Exchange two existing paths in one atomic step (Linux ``renameat2``); ``False`` where unsupported."""
    global _renameat2
    if not sys.platform.startswith("linux"):
        return False
    if _renameat2 is None:
        try:
            function = ctypes.CDLL(None, use_errno=True).renameat2
        except (OSError, AttributeError):  # no renameat2 in this C library
            _renameat2 = False
            return False
        function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        function.restype = ctypes.c_int
        _renameat2 = function
    if _renameat2 is False:
        return False
    if _renameat2(_AT_FDCWD, os.fsencode(first), _AT_FDCWD, os.fsencode(second), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False  # this file system (or kernel) cannot exchange
    raise OSError(code, os.strerror(code), str(second))


def _swap_in(staging: Path, real: Path) -> Path | None:
    """Put the folder ``staging`` at ``real``; return where the old ``real`` now is (``None``: there was none)."""
    if not os.path.lexists(real):
        os.rename(staging, real)
        return None
    if _exchange(staging, real):
        return staging
    previous = real.with_name(f".{real.name[:180]}{_PREVIOUS}{os.getpid()}-{secrets.token_hex(4)}")
    os.rename(real, previous)
    try:
        os.rename(staging, real)
    except BaseException:
        os.rename(previous, real)
        raise
    return previous


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _remove(path: Path) -> None:
    """Delete a folder; interrupted, finish it first (the folder it belonged to is already complete)."""
    try:
        shutil.rmtree(path, ignore_errors=True)
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)
        raise


def _remove_previous(parent: Path, name: str) -> None:
    """Delete the old reports a hard kill left moved aside (``.NAME.previous-PID-X``) by writers no longer running."""
    pattern = re.compile(rf"^\.{re.escape(name[:180])}{re.escape(_PREVIOUS)}(\d+)-[0-9a-f]{{8}}$")
    with contextlib.suppress(OSError), os.scandir(parent) as listing:
        for entry in list(listing):
            found = pattern.match(entry.name)
            if found and entry.is_dir(follow_symlinks=False) and int(found.group(1)) != os.getpid():
                try:
                    os.kill(int(found.group(1)), 0)
                except ProcessLookupError:
                    _remove(parent / entry.name)
                except (OverflowError, OSError):
                    pass


# --------------------------------------------------------------------------- writing


def _documents(report: Report, png: dict[str, bytes]) -> dict[str, str]:
    paths = {stem: f"{FIGURE_DIR}/{stem}.png" for stem in png}
    return {"report.md": render_markdown(report.data, paths), "report.html": render_html(report.data, png),
            "report.json": report_json_text(report)}


def _write_into(staging: Path, report: Report, png: dict[str, bytes], documents: dict[str, str]) -> list[str]:
    """Write every file under ``staging``: figures, counterexample files, then the documents; their relative paths."""
    written: list[str] = []
    (staging / FIGURE_DIR).mkdir()
    for stem in sorted(png):
        relative = f"{FIGURE_DIR}/{stem}.png"
        write_bytes_atomic(staging / relative, png[stem])
        written.append(relative)
    for relative in sorted(report.files):
        path = staging / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, report.files[relative])
        written.append(relative)
    for name in REPORT_FILES:
        write_text_atomic(staging / name, documents[name])
        written.append(name)
    return written


def write_report(report: Report, folder: str | os.PathLike[str]) -> list[Path]:
    """Write the report as the whole content of ``folder`` (module docstring); return the paths written.

    The folder's earlier content (a report, :func:`check_report_folder`) is replaced in one atomic
    step once every new file is written: counterexample or figure files the new report does not
    have are gone with it.  ``folder`` is created if needed.

    Raises
    ------
    OutputError
        The folder cannot be replaced (:func:`check_report_folder`) or a file cannot be written
        (disk full, permission denied): the message names the path and the fix; the folder is
        left as it was.
    """
    given = Path(folder)
    real = check_report_folder(given)
    parent = real.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise output_error(parent, err, "create the folder") from err
    clean_partial_files(parent, again=True)  # what interrupted reports beside this one left
    png = figures_png(report.figures)
    documents = _documents(report, png)
    mode = stat.S_IMODE(os.stat(real).st_mode) if real.is_dir() else folder_mode()
    try:
        staging = Path(tempfile.mkdtemp(prefix=partial_prefix(real.name), dir=parent))
    except OSError as err:
        raise output_error(parent, err, "create a folder in") from err
    swapped, old = False, None
    try:
        os.chmod(staging, mode)
        written = _write_into(staging, report, png, documents)
        _fsync_dir(staging)
        with sigint_deferred():
            old = _swap_in(staging, real)
            swapped = True
    except BaseException as err:
        if not swapped:
            _remove(staging)
        elif old is not None:
            _remove(old)
        if isinstance(err, OSError):  # named by where the file was going (not the hidden partial folder)
            wrapped = output_error(given, err, "write the report into")
            kept = "the folder is left as it was" if not swapped else "the new report is in place"
            out = OutputError(f"{str(wrapped).replace(str(staging), str(given))}; {kept}")
            out.errno = wrapped.errno
            raise out from err
        raise
    _fsync_dir(parent)
    if old is not None:
        _remove(old)
    _remove_previous(parent, real.name)
    return [given / relative for relative in written]
