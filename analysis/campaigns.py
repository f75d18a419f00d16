"""Campaigns of independent tasks over indices: executors, streaming, resumption, statistics.

A campaign is a picklable ``task(spec, index) -> result`` run for every index
of a set.  :func:`run_tasks` submits the tasks to any
:class:`concurrent.futures.Executor`, at most ``window`` in flight, and hands
each result to a sink in the calling thread, as it completes or in index
order; indices in ``skip`` (done in an earlier, interrupted run) are not run
again.  A task whose result depends on ``(spec, index)`` only gives the same
results whatever the executor, the number of workers or the interruptions.

:func:`campaign_executor` builds the executors: in process
(:class:`InlineExecutor`), a process pool whose workers ignore SIGINT and exit
when the campaign process dies (:func:`process_pool`), a Dask
``LocalCluster``, or a running Dask scheduler (probed with a bounded timeout,
:func:`probe_scheduler`: a peer that is not a Dask scheduler is named so,
whatever its first bytes make the Dask protocol do).  The Dask executors are
watched (:class:`WatchedExecutor`): when no worker has been alive for
``no_worker_timeout_s`` the tasks in flight fail with :class:`NoWorkerError`
instead of waiting forever.  :func:`wilson_interval` and :func:`quantiles` are
the statistics campaign summaries report.

Errors name the library's parameters (``workers``, ``scheduler address``,
``connect_timeout_s``, ``no_worker_timeout_s``); a front end shows its own
names for them with :meth:`CampaignOptionError.render`,
:meth:`SchedulerUnavailableError.render` and :meth:`NoWorkerError.render`.
Nothing here prints or writes files.

Examples
--------
>>> def square(spec, index):
...     return spec * index * index
>>> got = []
>>> run_tasks(square, 2, 4, InlineExecutor(), lambda i, r: got.append((i, r)), skip={1})
3
>>> got
[(0, 0), (2, 8), (3, 18)]
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures as cf
import contextlib
import ipaddress
import logging
import math
import multiprocessing
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybrid.errors import ParameterError

__all__ = [
    "ORDERS",
    "ORPHAN_POLL_S",
    "DEFAULT_NO_WORKER_TIMEOUT_S",
    "QUANTILES",
    "WILSON_Z",
    "CampaignOptionError",
    "SchedulerUnavailableError",
    "NotADaskSchedulerError",
    "NoWorkerError",
    "CampaignBackend",
    "InlineExecutor",
    "WatchedExecutor",
    "run_tasks",
    "campaign_executor",
    "process_pool",
    "probe_scheduler",
    "check_address",
    "dask_worker_count",
    "wilson_interval",
    "quantiles",
]

ORDERS = ("completion", "index")
"""Delivery orders of :func:`run_tasks`: as tasks complete, or in the order of the indices."""

ORPHAN_POLL_S = 1.0
"""How often a pool worker checks that its campaign process is alive [s]."""

QUANTILES = (0.0, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)
"""Default quantile levels of :func:`quantiles` (linear interpolation)."""

WILSON_Z = 1.959963984540054
"""Normal quantile of the 95 % Wilson score interval."""

DEFAULT_NO_WORKER_TIMEOUT_S = 60.0
"""How long a Dask campaign waits with no live worker before its tasks fail with :class:`NoWorkerError` [s]."""

_ADDRESS = re.compile(r"^(tcp|tls)://(\[[^\s/\[\]]+\]|[^\s/:\[\]]+):(\d{1,5})$")
_PLACEHOLDER = re.compile(r"\{(\w+)\}")
_DISPLAY_NAMES = {"scheduler": "scheduler address"}
"""How the library's own messages name a parameter (default: its identifier)."""


def _render(template: str, names: Mapping[str, str]) -> str:
    """``template`` with each ``{parameter}`` replaced by ``names[parameter]`` (or the library's name)."""
    return _PLACEHOLDER.sub(lambda m: names.get(m[1], _DISPLAY_NAMES.get(m[1], m[1])), template)


