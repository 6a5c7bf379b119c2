"""The views service: what a console's screens draw from the store, read by the server for them.

Recovery (the descent, what was commanded, a parachute drop), Iridium health, every capsule's PARACHUTE
overrides and the desk (the account's waivers and the checklists' ticks), in the operations layer's own
values (``drs_link.server.desk``). It reads; it never changes the store. The live re-prediction of a
descent is not here: it flies the console's own weather, and the console adds it to the track it is given.
"""

from __future__ import annotations

from drs_link.ops import (
    IridiumHealthView,
    ParachuteOverride,
    RecoveryView,
    iridium_health_from,
    parachute_override,
    recovery_view,
)
from drs_link.server.checklists import ChecklistService
from drs_link.server.desk_views import DeskView
from drs_link.server.desks import Desks
from drs_link.server.peers import Peer
from drs_link.server.waivers import WaiverService


class ViewService:
    def __init__(self, desks: Desks, waivers: WaiverService, checklists: ChecklistService) -> None:
        self.desks = desks
        self.waivers = waivers
        self.checklists = checklists

    def recovery(self, peer: Peer, name: str) -> RecoveryView:
        iridium = self.desks.desk(peer).iridium
        return recovery_view(iridium, iridium.state.config.capsule(name).name, None)

    def iridium(self, peer: Peer, name: str) -> IridiumHealthView:
        iridium = self.desks.desk(peer).iridium
        capsule = iridium.state.config.capsule(name).name
        return iridium_health_from(capsule, iridium.stored_reports(capsule), iridium.commands(capsule))

    def overrides(self, peer: Peer) -> tuple[ParachuteOverride, ...]:
        """Each capsule's PARACHUTE queued without landed evidence, from any console (``override``)."""
        iridium = self.desks.desk(peer).iridium
        found = (
            parachute_override(
                name, iridium.state.store.audit(name, action="mt.parachute"), iridium.commands(name)
            )
            for name in iridium.state.capsules
        )
        return tuple(override for override in found if override is not None)

    def newest_id(self) -> int:
        """The newest audit entry's id: every waiver, tick, send and session is audited."""
        return max((r.id for r in self.desks.store.audit(limit=1)), default=0)

    def desk(self, peer: Peer) -> DeskView:
        audit_id = self.newest_id()  # read first: a change made while the rest is read moves it on again
        return DeskView(
            self.waivers.all_held(peer), self.checklists.all_records(peer), self.overrides(peer), audit_id
        )
