"""The results file of a campaign: append-only JSON Lines, resumable after any interruption.

Line 1 is a header given by the campaign (a JSON object naming the format, its
version and the campaign's spec hash, usually with the full spec), to which the
store adds its own ``store_version``; every further line is one finished task,
bound to its campaign by the spec hash, written as soon as it arrives and
``fsync``-ed::

    {"format":"visnav-campaign","spec":{...},"spec_hash":"3f2a...","store_version":2,"version":1}
    {"result":{"index":4,"outcome":"success",...},"sha256":"9c1e0b7d5a3f2e41","spec_hash":"3f2a..."}

``sha256`` is the first 16 hex digits of the SHA-256 of the result's canonical
JSON, so that a line altered after it was written is detected, not only a cut
one.  :func:`open_store` reads an existing file back: it refuses a file of a
different campaign (another format, version or spec hash), reports every bad
line (1-based line number and why: cut, not JSON, nested more than
:data:`MAX_JSON_DEPTH` levels, checksum, a line of another campaign, malformed
field, index out of range, duplicate), keeps the valid lines and, if it found
bad ones, repairs the file: bad lines only at the end (a write cut by
``kill -9``) are truncated away in place, which needs no free space; others
are removed by an atomic rewrite.  The indices read back are then skipped by
the campaign.  :meth:`CampaignStore.compact` puts the file in index order, so
that its bytes do not depend on how the campaign was run; a file already in
that order (every task appended in index order) is left as it is.

A file written before lines were bound to their campaign (no ``store_version``
in its header) is migrated when it is opened: its lines are bound to the
header's campaign and the file is rewritten atomically (:attr:`StoreReport.migrated`).

One process at a time writes a campaign folder: :func:`open_store` takes an
advisory ``flock`` on the file's folder, held by the open file descriptor for
the life of the store, so that it is released when the process ends however it
ends and cannot be removed by deleting a file; :data:`LOCK_FILE` in the folder
only says which process holds it (pid and host), for the message a second
writer gets, and is removed on close.  Where folders cannot be locked (some
network file systems) the lock is taken on :data:`LOCK_FILE` itself (then kept);
without ``fcntl`` (not POSIX) there is no lock.

A write that fails (disk full, quota, I/O error) raises
:class:`CampaignStoreWriteError`, an :class:`OSError` (an
:class:`~visnav.app.files.OutputError`) that says what is kept on disk: a failed append is undone (the file stays valid for a resume), a failed
repair or compaction leaves the previous file unchanged.

The store knows nothing of what a result is: a :class:`ResultCodec` converts
results to JSON objects and back and gives their index (``visnav sweep`` uses
:class:`visnav.studies.campaign.SampleResult`; any campaign of indexed results
can use it).  This module writes files; the campaigns themselves do not.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import socket
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

from hybrid.jsonable import canonical_json

from visnav.app.files import OutputError, sigint_deferred, write_text_atomic

try:  # advisory lock against two campaigns writing one folder (POSIX only)
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "CHECKSUM_HEX",
    "MAX_JSON_DEPTH",
    "STORE_VERSION",
    "STORE_VERSION_KEY",
    "RESOURCE_ERRNOS",
    "CampaignStoreError",
    "CampaignStoreWriteError",
    "ResultCodec",
    "StoreHints",
    "BadLine",
    "StoreReport",
    "CampaignStore",
    "open_store",
    "line_checksum",
    "LOCK_FILE",
    "lock_path",
    "os_error_reason",
]

CHECKSUM_HEX = 16
"""Hex digits of the per-line SHA-256 kept in the file."""

MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays and objects read from a line (deeper: a corrupt line, never a RecursionError)."""

STORE_VERSION = 2
"""Version of the store's line format, kept in the header under :data:`STORE_VERSION_KEY`: 2 has the spec
hash in every line.  A header without it is of version 1 (lines not bound to their campaign), migrated on open."""

STORE_VERSION_KEY = "store_version"
"""Header key of :data:`STORE_VERSION` (reserved: a campaign's own header must not use it)."""

