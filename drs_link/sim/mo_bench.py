"""`drs mo bench`: measured, not assumed: the webhook's store-then-answer latency and the parser's speed.

The gateway gives a receiver 3 s to answer; this measures how long the real receiver (JWT check and
durable SQLite write with fsync included) takes on this machine, on loopback, with a temporary store:
once one POST at a time, and once as a burst from many clients at once, counting what a gateway
would see go wrong (a reset connection, a non-200 answer) and what the store kept (nothing lost,
nothing twice). The work ``drs mo serve`` does after each answer (advancing the commands) runs too:
it shares the interpreter with the threads that answer.
"""

from __future__ import annotations

import multiprocessing
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from drs_link.config import MoConfig
from drs_link.iridium import (
    CommandLifecycle,
    GnssFix,
    MoHttpServer,
    MoReceiver,
    ReportStore,
    StoredReport,
    format_mo,
    parse_hex,
)
from drs_link.sim.rockblock import MoDelivery, generate_test_keys, mo_body, post_body
from drs_link.store import Store

START = datetime(2026, 7, 1, 10, 0, tzinfo=UTC)


def _imei(client: int) -> str:
    return f"3002340100{client:05d}"


@dataclass(frozen=True)
class Latency:
    posts: int
    median_ms: float
    p95_ms: float
    p99_ms: float
    max_ms: float

    @classmethod
    def of(cls, timings: list[float]) -> Latency:
        ordered = sorted(timings)

        def at(share: float) -> float:
            return ordered[min(len(ordered) - 1, int(share * len(ordered)))]

        return cls(len(ordered), statistics.median(ordered), at(0.95), at(0.99), ordered[-1])

    def text(self) -> str:
        return (
            f"median {self.median_ms:.1f} ms, p95 {self.p95_ms:.1f} ms, p99 {self.p99_ms:.1f} ms, "
            f"max {self.max_ms:.1f} ms"
        )


@dataclass(frozen=True)
class BenchResult:
    sequential: Latency
    burst: Latency
    clients: int
    failed: int
    """POSTs that got no 200: a reset or refused connection, a timeout, any other status (the
    gateway retries these)."""
    lost: int
    """POSTs answered 200 whose report the store does not hold: what the gateway will never resend."""
    duplicated: int
    parse_us: float

    def lines(self) -> list[str]:
        return [
            f"webhook store+answer, one POST at a time over {self.sequential.posts}: "
            f"{self.sequential.text()} (gateway limit 3000 ms)",
            f"webhook burst, {self.clients} clients at once, {self.burst.posts} POSTs: {self.burst.text()}; "
            f"{self.failed} failed, {self.lost} lost, {self.duplicated} stored twice",
            f"MO parse: {self.parse_us:.1f} µs per report",
        ]


def _delivery(client: int, momsn: int) -> MoDelivery:
    fix = GnssFix(START + timedelta(minutes=2 * momsn), 46.5, 6.6, 30000 - 10 * momsn, 5.0, 90, 1.0, 9)
    return MoDelivery(_imei(client), 1 + client, momsn, format_mo(fix, 8.9, momsn), START, 46.5, 6.6, 3.0)


def _timed_post(url: str, body: tuple[bytes, str]) -> float | None:
    """Milliseconds to a 200, or None for anything a gateway would have to retry."""
    began = time.perf_counter()
    try:
        status = post_body(url, *body)
    except OSError:
        return None
    return (time.perf_counter() - began) * 1000 if status == 200 else None


def _burst(url: str, private_key: str, clients: int, per_client: int) -> list[list[float | None]]:
    """Run in a process of its own, as the gateway is: the clients' signing and HTTP do not share
    the receiver's interpreter lock. Every body is signed before the first POST."""
    bodies = [[mo_body(_delivery(c, m), jwt_private_key=private_key) for m in range(per_client)]
              for c in range(1, clients + 1)]  # fmt: skip
    with ThreadPoolExecutor(max_workers=clients) as pool:
        return list(pool.map(lambda own: [_timed_post(url, body) for body in own], bodies))


def run_bench(posts: int = 200, clients: int = 20, burst_per_client: int = 50) -> BenchResult:
    private_key, public_key = generate_test_keys()
    with tempfile.TemporaryDirectory(prefix="drs-bench-") as folder:
        key_file = Path(folder) / "gateway.pem"
        key_file.write_text(public_key)
        store = Store.open(Path(folder) / "bench.sqlite")
        config = MoConfig(listen_host="127.0.0.1", listen_port=0, jwt_public_key_file=key_file)
        reports, life = ReportStore(store), CommandLifecycle(store, "bench")

        def after_answer(stored: StoredReport) -> None:
            life.observe_store(reports, stored.delivery.imei)

        server = MoHttpServer(MoReceiver(reports, config, after_answer)).start()
        try:
            bodies = [mo_body(_delivery(0, momsn), jwt_private_key=private_key) for momsn in range(posts)]
            sequential = [_timed_post(server.url, body) for body in bodies]
            if None in sequential:
                raise RuntimeError("a bench POST got no 200 with one client")
            with ProcessPoolExecutor(
                max_workers=1, mp_context=multiprocessing.get_context("spawn")
            ) as gateway:
                burst = gateway.submit(_burst, server.url, private_key, clients, burst_per_client).result()
        finally:
            server.stop()
        kept = [r for client in range(1, clients + 1) for r in reports.for_imei(_imei(client))]
        store.close()
    keys = [(r.delivery.imei, r.delivery.momsn) for r in kept]
    answered = [t for times in burst for t in times if t is not None]
    acknowledged = {
        (_imei(c), m) for c, times in enumerate(burst, 1) for m, t in enumerate(times) if t is not None
    }
    hexes = [_delivery(0, momsn).payload.hex() for momsn in range(posts)]
    began = time.perf_counter()
    rounds = max(1, 20000 // posts)
    for _ in range(rounds):
        for text in hexes:
            parse_hex(text)
    parse_us = (time.perf_counter() - began) / (rounds * len(hexes)) * 1e6
    return BenchResult(
        sequential=Latency.of([t for t in sequential if t is not None]),
        burst=Latency.of(answered or [float("nan")]),
        clients=clients,
        failed=clients * burst_per_client - len(answered),
        lost=len(acknowledged - set(keys)),
        duplicated=len(keys) - len(set(keys)),
        parse_us=parse_us,
    )