class CampaignOptionError(ParameterError):
    """An invalid campaign option (executor choice, worker count, window, indices, ...).

    ``expected`` and ``fix`` may mention other parameters as ``{name}``
    placeholders, so that a front end can show every parameter under its own
    name (:meth:`render`); ``str(err)`` uses the library's names.

    Attributes
    ----------
    parameter : str
        The offending parameter's identifier (``"workers"``, ``"scheduler"``, ``"connect_timeout_s"``, ...).
    value : object
        The value found.
    expected, fix : str
        What a valid value looks like and how to correct it (templates).
    """

    def render(self, names: Mapping[str, str] | None = None) -> str:
        """The message with parameters named by ``names`` (identifier -> shown name, e.g. CLI flags)."""
        names = {} if names is None else names
        shown = _render(f"{{{self.parameter}}}", names)
        return f"{shown} = {self.value!r}: expected {_render(self.expected, names)}; fix: {_render(self.fix, names)}"


class SchedulerUnavailableError(ConnectionError):
    """A Dask scheduler that does not answer, or has no workers, within the connect timeout.

    Attributes
    ----------
    address : str
        The scheduler address tried.
    timeout_s : float or None
        The connect timeout [s] (``None``: the failure has nothing to do with time, e.g. no TLS set up).
    reason : str
        What happened (never empty).
    fix : str
        How to proceed (a template: see :class:`CampaignOptionError`).
    """

    def __init__(self, address: str, timeout_s: float | None, reason: str, fix: str) -> None:
        self.address = address
        self.timeout_s = timeout_s
        self.reason = reason
        self.fix = fix
        super().__init__(self.render())

    def render(self, names: Mapping[str, str] | None = None) -> str:
        """The message with parameters named by ``names`` (as :meth:`CampaignOptionError.render`)."""
        names = {} if names is None else names
        within = "" if self.timeout_s is None else f" within the connect timeout of {self.timeout_s:g} s"
        return f"{_render('{scheduler}', names)} {self.address!r}: {self.reason}{within}; fix: {_render(self.fix, names)}"

    def __reduce__(self):
        return (type(self), (self.address, self.timeout_s, self.reason, self.fix))


class NotADaskSchedulerError(SchedulerUnavailableError):
    """The peer at the scheduler address answers, but not as a Dask scheduler (another service, a Dask worker).

    ``reason`` says what it sent or how reading it as the Dask protocol failed.
    """

    def render(self, names: Mapping[str, str] | None = None) -> str:
        """The message with parameters named by ``names`` (as :meth:`CampaignOptionError.render`)."""
        names = {} if names is None else names
        return (f"{_render('{scheduler}', names)} {self.address!r}: not a Dask scheduler at {self.address} "
                f"({self.reason}); fix: {_render(self.fix, names)}")


class NoWorkerError(RuntimeError):
    """No Dask worker has been alive for the watchdog's time: the campaign's tasks cannot progress.

    Attributes
    ----------
    where : str
        The cluster (``"dask scheduler tcp://...: ..."``).
    timeout_s : float
        The time without a live worker [s] (``no_worker_timeout_s``).
    detail : str
        Why no worker was counted (empty, or e.g. the scheduler not answering).
    """

    def __init__(self, where: str, timeout_s: float, detail: str = "") -> None:
        self.where = where
        self.timeout_s = timeout_s
        self.detail = detail
        super().__init__(self.render())

    def render(self, names: Mapping[str, str] | None = None) -> str:
        """The message with parameters named by ``names`` (``no_worker_timeout_s`` by its CLI flag, say)."""
        names = {} if names is None else names
        detail = f"; {self.detail}" if self.detail else ""
        return (f"no Dask worker alive for {self.timeout_s:g} s (the limit of "
                f"{_render('{no_worker_timeout_s}', names)}) on {self.where}{detail}")

    def __reduce__(self):
        return (NoWorkerError, (self.where, self.timeout_s, self.detail))