LOCK_FILE = "campaign.lock"
"""Name of the file, in a campaign's folder, naming the process that holds the folder's lock."""

RESOURCE_ERRNOS = frozenset(code for code in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EFBIG, errno.EIO,
                                              errno.ENOMEM) if code is not None)
"""``errno`` values of a resource fault (disk full, quota, file too large, I/O error, no memory): the run could
not complete, nothing is wrong with the input."""

_BRACKETS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


class CampaignStoreError(ValueError):
    """A results file that cannot be resumed (another campaign, not a campaign file, in use).

    Attributes
    ----------
    path : str
        The file.
    expected : str
        What was expected.
    fix : str
        How to proceed.
    """

    def __init__(self, path: str, problem: str, expected: str, fix: str) -> None:
        self.path = path
        self.expected = expected
        self.fix = fix
        super().__init__(f"campaign file {path!r}: {problem}: expected {expected}; fix: {fix}")


def os_error_reason(err: BaseException) -> str:
    """The system's reason for a failed write (``"No space left on device"``), also through the wrappers that
    re-raise it (:class:`visnav.app.files.OutputError`); never empty."""
    seen: BaseException | None = err
    while seen is not None:
        if isinstance(seen, OSError) and seen.strerror:
            return seen.strerror
        seen = seen.__cause__
    return str(err) or type(err).__name__


class CampaignStoreWriteError(OutputError):
    """The results file could not be written (disk full, quota, I/O error, ...); what is on disk stays valid.

    An :class:`~visnav.app.files.OutputError` (so an :class:`OSError`): a command that does not handle it
    still ends with its message, not a traceback.  ``errno`` and ``strerror`` are those of the failed
    system call.

    Attributes
    ----------
    path : str
        The file.
    action : str
        What failed (``"appending sample 12"``, ``"rewriting it in index order"``, ...).
    kept : str
        What is on disk now (always a valid file to resume from).
    needed_bytes : int or None
        Free space the action needs, when known.
    """

    def __init__(self, path: str, action: str, cause: OSError, kept: str, needed_bytes: int | None = None) -> None:
        reason = os_error_reason(cause)
        super().__init__(cause.errno, reason)
        self.path = path
        self.action = action
        self.kept = kept
        self.needed_bytes = needed_bytes
        self.cause = reason

    @property
    def resource(self) -> bool:
        """Whether the cause is a resource fault (:data:`RESOURCE_ERRNOS`) rather than, e.g., a permission."""
        return self.errno in RESOURCE_ERRNOS

    def __str__(self) -> str:
        need = f"; it needs about {self.needed_bytes} bytes free" if self.needed_bytes else ""
        return f"campaign file {self.path!r}: {self.action} failed ({self.cause}{need}); {self.kept}"

    def __reduce__(self):  # pragma: no cover - not sent across processes by visnav
        return (_rebuild_write_error, (self.path, self.action, self.errno, self.cause, self.kept, self.needed_bytes))


def _rebuild_write_error(path: str, action: str, code: int | None, cause: str, kept: str,
                         needed: int | None) -> CampaignStoreWriteError:  # pragma: no cover
    return CampaignStoreWriteError(path, action, OSError(code, cause), kept, needed)


@dataclass(frozen=True, kw_only=True, slots=True)
class ResultCodec:
    """How one kind of result is stored.

    Attributes
    ----------
    to_dict : callable
        ``result -> dict`` of JSON types (its canonical JSON is what the checksum covers).
    from_dict : callable
        ``dict -> result``; raises ``ValueError`` or ``TypeError`` naming the field for a malformed one
        (any exception it raises marks the line malformed).
    index : callable
        ``result -> int``: the task index, in ``[0, samples)``.
    """

    to_dict: Callable[[Any], dict[str, Any]]
    from_dict: Callable[[Any], Any]
    index: Callable[[Any], int]


