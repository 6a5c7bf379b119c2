"""A stopping operations server leaves no request unanswered (issue #29, "the server restarted with
windows and requests open"): whatever is in flight when it stops, each client gets its answer or an EOF
(a ``LinkError`` on its side) within the stop's grace, never a wait for its own timeout, and the server
logs no traceback on the way out. A real server on a real Unix socket in this process, real clients.

The bounds below are hang checks, not speed checks: a failure means a client that would have waited its
whole timeout (600 s for a verb), and each bound is several times ``STOP_GRACE_S``."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import socket
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.config import Config, parse_config
from drs_link.errors import LinkError
from drs_link.ops import ApprovalBook
from drs_link.server import Client, InProcessServer, Second
from drs_link.server.app import STOP_GRACE_S, WITHDRAWN_DROPPED, WITHDRAWN_STOPPED, OperationsServer
from drs_link.server.desk import Desk
from drs_link.server.protocol import AuthoritySeen
from drs_link.store import Store, account_of
from tests.console.conftest import offline_config

HANG_S = 4 * STOP_GRACE_S
"""Longer than any stop may take (the grace, then a cancel): a client still waiting then is left hanging."""


@pytest.fixture
def config(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> Iterator[Config]:
    caplog.set_level(logging.WARNING)
    yield offline_config(tmp_path)
    logged = caplog.get_records("call")
    tracebacks = [r for r in logged if r.exc_info or r.levelno >= logging.ERROR]
    assert not tracebacks, [r.getMessage() for r in tracebacks]


def in_thread(work: object) -> tuple[threading.Thread, list[object]]:
    """Run ``work()`` in a daemon thread; what it returned or raised lands in the list."""
    ended: list[object] = []

    def run() -> None:
        try:
            ended.append(work())  # type: ignore[operator]
        except Exception as exc:  # noqa: BLE001 - the test looks at it
            ended.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, ended


def test_a_request_held_in_the_server_when_it_stops_gets_a_link_error_not_a_hang(config: Config) -> None:
    """A waiver's write waits on the store, locked by another process's transaction (a slow store):
    the server stops under it; its client is told at once, not after the write gives up."""
    server = InProcessServer(config)
    Desk(Client(server.socket)).view()  # the store exists and the desk is made
    other = sqlite3.connect(config.store_path, isolation_level=None)
    other.execute("BEGIN EXCLUSIVE")
    try:
        client = Client(server.socket)  # the verbs' own timeout (600 s)
        waiting, answered = in_thread(lambda: Desk(client).waive("DRS1", "gnss", "no sky in the hangar"))
        time.sleep(0.5)  # the request reached the server and waits on the store
        assert waiting.is_alive()
        stopper, _ = in_thread(server.stop)
        waiting.join(HANG_S)
        assert not waiting.is_alive(), "the client still waits on a server that stopped"
        [error] = answered
        assert isinstance(error, LinkError), error
        stopper.join(HANG_S)
        assert not stopper.is_alive()
    finally:
        other.execute("ROLLBACK")
        other.close()
    with pytest.raises(LinkError, match="no operations server listens"):
        Desk(Client(server.socket)).view()


def test_an_event_stream_open_when_the_server_stops_ends_and_nothing_is_logged(config: Config) -> None:
    """The stream's look at the state is in a worker when the server stops (held on the desks' lock):
    the stream ends for its client, and the look finishing late is no ``unexpected error``."""
    server = InProcessServer(config)
    Desk(Client(server.socket)).view()  # a desk exists, so each event looks at it (under the lock)
    held = server.server.desks._lock  # the lock every look at the desks takes: a worker waits on it
    held.acquire()
    try:
        listening, ended = in_thread(lambda: list(Client(server.socket).events()))
        time.sleep(0.5)  # the stream's first look waits on the lock
        stopper, _ = in_thread(server.stop)
        time.sleep(0.5)  # the server closed the stream under the look
    finally:
        held.release()
    stopper.join(HANG_S)
    listening.join(HANG_S)
    assert not stopper.is_alive() and not listening.is_alive()
    [events] = ended
    assert isinstance(events, list | LinkError), events


def test_a_pool_that_takes_no_more_work_ends_the_stream_and_refuses_the_verb_in_one_line(
    config: Config,
) -> None:
    """What CI saw at a worker's exit: a server in a thread of a process whose interpreter was ending (its
    worker pool then raises ``RuntimeError: cannot schedule new futures after interpreter shutdown``)
    logged an event stream's next look as an ``unexpected error`` with its traceback on the terminal. A pool
    shut down under an open stream does the same: the stream ends for its client, a verb is refused in one
    line naming the stop, and nothing is logged (the fixture fails the test on any error logged)."""
    server = InProcessServer(config)
    Desk(Client(server.socket)).view()  # a desk exists, so each event looks at it on the pool
    listening, ended = in_thread(lambda: list(Client(server.socket).events()))
    time.sleep(0.5)  # the stream's first event was sent; it waits for a change
    server.server.pool.shutdown(wait=True)
    with pytest.raises(LinkError, match="the operations server is stopping: ask again when it is back"):
        Desk(Client(server.socket)).waive("DRS1", "gnss", "no sky in the hangar")  # and wakes the stream
    listening.join(HANG_S)
    assert not listening.is_alive(), "the stream still waits on a pool that takes no work"
    [events] = ended
    assert isinstance(events, list | LinkError), events
    server.stop()


def reads_while_stopping(server: InProcessServer, readers: int = 4) -> list[str]:
    """Clients reading the desk without a pause while the server stops: how long each one that waited
    past ``HANG_S`` waited (their own timeout is longer still)."""
    stop = threading.Event()
    hung: list[str] = []

    def read() -> None:
        while not stop.is_set():
            started = time.monotonic()
            with contextlib.suppress(LinkError), Client(server.socket, 4 * HANG_S) as client:
                Desk(client).view()
            if time.monotonic() - started > HANG_S:
                hung.append(f"a read waited {time.monotonic() - started:.0f} s")

    threads = [threading.Thread(target=read, daemon=True) for _ in range(readers)]
    for thread in threads:
        thread.start()
    time.sleep(0.3)
    server.stop()
    time.sleep(0.2)
    stop.set()
    for thread in threads:
        thread.join(4 * HANG_S + 5)
    return hung


def test_requests_racing_the_stop_each_get_an_answer_or_an_eof(config: Config) -> None:
    """A connection accepted just before the listener closed must not be left open (its client waited
    its whole timeout) nor reach a worker pool that is shut down. A race, so tried over several stops."""
    for _ in range(8):
        assert not reads_while_stopping(InProcessServer(config))


class SharedServer:
    """A shared server of one operator (this account, EL) in a thread of this process: the one mode whose
    actions wait for another account's approval."""

    def __init__(self, tmp_path: Path) -> None:
        self.config = parse_config({
            "operator": [{"account": account_of(os.getuid()), "name": "EL"}],
            "data": {"dir": str(tmp_path / "data")},
            "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9}],
        })  # fmt: skip
        self.socket = tmp_path / "shared.sock"
        self.server = OperationsServer(self.config, "shared", self.socket)
        self.loop: list[asyncio.AbstractEventLoop] = []

        async def serve() -> None:
            self.loop.append(asyncio.get_running_loop())
            await self.server.run(lambda line: None)

        self.thread, _ = in_thread(lambda: asyncio.run(serve()))
        deadline = time.monotonic() + HANG_S
        while not self.socket.exists():
            assert time.monotonic() < deadline, "the shared server did not start"
            time.sleep(0.01)
        Desk(Client(self.socket)).view()  # EL's desk is made
        self.book = ApprovalBook(Store.open(self.config.store_path))

    def take_over(self, client: Client) -> tuple[threading.Thread, list[object]]:
        """EL's take-over of DRS1's release authority, waiting for another account's approval."""
        return in_thread(
            lambda: client.capsule("DRS1").take_over(
                AuthoritySeen(None, 0, 0),
                "DRS1",
                "the Pi's owner file is stale",
                Second(await_approval=True),
                lambda line: None,
            )
        )

    def request(self) -> tuple[str, str | None] | None:
        """The one approval request's state and reason (None before it is made)."""
        rows = self.book.store.query("SELECT state, reason FROM approval")
        return (str(rows[0]["state"]), rows[0]["reason"]) if rows else None

    def stop(self) -> None:
        if self.thread.is_alive():
            self.loop[0].call_soon_threadsafe(self.server.stopping.set)
        self.thread.join(HANG_S)
        assert not self.thread.is_alive()
        for approval in self.book.open_requests():  # a failed run's worker waits on it: let it go
            self.book.cancel(approval.id, "test", approval.requester)


