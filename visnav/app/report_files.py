"""Write a built report to a folder: report.json, report.md, report.html, the figures and the counterexamples.

A report replaces its folder whole (:func:`write_report`), so that the folder never mixes two runs:

1. every document and figure is rendered in memory (nothing is touched yet);
2. the files are written into a hidden sibling folder ``.NAME.partial-PID-XXXXXXXX`` (beside the
   folder ``NAME``, on the same file system), whose first file is a marker proving that visnav
   created it (:data:`~visnav.app.ownership.PARTIAL_MARKER`) and whose last is the manifest
   (:data:`~visnav.app.ownership.MANIFEST_NAME`: every file with its size and SHA-256);
3. the folder ``NAME`` is checked again (a file saved into it during the run refuses the swap), the
   two folders are exchanged in one atomic step (Linux ``renameat2(RENAME_EXCHANGE)``), and the old
   report, now under the partial name, is deleted if its manifest still proves every file in it
   visnav's (else it is put back and the run refused).

Only a folder visnav wrote may be replaced: ``NAME`` must be absent, empty, or hold a valid
manifest whose files all still have their recorded bytes and nothing else (a file browser's
``.DS_Store`` aside).  Anything else -- a user's own ``report.md``, an extra or a modified file, a
folder an earlier visnav wrote without a manifest -- is refused with an
:class:`~visnav.app.files.OutputError` naming the files (:func:`check_report_folder`, called before
the report is built and again right before the swap); nothing is deleted.  So are ``--out`` being
the current folder (or holding it), a mount point and a folder whose parent is not writable.

An interruption at any point (Ctrl-C, an error, ``kill -9``) leaves ``NAME`` holding the complete
old report or the complete new one; what remains of the other is a sibling whose name says
``partial`` and which holds the marker or a complete manifest: the next report of ``NAME`` deletes
it once its writer no longer runs (:func:`~visnav.app.ownership.remove_stale_partials`); a folder that
only has such a name is never deleted.  Where the file system cannot exchange two folders, the old
one is renamed to ``.NAME.previous-PID-XXXXXXXX`` and the new one renamed in (Ctrl-C is held back
between the two renames; on an error the old one is put back); only a hard kill between those two
renames leaves ``NAME`` missing, the old report then complete in ``.NAME.previous-…`` (deleted by the
next report that is swapped in, its manifest proving it visnav's).  The counterexample files
(``counterexamples/NAME.json``, re-run by ``visnav replay``) sit next to the report, where its links
point; the new folder keeps the old folder's mode.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import secrets
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import Any

from visnav.app.files import (
    sigint_deferred,
    OutputError,
    figures_png,
    folder_mode,
    output_error,
    partial_prefix,
    write_bytes_atomic,
    write_text_atomic,
)
from visnav.app.ownership import (
    MANIFEST_NAME,
    PARTIAL_MARKER,
    describe_entries,
    mark_partial,
    remove_stale_partials,
    unowned_entries,
    write_manifest,
)
from visnav.app.report import Report
from visnav.app.report_render import render_html, render_markdown

__all__ = ["FIGURE_DIR", "REPORT_FILES", "report_json_text", "check_report_folder", "write_report"]

FIGURE_DIR = "figures"
"""Sub-folder of the figures, referenced by relative links from report.md."""

REPORT_FILES = ("report.md", "report.html", "report.json")
"""The documents, in the order they are written (report.json last)."""

_PREVIOUS = ".previous-"
"""Mark of the old report moved aside where the folders cannot be exchanged atomically."""

_MOST_LISTED = 5
"""Foreign entries named in the refusal (the others counted)."""



def report_json_text(report: Report) -> str:
    """``report.json``'s exact text: sorted keys, 1-space indent, trailing newline (byte-reproducible)."""
    return json.dumps(report.data, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


# --------------------------------------------------------------------------- the folder


def check_report_folder(folder: str | os.PathLike[str], shown: str | os.PathLike[str] | None = None) -> Path:
    """Check that a report can replace ``folder`` (module docstring); return its real path.

    ``shown``: the folder as the messages name it (the ``--out`` the user gave; default ``folder``).

    Raises
    ------
    OutputError
        ``folder`` is a file, the current folder or one holding it, a mount point, holds files that
        are not part of a report, or its parent is not writable: the message says what to change.
    """
    given = Path(folder)
    label = f"--out {str(given if shown is None else shown)!r}"
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
            foreign = unowned_entries(real)
            mount = real == parent or os.stat(real).st_dev != os.stat(parent).st_dev
        except OSError as err:
            raise output_error(real, err, "read the folder") from err
        if foreign:
            listed = describe_entries(foreign, _MOST_LISTED)
            raise OutputError(f"{label} holds {len(foreign)} file(s) that are not part of a visnav report ({listed}): "
                              f"not listed with their bytes in a {MANIFEST_NAME} that visnav wrote; the report "
                              "replaces the whole folder, and only a folder visnav wrote or an empty one: move them "
                              "away, or choose another --out (a new or empty folder)")
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


# --------------------------------------------------------------------------- writing


def _documents(report: Report, png: dict[str, bytes]) -> dict[str, str]:
    paths = {stem: f"{FIGURE_DIR}/{stem}.png" for stem in png}
    return {"report.md": render_markdown(report.data, paths), "report.html": render_html(report.data, png),
            "report.json": report_json_text(report)}


def _write_into(staging: Path, report: Report, png: dict[str, bytes], documents: dict[str, str]) -> list[str]:
    """Write every file under ``staging``: figures, counterexample files, the documents, then the manifest (last);
    the relative paths of the files (not the manifest)."""
    written: list[str] = []
    (staging / FIGURE_DIR).mkdir()
    for stem in sorted(png):
        relative = f"{FIGURE_DIR}/{stem}.png"
        write_bytes_atomic(staging / relative, png[stem])
        written.append(relative)
    for relative in sorted(report.files):
        parts = relative.split("/")
        if relative.startswith("/") or any(p in ("", ".", "..") for p in parts) or "\\" in relative:
            raise OutputError(f"the report's file {relative!r} would leave its folder; this is a defect of visnav")
        path = staging / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, report.files[relative])
        written.append(relative)
    for name in REPORT_FILES:
        write_text_atomic(staging / name, documents[name])
        written.append(name)
    write_manifest(staging, written, "report")
    os.unlink(staging / PARTIAL_MARKER)  # complete: its manifest now proves it visnav's
    return written