@dataclass(frozen=True, kw_only=True, slots=True)
class StoreHints:
    """How the store's messages name the program writing the file and its options.

    Attributes
    ----------
    writer : str
        The command that writes such files (``"visnav sweep"``).
    out_option : str
        Its option choosing the file or folder (``"--out"``).
    same_campaign : str
        What must be repeated to resume (``"the same scenario, --samples, --seed and distributions"``).
    quiet_keys : tuple of str
        Keys of the header's ``spec`` not quoted when two campaigns differ (bulky values covered by
        another key, e.g. a scenario text and its digest).
    """

    writer: str = "visnav"
    out_option: str = "--out"
    same_campaign: str = "the same campaign"
    quiet_keys: tuple[str, ...] = ()


@dataclass(frozen=True, kw_only=True, slots=True)
class BadLine:
    """A line of the results file that was dropped: its 1-based number and why."""

    line: int
    reason: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.reason}"


@dataclass(frozen=True, kw_only=True, slots=True)
class StoreReport:
    """What :func:`open_store` found.

    Attributes
    ----------
    path : str
        The results file.
    created : bool
        The file did not exist and was created with its header.
    results : int
        Valid results read back (their indices are skipped on resume).
    bad_lines : tuple of BadLine
        Dropped lines.
    rewritten : bool
        The file was repaired without the bad lines (truncated in place when they were all at its end,
        rewritten atomically otherwise).
    migrated : bool
        The file was of store version 1 (lines without the spec hash) and was rewritten in the current format.
    """

    path: str
    created: bool
    results: int
    bad_lines: tuple[BadLine, ...]
    rewritten: bool
    migrated: bool = False


def line_checksum(result: dict[str, Any]) -> str:
    """First :data:`CHECKSUM_HEX` hex digits of the SHA-256 of the result's canonical JSON."""
    return hashlib.sha256(canonical_json(result).encode("utf-8")).hexdigest()[:CHECKSUM_HEX]


def lock_path(path: str | os.PathLike[str]) -> Path:
    """:data:`LOCK_FILE` beside the results file ``path``: who holds the lock of its folder (pid and host)."""
    return Path(path).parent / LOCK_FILE


def _result_line(codec: ResultCodec, result: Any, spec_hash: str) -> str:
    data = codec.to_dict(result)
    return canonical_json({"result": data, "sha256": line_checksum(data), "spec_hash": spec_hash})


def _line_of(result_json: str, checksum: str, spec_hash: str) -> str:
    """:func:`_result_line` from the canonical JSON of a result already at hand (its keys are in sorted order)."""
    return f'{{"result":{result_json},"sha256":{json.dumps(checksum)},"spec_hash":{json.dumps(spec_hash)}}}'


def _too_deep(text: str) -> int | None:
    """The nesting depth of ``text`` if it exceeds :data:`MAX_JSON_DEPTH` (``None`` otherwise); strings skipped."""
    if text.count("[") + text.count("{") <= MAX_JSON_DEPTH:
        return None
    depth = deepest = 0
    for match in _BRACKETS.finditer(text):
        token = match[0]
        if token in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif token in "]}":
            depth -= 1
    return deepest if deepest > MAX_JSON_DEPTH else None


def _load_json(text: str) -> Any:
    """``json.loads`` bounded in depth; ``ValueError`` with the reason otherwise."""
    depth = _too_deep(text)
    if depth is not None:
        raise ValueError(f"JSON nested {depth} levels deep (at most {MAX_JSON_DEPTH}): corrupt or not a record")
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise ValueError(f"not valid JSON ({err.msg} at column {err.colno}): cut by an interruption or "
                         "altered") from None
    except RecursionError:  # pragma: no cover - _too_deep comes first
        raise ValueError(f"JSON nested too deep (at most {MAX_JSON_DEPTH} levels): corrupt or not a record") from None


_BOUND_KEYS = frozenset({"result", "sha256", "spec_hash"})
_LEGACY_KEYS = frozenset({"result", "sha256"})


