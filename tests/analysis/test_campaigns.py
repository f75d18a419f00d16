"""analysis.campaigns: any picklable task over indices, streamed, resumable; executors; statistics.

Nothing here is about the robot: the tasks are arithmetic (``operator.mul(spec, index)``, picklable
for process pools) or local functions run on thread pools.
"""

import concurrent.futures as cf
import operator
import os
import pickle
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from analysis.campaigns import (
    CampaignOptionError,
    InlineExecutor,
    NoWorkerError,
    NotADaskSchedulerError,
    SchedulerUnavailableError,
    WatchedExecutor,
    _process_alive,
    campaign_executor,
    check_address,
    probe_scheduler,
    process_pool,
    quantiles,
    run_tasks,
    wilson_interval,
)


def collect(task, spec, indices, executor, **options):
    got = []
    count = run_tasks(task, spec, indices, executor, lambda i, r: got.append((i, r)), **options)
    assert count == len(got)
    return got


def slow_square(spec, index):
    """Later indices finish first (thread pools: no pickling needed)."""
    time.sleep(spec * (6 - index))
    return index * index


def test_inline_runs_every_index_in_order_and_skips_done_ones():
    assert collect(operator.mul, 3, 5, InlineExecutor()) == [(i, 3 * i) for i in range(5)]
    assert collect(operator.mul, 3, 5, InlineExecutor(), skip={0, 3}) == [(1, 3), (2, 6), (4, 12)]
    assert collect(operator.mul, 2, [7, 4, 9], InlineExecutor(), skip=[4]) == [(7, 14), (9, 18)]
    assert collect(operator.mul, 2, 0, InlineExecutor()) == []


def test_completion_order_streams_as_tasks_finish():
    with cf.ThreadPoolExecutor(max_workers=6) as pool:
        got = collect(slow_square, 0.05, 6, pool, window=6)
    assert sorted(got) == [(i, i * i) for i in range(6)]
    assert [i for i, _ in got] != list(range(6))  # the last index finished first


def test_index_order_holds_early_results_back():
    with cf.ThreadPoolExecutor(max_workers=6) as pool:
        got = collect(slow_square, 0.05, 6, pool, window=6, order="index", skip={2})
    assert got == [(i, i * i) for i in (0, 1, 3, 4, 5)]