def _describe(err: BaseException, limit: int = 160) -> str:
    """``Type: message`` of an exception, never an empty reason."""
    text = " ".join(str(err).split())
    if len(text) > limit:
        text = text[:limit] + "..."
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def _check_int(name: str, value: object, minimum: int, fix: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise CampaignOptionError(name, value, f"an integer >= {minimum}", fix)
    return int(value)


def _check_seconds(name: str, value: object, fix: str, *, zero: bool = False) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and (
        value >= 0 if zero else value > 0)
    if not ok:
        raise CampaignOptionError(name, value, f"a {'non-negative' if zero else 'positive'} number of seconds", fix)
    return float(value)


# ---------------------------------------------------------------------------------------------
# Running tasks
# ---------------------------------------------------------------------------------------------


class InlineExecutor(cf.Executor):
    """An executor that runs each call at submission, in the calling process (one worker)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        """Run ``fn(*args, **kwargs)`` now; return a finished future."""
        future: cf.Future = cf.Future()
        future.set_running_or_notify_cancel()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as err:  # noqa: BLE001 - delivered through the future, as other executors do
            future.set_exception(err)
        return future


class _Proxy(cf.Future):
    """The future :class:`WatchedExecutor` hands out for one of its inner executor's futures."""

    def __init__(self, inner: cf.Future) -> None:
        super().__init__()
        self._inner = inner

    def cancel(self) -> bool:
        """Cancel the inner future; this one is cancelled only if that succeeds (as a plain future)."""
        if not self._inner.cancel():
            return super().cancelled()
        return super().cancel()


class WatchedExecutor(cf.Executor):
    """An executor whose pending futures fail with :class:`NoWorkerError` once no worker has been alive for a time.

    A thread asks ``workers()`` every ``poll_s`` seconds; once it has answered 0 (or failed) without a
    break for ``timeout_s``, every future not yet done fails with :class:`NoWorkerError`, and so do later
    submissions.  A Dask cluster whose workers are all gone otherwise keeps its tasks pending forever.

    Parameters
    ----------
    inner : concurrent.futures.Executor
        The executor that runs the tasks (a Dask ``ClientExecutor``, typically).
    workers : callable
        ``() -> int``: the number of live workers (bounded in time; an exception counts as none).
    timeout_s : float
        Time without a live worker before the futures fail [s].
    where : str
        The cluster, for the message.
    poll_s : float, optional
        Between two questions [s] (default ``min(1, timeout_s / 4)``).

    Raises
    ------
    CampaignOptionError
        ``timeout_s`` or ``poll_s`` not a positive number of seconds.
    """

    def __init__(self, inner: cf.Executor, workers: Callable[[], int], timeout_s: float, *, where: str,
                 poll_s: float | None = None) -> None:
        self._timeout = _check_seconds("no_worker_timeout_s", timeout_s, "e.g. 60")
        self._poll = _check_seconds("poll_s", min(1.0, self._timeout / 4) if poll_s is None else poll_s, "e.g. 1")
        self._inner = inner
        self._workers = workers
        self._where = where
        self._lock = threading.RLock()
        self._outstanding: dict[_Proxy, cf.Future] = {}
        self._failure: NoWorkerError | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="campaign-worker-watchdog", daemon=True)
        self._thread.start()

    @property
    def failure(self) -> NoWorkerError | None:
        """The error the futures failed with, once the watchdog fired."""
        return self._failure

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        """Submit to the inner executor; a future that fails if no worker is alive for ``timeout_s``."""
        if self._failure is not None:
            failed: cf.Future = cf.Future()
            failed.set_exception(self._failure)
            return failed
        inner = self._inner.submit(fn, *args, **kwargs)
        outer = _Proxy(inner)
        with self._lock:
            if self._failure is not None:
                outer.set_exception(self._failure)
                inner.cancel()
                return outer
            self._outstanding[outer] = inner
        inner.add_done_callback(lambda done, outer=outer: self._settle(outer, done))
        return outer

    def _settle(self, outer: _Proxy, inner: cf.Future) -> None:
        with self._lock:
            self._outstanding.pop(outer, None)
            if outer.done():
                return
            if inner.cancelled():
                cf.Future.cancel(outer)
                outer.set_running_or_notify_cancel()
            elif inner.exception() is not None:
                outer.set_exception(inner.exception())
            else:
                outer.set_result(inner.result())

    def _fail(self, error: NoWorkerError) -> None:
        with self._lock:
            self._failure = error
            victims = list(self._outstanding.items())
            self._outstanding.clear()
            for outer, _ in victims:
                if not outer.done():
                    outer.set_exception(error)
        for _, inner in victims:
            inner.cancel()

    def _watch(self) -> None:
        since: float | None = None
        detail = ""
        while not self._stop.wait(self._poll):
            try:
                alive = int(self._workers())
                detail = ""
            except Exception as err:  # noqa: BLE001 - a scheduler that does not answer has no worker for us
                alive = 0
                detail = f"the scheduler did not answer ({_describe(err)})"
            now = time.monotonic()
            if alive > 0:
                since = None
                continue
            since = now if since is None else since
            if now - since >= self._timeout:
                self._fail(NoWorkerError(self._where, self._timeout, detail))
                return

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop the watchdog and shut the inner executor down."""
        self._stop.set()
        if cancel_futures:
            with self._lock:
                inner = list(self._outstanding.values())
            for future in inner:
                future.cancel()
        self._inner.shutdown(wait=wait)
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=self._poll + 1.0)


def _todo(indices: int | Iterable[int], skip: Collection[int]) -> list[int]:
    if isinstance(indices, (int, np.integer)) and not isinstance(indices, bool):
        _check_int("indices", indices, 0, "give the number of tasks, or the indices to run")
        listed = list(range(int(indices)))
    else:
        listed = list(indices)
        if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in listed):
            raise CampaignOptionError("indices", listed[:8], "integers", "give the task indices as integers")
        listed = [int(i) for i in listed]
        if len(set(listed)) != len(listed):
            raise CampaignOptionError("indices", sorted(i for i, n in collections.Counter(listed).items() if n > 1),
                                      "each index once", "remove the repeated indices")
    done = frozenset(skip)
    return [i for i in listed if i not in done]


def run_tasks(
    task: Callable[[Any, int], Any],
    spec: Any,
    indices: int | Iterable[int],
    executor: cf.Executor,
    sink: Callable[[int, Any], None],
    *,
    skip: Collection[int] = (),
    window: int = 8,
    order: str = "completion",
    interrupt_grace_s: float = 5.0,
) -> int:
    """Run ``task(spec, i)`` on ``executor`` for every index ``i`` not in ``skip``; call ``sink(i, result)``.

    Parameters
    ----------
    task : callable
        ``task(spec, index) -> result``; picklable (a module-level function) for process and
        Dask executors.  An exception it raises propagates from :func:`run_tasks` (after the
        tasks in flight are cancelled): a task should return its failures as results.
    spec : object
        The campaign's description, passed to every task (picklable).
    indices : int or iterable of int
        ``N`` for ``0..N-1``, or the distinct indices to run, in order.
    executor : concurrent.futures.Executor
        A process pool, a Dask ``ClientExecutor``, :class:`InlineExecutor`, ...
    sink : callable
        Receives each index and result in the calling thread (e.g. appends it to a file).
    skip : collection of int
        Indices already done (a resumed campaign).
    window : int
        Tasks submitted ahead, results held included (a few per worker keeps them busy).
    order : {"completion", "index"}
        ``"completion"``: results as they complete (those completing together in index
        order).  ``"index"``: in the order of ``indices``, a result that completes early
        held until those before it are delivered.
    interrupt_grace_s : float
        On ``KeyboardInterrupt``: queued tasks are cancelled, running ones are waited for
        up to this long [s] and their results, and those held, still reach ``sink`` (in
        index order); then the interrupt propagates.

    Returns
    -------
    int
        Number of results handed to ``sink``.

    Raises
    ------
    CampaignOptionError
        Bad ``indices``, ``window``, ``order`` or ``interrupt_grace_s``.
    """
    _check_int("window", window, 1, "use a few tasks per worker, e.g. 8")
    if order not in ORDERS:
        raise CampaignOptionError("order", order, f"one of {', '.join(ORDERS)}", "use 'completion' or 'index'")
    grace = _check_seconds("interrupt_grace_s", interrupt_grace_s, "e.g. 5", zero=True)
    todo = _todo(indices, skip)
    queue = iter(todo)
    expected = collections.deque(todo)  # "index" order: the indices still to deliver, in order
    pending: dict[cf.Future, int] = {}
    held: dict[int, Any] = {}
    delivered = 0

    def refill() -> None:
        while len(pending) + len(held) < window:
            index = next(queue, None)
            if index is None:
                return
            pending[executor.submit(task, spec, index)] = index

    def emit(index: int, result: Any) -> None:
        nonlocal delivered
        sink(index, result)
        delivered += 1

    def collect(future: cf.Future) -> None:
        index = pending.pop(future)
        result = future.result()
        if order == "completion":
            emit(index, result)
            return
        held[index] = result
        while expected and expected[0] in held:
            first = expected.popleft()
            emit(first, held.pop(first))

    try:
        refill()
        while pending:
            done, _ = cf.wait(list(pending), return_when=cf.FIRST_COMPLETED)
            for future in sorted(done, key=pending.__getitem__):
                collect(future)
                refill()
    except KeyboardInterrupt:
        _drain(pending, held, grace, emit)
        raise
    except BaseException:
        for future in pending:
            future.cancel()
        raise
    return delivered


def _drain(pending: dict[cf.Future, int], held: dict[int, Any], grace_s: float,
           emit: Callable[[int, Any], None]) -> None:
    """After an interrupt: cancel the queued tasks, wait for the running ones, deliver what finished."""
    for future in pending:
        future.cancel()
    running = [f for f in pending if not f.cancelled()]
    if running:
        cf.wait(running, timeout=grace_s)
    for future in running:
        if future.done() and not future.cancelled() and future.exception() is None:
            held[pending[future]] = future.result()
    for index in sorted(held):
        emit(index, held.pop(index))


# ---------------------------------------------------------------------------------------------
# Executors
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class CampaignBackend:
    """An executor ready for :func:`run_tasks`.

    Attributes
    ----------
    executor : concurrent.futures.Executor
        The executor.
    kind : str
        ``"inline"``, ``"process"`` or ``"dask"``.
    workers : int
        Worker processes (Dask: threads over all workers).
    description : str
        Human description (``"process pool, 2 workers"``, ``"dask tcp://...: 2 workers"``).
    window : int
        Suggested :func:`run_tasks` window.
    """

    executor: cf.Executor
    kind: str
    workers: int
    description: str
    window: int


def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (Linux ``/proc``; elsewhere existence only)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as handle:
            state = handle.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in ("Z", "X")


def _init_worker(campaign_pid: int) -> None:
    """Pool worker initialiser.

    The parent handles Ctrl-C (the terminal sends it to the whole process group),
    so workers ignore SIGINT.  A worker whose campaign process dies (killed with
    SIGKILL) exits within :data:`ORPHAN_POLL_S` instead of waiting forever on its
    task queue; the forkserver and the resource tracker then exit by themselves.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while True:
            time.sleep(ORPHAN_POLL_S)
            if not _process_alive(campaign_pid):
                os._exit(1)

    threading.Thread(target=watch, name="campaign-orphan-watch", daemon=True).start()


