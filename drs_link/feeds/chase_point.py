"""What the chase feed sends and keeps, as values: a capsule's point on chasemapper, a kept landing.

Apart from ``chase`` (the store, the reports, the socket) so that the operations server's protocol can
carry them to ``drs chase`` and back from a console without its clients loading the store.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

LIVE = "live re-prediction"
"""A descending capsule's landing, re-predicted from its Iridium fixes."""
RELEASE_NOW = "release now"
"""A capsule still on the balloon: the landing of a release now."""
KINDS = (LIVE, RELEASE_NOW)
"""What a kept landing can be: the comment chasemapper shows names it."""


@dataclass(frozen=True)
class ChasePoint:
    callsign: str
    time: datetime
    lat: float
    lon: float
    alt_m: float
    speed_kmh: float | None
    heading_deg: float | None
    comment: str

    def packet(self) -> dict[str, object]:
        """The ``PAYLOAD_SUMMARY`` as horusdemodlib sends it (-1: not known)."""
        return {
            "type": "PAYLOAD_SUMMARY",
            "callsign": self.callsign,
            "latitude": self.lat,
            "longitude": self.lon,
            "altitude": self.alt_m,
            "speed": -1 if self.speed_kmh is None else round(self.speed_kmh, 1),
            "heading": -1 if self.heading_deg is None else round(self.heading_deg, 1),
            "time": f"{self.time:%H:%M:%S}",
            "comment": self.comment,
        }


@dataclass(frozen=True)
class KeptLanding:
    capsule: str
    predicted_at: datetime
    landing_time: datetime
    lat: float
    lon: float
    alt_m: float
    kind: str
    """One of ``KINDS``."""
    is_demo: bool
