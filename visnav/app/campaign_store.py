"""The results file of a campaign: append-only JSON Lines, resumable after any interruption.

Line 1 is a header naming the format and the campaign's spec hash (and the
full spec); every further line is one finished sample, written as soon as it
arrives, then flushed and ``fsync``-ed::

    {"format":"visnav-campaign","spec":{...},"spec_hash":"3f2a...","version":1}
    {"result":{"index":4,"outcome":"success",...},"sha256":"9c1e0b7d5a3f2e41"}

``sha256`` is the first 16 hex digits of the SHA-256 of the result's canonical
JSON, so that a line altered after it was written is detected, not only a cut
one.  :func:`open_store` reads an existing file back: it refuses a file of a
different campaign, reports every bad line (1-based line number and why: cut,
not JSON, checksum, malformed field, index out of range, duplicate), keeps the
valid lines and, if it found bad ones, rewrites the file atomically without
them.  The indices read back are then skipped by the campaign.
:meth:`CampaignStore.compact` rewrites a complete file in index order, so that
its bytes do not depend on how the campaign was run.

This module writes files; :mod:`visnav.studies.campaign` does not.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import threading
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Iterator
from types import TracebackType
from typing import Any, BinaryIO

from visnav.studies.campaign import CAMPAIGN_FORMAT, CAMPAIGN_VERSION, CampaignSpec, SampleResult, canonical_json
from visnav.app.files import write_text_atomic

try:  # advisory lock against two sweeps writing one file (POSIX only)
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

__all__ = ["CampaignStoreError", "BadLine", "StoreReport", "CampaignStore", "open_store", "line_checksum"]

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


def _header(spec: CampaignSpec) -> str:
    return canonical_json({"format": CAMPAIGN_FORMAT, "version": CAMPAIGN_VERSION, "spec_hash": spec.spec_hash(),
                           "spec": spec.as_dict()})


def _result_line(result: SampleResult) -> str:
    data = result.as_dict()
    return canonical_json({"result": data, "sha256": line_checksum(data)})


def _parse_result(raw: bytes, samples: int) -> SampleResult:
    """One result line → :class:`SampleResult`; ``ValueError`` with the reason otherwise."""
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
        result = SampleResult.from_dict(data["result"])
    except (TypeError, ValueError) as err:
        raise ValueError(f"malformed result ({err})") from None
    if result.index >= samples:
        raise ValueError(f"index {result.index} outside the campaign's [0, {samples})")
    return result


def _spec_differences(found: Any, wanted: dict[str, Any]) -> str:
    if not isinstance(found, dict):
        return ""
    keys = [k for k in wanted if k != "scenario_toml" and found.get(k) != wanted[k]]  # the digest covers the text
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
    """

    def __init__(self, path: Path, spec: CampaignSpec, results: dict[int, SampleResult], lock: BinaryIO | None) -> None:
        self.path = path
        self.spec = spec
        self._results = results
        self._lock = lock
        self._handle: BinaryIO | None = open(path, "ab")

    @property
    def done(self) -> frozenset[int]:
        """Indices with a stored result."""
        return frozenset(self._results)

    def results(self) -> tuple[SampleResult, ...]:
        """Stored results in index order."""
        return tuple(self._results[i] for i in sorted(self._results))

    def append(self, result: SampleResult) -> None:
        """Write ``result`` as one line, flushed and ``fsync``-ed before returning.

        Raises
        ------
        ValueError
            For an index outside the campaign or already stored (a result is never written twice).
        """
        if self._handle is None:
            raise ValueError(f"campaign file {str(self.path)!r} is closed; fix: open it again with open_store")
        if not 0 <= result.index < self.spec.samples or result.index in self._results:
            raise ValueError(f"sample {result.index}: expected a new index in [0, {self.spec.samples}) "
                             "(already stored or out of range); fix: skip the indices in CampaignStore.done")
        with _sigint_deferred():  # a Ctrl-C here is raised once the line is durable and counted
            self._handle.write((_result_line(result) + "\n").encode("utf-8"))
            self._handle.flush()
            os.fsync(self._handle.fileno())
            self._results[result.index] = result

    def compact(self) -> None:
        """Rewrite the file atomically with the results in index order (its bytes then depend on
        the campaign only, not on the completion order)."""
        self._close_handle()
        text = "\n".join([_header(self.spec), *(_result_line(r) for r in self.results())]) + "\n"
        write_text_atomic(self.path, text)
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