def process_pool(workers: int, *, preload: Sequence[str] = ()) -> cf.ProcessPoolExecutor:
    """A process pool for campaigns: forkserver start, workers ignoring SIGINT, orphans exiting.

    ``forkserver`` keeps the pool safe in a process that already has threads (a Dask
    client, a test runner); the modules in ``preload`` are imported once in the server,
    which makes worker start-up cheap.

    Parameters
    ----------
    workers : int
        Worker processes, ``>= 1``.
    preload : sequence of str
        Modules the forkserver imports (the task's module, typically).

    Raises
    ------
    CampaignOptionError
        ``workers`` not an integer >= 1.
    """
    _check_int("workers", workers, 1, "give the number of worker processes, e.g. 2")
    context = multiprocessing.get_context("forkserver")
    if preload:
        context.set_forkserver_preload(list(preload))
    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_init_worker,
                                  initargs=(os.getpid(),))


def probe_scheduler(address: str, timeout_s: float) -> None:
    """Ask the Dask scheduler at ``address`` for its identity, within ``timeout_s`` overall.

    ``distributed.Client(address, timeout=...)`` can wait indefinitely on a peer
    that accepts the connection but never answers; this probe cannot.  A peer that
    is not a Dask scheduler (a service sending a banner, which the Dask protocol
    reads as the length of a huge message: ``MemoryError``; a Dask worker) is
    reported as such, whatever exception reading it raised.

    Raises
    ------
    NotADaskSchedulerError
        Something answers, but not a Dask scheduler.
    SchedulerUnavailableError
        Nothing answers the identity request in time (the reason says what timed out, after how
        long), or TLS is asked for and not configured.
    """
    from distributed.comm import connect
    from distributed.security import Security

    tls_fix = ("set distributed.comm.tls.ca-file, .client.cert and .client.key in the Dask configuration, "
               "or give a tcp:// {scheduler}")
    try:
        connection_args = Security().get_connection_args("client") if address.startswith("tls://") else {}
    except Exception as err:  # noqa: BLE001 - unreadable certificate files, a bad configuration
        raise SchedulerUnavailableError(address, None, f"the Dask TLS configuration cannot be used "
                                        f"({_describe(err)})", tls_fix) from err
    stage = ["connecting and exchanging the Dask handshake"]
    start = time.monotonic()

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout_s, **connection_args)
        stage[0] = "waiting for the answer to an identity request"
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    retry = ("start one (`dask scheduler`, then `dask worker ADDRESS`), check the address and port, "
             "or raise {connect_timeout_s}")
    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s))
    except (asyncio.TimeoutError, TimeoutError) as err:
        raise SchedulerUnavailableError(
            address, timeout_s, f"no Dask scheduler answered (timed out after {timeout_s:g} s {stage[0]})",
            retry) from err
    except OSError as err:
        raise SchedulerUnavailableError(address, timeout_s, f"no Dask scheduler answered ({_describe(err)})",
                                        retry) from err
    except Exception as err:  # noqa: BLE001 - MemoryError, msgpack, struct...: the peer speaks another protocol
        if address.startswith("tls://") and isinstance(err, TypeError) and "ssl" in str(err).lower():
            raise SchedulerUnavailableError(
                address, None, f"TLS is not configured for the Dask client ({_describe(err)})", tls_fix) from err
        sent = _first_bytes(address, max(0.0, min(0.5, timeout_s - (time.monotonic() - start))))
        raise NotADaskSchedulerError(
            address, timeout_s, f"{sent}reading its first message as the Dask protocol failed: {_describe(err)}",
            "give the {scheduler} of a Dask scheduler (`dask scheduler` prints it), not another service's port") from err
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        kind = reply.get("type") if isinstance(reply, dict) else None
        what = (f"it is a Dask {kind}" if isinstance(kind, str) else
                f"it answered the identity request with {reply!r:.80}")
        raise NotADaskSchedulerError(address, timeout_s, what,
                                     "give the {scheduler} of a Dask scheduler (a worker's log names its scheduler)")


