"""Which payload a request is about: a DRS capsule when it starts where and when the capsule reported.

Why: chasemapper has one prediction URL for everything it tracks, and asks it with nothing but the
payload's newest position (``launch_latitude``/``longitude``/``altitude``/``datetime``), never its name.
drs-console sends each capsule's Iridium fix to chasemapper (``drs chase``, the console's ``[chase]``),
and chasemapper hands those numbers back unchanged: the floats as JSON carried them, the time as the
``HH:MM:SS`` it was sent with. So a request that starts at one of a capsule's latest fixes is that
capsule, and is flown with its calibrated model; anything else (a radiosonde, the main balloon, another
team's payload) is flown with Tawhiri's law, as SondeHub would.

The tolerances (``MATCH_*``) are tight because the round trip is exact, and wide enough for a client
that rounds to 4 decimals (11 m) or whole metres and seconds. After release the capsule falls away from
the gondola at tens of m/s (and its fixes start only then), so no other payload starts within them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime

MATCH_DISTANCE_M = 25.0
MATCH_ALTITUDE_M = 25.0
MATCH_TIME_S = 2.0
"""A request within 25 m across, 25 m up or down and 2 s of a capsule's fix is that capsule: chasemapper
returns the fix to the metre and the second (its time is the whole-second ``HH:MM:SS`` we sent)."""
FIXES_PER_CAPSULE = 3
"""The newest fixes of each capsule a request may start from: chasemapper may still ask from the one
before when a new report has just arrived (we send every 10 s, it predicts every 15 s)."""


@dataclass(frozen=True)
class CapsuleFix:
    """A capsule's position report, as the store has it."""

    capsule: str
    time: datetime
    lat: float
    lon: float
    alt_m: float


FixSource = Callable[[], Sequence[CapsuleFix]]
"""The newest ``FIXES_PER_CAPSULE`` fixes of every capsule, read afresh for each request."""


def surface_distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance on a 6371 km sphere (haversine): ample for tens of metres."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    h = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * 6_371_000.0 * math.asin(min(1.0, math.sqrt(h)))


def matching_fix(
    fixes: Sequence[CapsuleFix], lat: float, lon: float, alt_m: float | None, when: datetime
) -> CapsuleFix | None:
    """The capsule fix the launch point and time are, the nearest in time if several; None for any other
    payload. A request without ``launch_altitude`` is a flight from the ground: never a capsule's fix."""
    if alt_m is None:
        return None
    near = [
        fix for fix in fixes
        if abs((fix.time - when).total_seconds()) <= MATCH_TIME_S
        and abs(fix.alt_m - alt_m) <= MATCH_ALTITUDE_M
        and surface_distance_m(fix.lat, fix.lon, lat, lon) <= MATCH_DISTANCE_M
    ]  # fmt: skip
    return min(near, key=lambda fix: abs((fix.time - when).total_seconds()), default=None)
