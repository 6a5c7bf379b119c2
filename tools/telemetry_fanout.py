"""How soon telemetry the operations server publishes reaches every console following it
(``make bench-telemetry``; issue #29: a telemetry event reaches five connected consoles within 100 ms).

A real ``drs server --private`` process; five subscribers on its telemetry stream
(``Client.telemetry_stream``, as a console's is), each in its own thread and event loop. The records
are polls of a capsule nobody listens for (the link-down record comes back at once), asked for through
the server's poll verb so that they come one after another, not every 5 s. The figure is the time from
the newest record's time stamp (the server's wall clock, taken as the poll ended, just before the records
are published) to each subscriber's receipt of the decoded batch.
"""

from __future__ import annotations

import asyncio
import os
import statistics
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from drs_link.ops import TelemetryRecord  # noqa: E402 - after the repository's path
from drs_link.server import Client  # noqa: E402
from tools.private_server import ServerDidNotStart, p99, private_server  # noqa: E402

SUBSCRIBERS = 5
POLLS = 100


class Subscriber(threading.Thread):
    """One console's telemetry stream: each record seen (its JSON) and how late it arrived."""

    def __init__(self, socket_path: Path) -> None:
        super().__init__(daemon=True)
        self.socket_path = socket_path
        self.late_ms: dict[str, float] = {}
        self.lock = threading.Lock()
        self.following = threading.Event()
        """Set at its first batch: it is subscribed, and what it is sent from now on is new."""

    def run(self) -> None:
        asyncio.run(self.listen())

    async def listen(self) -> None:
        batch: list[TelemetryRecord]
        async for batch in Client(self.socket_path).telemetry_stream():
            now = time.time()
            published = max(record.time for record in batch).timestamp()
            with self.lock:
                for record in batch:
                    self.late_ms[record.to_json()] = 1000.0 * (now - published)
            self.following.set()

    def seen(self, record: str) -> float | None:
        with self.lock:
            return self.late_ms.get(record)


def main() -> int:
    try:
        with private_server() as (_, socket_path):
            subscribers = [Subscriber(socket_path) for _ in range(SUBSCRIBERS)]
            for subscriber in subscribers:
                subscriber.start()
            for subscriber in subscribers:  # the first poll (the first subscriber's) or the snapshot
                if not subscriber.following.wait(timeout=30.0):
                    print("a subscriber was never sent anything", file=sys.stderr)
                    return 1
            latencies: list[float] = []
            with Client(socket_path) as client:
                for _ in range(POLLS):
                    records = [record.to_json() for record in client.capsule("DRS1").poll()]
                    deadline = time.monotonic() + 10.0
                    while not all(s.seen(r) is not None for s in subscribers for r in records):
                        if time.monotonic() > deadline:
                            print("the subscribers never saw a poll's records", file=sys.stderr)
                            return 1
                        time.sleep(0.002)
                    latencies += [s.seen(r) or 0.0 for s in subscribers for r in records]
            latencies.sort()
            print(
                f"{SUBSCRIBERS} subscribers, {POLLS} polls ({len(latencies) // SUBSCRIBERS} records) published by "
                f"the server: from publication to each subscriber's receipt median "
                f"{statistics.median(latencies):.1f} ms, p99 {p99(latencies):.1f} ms, max {latencies[-1]:.1f} ms "
                f"(load {os.getloadavg()[0]:.1f})"
            )
    except ServerDidNotStart as exc:
        print(exc, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
