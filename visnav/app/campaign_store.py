"""The results file of a campaign: append-only JSON Lines, resumable after any interruption.

Line 1 is a header given by the campaign (a JSON object naming the format, its
version and the campaign's spec hash, usually with the full spec); every further
line is one finished task, written as soon as it arrives, then flushed and
``fsync``-ed::

    {"format":"visnav-campaign","spec":{...},"spec_hash":"3f2a...","version":1}
    {"result":{"index":4,"outcome":"success",...},"sha256":"9c1e0b7d5a3f2e41"}

``sha256`` is the first 16 hex digits of the SHA-256 of the result's canonical
JSON, so that a line altered after it was written is detected, not only a cut
one.  :func:`open_store` reads an existing file back: it refuses a file of a
different campaign (another format, version or spec hash), reports every bad
line (1-based line number and why: cut, not JSON, checksum, malformed field,
index out of range, duplicate), keeps the valid lines and, if it found bad
ones, rewrites the file atomically without them.  The indices read back are
then skipped by the campaign.  :meth:`CampaignStore.compact` rewrites a file in
index order, so that its bytes do not depend on how the campaign was run.

The store knows nothing of what a result is: a :class:`ResultCodec` converts
results to JSON objects and back and gives their index (``visnav sweep`` uses
:class:`visnav.studies.campaign.SampleResult`; any campaign of indexed results
can use it).  This module writes files; the campaigns themselves do not.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from hybrid.jsonable import canonical_json

from visnav.app.files import write_text_atomic

try:  # advisory lock against two campaigns writing one file (POSIX only)
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "CHECKSUM_HEX",
    "CampaignStoreError",
    "ResultCodec",
    "StoreHints",
    "BadLine",
    "StoreReport",
    "CampaignStore",
    "open_store",
    "line_checksum",
]

CHECKSUM_HEX = 16
"""Hex digits of the per-line SHA-256 kept in the file."""


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


@dataclass(frozen=True, kw_only=True, slots=True)
class ResultCodec:
    """How one kind of result is stored.

    Attributes
    ----------
    to_dict : callable
        ``result -> dict`` of JSON types (its canonical JSON is what the checksum covers).
    from_dict : callable
        ``dict -> result``; raises ``ValueError`` or ``TypeError`` naming the field for a malformed one.
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
        The file was rewritten (atomically) without the bad lines.
    """

    path: str
    created: bool
    results: int
    bad_lines: tuple[BadLine, ...]
    rewritten: bool


def line_checksum(result: dict[str, Any]) -> str:
    """First :data:`CHECKSUM_HEX` hex digits of the SHA-256 of the result's canonical JSON."""
    return hashlib.sha256(canonical_json(result).encode("utf-8")).hexdigest()[:CHECKSUM_HEX]


def _result_line(codec: ResultCodec, result: Any) -> str:
    data = codec.to_dict(result)
    return canonical_json({"result": data, "sha256": line_checksum(data)})


