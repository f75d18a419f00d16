"""A wall-clock limit on one call of the user's code: a simulation that loops or sleeps ends, recorded.

:func:`time_limit` arms ``SIGALRM`` (``signal.setitimer``) for the duration of a ``with`` block and
raises :class:`TimeLimitExceeded` in the block when it fires.  It is a :class:`BaseException`, so a
user's ``except Exception`` cannot swallow it.  Signals reach only the main thread of a process: in
another thread (or where ``setitimer`` does not exist) the block runs without a limit and the
context manager yields ``False`` so the caller can say so.  The process pool's workers run tasks in
their main thread, so the limit holds there too.  Python checks for signals between bytecodes: a
single C call that never returns (a BLAS routine on a huge matrix) is not interrupted until it does.
An enclosing ``SIGALRM`` timer (a caller's own limit) is kept: whichever comes first fires, and the
enclosing one is re-armed with what is left of it when the block ends.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["TimeLimitExceeded", "time_limit"]


class TimeLimitExceeded(BaseException):
    """The call ran past its wall-clock limit (``seconds`` is that limit)."""

    def __init__(self, seconds: float) -> None:
        super().__init__(f"still running after {seconds:g} s")
        self.seconds = seconds


@contextmanager
def time_limit(seconds: float | None) -> Iterator[bool]:
    """Raise :class:`TimeLimitExceeded` inside the block after ``seconds`` of wall-clock time.

    Parameters
    ----------
    seconds : float or None
        The limit [s], finite and > 0; ``None`` for none.

    Yields
    ------
    bool
        Whether the limit is armed (``False`` outside the main thread or without ``setitimer``).
    """
    armed = (seconds is not None and math.isfinite(seconds) and seconds > 0
             and hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread())
    if not armed:
        yield False
        return

    begun = time.monotonic()
    outer_delay, outer_interval = signal.getitimer(signal.ITIMER_REAL)
    outer_first = 0.0 < outer_delay <= float(seconds)  # an enclosing limit (a caller's own timer) comes first
    state = {"outer_fired": False}

    def fire(signum: int, frame: object) -> None:
        if outer_first:
            state["outer_fired"] = True
            if callable(previous):
                previous(signum, frame)
            return
        raise TimeLimitExceeded(float(seconds))

    previous = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, outer_delay if outer_first else float(seconds))
    try:
        yield True
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
        if outer_delay > 0.0 and not state["outer_fired"]:  # give the enclosing timer back what is left of it
            left = outer_delay - (time.monotonic() - begun)
            signal.setitimer(signal.ITIMER_REAL, max(left, 1e-6), outer_interval)
