"""Atomic file output used by the CLI and report rendering (never by library code).

Every file is written to a hidden partial file beside it, ``.NAME.partial-PID-XXXXXXXX`` (PID: the
writing process), fsynced and renamed over ``NAME``: a reader sees the old file or the new one,
never a part.  The partial files that an interrupted write of ``NAME`` left behind are removed by
the next write of that same ``NAME`` (:func:`clean_partial_files`: a file, not a folder; writer no
longer running; older than this run); other names that merely look partial are never touched (the
report's partial folders are deleted only with visnav's marker in them, :mod:`visnav.app.ownership`).  A written file gets the mode a plain ``open()`` would give it under the current umask
(``0o666 & ~umask``), not :func:`tempfile.mkstemp`'s 0600.  Every :class:`OSError` of a write
(disk full, permission denied, a path component that is a file) is raised as :class:`OutputError`
naming the path and the fix.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import signal
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

__all__ = [
    "sigint_deferred",
    "OutputError", "PARTIAL_MARK", "prepare_output_dir", "write_bytes_atomic", "write_text_atomic",
    "figure_png_bytes", "figures_png", "write_png", "write_figures", "output_error", "clean_partial_files",
    "is_partial_name", "partial_prefix", "file_mode", "folder_mode",
]

PARTIAL_MARK = ".partial-"
"""What the name of every partial file (or folder) of an unfinished write holds: ``.NAME.partial-PID-XXXXXXXX``."""

_PARTIAL = re.compile(r"^\.(.+)\.partial-(\d+)-[a-z0-9_]{8}$")
"""A partial file or folder of ours: the writer's process id, then :mod:`tempfile`'s 8 random characters."""
_LEGACY = re.compile(r"^\.(.+)\.[a-z0-9_]{8}$")
"""The temporary files of the writes of earlier versions (``.NAME.XXXXXXXX``): only for the ``NAME`` being written."""

_RUN_START = time.time()
"""When this run started writing (the module's import): only partial files older than it are stale."""

_CLEANED: set[tuple[str, str]] = set()
"""(folder, target) pairs already cleaned by this process ("" for the folder's own partial files)."""


class OutputError(OSError):
    """An output folder or file cannot be written (the message names the path and the fix)."""


_FIXES = {
    errno.ENOSPC: "free space on that device, or give --out a folder on another one",
    errno.EDQUOT: "free space within your disk quota, or give --out a folder on another device",
    errno.EACCES: "make it writable, or choose a writable --out folder",
    errno.EPERM: "make it writable, or choose a writable --out folder",
    errno.EROFS: "the file system is read-only; choose an --out folder on a writable one",
    errno.ENOTDIR: "a component of the path is a file, not a folder; remove or rename it, or choose another --out",
    errno.EEXIST: "a component of the path is a file, not a folder; remove or rename it, or choose another --out",
    errno.EISDIR: "a folder has the name of the file; move it away, or choose another --out",
    errno.ENAMETOOLONG: "choose a shorter --out path",
    errno.ELOOP: "the path has a symbolic-link loop; choose another --out",
}


def output_error(path: str | os.PathLike[str], err: OSError, doing: str = "write") -> OutputError:
    """``err`` (raised while doing ``doing`` on ``path``) as an :class:`OutputError` with the path and the fix."""
    if isinstance(err, OutputError):
        return err
    reason = err.strerror or str(err) or type(err).__name__
    fix = _FIXES.get(err.errno, "check the path, or choose another --out folder")  # type: ignore[arg-type]
    out = OutputError(f"cannot {doing} {str(path)!r}: {reason}; {fix}")
    out.errno = err.errno  # callers may still tell a full disk from a refused folder
    return out


def _umask() -> int:
    """The process's umask, read without changing it where the system says it (Linux), else set and restored."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as handle:
            for line in handle:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """The mode ``open(path, "w")`` gives a new file under the current umask: ``0o666 & ~umask``."""
    return 0o666 & ~_umask()


def folder_mode() -> int:
    """The mode ``os.mkdir`` gives a new folder under the current umask: ``0o777 & ~umask``."""
    return 0o777 & ~_umask()


def partial_prefix(name: str) -> str:
    """The prefix of this process's partial files of ``name`` (:func:`tempfile.mkstemp` adds 8 characters)."""
    return f".{name[:180]}{PARTIAL_MARK}{os.getpid()}-"


def is_partial_name(name: str, targets: frozenset[str] | set[str] = frozenset()) -> bool:
    """Whether ``name`` is a partial file (or folder) of ours: ``.NAME.partial-PID-XXXXXXXX``, or the
    ``.NAME.XXXXXXXX`` of earlier versions for a ``NAME`` in ``targets``."""
    if _PARTIAL.match(name):
        return True
    legacy = _LEGACY.match(name)
    return bool(legacy and legacy.group(1) in targets)


def _writer_running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OverflowError, OSError):
        return True  # someone else's live process, or cannot tell: keep its file
    return True


