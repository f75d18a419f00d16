"""The wall-clock limit of one call (analysis.timelimit): it fires, it nests inside a caller's own timer."""

from __future__ import annotations

import signal
import threading
import time

import pytest

from analysis.timelimit import TimeLimitExceeded, time_limit


def test_a_sleeping_call_is_stopped_near_its_limit():
    start = time.monotonic()
    with pytest.raises(TimeLimitExceeded):
        with time_limit(0.2):
            time.sleep(5)
    assert 0.15 < time.monotonic() - start < 2.0


def test_a_busy_loop_is_stopped_and_except_exception_cannot_swallow_it():
    with pytest.raises(TimeLimitExceeded):
        with time_limit(0.2):
            while True:
                try:
                    sum(range(1000))
                except Exception:  # a user's catch-all
                    pass


def test_a_call_within_its_limit_returns_and_leaves_no_timer():
    with time_limit(5.0) as armed:
        assert armed
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


class _Outer(Exception):
    pass


def test_an_enclosing_timer_is_kept_and_fires_first_when_it_is_earlier():
    def outer(signum, frame):
        raise _Outer()

    previous = signal.signal(signal.SIGALRM, outer)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        with pytest.raises(_Outer):
            with time_limit(5.0):
                time.sleep(3)
        signal.setitimer(signal.ITIMER_REAL, 0.6)
        with time_limit(0.1):
            pass
        left, _ = signal.getitimer(signal.ITIMER_REAL)
        assert 0.3 < left <= 0.6  # re-armed with what was left
        with pytest.raises(_Outer):
            time.sleep(3)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_outside_the_main_thread_the_limit_is_not_armed_and_says_so():
    seen = []

    def work():
        with time_limit(0.1) as armed:
            seen.append(armed)

    thread = threading.Thread(target=work)
    thread.start()
    thread.join()
    assert seen == [False]