@pytest.fixture
def shared(tmp_path: Path) -> Iterator[SharedServer]:
    server = SharedServer(tmp_path)
    try:
        yield server
    finally:
        server.stop()


def test_a_request_asked_for_while_the_server_stops_is_withdrawn_too(shared: SharedServer) -> None:
    """A take-over's approval request made after the stop withdrew the held ones (its worker waited on
    the desks' lock): nobody waits for it once the stop has closed its connection, so it is withdrawn as
    the others were, never left pending for another account to approve after a restart (the worker,
    which the pool does not stop, would then act on that approval)."""
    held = shared.server.desks._lock  # the take-over's worker waits on it, past the stop's withdrawal
    held.acquire()
    try:
        asking, answered = shared.take_over(Client(shared.socket))
        time.sleep(0.5)  # the request reached its worker, which waits on the lock
        shared.loop[0].call_soon_threadsafe(shared.server.stopping.set)
        time.sleep(0.5)  # the stop withdrew what was held (nothing yet)
    finally:
        held.release()
    shared.thread.join(HANG_S)
    asking.join(HANG_S)
    assert not shared.thread.is_alive() and not asking.is_alive()
    [error] = answered
    assert isinstance(error, LinkError), error
    assert shared.request() == ("cancelled", WITHDRAWN_STOPPED)