def _parse_result(raw: bytes, samples: int, codec: ResultCodec, spec_hash: str, legacy: bool) -> tuple[Any, str]:
    """One result line -> (result, the line as the store writes it); ``ValueError`` with the reason otherwise."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ValueError(f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    if not text.strip():
        raise ValueError("empty line")
    data = _load_json(text)
    allowed = (_LEGACY_KEYS, _BOUND_KEYS) if legacy else (_BOUND_KEYS,)
    if not isinstance(data, dict) or frozenset(data) not in allowed:
        keys = sorted(data) if isinstance(data, dict) else type(data).__name__
        if isinstance(data, dict) and frozenset(data) == _LEGACY_KEYS:
            raise ValueError("not bound to a campaign (no 'spec_hash'), in a file whose lines all carry one: "
                             "altered or copied from an older file")
        raise ValueError(f"not a result record (expected the keys 'result', 'sha256' and 'spec_hash', found {keys})")
    try:
        result_json = canonical_json(data["result"]) if isinstance(data["result"], dict) else ""
    except (TypeError, ValueError, RecursionError):  # not JSON types after all (e.g. NaN)
        result_json = ""
    checksum = hashlib.sha256(result_json.encode("utf-8")).hexdigest()[:CHECKSUM_HEX]
    if not result_json or data["sha256"] != checksum:
        raise ValueError("checksum mismatch: the line was altered after it was written")
    if "spec_hash" in data and data["spec_hash"] != spec_hash:
        found = data["spec_hash"]
        shown = f"{found[:12]}..." if isinstance(found, str) else repr(found)[:40]
        raise ValueError(f"a result of another campaign (spec hash {shown}, this campaign {spec_hash[:12]}...): "
                         "not counted")
    try:
        result = codec.from_dict(data["result"])
        index = codec.index(result)
    except Exception as err:  # noqa: BLE001 - whatever the codec refuses is a malformed line
        raise ValueError(f"malformed result ({err})") from None
    if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < samples:
        raise ValueError(f"index {index} outside the campaign's [0, {samples})")
    return result, _line_of(result_json, checksum, spec_hash)


def _spec_differences(found: Any, wanted: Any, quiet: tuple[str, ...]) -> str:
    if not isinstance(found, dict) or not isinstance(wanted, Mapping):
        return ""
    keys = [k for k in wanted if k not in quiet and found.get(k) != wanted[k]]
    shown = [_difference(k, found.get(k), wanted[k]) for k in keys[:4]]
    return f" ({'; '.join(shown)})" if shown else ""


def _difference(key: str, found: Any, wanted: Any) -> str:
    """One key's difference; for two mappings, the entries that changed, appeared or disappeared."""
    if isinstance(found, dict) and isinstance(wanted, Mapping):
        changed = [k for k in wanted if k in found and found[k] != wanted[k]]
        new = [k for k in wanted if k not in found]
        gone = [k for k in found if k not in wanted]
        parts = [f"{', '.join(changed[:4])} changed" if changed else "",
                 f"{', '.join(new[:4])} new" if new else "", f"{', '.join(gone[:4])} gone" if gone else ""]
        return f"{key}: " + "; ".join(p for p in parts if p)
    return f"{key} {json.dumps(found)} in the file, {json.dumps(wanted)} now"


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


# ---------------------------------------------------------------------------------------------
# The lock
# ---------------------------------------------------------------------------------------------


class _Lock:
    """A held campaign lock: an ``flock`` on an open descriptor (the folder's, or the lock file's)."""

    def __init__(self, fd: int, info: Path, on_folder: bool) -> None:
        self.fd: int | None = fd
        self.info = info
        self.on_folder = on_folder

    def release(self) -> None:
        if self.fd is None:
            return
        if self.on_folder:  # the lock file only names the holder: removed while the folder is still locked
            with contextlib.suppress(OSError):
                os.unlink(self.info)
        with contextlib.suppress(OSError):
            os.close(self.fd)  # releases the flock
        self.fd = None


def _holder_text() -> str:
    return canonical_json({"host": socket.gethostname(), "pid": os.getpid()}) + "\n"


def _holder(info: Path) -> str:
    """Who holds the lock, as recorded in ``info`` ("" when unknown)."""
    try:
        with open(info, "rb") as handle:
            data = json.loads(handle.read(4096).decode("utf-8"))
        pid, host = data["pid"], data.get("host")
    except Exception:  # noqa: BLE001 - missing, empty, or not ours: the holder is unknown
        return ""
    if not isinstance(pid, int) or isinstance(pid, bool):
        return ""
    here = host is None or host == socket.gethostname()
    return f"pid {pid}" + ("" if here else f" on host {host}")


