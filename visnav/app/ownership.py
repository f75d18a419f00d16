"""What visnav may replace or delete: its manifests, its partial-folder markers and safe names from data.

Nothing of the user's may be lost by a writer (``docs/failure_modes.md``, "Output folders").  A
folder that visnav writes as a whole (``report --out``, ``verify --out``) gets a manifest,
:data:`MANIFEST_NAME`, written last: the tool, its version, the command and every file written with
its size and SHA-256.  Such a folder may be replaced or its files overwritten only where the
manifest proves them visnav's: :func:`unowned_entries` lists everything that is not (a file not
listed, a listed file whose bytes changed since, a manifest that is not visnav's).

A partial folder (``.NAME.partial-PID-XXXXXXXX``, written beside a report folder and swapped in) holds
a marker file, :data:`PARTIAL_MARKER`, written first; :func:`remove_stale_partials` deletes only the
partial folders of one ``NAME`` whose writer no longer runs and whose marker (pid and name matching
the folder's name) or complete manifest (every file listed with its bytes, nothing else) proves them
visnav's: a folder that merely has such a name is kept.

Names taken from data (a scenario's or problem's ``name``, a requirement's name) become file or
folder names only through :func:`safe_name`: a path separator, ``..``, a leading dot, a NUL or
control character, or more than :data:`MAX_NAME_BYTES` bytes is refused before any work.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from visnav.app.files import OutputError, write_text_atomic

__all__ = ["MANIFEST_NAME", "MANIFEST_FORMAT", "PARTIAL_MARKER", "MAX_NAME_BYTES", "safe_name", "file_digest",
           "manifest_text", "write_manifest", "read_manifest", "unowned_entries", "unowned_targets",
           "mark_partial", "remove_stale_partials", "describe_entries", "start_folder", "anchored",
           "check_requirement_names"]

MANIFEST_NAME = ".visnav-manifest.json"
"""The manifest of a folder visnav wrote (written last, so that a complete folder holds one)."""
MANIFEST_FORMAT = "visnav-output-manifest"
PARTIAL_MARKER = ".visnav-partial"
"""The first file of a partial folder: proves that visnav created it (JSON: format, pid, name)."""
MAX_NAME_BYTES = 100
"""Longest name from data used as a file name [UTF-8 bytes]: with ``.json``, a figure's prefix and a partial
file's ``.NAME.partial-PID-XXXXXXXX`` it stays under the 255 bytes of common file systems."""

_DESKTOP_FILES = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
"""What a file browser writes into a folder it shows: not the user's data; tolerated and replaced with the folder."""
_PARTIAL_FOLDER = re.compile(r"^\.(.+)\.partial-(\d+)-[a-z0-9_]{8}$")
_CHUNK = 1 << 20


def safe_name(field: str, value: Any, fix: str) -> str:
    """``value`` if it can be one file or folder name inside the intended parent, else an :class:`OutputError`.

    Refused: not a string, empty, a ``/`` or ``\\``, a leading dot (``.``, ``..``, hidden names), a NUL or
    another control character, more than :data:`MAX_NAME_BYTES` UTF-8 bytes.  The message names
    ``field``, the value, what is expected and ``fix``.
    """
    problem = None
    if not isinstance(value, str) or not value:
        problem = "is empty" if value == "" else f"is not a string ({type(value).__name__})"
    elif "/" in value or "\\" in value or (os.altsep and os.altsep in value):
        problem = "holds a path separator"
    elif value.startswith("."):
        problem = "starts with a dot ('..' and hidden names leave or hide in the folder)"
    elif any(ord(c) < 32 or ord(c) == 127 for c in value):
        problem = "holds a NUL or control character"
    else:
        size = len(value.encode("utf-8", errors="surrogatepass"))
        if size > MAX_NAME_BYTES:
            problem = f"is {size} bytes long"
    if problem is None:
        return value
    shown = repr(value) if len(repr(value)) <= 120 else repr(value)[:117] + "..."
    raise OutputError(f"{field} = {shown} {problem}; it names a file or folder written by visnav, so it must be "
                      f"one plain name: no '/' or '\\', no leading dot, no control character, at most "
                      f"{MAX_NAME_BYTES} bytes; {fix}")


