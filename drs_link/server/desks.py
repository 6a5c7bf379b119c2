"""One ``OperatorOps`` per operator, all on the server's one store: the rules of ``drs_link.ops`` as they are.

Why one per operator rather than one for all: a desk acts under one operator name, one login and
one ARM-window holder, and every rule in ``drs_link.ops`` was written for several processes on one store
(ARM windows, approvals and the release state are compare-and-sets in SQLite). Each desk is such a
process's engine, held by the server instead of by the operator's own process, so its login is the
kernel's account and nothing the operator wrote.
"""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Callable
from dataclasses import replace
from datetime import datetime
from pathlib import Path

from drs_link.config import Config
from drs_link.ops import Login, OperatorOps, OpsState, Predict
from drs_link.server.peers import Peer
from drs_link.store import Store, account_of

SERVER_OPERATOR = "drs server"
"""Who the server's own engine acts as (its telemetry polls), in the audit and the release record."""
PredictorFor = Callable[[list[Path], OpsState], Predict]
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
        self._desks: dict[int, OperatorOps] = {}
        self._server: OperatorOps | None = None
        self._lock = threading.Lock()

    def desk(self, peer: Peer) -> OperatorOps:
        """The peer's engine, made on its first request."""
        with self._lock:
            ops = self._desks.get(peer.uid)
            if ops is None:
                config = replace(self.config, operator=replace(self.config.operator, name=peer.operator))
                ops = OperatorOps(
                    config, self.store, clock=self.clock, environ=self.environ,
                    holder=holder_of(peer), login=Login(peer.account, peer.operator),
                )  # fmt: skip
                self._desks[peer.uid] = ops
            return ops

    def server_desk(self) -> OperatorOps:
        """The server's own engine, acting as the server and for nobody (``SERVER_OPERATOR``): the
        telemetry it polls for every console (``telemetry``). Its polls only read, except what a poll
        itself settles (a Go that was never taken), which the record then shows the server noticed."""
        with self._lock:
            if self._server is None:
                config = replace(self.config, operator=replace(self.config.operator, name=SERVER_OPERATOR))
                self._server = OperatorOps(
                    config, self.store, clock=self.clock, environ=self.environ, holder=SERVER_OPERATOR,
                    login=Login(account_of(os.geteuid()), SERVER_OPERATOR),
                )  # fmt: skip
            return self._server

    def any_desk(self) -> OperatorOps | None:
        with self._lock:
            return next(iter(self._desks.values()), None)

    def close(self) -> None:
        with self._lock:
            for ops in [*self._desks.values(), *([self._server] if self._server is not None else [])]:
                for capsule in ops.state.capsules.values():
                    capsule.link.close()