def _first_bytes(address: str, wait_s: float) -> str:
    """``"it sent b'...'; "``: what a TCP peer sends first (best effort, within ``wait_s``), for a message."""
    match = _ADDRESS.match(address)
    if match is None or match[1] != "tcp" or wait_s <= 0:
        return ""
    host = match[2].strip("[]")

    async def peek() -> bytes:
        reader, writer = await asyncio.open_connection(host, int(match[3]))
        try:
            return await reader.read(48)
        finally:
            writer.close()

    try:
        sent = asyncio.run(asyncio.wait_for(peek(), wait_s))
    except Exception:  # noqa: BLE001 - only for the message
        return ""
    return f"it sent {sent!r}; " if sent else ""


def check_address(address: object) -> str:
    """``address`` if it reads ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` (port 1-65535; an IPv6 host in
    brackets, ``tcp://[::1]:8786``).

    Raises
    ------
    CampaignOptionError
        Naming the ``scheduler`` parameter.
    """
    match = _ADDRESS.match(address) if isinstance(address, str) else None
    ok = match is not None and 0 < int(match[3]) < 65536
    if ok and match[2].startswith("["):
        try:
            ipaddress.IPv6Address(match[2][1:-1])
        except ValueError:
            ok = False
    if not ok:
        raise CampaignOptionError("scheduler", address, "an address tcp://HOST:PORT (or tls://HOST:PORT; an IPv6 "
                                  "host in brackets: tcp://[::1]:8786)", "e.g. {scheduler} tcp://127.0.0.1:8786")
    return address  # type: ignore[return-value]