def file_digest(path: str | os.PathLike[str]) -> tuple[int, str]:
    """Size [bytes] and SHA-256 (hex) of a file (read in 1 MiB chunks)."""
    digest, size = hashlib.sha256(), 0
    with open(path, "rb") as handle:
        while chunk := handle.read(_CHUNK):
            digest.update(chunk)
            size += len(chunk)
    return size, digest.hexdigest()


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("visnav")
    except metadata.PackageNotFoundError:
        return "unknown"


def manifest_text(folder: str | os.PathLike[str], relatives: Iterable[str], command: str) -> str:
    """The manifest of ``folder`` listing the files ``relatives`` (paths relative to it, ``/``-separated)."""
    root = Path(folder)
    files = {}
    for relative in sorted(set(relatives)):
        size, digest = file_digest(root / relative)
        files[relative] = {"bytes": size, "sha256": digest}
    data = {"format": MANIFEST_FORMAT, "version": 1, "tool": "visnav", "tool_version": _version(),
            "command": command, "files": files}
    return json.dumps(data, indent=1, sort_keys=True) + "\n"


def write_manifest(folder: str | os.PathLike[str], relatives: Iterable[str], command: str) -> None:
    """Write ``folder``'s manifest (atomically; :func:`manifest_text`)."""
    write_text_atomic(Path(folder) / MANIFEST_NAME, manifest_text(folder, relatives, command))


def read_manifest(folder: str | os.PathLike[str]) -> dict[str, dict[str, Any]] | None:
    """The files ``folder``'s manifest lists (``{relative: {"bytes", "sha256"}}``); ``None``: no valid manifest."""
    path = Path(folder) / MANIFEST_NAME
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > 50_000_000:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or data.get("tool") != "visnav":
        return None
    files = data.get("files")
    if not isinstance(files, dict):
        return None
    valid = {}
    for relative, entry in files.items():
        parts = relative.split("/") if isinstance(relative, str) else [""]
        if (not isinstance(entry, dict) or any(p in ("", ".", "..") for p in parts)
                or not isinstance(entry.get("sha256"), str) or not isinstance(entry.get("bytes"), int)):
            return None
        valid[relative] = entry
    return valid


def _matches(path: Path, entry: dict[str, Any]) -> bool:
    try:
        if path.is_symlink() or not path.is_file() or path.stat().st_size != entry["bytes"]:
            return False
        return file_digest(path)[1] == entry["sha256"]
    except OSError:
        return False


def _walk(folder: Path) -> tuple[list[str], list[str]]:
    """Every file (and symbolic link, special file) and every folder under ``folder``, relative, sorted.

    Raises
    ------
    OSError
        A folder under ``folder`` cannot be listed.
    """
    files, folders = [], []
    def unreadable(err: OSError) -> None:
        raise err  # a sub-folder that cannot be listed may hold anything: never judged visnav's

    for here, dirs, names in os.walk(folder, onerror=unreadable, followlinks=False):
        base = Path(here).relative_to(folder)
        for d in list(dirs):
            if os.path.islink(os.path.join(here, d)):  # a link to a folder is an entry, not followed
                dirs.remove(d)
                names.append(d)
            else:
                folders.append((base / d).as_posix())
        files += [(base / n).as_posix() for n in names]
    return sorted(files), sorted(folders)


def unowned_entries(folder: str | os.PathLike[str], *, marker: bool = False) -> list[str]:
    """What in ``folder`` visnav's manifest does not prove its own (relative paths; ``[]``: all of it is).

    An empty folder is visnav's to replace.  Otherwise every file must be listed in a valid manifest
    with its size and digest; a folder holding no listed file, a file browser's ``.DS_Store`` and (with
    ``marker``) a :data:`PARTIAL_MARKER` are tolerated.  Without a valid manifest, every file is
    unowned (the manifest itself included, when it is there).

    Raises
    ------
    OSError
        A folder under ``folder`` cannot be listed (what it holds cannot be judged).
    """
    root = Path(folder)
    files, _ = _walk(root)
    listed = read_manifest(root) or {}
    unowned = []
    for relative in files:
        name = relative.rsplit("/", 1)[-1]
        if name in _DESKTOP_FILES or (marker and relative == PARTIAL_MARKER):
            continue
        if relative == MANIFEST_NAME and listed:
            continue
        entry = listed.get(relative)
        if entry is None or not _matches(root / relative, entry):
            unowned.append(relative)
    return unowned


