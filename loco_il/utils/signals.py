"""Graceful stops for long training loops: SIGINT/SIGTERM ask the loop to stop at its next safe point.

Long runs are stopped and resumed: a machine that shuts down sends SIGTERM, a user presses Ctrl-C. Instead of
dying mid-iteration (and losing everything since the last checkpoint), the loop checks `flag.signal`
after each iteration, writes a checkpoint and exits; a second Ctrl-C stops at once, without a checkpoint.
"""
from __future__ import annotations

import contextlib
import signal
import threading
from dataclasses import dataclass
from typing import Callable, Iterator


@dataclass
class StopFlag:
    """`signal` is the name of the first stop signal received ("SIGINT", "SIGTERM"), else None."""
    signal: str | None = None


@contextlib.contextmanager
def stop_requests(log: Callable[[str], None] | None = None) -> Iterator[StopFlag]:
    """While inside, SIGINT/SIGTERM set the yielded flag instead of ending the process.

    Only the main thread can install handlers; elsewhere the signals keep their usual effect (the flag
    then never gets set). The previous handlers come back on exit.
    """
    flag = StopFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def request_stop(signum: int, _frame) -> None:
        if signum == signal.SIGINT and flag.signal is not None:
            raise KeyboardInterrupt
        flag.signal = signal.Signals(signum).name
        if log is not None:
            log(f"{flag.signal}: stopping after the current iteration, with a checkpoint "
                "(Ctrl-C again to stop at once, without one)")

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


__all__ = ["StopFlag", "stop_requests"]
