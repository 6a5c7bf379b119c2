"""How the long-running commands (`drs mo serve`, `drs serve predictor`, `drs chase`) stop: on SIGTERM
(systemd's stop) or SIGINT (Ctrl-C), after finishing what they were doing.

Python's default for SIGTERM ends the process at once, with whatever was in flight unanswered or half
sent. The signals are blocked before any server thread starts (threads inherit the mask) and taken
with ``sigwait``/``sigtimedwait``: no handler runs at an arbitrary moment, where setting an Event could
deadlock on a lock the interrupted code holds.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator

STOP_SIGNALS = {signal.SIGTERM, signal.SIGINT}

WaitForStop = Callable[[float | None], str | None]
"""Wait for a stop signal (at most ``timeout_s`` seconds; None: for ever); its name, or None on time-out."""


@contextlib.contextmanager
def stop_signals() -> Iterator[WaitForStop]:
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)

    def wait(timeout_s: float | None = None) -> str | None:
        if timeout_s is None:
            return signal.Signals(signal.sigwait(STOP_SIGNALS)).name
        taken = signal.sigtimedwait(STOP_SIGNALS, timeout_s)
        return None if taken is None else signal.Signals(taken.si_signo).name

    try:
        yield wait
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