def _in_use(target: Path, info: Path, hints: StoreHints) -> CampaignStoreError:
    holder = _holder(info)
    who = f"another process ({holder})" if holder else "another process (pid unknown: no readable lock file)"
    stop = f" (or stop it: kill {holder.split()[1]})" if holder and " on host " not in holder else ""
    return CampaignStoreError(str(target), f"{who} is writing this campaign",
                              f"a folder no other {hints.writer} uses",
                              f"wait for the other `{hints.writer}` to finish{stop}, or choose another "
                              f"{hints.out_option}")


def _busy(err: OSError) -> bool:
    return err.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EACCES)


def _acquire_lock(path: Path, hints: StoreHints) -> _Lock | None:
    """Lock the folder of ``path`` for this process (non-blocking); ``None`` without ``fcntl``."""
    if fcntl is None:  # pragma: no cover - not POSIX
        return None
    info = lock_path(path)
    folder = path.parent
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        fd = -1  # a folder we may not read: lock the lock file instead
    if fd >= 0:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(fd)
            if _busy(err):
                raise _in_use(path, info, hints) from None
        else:
            with contextlib.suppress(OSError):  # informative only (a full disk must not stop the campaign here)
                write_text_atomic(info, _holder_text())
            return _Lock(fd, info, on_folder=True)
    return _lock_file(path, info, hints)