def test_a_request_asked_for_after_its_requester_dropped_is_withdrawn(shared: SharedServer) -> None:
    """The requester's connection closes while its worker waits on the desks' lock: the request its
    worker asks for after is withdrawn at once, not left pending (with the action waiting on it) for
    another account to approve with nobody watching."""
    held = shared.server.desks._lock
    held.acquire()
    try:
        client = Client(shared.socket)
        asking, _ = shared.take_over(client)
        time.sleep(0.5)  # the request reached its worker, which waits on the lock
        client.abort()
        time.sleep(0.5)  # the server saw the connection close and withdrew what it waited on (nothing yet)
    finally:
        held.release()
    asking.join(HANG_S)
    deadline = time.monotonic() + HANG_S
    while shared.request() in (None, ("pending", None)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert shared.request() == ("cancelled", WITHDRAWN_DROPPED)


def test_a_server_out_of_descriptors_that_stops_before_it_listens_again_logs_nothing(
    config: Config, caplog: pytest.LogCaptureFixture
) -> None:
    """An accept that fails for want of file descriptors listens again a second later; a stop in that
    second (held by a read in flight) closed the listening socket, and listening on it again was an
    error in the loop (``Invalid file descriptor: -1``, which the fixture finds)."""
    server = InProcessServer(config)
    Desk(Client(server.socket)).view()
    held = server.server.desks._lock  # a read in flight holds the stop for its grace
    held.acquire()
    waiting = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    taken: list[int] = []
    try:
        reading, _ = in_thread(lambda: Desk(Client(server.socket)).view())
        time.sleep(0.3)
        with contextlib.suppress(OSError):  # every descriptor this process may have (EMFILE)
            while True:
                taken.append(os.open("/dev/null", os.O_RDONLY))
        waiting.connect(str(server.socket))  # its descriptor was made before: the server's accept has none
        time.sleep(0.2)  # the server's accept failed: it listens again in a second
        for fd in taken:
            os.close(fd)
        taken.clear()
        assert any("cannot accept a connection" in r.getMessage() for r in caplog.records)
        stopper, _ = in_thread(server.stop)
        time.sleep(STOP_GRACE_S / 2)  # past the second, the stop still waits for the read
    finally:
        held.release()
        for fd in taken:
            os.close(fd)
        waiting.close()
    stopper.join(HANG_S)
    reading.join(HANG_S)
    assert not stopper.is_alive() and not reading.is_alive()


def test_a_worker_still_running_after_the_server_stopped_finishes_its_action_and_logs_nothing(
    config: Config, tmp_path: Path
) -> None:
    """An ARM's go/no-go prediction outlasts the whole stop (its grace, the loop's end): when the
    worker goes on, the lines it says have nobody to reach, and it finishes its action (refused here:
    the capsule is unreachable) instead of dying on the closed loop with an 'unexpected error' (the
    fixture fails the test on any error logged)."""
    weather = tmp_path / "forecast.grib2"
    weather.write_bytes(b"GRIB")  # only handed to the predictor, which never reads it
    predicting, go_on = threading.Event(), threading.Event()
    finished: list[object] = []

    def predictor_for(files: list[Path], state: object) -> object:
        predicting.set()
        go_on.wait(HANG_S)
        finished.append(files)
        return lambda name, origin: []  # no landing: the poll judges the prediction NO-GO and says so

    server = InProcessServer(config, predictor_for)  # type: ignore[arg-type]
    arming, answered = in_thread(lambda: Client(server.socket).capsule("DRS1").arm(weather=(str(weather),)))
    assert predicting.wait(HANG_S), "the ARM never reached its prediction"
    server.stop()  # the grace ends with the worker still predicting, and the loop ends
    arming.join(HANG_S)
    assert isinstance(answered[0], LinkError), answered
    go_on.set()
    server.server.pool.shutdown(wait=True)  # the worker has finished its action
    assert finished, "the worker never went on past its prediction"
