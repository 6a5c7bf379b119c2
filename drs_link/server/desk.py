"""A console's desk at the operations server: what it shows and records beside the commanding verbs.

Its waivers, the checklists' ticks, the PARACHUTE overrides, the audit log, the session's start and loss,
the recovery and Iridium views and a PARACHUTE plan: all held or computed by the server, answered in the
operations layer's own values (``drs_link.ops``) so the console draws them as it always did, and never
opens the store. Why a module apart from ``client``: the command-line client and the protocol hold no
``drs_link.ops`` (their import contract keeps ``drs …`` light); a console, which shows these values,
decodes them here, through the same ``Client.call``.
"""

from __future__ import annotations

from drs_link.ops import (
    HISTORY_ROWS,
    IridiumHealthView,
    LandedEvidence,
    RecoveryView,
    SessionLoss,
    StepRecord,
    Waiver,
)
from drs_link.server.client import Client
from drs_link.server.desk_views import DeskView, HistoryView, ParachuteView, SessionStart
from drs_link.server.protocol import (
    PROTOCOL,
    HistoryRequest,
    ItemRequest,
    PlanRequest,
    SessionLossRequest,
    StepRequest,
    WaiveRequest,
)


class Desk:
    """The desk's verbs, each one request on ``client``."""

    def __init__(self, client: Client) -> None:
        self.client = client

    def view(self) -> DeskView:
        return self.client.call("GET", "/desk", None, DeskView)

    def waive(self, name: str, item: str, reason: str) -> tuple[Waiver, ...]:
        """Waive ``item`` for this account (audited once, here); the account's waivers of ``name``."""
        request = WaiveRequest(PROTOCOL, item, reason)
        return self.client.call("POST", f"/capsules/{name}/waivers", request, tuple[Waiver, ...])

    def withdraw(self, name: str, item: str) -> tuple[Waiver, ...]:
        request = ItemRequest(PROTOCOL, item)
        return self.client.call("POST", f"/capsules/{name}/waivers/withdraw", request, tuple[Waiver, ...])

    def waivers(self, name: str) -> tuple[Waiver, ...]:
        return self.client.call("GET", f"/capsules/{name}/waivers", None, tuple[Waiver, ...])

    def tick(self, name: str, checklist: str, step: str) -> tuple[StepRecord, ...]:
        """Tick a manual step (audited with this account's operator); the capsule's steps recorded."""
        request = StepRequest(PROTOCOL, checklist, step)
        return self.client.call("POST", f"/capsules/{name}/checklist", request, tuple[StepRecord, ...])

    def skip(self, name: str, checklist: str, step: str, reason: str) -> tuple[StepRecord, ...]:
        request = StepRequest(PROTOCOL, checklist, step, reason)
        return self.client.call("POST", f"/capsules/{name}/checklist", request, tuple[StepRecord, ...])

    def history(self, text: str | None = None, limit: int = HISTORY_ROWS) -> HistoryView:
        """The newest ``limit`` entries containing ``text``, newest first (``limit`` 0: every one, oldest
        first, for an export the console writes itself)."""
        return self.client.call("POST", "/audit", HistoryRequest(PROTOCOL, text, limit), HistoryView)

    def after(self, entry: int) -> HistoryView:
        """Every entry after ``entry``, oldest first (what another console did since)."""
        return self.client.call("POST", "/audit", HistoryRequest(PROTOCOL, after=entry), HistoryView)

    def session_started(self) -> SessionLoss | None:
        """Note that this console started; the loss that ended the last session, if nobody started since."""
        return self.client.call("POST", "/session/start", HistoryRequest(PROTOCOL), SessionStart).last_loss

    def session_lost(self, signal: str, disarmed: list[str], go_in_flight: list[str]) -> SessionLoss:
        request = SessionLossRequest(PROTOCOL, signal, tuple(disarmed), tuple(go_in_flight))
        return self.client.call("POST", "/session/lost", request, SessionLoss)

    def recovery(self, name: str) -> RecoveryView:
        """The capsule's recovery from the reports, MTs and PARACHUTE audit the server holds (no live
        re-prediction: that is the console's own, on its weather)."""
        return self.client.call("GET", f"/views/{name}/recovery", None, RecoveryView)

    def iridium(self, name: str) -> IridiumHealthView:
        return self.client.call("GET", f"/views/{name}/iridium", None, IridiumHealthView)

    def plan_parachute(self, name: str, requested: tuple[int, int] | None) -> ParachuteView:
        """When a PARACHUTE can fire, and the landed evidence the gate will judge (the send re-checks both)."""
        return self.client.call(
            "POST", f"/iridium/{name}/parachute-plan", PlanRequest(PROTOCOL, requested), ParachuteView
        )

    def landed(self, name: str) -> LandedEvidence:
        return self.client.call("GET", f"/iridium/{name}/landed", None, LandedEvidence)
