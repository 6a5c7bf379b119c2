"""A console's desk as values: what the server answers for it and a console decodes (``desk``).

Apart from ``desk`` (the console's verbs over the client) so that the server's services build these
without importing the client: the client reaches a private server, which is the server itself.
"""

from __future__ import annotations

import msgspec

from drs_link.ops import LandedEvidence, ParachuteOverride, ParachutePlan, SessionLoss, StepRecord, Waiver
from drs_link.store import AuditRecord


class DeskView(msgspec.Struct, frozen=True):
    """What a console shows of its desk: this account's waivers and every capsule's checklist ticks and
    PARACHUTE overrides (from any console: the overrides stay loud until replaced)."""

    waivers: dict[str, tuple[Waiver, ...]]
    checklists: dict[str, tuple[StepRecord, ...]]
    overrides: tuple[ParachuteOverride, ...]
    audit_id: int = 0
    """The newest audit entry when it was read (``Event.audit_id``): a later one may have changed it."""

    def with_waivers(self, capsule: str, held: tuple[Waiver, ...]) -> DeskView:
        """The desk with a capsule's waivers as a verb's answer said them."""
        return msgspec.structs.replace(self, waivers={**self.waivers, capsule: held})

    def with_steps(self, capsule: str, recorded: tuple[StepRecord, ...]) -> DeskView:
        return msgspec.structs.replace(self, checklists={**self.checklists, capsule: recorded})


class HistoryView(msgspec.Struct, frozen=True):
    """Audit entries, each text in them as it may reach a terminal (``shown``), and who asked."""

    records: tuple[AuditRecord, ...]
    session: str
    """The server's own session: the entries it wrote for its clients carry it."""
    operator: str
    """The asking account's operator name."""

    def elsewhere(self, record: AuditRecord) -> str | None:
        """The console that wrote ``record`` when it is not the asker's (its session, or the operator who
        acted through this server), else None."""
        if record.session and record.session != self.session:
            return record.session
        if record.operator != self.operator:
            return f"{record.operator} through the operations server"
        return None


class SessionStart(msgspec.Struct, frozen=True):
    """A console's start, noted: the loss that ended the session before, if nobody started one since."""

    last_loss: SessionLoss | None


class ParachuteView(msgspec.Struct, frozen=True):
    """A PARACHUTE time the capsule would accept, and the landed evidence the operator reads first."""

    plan: ParachutePlan
    evidence: LandedEvidence