class Counting(cf.ThreadPoolExecutor):
    """A thread pool recording the most tasks submitted and not yet delivered."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.submitted = 0
        self.delivered = 0
        self.most = 0

    def submit(self, fn, /, *args, **kwargs):
        self.submitted += 1
        self.most = max(self.most, self.submitted - self.delivered)
        return super().submit(fn, *args, **kwargs)


@pytest.mark.parametrize("order", ["completion", "index"])
def test_window_bounds_the_tasks_in_flight_and_held(order):
    with Counting(max_workers=4) as pool:
        def sink(index, result):
            pool.delivered += 1

        run_tasks(slow_square, 0.01, 6, pool, sink, window=3, order=order)
    assert pool.submitted == 6 and pool.most <= 3


def test_a_task_exception_propagates_and_cancels_the_rest():
    def task(spec, index):
        if index == 1:
            raise ArithmeticError("task 1 failed")
        time.sleep(0.05)
        return index

    got = []
    with cf.ThreadPoolExecutor(max_workers=1) as pool:
        with pytest.raises(ArithmeticError, match="task 1 failed"):
            run_tasks(task, None, 50, pool, lambda i, r: got.append(i), window=4)
    assert got == [0]


def test_interrupt_in_the_sink_waits_for_running_tasks_and_delivers_them():
    got = []

    def sink(index, result):
        got.append(index)
        if len(got) == 3:
            raise KeyboardInterrupt

    with cf.ThreadPoolExecutor(max_workers=4) as pool:
        with pytest.raises(KeyboardInterrupt):
            run_tasks(slow_square, 0.01, 6, pool, sink, window=4, interrupt_grace_s=5.0)
    assert len(got) == len(set(got)) >= 3  # what was running when Ctrl-C came still reached the sink
    rest = collect(slow_square, 0.0, 6, InlineExecutor(), skip=got)
    assert sorted(got + [i for i, _ in rest]) == list(range(6))


def test_interrupt_in_index_order_delivers_the_held_results_in_order():
    release = threading.Event()

    def task(spec, index):
        if index == 0:
            release.wait(5.0)  # a slow head: 1, 2, 3 finish first and are held
        return index

    def sink(index, result):
        got.append(index)
        if index == 0:
            raise KeyboardInterrupt

    got = []
    threading.Timer(0.2, release.set).start()
    with cf.ThreadPoolExecutor(max_workers=4) as pool:
        with pytest.raises(KeyboardInterrupt):
            run_tasks(task, None, 20, pool, sink, window=4, order="index")
    assert got == [0, 1, 2, 3]


@pytest.mark.parametrize("call, message", [
    (dict(window=0), r"^window = 0: expected an integer >= 1; fix: use a few tasks per worker"),
    (dict(order="random"), r"^order = 'random': expected one of completion, index"),
    (dict(interrupt_grace_s=-1.0), r"^interrupt_grace_s = -1.0: expected a non-negative number of seconds"),
    (dict(indices=[1, 2, 1]), r"^indices = \[1\]: expected each index once"),
    (dict(indices=[0.5]), r"^indices = \[0.5\]: expected integers"),
    (dict(indices=-3), r"^indices = -3: expected an integer >= 0"),
])
def test_run_tasks_options_are_validated(call, message):
    indices = call.pop("indices", 3)
    with pytest.raises(CampaignOptionError, match=message):
        run_tasks(operator.mul, 1, indices, InlineExecutor(), print, **call)


def test_process_pool_runs_picklable_tasks_with_sigint_ignored():
    with process_pool(2, preload=("operator",)) as pool:
        got = collect(operator.mul, 5, 8, pool, window=4, order="index")
        assert got == [(i, 5 * i) for i in range(8)]
        assert pool.submit(signal.getsignal, signal.SIGINT).result() == signal.SIG_IGN
    with campaign_executor(workers=2) as backend:
        assert backend.kind == "process" and backend.window == 4
        assert sorted(collect(operator.mul, 2, 5, backend.executor)) == [(i, 2 * i) for i in range(5)]
    with campaign_executor(workers=1) as backend:
        assert backend.kind == "inline" and isinstance(backend.executor, InlineExecutor)


def test_process_alive():
    assert _process_alive(os.getpid())
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    assert not _process_alive(child.pid)


def test_errors_name_library_parameters_and_render_a_front_ends_names():
    err = CampaignOptionError("dask_local", 2, "one executor option, but {workers} and {dask_local} were given",
                              "keep one of them")
    assert str(err) == "dask_local = 2: expected one executor option, but workers and dask_local were given; " \
                       "fix: keep one of them"
    assert err.render({"workers": "-w", "dask_local": "--dl"}) == \
        "--dl = 2: expected one executor option, but -w and --dl were given; fix: keep one of them"
    again = pickle.loads(pickle.dumps(err))
    assert str(again) == str(err) and again.parameter == "dask_local"
    down = SchedulerUnavailableError("tcp://h:1", 2.0, "no Dask scheduler answered", "or raise {connect_timeout_s}")
    assert str(down) == ("scheduler address 'tcp://h:1': no Dask scheduler answered within the connect timeout of "
                         "2 s; fix: or raise connect_timeout_s")
    assert down.render({"scheduler": "--scheduler", "connect_timeout_s": "--connect-timeout"}).startswith(
        "--scheduler 'tcp://h:1'")
    assert str(pickle.loads(pickle.dumps(down))) == str(down)


def test_check_address():
    assert check_address("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    assert check_address("tls://scheduler:1") == "tls://scheduler:1"
    assert check_address("tcp://[::1]:8786") == "tcp://[::1]:8786"  # IPv6 in brackets
    assert check_address("tcp://[fe80::1%eth0]:8786") == "tcp://[fe80::1%eth0]:8786"
    for bad in ("127.0.0.1:8786", "tcp://host:0", "tcp://host:65536", "tcp://host", None, "tcp://::1:8786",
                "tcp://[::1]", "tcp://[not-v6]:8786", "tcp://[::1:8786"):
        with pytest.raises(CampaignOptionError, match=r"^scheduler address = .*expected an address tcp://HOST:PORT "
                                                      r"\(or tls://HOST:PORT; an IPv6 host in brackets: "
                                                      r"tcp://\[::1\]:8786\)"):
            check_address(bad)


# ---------------------------------------------------------------------------------------------
# A scheduler address that is not a Dask scheduler; a cluster whose workers are gone
# ---------------------------------------------------------------------------------------------


class Peer:
    """A TCP server on localhost (in a thread) that sends ``greeting`` to each client, or nothing."""

    def __init__(self, greeting=b"", family=socket.AF_INET, host="127.0.0.1"):
        self.server = socket.socket(family)
        self.server.bind((host, 0))
        self.server.listen(8)
        port = self.server.getsockname()[1]
        self.address = f"tcp://{host}:{port}" if family == socket.AF_INET else f"tcp://[{host}]:{port}"
        self.greeting = greeting
        self.clients = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            self.clients.append(client)
            if self.greeting:
                client.sendall(self.greeting)

    def close(self):
        self.server.close()
        for client in self.clients:
            client.close()


BANNER = b"SSH-2.0-OpenSSH_9.2p1 Debian-2\r\n"


def test_a_service_sending_a_banner_is_not_a_dask_scheduler():
    """The Dask protocol reads the banner as a message of 2.82 EiB: MemoryError, caught and explained."""
    peer = Peer(BANNER)
    try:
        start = time.perf_counter()
        with pytest.raises(NotADaskSchedulerError) as info:
            with campaign_executor(scheduler=peer.address, connect_timeout_s=2.0):
                pass
        assert time.perf_counter() - start < 2.0 + 1.5
    finally:
        peer.close()
    err = info.value
    assert isinstance(err, SchedulerUnavailableError)  # a front end's handler of unusable schedulers catches it
    message = err.render({"scheduler": "--scheduler"})
    assert message.startswith(f"--scheduler '{peer.address}': not a Dask scheduler at {peer.address} (it sent "
                              f"{BANNER!r}; reading its first message as the Dask protocol failed: MemoryError: ")
    assert message.endswith("; fix: give the --scheduler of a Dask scheduler (`dask scheduler` prints it), not "
                            "another service's port")
    assert str(pickle.loads(pickle.dumps(err))) == str(err)


def test_a_silent_peer_times_out_with_a_reason():
    peer = Peer()
    try:
        with pytest.raises(SchedulerUnavailableError) as info:
            probe_scheduler(peer.address, 0.5)
    finally:
        peer.close()
    assert not isinstance(info.value, NotADaskSchedulerError)
    assert re.search(r"no Dask scheduler answered \(timed out after 0\.5 s (connecting and exchanging the Dask "
                     r"handshake|waiting for the answer to an identity request)\) within the connect timeout of "
                     r"0\.5 s", str(info.value)), str(info.value)
    assert "TimeoutError: )" not in str(info.value) and "()" not in str(info.value)


def test_tls_without_configuration_is_named_not_a_traceback():
    with pytest.raises(SchedulerUnavailableError) as info:
        probe_scheduler("tls://127.0.0.1:1", 1.0)
    assert info.value.render({"scheduler": "--scheduler"}).startswith(
        "--scheduler 'tls://127.0.0.1:1': TLS is not configured for the Dask client (TypeError: TLS expects a "
        "`ssl_context` argument")
    assert "within the connect timeout" not in str(info.value)  # nothing to do with time
    assert str(info.value).endswith("fix: set distributed.comm.tls.ca-file, .client.cert and .client.key in the Dask "
                                    "configuration, or give a tcp:// scheduler address")


def test_an_ipv6_address_is_probed():
    try:
        peer = Peer(BANNER, socket.AF_INET6, "::1")
    except OSError:
        pytest.skip("no IPv6 loopback here")
    try:
        with pytest.raises(NotADaskSchedulerError, match=re.escape(f"not a Dask scheduler at {peer.address}")):
            probe_scheduler(check_address(peer.address), 2.0)
    finally:
        peer.close()


def blocked(event, index):
    event.wait(10.0)
    return index


def test_watched_executor_fails_pending_futures_once_no_worker_is_alive():
    release = threading.Event()
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        watched = WatchedExecutor(pool, lambda: 0, 0.3, where="a test cluster", poll_s=0.05)
        start = time.perf_counter()
        with pytest.raises(NoWorkerError) as info:
            run_tasks(blocked, release, 6, watched, lambda i, r: None, window=3)
        elapsed = time.perf_counter() - start
        release.set()
        watched.shutdown()
    assert 0.3 <= elapsed < 0.3 + 1.0
    assert str(info.value) == "no Dask worker alive for 0.3 s (the limit of no_worker_timeout_s) on a test cluster"
    assert info.value.render({"no_worker_timeout_s": "--no-worker-timeout"}) == (
        "no Dask worker alive for 0.3 s (the limit of --no-worker-timeout) on a test cluster")
    assert watched.submit(operator.mul, 2, 3).exception() is info.value  # later submissions fail at once
    assert str(pickle.loads(pickle.dumps(info.value))) == str(info.value)


def test_watched_executor_runs_normally_while_workers_are_alive_or_come_back():
    answers = iter([0, 0, 1] + [0] * 3 + [1] * 1000)  # never 0 for 0.3 s in a row (polled every 0.05 s)
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        watched = WatchedExecutor(pool, lambda: next(answers), 0.3, where="x", poll_s=0.05)
        got = []
        run_tasks(slow_square, 0.05, 6, watched, lambda i, r: got.append((i, r)), window=2)
        watched.shutdown()
    assert sorted(got) == [(i, i * i) for i in range(6)] and watched.failure is None


def test_watched_executor_counts_a_silent_scheduler_as_no_worker():
    def ask():
        raise OSError("Timed out during handshake")

    with cf.ThreadPoolExecutor(max_workers=1) as pool:
        watched = WatchedExecutor(pool, ask, 0.2, where="x", poll_s=0.05)
        release = threading.Event()
        future = watched.submit(blocked, release, 0)
        with pytest.raises(NoWorkerError, match=r"on x; the scheduler did not answer \(OSError: Timed out during "
                                                r"handshake\)$"):
            future.result(timeout=5.0)
        release.set()
        watched.shutdown()


def test_watched_executor_cancels_through_to_the_inner_executor():
    release = threading.Event()
    with cf.ThreadPoolExecutor(max_workers=1) as pool:
        watched = WatchedExecutor(pool, lambda: 1, 60.0, where="x")
        running = watched.submit(blocked, release, 0)
        queued = watched.submit(blocked, release, 1)
        time.sleep(0.1)
        assert queued.cancel() and queued.cancelled()  # still queued in the pool: cancelled there too
        assert not running.cancel()  # running: as a plain future
        release.set()
        assert running.result(timeout=5.0) == 0
        watched.shutdown()


def test_a_dask_cluster_whose_workers_are_gone_stops_within_the_no_worker_timeout():
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://",
                      dashboard_address=None) as cluster:
        got = []

        def sink(index, result):
            got.append(index)
            if index == 0:  # the only worker goes away: the next tasks would wait forever
                threading.Thread(target=cluster.scale, args=(0,)).start()

        with campaign_executor(scheduler=cluster.scheduler_address, connect_timeout_s=5.0,
                               no_worker_timeout_s=0.5) as backend:
            start = time.perf_counter()
            with pytest.raises(NoWorkerError, match=rf"^no Dask worker alive for 0.5 s \(the limit of "
                                                    rf"no_worker_timeout_s\) on dask scheduler "
                                                    rf"{re.escape(cluster.scheduler_address)}$"):
                run_tasks(time_then_index, 0.2, 20, backend.executor, sink, window=2, order="index")
            assert time.perf_counter() - start < 0.2 + 0.5 + 3.0
    assert got[0] == 0 and len(got) < 20


def time_then_index(spec, index):
    time.sleep(spec)
    return index


def test_no_worker_timeout_is_validated():
    with pytest.raises(CampaignOptionError, match=r"^no_worker_timeout_s = 0: expected a positive number of seconds"):
        with campaign_executor(workers=1, no_worker_timeout_s=0):
            pass


def test_wilson_interval_and_quantiles():
    assert wilson_interval(0, 0) is None
    assert wilson_interval(10, 10) == (pytest.approx(0.722467, abs=1e-6), 1.0)
    assert wilson_interval(0, 10) == (0.0, pytest.approx(0.277533, abs=1e-6))
    assert quantiles([]) == ()
    values = [3.0, 1.0, 2.0, 10.0]
    assert quantiles(values, (0.0, 0.5, 1.0)) == ((0.0, 1.0), (0.5, 2.5), (1.0, 10.0))
    assert [v for _, v in quantiles(values)] == pytest.approx(np.quantile(values, [0, .05, .25, .5, .75, .95, 1]))


def test_the_module_imports_nothing_of_the_case_study():
    code = ("import sys, analysis.campaigns; bad = [m for m in ('visnav', 'matplotlib', 'distributed') "
            "if m in sys.modules]; print(','.join(bad)); sys.exit(1 if bad else 0)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, f"analysis.campaigns imported {proc.stdout.strip()}"