@contextlib.contextmanager
def campaign_executor(
    *,
    workers: int | None = None,
    dask_local: int | None = None,
    scheduler: str | None = None,
    connect_timeout_s: float = 10.0,
    no_worker_timeout_s: float = DEFAULT_NO_WORKER_TIMEOUT_S,
    preload: Sequence[str] = (),
) -> Iterator[CampaignBackend]:
    """An executor for a campaign, shut down (cluster included) on exit.

    Give at most one of ``workers``, ``dask_local`` and ``scheduler``; with none,
    a process pool of ``os.cpu_count()`` workers.

    Parameters
    ----------
    workers : int, optional
        Process pool size (:func:`process_pool`); 1 runs in the calling process
        (:class:`InlineExecutor`).
    dask_local : int, optional
        Workers of a ``distributed.LocalCluster`` (one process and one thread each).
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running Dask scheduler; its workers must be able to import
        the task's module.
    connect_timeout_s : float
        Bound on reaching the scheduler, and on waiting for its first worker [s].
    no_worker_timeout_s : float
        Dask executors: once no worker has been alive for this long [s], the tasks in flight fail
        with :class:`NoWorkerError` (:class:`WatchedExecutor`).  A process pool whose worker dies
        fails at once (``BrokenProcessPool``).
    preload : sequence of str
        Modules the process pool's forkserver imports (:func:`process_pool`).

    Raises
    ------
    CampaignOptionError
        Bad option values.
    SchedulerUnavailableError
        The scheduler does not answer, is not a Dask scheduler (:class:`NotADaskSchedulerError`), or
        has no worker within ``connect_timeout_s``.
    """
    options = {"workers": workers, "dask_local": dask_local, "scheduler": scheduler}
    chosen = [name for name, value in options.items() if value is not None]
    if len(chosen) > 1:
        listed = " and ".join(f"{{{name}}}" for name in chosen)
        raise CampaignOptionError(chosen[1], options[chosen[1]], f"one executor option, but {listed} were given",
                                  "keep one of them")
    timeout = _check_seconds("connect_timeout_s", connect_timeout_s, "e.g. 10")
    idle = _check_seconds("no_worker_timeout_s", no_worker_timeout_s, "e.g. 60")
    if scheduler is not None:
        with _scheduler_backend(check_address(scheduler), timeout, idle) as backend:
            yield backend
        return
    if dask_local is not None:
        _check_int("dask_local", dask_local, 1, "give the number of Dask worker processes, e.g. 2")
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=dask_local, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as cluster, Client(cluster, set_as_default=False) as client:
            description = f"dask LocalCluster, {dask_local} workers"
            with _watched(client, idle, description) as executor:
                yield CampaignBackend(executor=executor, kind="dask", workers=dask_local, description=description,
                                      window=max(4, 2 * dask_local))
        return
    n = (os.cpu_count() or 1) if workers is None else workers
    _check_int("workers", n, 1, "give the number of worker processes, e.g. 2")
    if n == 1:
        yield CampaignBackend(executor=InlineExecutor(), kind="inline", workers=1,
                              description="1 worker (in process)", window=1)
        return
    pool = process_pool(n, preload=preload)
    try:
        yield CampaignBackend(executor=pool, kind="process", workers=n, description=f"process pool, {n} workers",
                              window=2 * n)
    except BaseException:
        # interrupted or failed: what finished was delivered (run_campaign drains within its grace); a blocking
        # shutdown can hang when the interrupt hit the pool mid-submit, so the workers are stopped instead
        # (their tasks are recomputed on resume: results depend on (seed, index) only)
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True, cancel_futures=True)


