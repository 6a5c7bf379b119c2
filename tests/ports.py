"""A loopback port nothing listens on, for a server a test starts (or for a refused connection)."""

from __future__ import annotations

import socket
import time
from pathlib import Path


def free_port(kind: socket.SocketKind = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def accept_queue(port: int) -> int | None:
    """How many connections wait in the accept queue of the loopback TCP listener on ``port`` (None: no
    listener). Linux shows a listening socket's backlog as its rx_queue in /proc/net/tcp."""
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        local, state, queues = fields[1], fields[3], fields[4]
        if state == "0A" and int(local.rpartition(":")[2], 16) == port:
            return int(queues.partition(":")[2], 16)
    return None


def wait_until_accepted(port: int, timeout_s: float = 60.0) -> None:
    """Until the server on ``port`` has accepted every connection made to it so far.

    A connection is complete (``connect`` returns) while it still waits in the kernel's queue; a server
    thread on a loaded machine can take seconds to ``accept`` it. A test that needs the server to have
    the connection (a request "in flight") waits here instead of sleeping a guessed time. The limit is
    a readiness bound only: the wait ends as soon as the queue is empty.
    """
    deadline = time.monotonic() + timeout_s
    while (waiting := accept_queue(port)) != 0:
        if time.monotonic() > deadline:
            raise AssertionError(f"port {port}: {waiting} connection(s) never accepted in {timeout_s:.0f} s")
        time.sleep(0.02)
