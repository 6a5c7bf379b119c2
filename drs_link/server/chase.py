"""The chase service: what ``drs chase`` sends to chasemapper, read by the server from the reports and
landings it holds, and the landings a console keeps for it.

A console predicts (it holds the weather and the prediction service) and writes the KML overlay itself,
so that file is its operator's own; the landing it kept is recorded here, in the one store, where every
``drs chase`` on any machine finds it.
"""

from __future__ import annotations

from drs_link.errors import RefusedError
from drs_link.feeds import KINDS, ChasePoint, ChaseStore, KeptLanding, chase_points
from drs_link.server.desks import Desks


class ChaseService:
    def __init__(self, desks: Desks) -> None:
        self.desks = desks
        self.landings = ChaseStore(desks.store)

    def points(self) -> list[ChasePoint]:
        """Each configured capsule's newest fix, and its recent landing's marker."""
        return chase_points(self.desks.config, self.desks.store, self.desks.clock())

    def keep(self, landing: KeptLanding) -> None:
        """Record a console's landing, refused unless it is a configured capsule's and a place on Earth."""
        self.desks.config.capsule(landing.capsule)
        # NaN and infinities never arrive: JSON writes them as null, which the protocol refuses unread.
        if not -90.0 <= landing.lat <= 90.0:
            raise RefusedError(f"{landing.capsule}: landing latitude {landing.lat!r} is not on Earth")
        if not -180.0 <= landing.lon <= 180.0:
            raise RefusedError(f"{landing.capsule}: landing longitude {landing.lon!r} is not on Earth")
        if landing.kind not in KINDS:
            raise RefusedError(
                f"{landing.capsule}: a kept landing is one of {', '.join(KINDS)}, not {landing.kind!r}"
            )
        self.landings.record(landing)