def _lock_file(path: Path, info: Path, hints: StoreHints) -> _Lock | None:
    """Fallback where folders cannot be locked: an ``flock`` on :data:`LOCK_FILE` itself (never removed)."""
    for _ in range(8):
        fd = os.open(info, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(fd)
            if _busy(err):
                raise _in_use(path, info, hints) from None
            return None  # no advisory locks on this file system: as without fcntl
        try:
            same = os.fstat(fd).st_ino == os.stat(info).st_ino
        except OSError:
            same = False
        if same:  # not replaced between open and flock
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
                os.pwrite(fd, _holder_text().encode("utf-8"), 0)
            return _Lock(fd, info, on_folder=False)
        os.close(fd)
    raise CampaignStoreError(str(path), f"its lock file {str(info)!r} keeps being replaced",
                             f"a folder no other {hints.writer} uses",
                             f"stop whatever removes {info.name}, or choose another {hints.out_option}")


# ---------------------------------------------------------------------------------------------
# The store
# ---------------------------------------------------------------------------------------------


class CampaignStore:
    """The open results file of one campaign; use :func:`open_store` to get one.

    Appends are durable one by one (written unbuffered, then ``fsync``).  Use it as a
    context manager, or call :meth:`close`.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    header : dict
        The header (line 1): the campaign's, with :data:`STORE_VERSION_KEY`.
    samples : int
        Number of tasks: valid indices are ``0 .. samples - 1``.
    """

    def __init__(self, path: Path, header: dict[str, Any], codec: ResultCodec, samples: int,
                 results: dict[int, Any], lock: _Lock | None, *, in_order: bool) -> None:
        self.path = path
        self.header = header
        self.samples = samples
        self._codec = codec
        self._spec_hash: str = header["spec_hash"]
        self._results = results
        self._lock = lock
        self._in_order = in_order and list(results) == sorted(results)
        self._last = max(results, default=-1)
        self._broken = False
        self._fd: int | None = os.open(path, os.O_WRONLY | os.O_APPEND)

    @property
    def done(self) -> frozenset[int]:
        """Indices with a stored result."""
        return frozenset(self._results)

    @property
    def in_index_order(self) -> bool:
        """Whether the file already is what :meth:`compact` would write (then it writes nothing)."""
        return self._in_order

    def results(self) -> tuple[Any, ...]:
        """Stored results in index order."""
        return tuple(self._results[i] for i in sorted(self._results))

    def append(self, result: Any) -> None:
        """Write ``result`` as one line, ``fsync``-ed before returning.

        Raises
        ------
        ValueError
            For an index outside the campaign or already stored (a result is never written twice).
        CampaignStoreWriteError
            The line could not be written (disk full, ...): it is undone, the file keeps the results
            stored before.
        """
        if self._fd is None:
            raise ValueError(f"campaign file {str(self.path)!r} is closed; fix: open it again with open_store")
        index = self._codec.index(result)
        if not 0 <= index < self.samples or index in self._results:
            raise ValueError(f"sample {index}: expected a new index in [0, {self.samples}) "
                             "(already stored or out of range); fix: skip the indices in CampaignStore.done")
        kept = (f"the {len(self._results)} results stored before are kept and valid; rerun the same command to "
                "resume")
        if self._broken:
            raise CampaignStoreWriteError(str(self.path), f"appending sample {index}",
                                          OSError(errno.EIO, "an earlier write failed and could not be undone"),
                                          kept.replace("kept and valid", "kept (the cut line is dropped on resume)"))
        line = (_result_line(self._codec, result, self._spec_hash) + "\n").encode("utf-8")
        with sigint_deferred():  # a Ctrl-C here is raised once the line is durable and counted
            size = os.lseek(self._fd, 0, os.SEEK_END)
            try:
                _write_all(self._fd, line)
                os.fsync(self._fd)
            except OSError as err:
                self._undo(size)
                raise CampaignStoreWriteError(str(self.path), f"appending sample {index}", err, kept) from err
            self._results[index] = result
            self._in_order = self._in_order and index > self._last
            self._last = max(self._last, index)

    def _undo(self, size: int) -> None:
        """Cut a partly written line back to ``size`` bytes (if that fails too, refuse further appends)."""
        try:
            os.ftruncate(self._fd, size)  # type: ignore[arg-type]
            os.fsync(self._fd)  # type: ignore[arg-type]
        except OSError:
            self._broken = True

    def compact(self) -> None:
        """Put the file in index order (its bytes then depend on the campaign only, not on the completion
        order): an atomic rewrite, skipped when the file already is in that order.

        Raises
        ------
        CampaignStoreWriteError
            The rewrite failed (disk full, ...): the file is unchanged, valid and complete.
        """
        if self._fd is None:
            raise ValueError(f"campaign file {str(self.path)!r} is closed; fix: open it again with open_store")
        if self._in_order:
            return
        text = "\n".join([canonical_json(self.header),
                          *(_result_line(self._codec, r, self._spec_hash) for r in self.results())]) + "\n"
        data = text.encode("utf-8")
        try:
            write_text_atomic(self.path, text)
        except OSError as err:
            raise CampaignStoreWriteError(
                str(self.path), "rewriting it in index order", err,
                f"the file is unchanged: its {len(self._results)} results are valid, in the order they arrived",
                needed_bytes=len(data)) from err
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        with contextlib.suppress(OSError):
            os.close(self._fd)
        self._fd = fd
        self._in_order = True
        self._broken = False

    def close(self) -> None:
        """Close the file and release the lock (idempotent; never raises: every line was already fsync-ed)."""
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self) -> CampaignStore:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()


def _checked_header(header: Mapping[str, Any]) -> dict[str, Any]:
    if not isinstance(header, Mapping):
        raise TypeError(f"open_store: header = {header!r:.80}: expected a mapping with 'format', 'version' and "
                        "'spec_hash'; fix: pass the campaign's header, e.g. visnav.studies.campaign.store_header(spec)")
    for key, kind in (("format", str), ("version", int), ("spec_hash", str)):
        value = header.get(key)
        if not isinstance(value, kind) or isinstance(value, bool) or value == "":
            raise ValueError(f"open_store: header[{key!r}] = {value!r}: expected a non-empty {kind.__name__}; "
                             "fix: name the file format, its version and the campaign's spec hash in the header")
    if STORE_VERSION_KEY in header:
        raise ValueError(f"open_store: header[{STORE_VERSION_KEY!r}] = {header[STORE_VERSION_KEY]!r}: expected no "
                         f"such key (the store writes it); fix: remove {STORE_VERSION_KEY!r} from the header")
    return {**header, STORE_VERSION_KEY: STORE_VERSION}


