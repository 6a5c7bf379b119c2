"""Everything one operator may do, each concern of the operations layer over one shared ``OpsState``.

Why a composition: the server keeps one per operator account (its desk, ``drs_link.server.desks``), and
each of its services reaches the one concern it serves (``.release``, ``.iridium``, ...); the release
needs the links and Iridium of the same operator for its go/no-go poll. Nothing here acts: every method
is a concern's own.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from drs_link.config import Config
from drs_link.ops.approval import Login
from drs_link.ops.enrolment import Enrolment
from drs_link.ops.iridium_ops import IridiumOps
from drs_link.ops.links import CapsuleLinks
from drs_link.ops.ops_state import OpsState
from drs_link.ops.release import Release
from drs_link.ops.telemetry import TelemetryRecorder
from drs_link.store import Store, utc_now


class OperatorOps:
    """The capsule links, the release, Iridium and enrolment of one operator, on one ``OpsState``."""

    def __init__(
        self,
        config: Config,
        store: Store,
        clock: Callable[[], datetime] = utc_now,
        recorder: TelemetryRecorder | None = None,
        environ: dict[str, str] | None = None,
        sleep: Callable[[float], None] | None = None,
        holder: str | None = None,
        login: Login | None = None,
    ) -> None:
        """As ``OpsState``: ``holder`` is who may FIRE in an ARM window these operations open."""
        self.state = OpsState(config, store, clock, recorder, environ, sleep, holder, login)
        self.links = CapsuleLinks(self.state)
        self.iridium = IridiumOps(self.state)
        self.release = Release(self.state, self.links, self.iridium)
        self.enrolment = Enrolment(self.state)

    def close(self) -> None:
        self.state.close()
