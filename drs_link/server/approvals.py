"""The approvals service: ``drs approve`` answered by the server, for the account the kernel names.

A thin service over ``drs_link.ops.ApprovalBook``: the requester's and the approver's logins are the
accounts of two connections' uids (``peers``), so "another login" is another account, and neither a
config file nor a row of the store (the operators cannot write it) can stand in for one. Both uids are
written to the audit beside the book's own rows (``approval.peer``).
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from drs_link.errors import ConfigError
from drs_link.ops import Approval, ApprovalBook, Login
from drs_link.server.peers import Peer
from drs_link.server.protocol import ApprovalView
from drs_link.store import Store, iso_utc
from predictor.errors import UsageError


def login_of(peer: Peer) -> Login:
    return Login(peer.account, peer.operator)


class ApprovalService:
    def __init__(self, store: Store, clock: Callable[[], datetime] | None = None) -> None:
        self.store = store
        self.book = ApprovalBook(store, clock or (lambda: store.clock()))

    def view(self, request: Approval) -> ApprovalView:
        return ApprovalView(
            request.id, request.capsule, request.action, request.summary, request.command, request.requested_by,
            request.requester.user, request.state, iso_utc(request.expires_utc), request.decided_by,
            request.decider.user if request.decider else None, "\n".join(request.for_approver(self.book.clock())),
            request.expires_utc,
        )  # fmt: skip

    def waiting(self) -> list[ApprovalView]:
        return [self.view(request) for request in self.book.open_requests()]

    def requested(self, peer: Peer, request: Approval) -> None:
        """The requester's uid, from its connection, beside the book's ``approval.requested``."""
        self._audit(peer, request, "requester")

    def decide(self, peer: Peer, approval_id: int, approve: bool, reason: str) -> ApprovalView:
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every approval is audited with it")
        if not approve and not reason.strip():
            raise UsageError("--reject needs --reason: the requester is told why")
        decided = self.book.decide(approval_id, peer.operator, login_of(peer), approve, reason)
        self._audit(peer, decided, "approver" if approve else "rejecter")
        return self.view(decided)

    def _audit(self, peer: Peer, request: Approval, role: str) -> None:
        detail = {"approval": request.id, "role": role, "uid": peer.uid, "account": peer.account}
        self.store.append_audit(peer.operator, request.capsule, "approval.peer", role, detail)
