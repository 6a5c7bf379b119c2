"""The server polls each capsule once for every console and pushes the telemetry (``/v1/telemetry``):
a real server on its Unix socket, two capsule simulators behind their SSH servers, and clients on the
stream as consoles follow it. Polls are counted where they land, on the simulated Pi."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import aiohttp
import msgspec
import paramiko
import pytest

from drs_link.config import Config, parse_config
from drs_link.link import remote
from drs_link.ops import LinkSample, TelemetryRecord
from drs_link.ops.telemetry import GatewaySample
from drs_link.server import Client, Failure, InProcessServer
from drs_link.server.protocol import ROOT
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store
from tests.drs_link.conftest import capsule_table

pytestmark = pytest.mark.asyncio
POLL_S = 0.3
WAIT_S = 30.0


class Arrivals(list[str]):
    """A simulated Pi's commands, with when each arrived (``CapsuleSimulator.commands`` replaced)."""

    def __init__(self) -> None:
        super().__init__()
        self.times: list[float] = []

    def append(self, command: str) -> None:
        self.times.append(time.monotonic())
        super().append(command)


def heartbeat_times(sim: CapsuleSimulator) -> list[float]:
    """When each poll reached this Pi (each poll asks for one heartbeat)."""
    assert isinstance(sim.commands, Arrivals)
    pairs = list(zip(sim.commands.times, list(sim.commands), strict=False))
    return [at for at, command in pairs if (remote.parse_label(command) or ("",))[0] == "heartbeat"]


def heartbeats(sim: CapsuleSimulator) -> int:
    return len(heartbeat_times(sim))


@pytest.fixture
def fleet(
    tmp_path: Path, make_sim: Callable[..., CapsuleSimulator], client_key: tuple[Path, paramiko.PKey]
) -> Iterator[tuple[Config, InProcessServer, list[CapsuleSimulator]]]:
    sims = [make_sim(name="DRS1"), make_sim(name="DRS2")]
    tables = []
    for sim in sims:
        sim.commands = Arrivals()
        known_hosts = tmp_path / f"known_hosts_{sim.name}"
        known_hosts.write_text(sim.known_hosts_line())
        tables.append(capsule_table(sim, client_key[0], known_hosts=str(known_hosts)))
    config = parse_config(
        {"operator": {"name": "EL"}, "data": {"dir": str(tmp_path / "data")}, "capsule": tables}
    )
    server = InProcessServer(config, poll_period_s=POLL_S)
    try:
        yield config, server, sims
    finally:
        server.stop()


class Follower:
    """One console's telemetry stream: every batch it was sent, in order."""

    def __init__(self, socket_path: Path) -> None:
        self.batches: list[list[TelemetryRecord]] = []
        self.task = asyncio.ensure_future(self.follow(socket_path))

    async def follow(self, socket_path: Path) -> None:
        async for batch in Client(socket_path).telemetry_stream():
            self.batches.append(batch)

    def records(self) -> list[TelemetryRecord]:
        return [record for batch in self.batches for record in batch]

    def polls(self, capsule: str) -> set[str]:
        """The polls of ``capsule`` this follower saw: one link record each."""
        return {
            r.to_json() for r in self.records() if r.capsule == capsule and isinstance(r.data, LinkSample)
        }

    async def stop(self) -> None:
        self.task.cancel()
        await asyncio.gather(self.task, return_exceptions=True)


