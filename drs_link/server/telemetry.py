"""The server's telemetry: each capsule polled once per period for every console, whatever their number.

Why here: five consoles each polling every Pi over SSH made five polls of each (issue #29), and the
gateway check and the Iridium reports were read five times too. The server polls through its own
engine (``Desks.server_desk``), keeps the latest record of each kind per capsule (the snapshot, which a
console that connects late is sent first), and pushes each new batch to every subscriber
(``/v1/telemetry``). Nothing is polled while nobody subscribes: a Pi is not woken for nobody.

Each capsule has its own loop: one poll at a time per capsule, the next one a period after it ended (polls
never pile up), and a slow Pi holds only its own loop. The gateway check and the report reads run in loops
of their own. The periods are real seconds for the store's time scale (``Periods.at_scale``: the demo runs
its simulated time faster, and a report every 2 simulated minutes comes every 15 s at ×8).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from drs_link.ops import OperatorOps, ReportSample, TelemetryRecord

log = logging.getLogger(__name__)
POLL_PERIOD_S = 5.0
"""How often each capsule is polled at the wall clock's pace (a live flight)."""
POLL_SIM_S = 8.0
"""At a faster simulated pace, a poll every this many simulated seconds, at least ``MIN_POLL_S`` apart."""
MIN_POLL_S = 1.0
GATEWAY_CHECK_S = 300.0
"""How often, in simulated seconds, the gateway's credentials are checked (at least a second apart)."""
REPORT_POLL_S = 3.0
"""How often the store is read for new Iridium reports (at most; faster when time runs fast)."""
REPORT_SIM_S = 30.0

Blocking = Callable[[Callable[[], list[TelemetryRecord]]], Awaitable[list[TelemetryRecord]]]
"""Runs blocking work (SSH, SQLite) in the server's worker pool and awaits it in the loop."""
Batch = list[TelemetryRecord]


@dataclass(frozen=True)
class Periods:
    """Real seconds between two polls of a capsule, two gateway checks and two report reads."""

    poll_s: float
    gateway_s: float
    reports_s: float

    @classmethod
    def at_scale(cls, scale: float, poll_s: float | None = None) -> Periods:
        """The periods when ``scale`` simulated seconds pass each real second; ``poll_s`` overrides the
        poll period (a demo or a test that wants a brisker pace)."""
        poll = max(MIN_POLL_S, min(POLL_PERIOD_S, POLL_SIM_S / scale))
        return cls(
            poll if poll_s is None else poll_s,
            max(1.0, GATEWAY_CHECK_S / scale),
            max(0.5, min(REPORT_POLL_S, REPORT_SIM_S / scale)),
        )


class Subscription:
    """One subscriber's batches, in order: the snapshot first, then each new one (``TelemetryService``)."""

    def __init__(self, snapshot: Batch) -> None:
        self.batches: asyncio.Queue[Batch] = asyncio.Queue()
        if snapshot:
            self.batches.put_nowait(snapshot)

    async def next(self) -> Batch:
        """The next batch, merged with any others already waiting (a slow reader gets them at once)."""
        batch = list(await self.batches.get())
        while not self.batches.empty():
            batch += self.batches.get_nowait()
        return batch


class TelemetryService:
    """Polls while anybody subscribes; ``subscribe``/``unsubscribe`` run in the server's event loop."""

    def __init__(self, desk: Callable[[], OperatorOps], capsules: list[str], periods: Periods,
                 blocking: Blocking) -> None:  # fmt: skip
        self.desk = desk
        """The server's own engine (made on the first poll: a server nobody watches opens no link)."""
        self.capsules = capsules
        self.periods = periods
        self.blocking = blocking
        self.subscribers: set[Subscription] = set()
        self.latest: dict[tuple[str | None, str], TelemetryRecord] = {}
        """The newest record of each (capsule, kind)."""
        self.reports: list[TelemetryRecord] = []
        """Every Iridium report read, oldest first: a console counts and draws them all (a late one too)."""
        self.wanted = asyncio.Event()
        """Set while at least one subscriber listens: every loop waits for it before it polls."""
        self.loops: list[asyncio.Task[None]] = []

    def snapshot(self) -> Batch:
        return sorted([*self.latest.values(), *self.reports], key=lambda r: r.time)

    def subscribe(self) -> Subscription:
        """A new subscriber, handed the snapshot first; the first one starts the loops."""
        subscription = Subscription(self.snapshot())
        self.subscribers.add(subscription)
        self.wanted.set()
        if not self.loops:
            self.loops = [
                *(asyncio.ensure_future(self.every(self.periods.poll_s, self.poller(n))) for n in self.capsules),
                asyncio.ensure_future(self.every(self.periods.gateway_s, lambda: self.desk().iridium.gateway_check())),
                asyncio.ensure_future(self.every(self.periods.reports_s, self.read_reports)),
            ]  # fmt: skip
        return subscription

    def unsubscribe(self, subscription: Subscription) -> None:
        """The last one gone, the loops stop at their next look (a poll under way ends first)."""
        self.subscribers.discard(subscription)
        if not self.subscribers:
            self.wanted.clear()

    def publish(self, records: Batch) -> None:
        """Keep ``records`` in the snapshot and hand them to every subscriber (the loop thread only)."""
        if not records:
            return
        for record in records:
            if isinstance(record.data, ReportSample):
                self.reports.append(record)
            else:
                self.latest[(record.capsule, record.kind)] = record
        for subscription in self.subscribers:
            subscription.batches.put_nowait(records)

    def poller(self, name: str) -> Callable[[], Batch]:
        return lambda: self.desk().links.poll(name)

    def read_reports(self) -> Batch:
        iridium = self.desk().iridium
        return [record for name in self.capsules for record in iridium.new_reports(name)]

    async def every(self, period_s: float, work: Callable[[], Batch]) -> None:
        """``work`` in a worker, then a pause of ``period_s``, for as long as anybody subscribes. A failed
        poll is said by the records it returns (a link down is a ``LinkSample``); one that raises (a
        locked store) is logged here and tried again a period later."""
        while True:
            await self.wanted.wait()
            try:
                self.publish(await self.blocking(work))
            except asyncio.CancelledError:
                raise
            except Exception:  # noqa: BLE001 - the next period tries again; the link's error is in its records
                log.exception("a telemetry poll failed")
            await asyncio.sleep(period_s)

    async def stop(self) -> None:
        for loop in self.loops:
            loop.cancel()
        for loop in self.loops:
            with contextlib.suppress(asyncio.CancelledError):
                await loop
        self.loops = []