def _acquire_lock(path: Path) -> BinaryIO | None:
    if fcntl is None:  # pragma: no cover - not POSIX
        return None
    lock = open(path.with_name(path.name + ".lock"), "ab")
    try:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        raise CampaignStoreError(str(path), "another process is writing this campaign", "a file no other sweep uses",
                                 "wait for the other `visnav sweep` to finish, or choose another --out") from None
    return lock


def open_store(path: str | os.PathLike[str], spec: CampaignSpec) -> tuple[CampaignStore, StoreReport]:
    """Create the results file of ``spec`` at ``path``, or open an existing one to resume it.

    Parameters
    ----------
    path : path-like
        The JSON Lines file (its folder must exist and be writable).
    spec : CampaignSpec
        The campaign; an existing file must carry the same spec hash.

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
    """
    target = Path(path)
    lock = _acquire_lock(target)
    try:
        if not target.exists():
            write_text_atomic(target, _header(spec) + "\n")
            report = StoreReport(path=str(target), created=True, results=0, bad_lines=(), rewritten=False)
            return CampaignStore(target, spec, {}, lock), report
        store, report = _resume(target, spec, lock)
        return store, report
    except BaseException:
        if lock is not None:
            lock.close()
        raise


def _resume(target: Path, spec: CampaignSpec, lock: BinaryIO | None) -> tuple[CampaignStore, StoreReport]:
    data = target.read_bytes()
    lines = data.split(b"\n")
    ends_cleanly = data.endswith(b"\n")
    if ends_cleanly:
        lines.pop()  # the empty string after the final newline
    header_problem = None
    header: Any = None
    if not data:
        header_problem = "the file is empty"
    else:
        try:
            header = json.loads(lines[0].decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            header_problem = f"line 1 is not a campaign header ({err})"
        else:
            if not isinstance(header, dict) or header.get("format") != CAMPAIGN_FORMAT:
                header_problem = f"line 1 is not a {CAMPAIGN_FORMAT} header"
            elif header.get("version") != CAMPAIGN_VERSION:
                header_problem = f"format version {header.get('version')!r}, this visnav writes {CAMPAIGN_VERSION}"
    if header_problem is not None:
        raise CampaignStoreError(str(target), header_problem, f"a {CAMPAIGN_FORMAT} results file written by visnav sweep",
                                 "choose another --out, or move this file away to start afresh")
    wanted = spec.spec_hash()
    if header.get("spec_hash") != wanted:
        differences = _spec_differences(header.get("spec"), spec.as_dict())
        raise CampaignStoreError(
            str(target),
            f"it belongs to another campaign (spec hash {str(header.get('spec_hash'))[:12]}..., this campaign "
            f"{wanted[:12]}...{differences})",
            "the same scenario, --samples, --seed and distributions to resume",
            "rerun with the options of the interrupted campaign, or choose another --out",
        )
    results: dict[int, SampleResult] = {}
    first_line: dict[int, int] = {}
    bad: list[BadLine] = []
    for number, raw in enumerate(lines[1:], start=2):
        try:
            result = _parse_result(raw, spec.samples)
        except ValueError as err:
            reason = str(err)
            if number == len(lines) and not ends_cleanly:
                reason += " (last line, without an end of line: the write was cut)"
            bad.append(BadLine(line=number, reason=reason))
            continue
        if result.index in results:
            same = results[result.index] == result
            bad.append(BadLine(line=number, reason=(
                f"sample {result.index} again (already on line {first_line[result.index]}"
                + (", identical)" if same else ", with different values: the first is kept)"))))
            continue
        results[result.index] = result
        first_line[result.index] = number
    rewritten = bool(bad) or not ends_cleanly
    if rewritten:
        kept = [lines[0].decode("utf-8")] + [_result_line(results[i]) for i in results]
        write_text_atomic(target, "\n".join(kept) + "\n")
    report = StoreReport(path=str(target), created=False, results=len(results), bad_lines=tuple(bad),
                         rewritten=rewritten)
    return CampaignStore(target, spec, results, lock), report