async def until(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        assert time.monotonic() < deadline, f"never: {what}"
        await asyncio.sleep(0.02)


async def quiet(sims: list[CapsuleSimulator]) -> list[int]:
    """The polls each Pi saw once several poll periods passed (a poll under way when the last follower
    left may still land: at most one more each)."""
    await asyncio.sleep(5 * POLL_S)
    return [heartbeats(sim) for sim in sims]


async def test_three_followers_get_the_same_records_from_one_poll_of_each_capsule_per_period(
    fleet: tuple[Config, InProcessServer, list[CapsuleSimulator]],
) -> None:
    _, server, sims = fleet
    followers = [Follower(server.socket) for _ in range(3)]
    await until(
        lambda: all(len(f.polls(name)) >= 4 for f in followers for name in ("DRS1", "DRS2")),
        "every follower saw four polls of each capsule",
    )
    for follower in followers:
        await follower.stop()
    for sim in sims:
        seen = [f.polls(sim.name) for f in followers]
        common, union = set.intersection(*seen), set.union(*seen)
        assert len(common) >= 3, "every follower was sent the records of each poll made while all listened"
        assert all(r.data.up for f in followers for r in f.records() if isinstance(r.data, LinkSample))
        assert len(union) <= heartbeats(sim) <= len(union) + 1, f"{sim.name}: every poll was pushed to them"
        times = heartbeat_times(sim)
        gaps = [later - earlier for earlier, later in zip(times, times[1:], strict=False)]
        assert min(gaps) >= POLL_S, (
            f"{sim.name}: polls {min(gaps):.3f} s apart: one poll per period for all three followers, the "
            f"next a period after the last ended, not one per follower"
        )


async def test_a_late_follower_is_sent_the_fleet_first_and_nothing_is_polled_with_nobody_following(
    fleet: tuple[Config, InProcessServer, list[CapsuleSimulator]],
) -> None:
    _, server, sims = fleet
    assert await quiet(sims) == [0, 0], "no follower: no Pi was polled"

    first = Follower(server.socket)
    await until(lambda: all(first.polls(name) for name in ("DRS1", "DRS2")), "the first follower saw both")
    late = Follower(server.socket)
    await until(lambda: bool(late.batches), "the late follower was sent something")
    snapshot = late.batches[0]
    kinds = {(r.capsule, r.kind) for r in snapshot}
    assert kinds == {(r.capsule, r.kind) for r in first.records()}, "the latest of each kind, at once"
    assert len(kinds) == len(snapshot), "one record of each kind per capsule"
    assert {"link", "release", "storage", "sync"} <= {kind for capsule, kind in kinds if capsule == "DRS2"}
    gateway = [r for r in snapshot if isinstance(r.data, GatewaySample)]
    assert gateway and gateway[0] in first.records(), "the one gateway check, made before it followed"
    assert all(record in first.records() for record in snapshot)

    for follower in (first, late):
        await follower.stop()
    left = [heartbeats(sim) for sim in sims]
    after = await quiet(sims)
    assert all(was <= now <= was + 1 for was, now in zip(left, after, strict=True)), (left, after)
    assert await quiet(sims) == after, "the polls stopped with the last follower"


async def test_a_poll_now_answers_and_reaches_every_follower(
    fleet: tuple[Config, InProcessServer, list[CapsuleSimulator]],
) -> None:
    _, server, sims = fleet
    with Client(server.socket) as client:
        records = await asyncio.to_thread(client.capsule("DRS1").poll)
    assert {r.kind for r in records} >= {"release", "link", "storage"} and {r.capsule for r in records} == {
        "DRS1"
    }
    assert [heartbeats(sim) for sim in sims] == [1, 0]
    follower = Follower(server.socket)
    await until(lambda: bool(follower.batches), "the follower was sent the snapshot")
    link = next(r for r in records if isinstance(r.data, LinkSample))
    assert link in follower.batches[0], "the poll made on demand is in the snapshot"
    await follower.stop()


async def test_a_message_on_the_telemetry_stream_gets_one_failure_and_changes_nothing(
    fleet: tuple[Config, InProcessServer, list[CapsuleSimulator]],
) -> None:
    config, server, sims = fleet
    store = Store.open(config.store_path)
    audit = store.audit()
    connector = aiohttp.UnixConnector(path=str(server.socket))
    async with aiohttp.ClientSession(connector=connector) as session:
        async with session.ws_connect(f"http://drs-server{ROOT}/telemetry") as ws:
            await ws.send_str('{"poll": "DRS1"}')
            said: list[Any] = []
            async for message in ws:
                said.append(message.data)
            assert ws.close_code is not None
    failures = [msgspec.json.decode(data, type=Failure) for data in said if b'"failure"' in data]
    assert failures == [Failure("protocol", "the telemetry stream takes no messages")]
    left = [heartbeats(sim) for sim in sims]
    after = await quiet(sims)
    assert all(was <= now <= was + 1 for was, now in zip(left, after, strict=True))
    assert await quiet(sims) == after, "nothing polls for a stream that was closed"
    assert store.audit() == audit
    store.close()
