"""How soon a change made through the operations server reaches every console watching it
(``make bench-fanout``; issue #29: five consoles within 100 ms).

A real ``drs server --private`` process; five subscribers on its event stream (``Client.events``, as a
console's is), each in its own thread. A change is an approval request another console is waiting on
being rejected through the server (``drs approve --reject``'s verb): the request is written straight
into the server's store beforehand (as a waiting FIRE of another account would have made it), and the
figure is the time from the reject's answer to each subscriber's first event without the request.
"""

from __future__ import annotations

import os
import statistics
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from drs_link.config import load_config  # noqa: E402 - after the repository's path
from drs_link.ops import ApprovalBook, Login  # noqa: E402
from drs_link.server import Client, Event  # noqa: E402
from drs_link.store import Store  # noqa: E402
from tools.private_server import ServerDidNotStart, p99, private_server  # noqa: E402

SUBSCRIBERS = 5
CHANGES = 40


class Subscriber(threading.Thread):
    """One console's event stream: when each approval id was last seen waiting, and first seen gone."""

    def __init__(self, socket_path: Path) -> None:
        super().__init__(daemon=True)
        self.socket_path = socket_path
        self.waiting: set[int] = set()
        self.gone_at: dict[int, float] = {}
        self.lock = threading.Lock()

    def run(self) -> None:
        event: Event
        for event in Client(self.socket_path).events():
            now = time.perf_counter()
            ids = {view.id for view in event.approvals}
            with self.lock:
                for gone in self.waiting - ids:
                    self.gone_at.setdefault(gone, now)
                self.waiting = ids

    def sees(self, approval: int) -> bool:
        with self.lock:
            return approval in self.waiting


def main() -> int:
    try:
        with private_server() as (config_path, socket_path):
            subscribers = [Subscriber(socket_path) for _ in range(SUBSCRIBERS)]
            for subscriber in subscribers:
                subscriber.start()
            book = ApprovalBook(Store.open(load_config(config_path).store_path))
            latencies: list[float] = []
            with Client(socket_path) as client:
                for n in range(CHANGES):
                    request = book.request(
                        "DRS1", "go", f"bench change {n}", "JM", Login("bench-other-console")
                    )
                    deadline = time.monotonic() + 10.0
                    while not all(s.sees(request.id) for s in subscribers):
                        if time.monotonic() > deadline:
                            print("the subscribers never saw the request", file=sys.stderr)
                            return 1
                        time.sleep(0.01)
                    client.approvals.reject(request.id, "bench")
                    answered = time.perf_counter()
                    deadline = time.monotonic() + 10.0
                    while not all(request.id in s.gone_at for s in subscribers):
                        if time.monotonic() > deadline:
                            print("the subscribers never saw the rejection", file=sys.stderr)
                            return 1
                        time.sleep(0.002)
                    latencies += [1000.0 * max(0.0, s.gone_at[request.id] - answered) for s in subscribers]
            latencies.sort()
            print(
                f"{SUBSCRIBERS} subscribers, {CHANGES} changes through the server: from the verb's answer to "
                f"each subscriber's event median {statistics.median(latencies):.1f} ms, p99 {p99(latencies):.1f} ms, "
                f"max {latencies[-1]:.1f} ms (load {os.getloadavg()[0]:.1f})"
            )
    except ServerDidNotStart as exc:
        print(exc, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