def _stop_pool(pool: cf.ProcessPoolExecutor, join_s: float = 5.0) -> None:
    """Shut ``pool`` down without waiting on its queues, then end its worker processes (joined, else terminated)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + join_s
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.terminate()
            process.join(1.0)


def dask_worker_count(client: Any, timeout_s: float) -> int:
    """Live workers of a Dask ``client``'s scheduler, asked with a bound of ``timeout_s`` [s]."""
    info = client.sync(client.scheduler.identity, n_workers=0, callback_timeout=timeout_s)
    return int(info["n_workers"])


@contextlib.contextmanager
def _watched(client: Any, idle_s: float, where: str) -> Iterator[WatchedExecutor]:
    executor = WatchedExecutor(client.get_executor(pure=False),
                               lambda: dask_worker_count(client, max(1.0, min(5.0, idle_s))), idle_s, where=where)
    try:
        yield executor
    finally:
        executor.shutdown(wait=False)


@contextlib.contextmanager
def _scheduler_backend(scheduler: str, timeout_s: float, idle_s: float) -> Iterator[CampaignBackend]:
    """The executor of a running Dask scheduler (probed first), with at least one worker."""
    probe_scheduler(scheduler, timeout_s)
    from distributed import Client

    try:
        client = Client(scheduler, timeout=timeout_s, set_as_default=False)
    except Exception as err:  # noqa: BLE001 - after a good probe: a scheduler that went away, a refused client
        raise SchedulerUnavailableError(scheduler, timeout_s, f"the client could not connect ({_describe(err)})",
                                        "check the scheduler and raise {connect_timeout_s}") from err
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except (OSError, asyncio.TimeoutError) as err:
            raise SchedulerUnavailableError(scheduler, timeout_s, "the scheduler has no worker",
                                            "start workers with `dask worker ADDRESS`") from err
        threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
        description = f"dask scheduler {scheduler}: {threads} worker threads"
        with _watched(client, idle_s, f"dask scheduler {scheduler}") as executor:
            yield CampaignBackend(executor=executor, kind="dask", workers=threads, description=description,
                                  window=max(4, 2 * threads))
    finally:
        client.close()


# ---------------------------------------------------------------------------------------------
# Statistics
# ---------------------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, z: float = WILSON_Z) -> tuple[float, float] | None:
    """Wilson score interval of a binomial proportion (``None`` for ``n = 0``).

    Examples
    --------
    >>> lo, hi = wilson_interval(10, 10)
    >>> round(lo, 4), hi
    (0.7225, 1.0)
    """
    if n == 0:
        return None
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)  # exact bounds, not 1 - 1e-16
    high = 1.0 if successes == n else min(1.0, centre + half)
    return (low, high)


def quantiles(values: Sequence[float], levels: Sequence[float] = QUANTILES) -> tuple[tuple[float, float], ...]:
    """``(level, value)`` pairs of the linearly interpolated quantiles of ``values`` (``()`` when empty)."""
    if not len(values):
        return ()
    q = np.quantile(np.asarray(values, dtype=float), levels, method="linear")
    return tuple((level, float(v)) for level, v in zip(levels, q))