def open_store(
    path: str | os.PathLike[str],
    header: Mapping[str, Any],
    codec: ResultCodec,
    *,
    samples: int,
    hints: StoreHints = StoreHints(),
) -> tuple[CampaignStore, StoreReport]:
    """Create the results file of a campaign at ``path``, or open an existing one to resume it.

    Parameters
    ----------
    path : path-like
        The JSON Lines file (its folder must exist and be writable).  The lock covers the folder:
        one open store per folder.
    header : mapping
        Line 1: ``format`` (str), ``version`` (int) and ``spec_hash`` (str) identify the
        campaign; an optional ``spec`` mapping is used to name what differs from an
        existing file.  Written as canonical JSON (sorted keys), with :data:`STORE_VERSION_KEY` added.
    codec : ResultCodec
        Converts the results to JSON objects and back, and gives their index.
    samples : int
        Number of tasks; results must have an index in ``[0, samples)``.
    hints : StoreHints
        How messages name the writing program and its options.

    Returns
    -------
    (CampaignStore, StoreReport)
        The open store (valid results loaded) and what was found.

    Raises
    ------
    CampaignStoreError
        The file belongs to another campaign, has no valid header, or is in use (naming the holder's pid).
    CampaignStoreWriteError
        A repair or a migration could not be written (disk full, ...): the file is unchanged.
    OSError
        The file cannot be read or written.
    TypeError, ValueError
        A header without its format, version and spec hash.
    """
    wanted = _checked_header(header)
    target = Path(path)
    lock = _acquire_lock(target, hints)
    try:
        if not target.exists():
            write_text_atomic(target, canonical_json(wanted) + "\n")
            report = StoreReport(path=str(target), created=True, results=0, bad_lines=(), rewritten=False)
            return CampaignStore(target, wanted, codec, samples, {}, lock, in_order=True), report
        return _resume(target, wanted, codec, samples, hints, lock)
    except BaseException:
        if lock is not None:
            lock.release()
        raise


def _header_problem(data: bytes, first: bytes, wanted: dict[str, Any]) -> tuple[str | None, Any]:
    """Why line 1 is not a header of the format of ``wanted`` (``None`` if it is), and the header read."""
    if not data:
        return "the file is empty", None
    try:
        header = _load_json(first.decode("utf-8"))
    except UnicodeDecodeError as err:
        return f"line 1 is not a campaign header (not UTF-8 text: {err.reason} at byte {err.start})", None
    except ValueError as err:
        return f"line 1 is not a campaign header ({err})", None
    if not isinstance(header, dict) or header.get("format") != wanted["format"]:
        return f"line 1 is not a {wanted['format']} header", header
    if header.get("version") != wanted["version"]:
        return f"format version {header.get('version')!r}, this visnav writes {wanted['version']}", header
    store_version = header.get(STORE_VERSION_KEY, 1)
    if store_version not in (1, STORE_VERSION):
        return f"store version {store_version!r}, this visnav reads 1 and {STORE_VERSION}", header
    return None, header


@dataclass(slots=True)
class _Read:
    """The lines read back from a results file."""

    results: dict[int, Any]
    bad: list[BadLine]
    canonical: bool  # every valid line is byte for byte what the store writes for it
    good_end: int  # bytes up to the end of the last valid line (the header counts), its newline included if any
    last_good: int  # its 1-based line number


