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
:func:`probe_scheduler`).  :func:`wilson_interval` and :func:`quantiles` are
the statistics campaign summaries report.

Errors name the library's parameters (``workers``, ``scheduler address``,
``connect_timeout_s``); a front end shows its own names for them with
:meth:`CampaignOptionError.render` and :meth:`SchedulerUnavailableError.render`.
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
    "QUANTILES",
    "WILSON_Z",
    "CampaignOptionError",
    "SchedulerUnavailableError",
    "CampaignBackend",
    "InlineExecutor",
    "run_tasks",
    "campaign_executor",
    "process_pool",
    "probe_scheduler",
    "check_address",
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

_ADDRESS = re.compile(r"^(tcp|tls)://[^\s/:]+:(\d{1,5})$")
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
    timeout_s : float
        The connect timeout [s].
    reason : str
        What happened.
    fix : str
        How to proceed (a template: see :class:`CampaignOptionError`).
    """

    def __init__(self, address: str, timeout_s: float, reason: str, fix: str) -> None:
        self.address = address
        self.timeout_s = timeout_s
        self.reason = reason
        self.fix = fix
        super().__init__(self.render())

    def render(self, names: Mapping[str, str] | None = None) -> str:
        """The message with parameters named by ``names`` (as :meth:`CampaignOptionError.render`)."""
        names = {} if names is None else names
        return (f"{_render('{scheduler}', names)} {self.address!r}: {self.reason} within the connect timeout of "
                f"{self.timeout_s:g} s; fix: {_render(self.fix, names)}")

    def __reduce__(self):
        return (SchedulerUnavailableError, (self.address, self.timeout_s, self.reason, self.fix))


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
    that accepts the connection but never answers; this probe cannot.

    Raises
    ------
    SchedulerUnavailableError
        If nothing answers the identity request in time.
    """
    from distributed.comm import connect

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s))
    except (OSError, asyncio.TimeoutError, ValueError) as err:
        raise SchedulerUnavailableError(
            address, timeout_s, f"no Dask scheduler answered ({type(err).__name__}: {err})".replace(" ()", ""),
            "start one (`dask scheduler`, then `dask worker ADDRESS`), check the address and port, "
            "or raise {connect_timeout_s}",
        ) from err
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise SchedulerUnavailableError(
            address, timeout_s, f"the peer answered but is not a Dask scheduler ({reply!r:.80})",
            "give the {scheduler} of a Dask scheduler",
        )


def check_address(address: object) -> str:
    """``address`` if it reads ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` (port 1-65535).

    Raises
    ------
    CampaignOptionError
        Naming the ``scheduler`` parameter.
    """
    match = _ADDRESS.match(address) if isinstance(address, str) else None
    if match is None or not 0 < int(match[2]) < 65536:
        raise CampaignOptionError("scheduler", address, "an address tcp://HOST:PORT (or tls://HOST:PORT)",
                                  "e.g. {scheduler} tcp://127.0.0.1:8786")
    return address  # type: ignore[return-value]


@contextlib.contextmanager
def campaign_executor(
    *,
    workers: int | None = None,
    dask_local: int | None = None,
    scheduler: str | None = None,
    connect_timeout_s: float = 10.0,
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
    preload : sequence of str
        Modules the process pool's forkserver imports (:func:`process_pool`).

    Raises
    ------
    CampaignOptionError
        Bad option values.
    SchedulerUnavailableError
        The scheduler does not answer, or has no worker, within ``connect_timeout_s``.
    """
    options = {"workers": workers, "dask_local": dask_local, "scheduler": scheduler}
    chosen = [name for name, value in options.items() if value is not None]
    if len(chosen) > 1:
        listed = " and ".join(f"{{{name}}}" for name in chosen)
        raise CampaignOptionError(chosen[1], options[chosen[1]], f"one executor option, but {listed} were given",
                                  "keep one of them")
    timeout = _check_seconds("connect_timeout_s", connect_timeout_s, "e.g. 10")
    if scheduler is not None:
        with _scheduler_backend(check_address(scheduler), timeout) as backend:
            yield backend
        return
    if dask_local is not None:
        _check_int("dask_local", dask_local, 1, "give the number of Dask worker processes, e.g. 2")
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=dask_local, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as cluster, Client(cluster, set_as_default=False) as client:
            yield CampaignBackend(executor=client.get_executor(pure=False), kind="dask", workers=dask_local,
                                  description=f"dask LocalCluster, {dask_local} workers",
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
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _scheduler_backend(scheduler: str, timeout_s: float) -> Iterator[CampaignBackend]:
    """The executor of a running Dask scheduler (probed first), with at least one worker."""
    probe_scheduler(scheduler, timeout_s)
    from distributed import Client

    try:
        client = Client(scheduler, timeout=timeout_s, set_as_default=False)
    except (OSError, asyncio.TimeoutError) as err:
        raise SchedulerUnavailableError(scheduler, timeout_s, f"the client could not connect ({err})",
                                        "check the scheduler and raise {connect_timeout_s}") from err
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except (OSError, asyncio.TimeoutError) as err:
            raise SchedulerUnavailableError(scheduler, timeout_s, "the scheduler has no worker",
                                            "start workers with `dask worker ADDRESS`") from err
        threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
        yield CampaignBackend(executor=client.get_executor(pure=False), kind="dask", workers=threads,
                              description=f"dask scheduler {scheduler}: {threads} worker threads",
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