def _refusal(label: str, entries: list[str], when: str) -> OutputError:
    return OutputError(f"{label}: {len(entries)} file(s) were saved into the folder or changed {when} "
                       f"({describe_entries(entries, _MOST_LISTED)}); nothing was deleted and the folder is left as "
                       "it is (the new report was not written): move them away and run again, or choose another --out")


def _put_back(staging: Path, real: Path, old: Path) -> None:
    """Undo :func:`_swap_in`: the old folder back at ``real``, the new one (ours) deleted."""
    if old == staging:
        if not _exchange(staging, real):  # pragma: no cover - exchanged a moment ago
            raise OSError(errno.EIO, "cannot exchange the folders back", str(real))
    else:
        os.rename(real, staging)
        os.rename(old, real)
    _remove(staging)


def _remove_if_ours(path: Path) -> None:
    """Delete the old report moved aside, unless it holds anything its manifest does not prove visnav's."""
    try:
        unowned = unowned_entries(path)
    except OSError:
        return
    if not unowned:
        _remove(path)


def write_report(report: Report, folder: str | os.PathLike[str], shown: str | os.PathLike[str] | None = None
                 ) -> list[Path]:
    """Write the report as the whole content of ``folder`` (module docstring); return the paths written.

    The folder's earlier content (a report visnav wrote, :func:`check_report_folder`) is replaced in one
    atomic step once every new file and the manifest are written: counterexample or figure files the
    new report does not have are gone with it.  The folder is checked again right before the swap
    and once more on the old content after it (put back if a file appeared meanwhile).  ``folder`` is
    created if needed; ``shown`` is how messages name it (default ``folder``).

    Raises
    ------
    OutputError
        The folder cannot be replaced (:func:`check_report_folder`; a file saved into it during the
        run) or a file cannot be written (disk full, permission denied): the message names the path
        and the fix; the folder is left as it was.
    """
    given = Path(folder)
    real = check_report_folder(given, shown)
    parent = real.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise output_error(parent, err, "create the folder") from err
    remove_stale_partials(parent, real.name, (".partial-", _PREVIOUS))  # only those proven visnav's
    png = figures_png(report.figures)
    documents = _documents(report, png)
    mode = stat.S_IMODE(os.stat(real).st_mode) if real.is_dir() else folder_mode()
    try:
        staging = Path(tempfile.mkdtemp(prefix=partial_prefix(real.name), dir=parent))
    except OSError as err:
        raise output_error(parent, err, "create a folder in") from err
    swapped, old = False, None
    try:
        mark_partial(staging, real.name)  # first: a folder left by a hard kill is provably ours
        os.chmod(staging, mode)
        written = _write_into(staging, report, png, documents)
        _fsync_dir(staging)
        with sigint_deferred():
            check_report_folder(given, shown)  # again: a file saved into it while the report ran
            old = _swap_in(staging, real)
            swapped = True
            late = [] if old is None else unowned_entries(old)
            if late:  # saved between the check and the swap: the old folder goes back, untouched
                _put_back(staging, real, old)
                swapped, old = False, None
                raise _refusal(f"--out {str(given if shown is None else shown)!r}", late,
                               "while the report was being swapped in")
    except BaseException as err:
        if not swapped:
            _remove(staging)
        elif old is not None:
            _remove_if_ours(old)
        if isinstance(err, OSError) and not isinstance(err, OutputError) or (
                isinstance(err, OutputError) and str(staging) in str(err)):
            wrapped = output_error(given, err, "write the report into")  # named by where the file was going
            kept = "the folder is left as it was" if not swapped else "the new report is in place"
            out = OutputError(f"{str(wrapped).replace(str(staging), str(given))}; {kept}")
            out.errno = wrapped.errno
            raise out from err
        raise
    _fsync_dir(parent)
    if old is not None:
        _remove_if_ours(old)
    return [given / relative for relative in written]