def _parse_result(raw: bytes, samples: int, codec: ResultCodec) -> Any:
    """One result line -> result; ``ValueError`` with the reason otherwise."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ValueError(f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    if not text.strip():
        raise ValueError("empty line")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise ValueError(f"not valid JSON ({err.msg} at column {err.colno}): cut by an interruption or altered") from None
    if not isinstance(data, dict) or set(data) != {"result", "sha256"}:
        keys = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ValueError(f"not a result record (expected the keys 'result' and 'sha256', found {keys})")
    if not isinstance(data["result"], dict) or data["sha256"] != line_checksum(data["result"]):
        raise ValueError("checksum mismatch: the line was altered after it was written")
    try:
        result = codec.from_dict(data["result"])
        index = codec.index(result)
    except (TypeError, ValueError) as err:
        raise ValueError(f"malformed result ({err})") from None
    if not 0 <= index < samples:
        raise ValueError(f"index {index} outside the campaign's [0, {samples})")
    return result


def _spec_differences(found: Any, wanted: Any, quiet: tuple[str, ...]) -> str:
    if not isinstance(found, dict) or not isinstance(wanted, Mapping):
        return ""
    keys = [k for k in wanted if k not in quiet and found.get(k) != wanted[k]]
    shown = [f"{k} {json.dumps(found.get(k))} in the file, {json.dumps(wanted[k])} now" for k in keys[:4]]
    return f" ({'; '.join(shown)})" if shown else ""


@contextlib.contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold back ``KeyboardInterrupt`` until the block ends (main thread, default handler only)."""
    if threading.current_thread() is not threading.main_thread() or (
        signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
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


class CampaignStore:
    """The open results file of one campaign; use :func:`open_store` to get one.

    Appends are durable one by one (write, flush, ``fsync``).  Use it as a
    context manager, or call :meth:`close`.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    header : dict
        The campaign's header (line 1).
    samples : int
        Number of tasks: valid indices are ``0 .. samples - 1``.
    """

    def __init__(self, path: Path, header: dict[str, Any], codec: ResultCodec, samples: int,
                 results: dict[int, Any], lock: BinaryIO | None) -> None:
        self.path = path
        self.header = header
        self.samples = samples
        self._codec = codec
        self._results = results
        self._lock = lock
        self._handle: BinaryIO | None = open(path, "ab")

    @property
    def done(self) -> frozenset[int]:
        """Indices with a stored result."""
        return frozenset(self._results)

    def results(self) -> tuple[Any, ...]:
        """Stored results in index order."""
        return tuple(self._results[i] for i in sorted(self._results))

    def append(self, result: Any) -> None:
        """Write ``result`` as one line, flushed and ``fsync``-ed before returning.

        Raises
        ------
        ValueError
            For an index outside the campaign or already stored (a result is never written twice).
        """
        if self._handle is None:
            raise ValueError(f"campaign file {str(self.path)!r} is closed; fix: open it again with open_store")
        index = self._codec.index(result)
        if not 0 <= index < self.samples or index in self._results:
            raise ValueError(f"sample {index}: expected a new index in [0, {self.samples}) "
                             "(already stored or out of range); fix: skip the indices in CampaignStore.done")
        line = _result_line(self._codec, result) + "\n"
        with _sigint_deferred():  # a Ctrl-C here is raised once the line is durable and counted
            self._handle.write(line.encode("utf-8"))
            self._handle.flush()
            os.fsync(self._handle.fileno())
            self._results[index] = result

    def compact(self) -> None:
        """Rewrite the file atomically with the results in index order (its bytes then depend on
        the campaign only, not on the completion order)."""
        self._close_handle()
        lines = [canonical_json(self.header), *(_result_line(self._codec, r) for r in self.results())]
        write_text_atomic(self.path, "\n".join(lines) + "\n")
        self._handle = open(self.path, "ab")

    def _close_handle(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def close(self) -> None:
        """Close the file and release the lock (idempotent)."""
        self._close_handle()
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def __enter__(self) -> CampaignStore:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()


def _acquire_lock(path: Path, hints: StoreHints) -> BinaryIO | None:
    if fcntl is None:  # pragma: no cover - not POSIX
        return None
    lock = open(path.with_name(path.name + ".lock"), "ab")
    try:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        raise CampaignStoreError(str(path), "another process is writing this campaign",
                                 f"a file no other {hints.writer} uses",
                                 f"wait for the other `{hints.writer}` to finish, or choose another "
                                 f"{hints.out_option}") from None
    return lock


def _checked_header(header: Mapping[str, Any]) -> dict[str, Any]:
    if not isinstance(header, Mapping):
        raise TypeError(f"open_store: header = {header!r:.80}: expected a mapping with 'format', 'version' and "
                        "'spec_hash'; fix: pass the campaign's header, e.g. visnav.studies.campaign.store_header(spec)")
    for key, kind in (("format", str), ("version", int), ("spec_hash", str)):
        value = header.get(key)
        if not isinstance(value, kind) or isinstance(value, bool) or value == "":
            raise ValueError(f"open_store: header[{key!r}] = {value!r}: expected a non-empty {kind.__name__}; "
                             "fix: name the file format, its version and the campaign's spec hash in the header")
    return dict(header)


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
        The JSON Lines file (its folder must exist and be writable).
    header : mapping
        Line 1: ``format`` (str), ``version`` (int) and ``spec_hash`` (str) identify the
        campaign; an optional ``spec`` mapping is used to name what differs from an
        existing file.  Written as canonical JSON (sorted keys).
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
        The file belongs to another campaign, has no valid header, or is in use.
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
            return CampaignStore(target, wanted, codec, samples, {}, lock), report
        return _resume(target, wanted, codec, samples, hints, lock)
    except BaseException:
        if lock is not None:
            lock.close()
        raise


def _header_problem(data: bytes, first: bytes, wanted: dict[str, Any]) -> tuple[str | None, Any]:
    """Why line 1 is not a header of the format of ``wanted`` (``None`` if it is), and the header read."""
    if not data:
        return "the file is empty", None
    try:
        header = json.loads(first.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        return f"line 1 is not a campaign header ({err})", None
    if not isinstance(header, dict) or header.get("format") != wanted["format"]:
        return f"line 1 is not a {wanted['format']} header", header
    if header.get("version") != wanted["version"]:
        return f"format version {header.get('version')!r}, this visnav writes {wanted['version']}", header
    return None, header


def _resume(target: Path, wanted: dict[str, Any], codec: ResultCodec, samples: int, hints: StoreHints,
            lock: BinaryIO | None) -> tuple[CampaignStore, StoreReport]:
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
    results, bad = _read_results(lines, ends_cleanly, samples, codec)
    rewritten = bool(bad) or not ends_cleanly
    if rewritten:
        kept = [lines[0].decode("utf-8")] + [_result_line(codec, results[i]) for i in results]
        write_text_atomic(target, "\n".join(kept) + "\n")
    report = StoreReport(path=str(target), created=False, results=len(results), bad_lines=tuple(bad),
                         rewritten=rewritten)
    return CampaignStore(target, wanted, codec, samples, results, lock), report


def _read_results(lines: list[bytes], ends_cleanly: bool, samples: int,
                  codec: ResultCodec) -> tuple[dict[int, Any], list[BadLine]]:
    """The valid results of lines 2.. (first of each index kept) and the dropped lines."""
    results: dict[int, Any] = {}
    first_line: dict[int, int] = {}
    bad: list[BadLine] = []
    for number, raw in enumerate(lines[1:], start=2):
        try:
            result = _parse_result(raw, samples, codec)
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
    return results, bad