def _stale(entry: os.DirEntry[str], targets: frozenset[str] | set[str]) -> bool:
    """A partial file of one of ``targets`` (never a folder, never another name) whose writer is gone."""
    new = _PARTIAL.match(entry.name)
    if new is None and not is_partial_name(entry.name, targets):
        return False
    if new is not None and new.group(1) not in {t[:180] for t in targets}:
        return False  # looks partial, but of no file being written: not ours to judge
    try:
        if not entry.is_file(follow_symlinks=False):
            return False  # partial folders carry a marker (visnav.app.ownership)
        if entry.stat(follow_symlinks=False).st_mtime >= _RUN_START:
            return False  # written during this run: maybe by a concurrent writer
    except OSError:
        return False
    return new is None or not _writer_running(int(new.group(2)))


def clean_partial_files(folder: str | os.PathLike[str], targets: tuple[str, ...] = (), *,
                        again: bool = False) -> list[Path]:
    """Remove the partial files that interrupted writes of ``targets`` left in ``folder``; return them.

    A partial file ``.NAME.partial-PID-XXXXXXXX`` (or an earlier version's ``.NAME.XXXXXXXX``) of a
    ``NAME`` in ``targets`` is stale when it is a regular file older than this run and its writer no
    longer runs; nothing else is removed (a folder, another name).  A folder
    is listed once per process and target unless ``again``.  Errors are ignored: a stale file that
    cannot be removed is harmless, its name says it is partial.
    """
    where = Path(folder)
    key = os.path.abspath(where)
    wanted = {(key, t) for t in targets} | {(key, "")}
    if wanted <= _CLEANED and not again:
        return []
    removed: list[Path] = []
    try:
        with os.scandir(where) as listing:
            entries = list(listing)
    except OSError:
        return removed
    names = frozenset(targets)
    for entry in entries:
        if not _stale(entry, names):
            continue
        path = where / entry.name
        try:
            os.unlink(path)
            removed.append(path)
        except OSError:
            pass
    _CLEANED.update(wanted)
    return removed


def prepare_output_dir(path: str | os.PathLike[str]) -> Path:
    """Create ``path`` if needed and check that it is a writable folder."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"--out {str(folder)!r}: exists and is not a folder; choose a folder path")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"--out {str(folder)!r}: cannot create the folder ({err.strerror}); "
                          f"{_FIXES.get(err.errno, 'choose a writable path')}") from err  # type: ignore[arg-type]
    if not folder.is_dir():
        raise OutputError(f"--out {str(folder)!r}: exists and is not a folder; choose a folder path")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"--out {str(folder)!r}: folder is not writable; choose a writable path")
    return folder


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a partial file and an atomic rename (module docstring).

    Raises
    ------
    OutputError
        For any :class:`OSError`: the path, the reason and the fix; no partial file is left.
    """
    target = Path(path)
    clean_partial_files(target.parent, (target.name,))
    try:
        fd, tmp = tempfile.mkstemp(prefix=partial_prefix(target.name), dir=target.parent)
    except OSError as err:
        raise output_error(target, err) from err
    try:
        with os.fdopen(fd, "wb") as handle:
            os.fchmod(handle.fileno(), file_mode())
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException as err:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(err, OSError):
            raise output_error(target, err) from err
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


@contextlib.contextmanager
def sigint_deferred() -> Iterator[None]:
    """Hold back ``KeyboardInterrupt`` until the block ends (main thread, default handler only): the one
    mechanism by which a write that must not be cut (a results line, a folder swap) finishes before Ctrl-C acts."""
    if threading.current_thread() is not threading.main_thread() or (
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    received: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if received:
        raise KeyboardInterrupt
