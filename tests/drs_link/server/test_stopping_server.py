"""A stopping operations server leaves no request unanswered (issue #29, "the server restarted with
windows and requests open"): whatever is in flight when it stops, each client gets its answer or an EOF
(a ``LinkError`` on its side) within the stop's grace, never a wait for its own timeout, and the server
logs no traceback on the way out. A real server on a real Unix socket in this process, real clients.

The bounds below are hang checks, not speed checks: a failure means a client that would have waited its
whole timeout (600 s for a verb), and each bound is several times ``STOP_GRACE_S``."""

from __future__ import annotations

import contextlib
import logging
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.config import Config
from drs_link.errors import LinkError
from drs_link.server import Client, InProcessServer
from drs_link.server.app import STOP_GRACE_S
from drs_link.server.desk import Desk
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