def _resume(target: Path, wanted: dict[str, Any], codec: ResultCodec, samples: int, hints: StoreHints,
            lock: _Lock | None) -> tuple[CampaignStore, StoreReport]:
    data = target.read_bytes()
    lines = data.split(b"\n")
    ends_cleanly = data.endswith(b"\n")
    if ends_cleanly:
        lines.pop()  # the empty string after the final newline
    problem, header = _header_problem(data, lines[0], wanted)
    if problem is not None:
        raise CampaignStoreError(str(target), problem, f"a {wanted['format']} results file written by {hints.writer}",
                                 f"choose another {hints.out_option}, or move this file away to start afresh")
    if header.get("spec_hash") != wanted["spec_hash"]:
        differences = _spec_differences(header.get("spec"), wanted.get("spec"), hints.quiet_keys)
        raise CampaignStoreError(
            str(target),
            f"it belongs to another campaign (spec hash {str(header.get('spec_hash'))[:12]}..., this campaign "
            f"{wanted['spec_hash'][:12]}...{differences})",
            f"{hints.same_campaign} to resume",
            f"rerun with the options of the interrupted campaign, or choose another {hints.out_option}",
        )
    legacy = STORE_VERSION_KEY not in header
    read = _read_results(lines, ends_cleanly, samples, codec, wanted["spec_hash"], legacy)
    results, bad = read.results, read.bad
    header_canonical = lines[0] == canonical_json(wanted).encode("utf-8")
    in_order = read.canonical and header_canonical and not legacy
    rewritten = bool(bad) or not ends_cleanly
    if legacy or (rewritten and any(b.line < read.last_good for b in bad)):
        text = "\n".join([canonical_json(wanted), *(_result_line(codec, results[i], wanted["spec_hash"])
                                                    for i in results)]) + "\n"
        what = ("migrating it to store version 2 (the spec hash in every line)" if legacy else
                f"rewriting it without its {len(bad)} bad line(s)")
        try:
            write_text_atomic(target, text)
        except OSError as err:
            raise CampaignStoreWriteError(str(target), what, err, "the file is unchanged",
                                          needed_bytes=len(text.encode("utf-8"))) from err
        in_order = True
    elif rewritten:  # bad lines only after the last valid one (a cut write): truncate them away, no space needed
        try:
            with open(target, "r+b") as handle:
                handle.truncate(read.good_end)
                if not data[:read.good_end].endswith(b"\n"):
                    handle.seek(0, os.SEEK_END)
                    handle.write(b"\n")
                handle.flush()
                os.fsync(handle.fileno())
        except OSError as err:
            raise CampaignStoreWriteError(str(target), f"truncating its {len(bad)} cut line(s)", err,
                                          "the valid lines before them are unchanged") from err
    report = StoreReport(path=str(target), created=False, results=len(results), bad_lines=tuple(bad),
                         rewritten=rewritten or legacy, migrated=legacy)
    return CampaignStore(target, wanted, codec, samples, results, lock, in_order=in_order), report


def _read_results(lines: list[bytes], ends_cleanly: bool, samples: int, codec: ResultCodec, spec_hash: str,
                  legacy: bool) -> _Read:
    """The valid results of lines 2.. (first of each index kept) and the dropped lines."""
    results: dict[int, Any] = {}
    first_line: dict[int, int] = {}
    bad: list[BadLine] = []
    canonical = True
    results_checked = False
    offset = len(lines[0]) + 1
    good_end, last_good = min(offset, sum(len(raw) + 1 for raw in lines) - (0 if ends_cleanly else 1)), 1
    for number, raw in enumerate(lines[1:], start=2):
        start, offset = offset, offset + len(raw) + 1
        try:
            result, line = _parse_result(raw, samples, codec, spec_hash, legacy)
        except ValueError as err:
            reason = str(err)
            if number == len(lines) and not ends_cleanly:
                reason += " (last line, without an end of line: the write was cut)"
            bad.append(BadLine(line=number, reason=reason))
            continue
        index = codec.index(result)
        if index in results:
            same = results[index] == result
            bad.append(BadLine(line=number, reason=(
                f"sample {index} again (already on line {first_line[index]}"
                + (", identical)" if same else ", with different values: the first is kept)"))))
            continue
        results[index] = result
        first_line[index] = number
        good_end, last_good = start + len(raw) + (1 if number < len(lines) or ends_cleanly else 0), number
        if canonical and not results_checked:  # the codec writes back what it read (checked once: it is costly)
            canonical = line == _result_line(codec, result, spec_hash)
            results_checked = True
        canonical = canonical and raw == line.encode("utf-8")
    return _Read(results=results, bad=bad, canonical=canonical, good_end=good_end, last_good=last_good)
