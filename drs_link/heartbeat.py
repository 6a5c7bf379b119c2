"""Knowing the link is alive: a periodic no-op command, since SSH keepalives cannot tell.

paramiko's keepalive sends ``keepalive@lag.net`` without asking for a reply, so a dead peer goes
unnoticed until the next real command hangs. ``LinkMonitor`` runs ``CapsuleLink.heartbeat`` on
its own thread every ``interval_s``; after ``failures_to_down`` misses in a row it reports the
link DOWN and keeps reconnecting with exponential backoff. The console renders ``status()``;
nothing here imports Textual.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from drs_link.ssh import HEARTBEAT_TIMEOUT_S, CapsuleLink


class LinkState(StrEnum):
    UNKNOWN = "unknown"
    UP = "up"
    DOWN = "down"


@dataclass(frozen=True)
class LinkStatus:
    state: LinkState
    consecutive_failures: int
    last_ok_monotonic: float | None
    next_try_in_s: float


class LinkMonitor:
    def __init__(
        self,
        link: CapsuleLink,
        interval_s: float = 5.0,
        heartbeat_timeout_s: float = HEARTBEAT_TIMEOUT_S,
        failures_to_down: int = 3,
        max_backoff_s: float = 60.0,
        on_change: Callable[[LinkStatus], None] | None = None,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        self.interval_s = interval_s
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.failures_to_down = failures_to_down
        self.max_backoff_s = max_backoff_s
        self.on_change = on_change
        self._monotonic = monotonic
        self._state = LinkState.UNKNOWN
        self._failures = 0
        self._last_ok: float | None = None
        self._delay = interval_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def status(self) -> LinkStatus:
        with self._lock:
            return LinkStatus(self._state, self._failures, self._last_ok, self._delay)

    def beat(self) -> LinkStatus:
        """One heartbeat and the resulting state (the thread calls this; tests may too)."""
        alive = self.link.heartbeat(timeout_s=self.heartbeat_timeout_s)
        with self._lock:
            before = self._state
            if alive:
                self._failures = 0
                self._last_ok = self._monotonic()
                self._state = LinkState.UP
                self._delay = self.interval_s
            else:
                self._failures += 1
                if self._failures >= self.failures_to_down:
                    self._state = LinkState.DOWN
                    self._delay = min(self._delay * 2, self.max_backoff_s)
            status = LinkStatus(self._state, self._failures, self._last_ok, self._delay)
        if status.state is not before and self.on_change is not None:
            self.on_change(status)
        return status

    def start(self) -> None:
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._run, name=f"heartbeat-{self.link.capsule.name}", daemon=True
        )
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            status = self.beat()
            self._stop.wait(status.next_try_in_s)

    def stop(self) -> None:
        """Stop beating and close the link, which also unblocks a heartbeat in flight."""
        self._stop.set()
        self.link.close()
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None
