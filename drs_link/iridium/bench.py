"""`drs mo bench`: measured, not assumed: the webhook's store-then-answer latency and the parser's speed.

The gateway gives a receiver 3 s to answer; this measures how long the real receiver (durable
SQLite write with fsync included) takes on this machine, on loopback, with a temporary store.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from drs_link.config import MoConfig
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.mo import parse_hex
from drs_link.iridium.reports import ReportStore
from drs_link.iridium.webhook import MoHttpServer, MoReceiver
from drs_link.simulator.rockblock import MoDelivery, post_mo
from drs_link.store import Store

BENCH_IMEI = "300234010000001"


@dataclass(frozen=True)
class BenchResult:
    posts: int
    median_ms: float
    p95_ms: float
    max_ms: float
    parse_us: float

    def lines(self) -> list[str]:
        return [
            f"webhook store+answer over {self.posts} POSTs: median {self.median_ms:.1f} ms, "
            f"p95 {self.p95_ms:.1f} ms, max {self.max_ms:.1f} ms (gateway limit 3000 ms)",
            f"MO parse: {self.parse_us:.1f} µs per report",
        ]


def run_bench(posts: int = 200) -> BenchResult:
    start = datetime(2026, 7, 1, 10, 0, tzinfo=UTC)
    payloads = [
        format_mo(
            GnssFix(start + timedelta(minutes=2 * i), 46.5, 6.6, 30000 - 10 * i, 5.0, 90, 1.0, 9), 8.9, i
        )
        for i in range(posts)
    ]
    with tempfile.TemporaryDirectory(prefix="drs-bench-") as folder:
        store = Store.open(Path(folder) / "bench.sqlite")
        server = MoHttpServer(
            MoReceiver(ReportStore(store), MoConfig(listen_host="127.0.0.1", listen_port=0))
        ).start()
        timings = []
        try:
            for momsn, payload in enumerate(payloads):
                delivery = MoDelivery(BENCH_IMEI, 1, momsn, payload, start, 46.5, 6.6, 3.0)
                began = time.perf_counter()
                status = post_mo(server.url, delivery)
                timings.append((time.perf_counter() - began) * 1000)
                if status != 200:
                    raise RuntimeError(f"bench POST answered {status}")
        finally:
            server.stop()
            store.close()
    hexes = [p.hex() for p in payloads]
    began = time.perf_counter()
    rounds = max(1, 20000 // posts)
    for _ in range(rounds):
        for text in hexes:
            parse_hex(text)
    parse_us = (time.perf_counter() - began) / (rounds * len(hexes)) * 1e6
    ordered = sorted(timings)
    return BenchResult(
        posts=posts,
        median_ms=statistics.median(ordered),
        p95_ms=ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))],
        max_ms=ordered[-1],
        parse_us=parse_us,
    )
