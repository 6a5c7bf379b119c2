"""One ``Operations`` per operator, all on the server's one store: the rules of ``drs_link.ops`` as they are.

Why one per operator rather than one for all: ``Operations`` acts under one operator name, one login and
one ARM-window holder, and every rule in ``drs_link.ops`` was written for several processes on one store
(ARM windows, approvals and the release state are compare-and-sets in SQLite). Each desk is such a
process's engine, held by the server instead of by the operator's own process, so its login is the
kernel's account and nothing the operator wrote.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from dataclasses import replace
from datetime import datetime
from pathlib import Path

from drs_link.config import Config
from drs_link.ops import Login, Operations, Predict
from drs_link.server.peers import Peer
from drs_link.store import Store

PredictorFor = Callable[[list[Path], Operations], Predict]
"""Builds the "release now" prediction go/no-go judges from GRIB2 files (the console's service, which
the command line hands in: ``drs_link`` cannot import the console)."""


def holder_of(peer: Peer) -> str:
    """Who holds an ARM window a peer opens: its account on this host (as ``drs capsule arm`` was)."""
    return f"{peer.account}@{socket.gethostname()} drs"


class Desks:
    def __init__(
        self, config: Config, store: Store, environ: dict[str, str] | None = None,
        clock: Callable[[], datetime] | None = None,
    ) -> None:  # fmt: skip
        self.config = config
        self.store = store
        self.environ = environ
        self.clock = clock or (lambda: store.clock())
        """The store's clock (the demo's scaled time is written into the store), or the one given: a
        console's own in-process server keeps the console's time."""
        self._desks: dict[int, Operations] = {}
        self._lock = threading.Lock()

    def desk(self, peer: Peer) -> Operations:
        """The peer's engine, made on its first request."""
        with self._lock:
            ops = self._desks.get(peer.uid)
            if ops is None:
                config = replace(self.config, operator=replace(self.config.operator, name=peer.operator))
                ops = Operations(
                    config, self.store, clock=self.clock, environ=self.environ,
                    holder=holder_of(peer), login=Login(peer.account, None, peer.operator),
                )  # fmt: skip
                self._desks[peer.uid] = ops
            return ops

    def any_desk(self) -> Operations | None:
        with self._lock:
            return next(iter(self._desks.values()), None)

    def close(self) -> None:
        with self._lock:
            for ops in self._desks.values():
                for capsule in ops.capsules.values():
                    capsule.link.close()