def unowned_targets(folder: str | os.PathLike[str], relatives: Iterable[str]) -> list[str]:
    """Which of the files ``relatives`` (to be overwritten in ``folder``) exist and are not proven visnav's.

    A target is visnav's when ``folder``'s manifest lists it with its current size and digest.  The
    manifest itself is a target when it is there but not a valid visnav manifest.
    """
    root = Path(folder)
    listed = read_manifest(root)
    out = []
    if os.path.lexists(root / MANIFEST_NAME) and listed is None:
        out.append(MANIFEST_NAME)
    for relative in relatives:
        path = root / relative
        if os.path.lexists(path) and not _matches(path, (listed or {}).get(relative, {"bytes": -1, "sha256": ""})):
            out.append(relative)
    return out


def describe_entries(entries: list[str], most: int = 5) -> str:
    """``a, b and 3 more``: the first ``most`` of ``entries``."""
    return ", ".join(entries[:most]) + (f" and {len(entries) - most} more" if len(entries) > most else "")


def mark_partial(folder: str | os.PathLike[str], name: str) -> None:
    """Write the marker that proves ``folder`` (a new, empty partial folder of ``name``) visnav's; its first file."""
    data = {"format": "visnav-partial-folder", "pid": os.getpid(), "name": name}
    write_text_atomic(Path(folder) / PARTIAL_MARKER, json.dumps(data, sort_keys=True) + "\n")


def _writer_gone(pid: int) -> bool:
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OverflowError, OSError):
        return False  # someone else's live process, or cannot tell
    return False


def _proven_partial(path: Path, name: str, pid: int) -> bool:
    """``path`` holds visnav's marker for (``pid``, ``name``), or a manifest proving every file in it visnav's."""
    try:
        data = json.loads((path / PARTIAL_MARKER).read_text(encoding="utf-8"))
        if isinstance(data, dict) and data.get("pid") == pid and data.get("name") == name and (
                data.get("format") == "visnav-partial-folder"):
            return True  # written first into the folder mkdtemp had just created: visnav's, being written
    except (OSError, ValueError):
        pass
    try:
        return read_manifest(path) is not None and not unowned_entries(path)
    except OSError:
        return False


def remove_stale_partials(parent: str | os.PathLike[str], name: str, kinds: tuple[str, ...] = (".partial-",)
                          ) -> list[Path]:
    """Delete the partial folders of ``name`` in ``parent`` that visnav provably left (module docstring); them.

    ``kinds``: the marks in the names (``.partial-``, and ``.previous-`` for the old report moved aside).
    A folder whose writer may still run, or without a matching marker or a manifest covering all of it, is kept.
    """
    pattern = re.compile(rf"^\.{re.escape(name[:180])}(?:{'|'.join(map(re.escape, kinds))})(\d+)-[a-z0-9_]{{8}}$")
    removed: list[Path] = []
    try:
        with os.scandir(parent) as listing:
            entries = list(listing)
    except OSError:
        return removed
    for entry in entries:
        found = pattern.match(entry.name)
        if not found or not entry.is_dir(follow_symlinks=False):
            continue
        pid = int(found.group(1))
        path = Path(parent) / entry.name
        if _writer_gone(pid) and _proven_partial(path, name, pid):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def start_folder() -> str | None:
    """The current folder at the start of a command (``None``: it was deleted), before any user code ran."""
    try:
        return os.getcwd()
    except OSError:
        return None


def anchored(args: Any, given: str | os.PathLike[str]) -> Path:
    """``given`` (an ``--out`` or a default output folder) resolved against ``args.start_dir`` (the folder
    :func:`start_folder` read when the command started): a ``chdir`` in the user's code later changes
    nothing (an absolute ``given`` is kept; ``..`` is left to the file system)."""
    start = getattr(args, "start_dir", None)
    return Path(given) if start is None else Path(os.path.join(start, os.fspath(given)))


def check_requirement_names(names: Iterable[str], whose: str) -> None:
    """Refuse (:func:`safe_name`) requirement names that cannot name their counterexample file, before any search."""
    for name in names:
        safe_name(f"requirement name of {whose}", name,
                  "rename the requirement (its counterexample is written as counterexamples/NAME.json)")
