"""The history service: the audit log as a console's History and notices read it, and a console's session
start and loss written to it, for the account the kernel names.

It reads the store's one record of who did what (``AuditLog``) and hands the entries over; an export is
written by the console, so the file is its operator's own. The entries the server wrote for its clients
carry its session: the answer names it, so a console can tell another's entries from its own.
"""

from __future__ import annotations

from drs_link.ops import AuditLog, SessionLoss, record_loss, record_start, shown_record
from drs_link.server.desk_views import HistoryView, SessionStart
from drs_link.server.desks import Desks
from drs_link.server.peers import Peer
from drs_link.server.protocol import HistoryRequest, SessionLossRequest
from predictor.errors import UsageError

MOST_ROWS = 5000
"""The most entries one answer lists (History shows 500); an export asks for all of them (``limit`` 0)."""


class HistoryService:
    def __init__(self, desks: Desks) -> None:
        self.desks = desks
        self.log = AuditLog(desks.store)

    def read(self, peer: Peer, request: HistoryRequest) -> HistoryView:
        store = self.desks.store
        if not 0 <= request.limit <= MOST_ROWS:
            raise UsageError(f"limit: 0 (every entry) to {MOST_ROWS}, not {request.limit}")
        if request.after is not None:
            records = [shown_record(r) for r in store.audit(after_id=request.after)]
        elif request.limit:
            records = self.log.newest(request.text, request.limit)
        else:
            records = store.audit(text=request.text or None)
        return HistoryView(tuple(records), store.session, peer.operator)

    def started(self, peer: Peer) -> SessionStart:
        """A console started: the loss that ended the session before, if nobody has started one since."""
        return SessionStart(record_start(self.desks.store, peer.operator))

    def lost(self, peer: Peer, request: SessionLossRequest) -> SessionLoss:
        """A console cut off, after its open windows were disarmed through the server."""
        config = self.desks.desk(peer).state.config
        disarmed = [config.capsule(name).name for name in request.disarmed]
        in_flight = [config.capsule(name).name for name in request.go_in_flight]
        return record_loss(self.desks.store, peer.operator, request.signal, disarmed, in_flight)
