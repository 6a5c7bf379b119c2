"""The console's chase feed: its capsules and their latest predictions on the chase team's chasemapper.

The feed itself (packets, socket, the shared landing table) is ``drs_link.feeds.chase``; what only the
console has is its predictions. Before each round the feed keeps every capsule's latest one: the live
re-prediction of a descending capsule (from the Iridium fixes the operations server holds), else the
"release now" prediction from the balloon. Keeping it writes the capsule's KML at its fixed path for
chasemapper's ``[kml_overlays]`` (this account's own file) and hands its landing to the operations
server, where ``drs chase`` on any machine finds it too; the round's packets are what the server says
(``client.chase.points``). A prediction is kept once (the KML is not rewritten every round) and is timed
by the position it started from, so a capsule whose predictions stopped drops out of the feed; a landed
capsule gets no more predicted landings (its fixes say where it is).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from drs_link.config import Config
from drs_link.errors import LinkError
from drs_link.feeds import (
    LIVE,
    RELEASE_NOW,
    ChaseFeed,
    ChaseSender,
    KeptLanding,
    chase_kml_path,
    write_chase_kml,
)
from drs_link.server import Client
from predictor.errors import PredictorError

if TYPE_CHECKING:
    from console.context import ConsoleSetup, ServerViews
    from drs_link.feeds import ChasePoint
    from predictor import Prediction

log = logging.getLogger(__name__)


class LandingKeeper:
    """Keeps each capsule's newest prediction for the chase feed (once per prediction)."""

    def __init__(self, config: Config, setup: ConsoleSetup, client: Callable[[], Client]) -> None:
        from console.context import ServerViews

        self.config = config
        self.setup = setup
        self.client = client
        service = setup.predictions
        self.views: ServerViews = ServerViews(client, lambda: service.live if service is not None else None)
        self._kept: dict[str, Prediction] = {}

    def current(self, capsule: str) -> tuple[Prediction, str] | None:
        """The live re-prediction while the capsule descends; before its first fix, the release-now one;
        nothing once it has landed (its fixes then say where it is)."""
        service = self.setup.predictions
        if service is None:
            return None
        descent = self.views.recovery(capsule).descent
        if not descent.track:
            return (service.latest[capsule], RELEASE_NOW) if capsule in service.latest else None
        if descent.landing is not None:
            return None
        if descent.live_error is not None:
            log.warning("chase feed: no live prediction for %s: %s", capsule, descent.live_error)
        return (service.live_latest[capsule], LIVE) if capsule in service.live_latest else None

    def keep_all(self) -> None:
        for capsule in self.setup.capsules:
            found = self.current(capsule)
            if found is None or found[0] is self._kept.get(capsule):
                continue
            prediction, kind = found
            kml = chase_kml_path(self.config.data.dir, capsule)
            land = prediction.landing
            try:
                write_chase_kml(prediction, kml)
                with self.client() as client:
                    client.chase.keep(KeptLanding(capsule, prediction.release.time, land.time, land.lat,
                                                  land.lon, land.alt_m, kind, prediction.is_demo))  # fmt: skip
            except (PredictorError, OSError, LinkError) as exc:  # the positions still go out; retried
                log.warning("chase feed: cannot keep %s's prediction at %s: %s", capsule, kml, exc)
                continue
            self._kept[capsule] = prediction

    def points(self) -> list[ChasePoint]:
        self.keep_all()
        with self.client() as client:
            return client.chase.points()


def started_chase_feed(config: Config, setup: ConsoleSetup) -> ChaseFeed | None:
    """The feed to ``[chase] udp``, sending; None when the configuration sets no chase feed, or the session
    has no operations server behind it (a replay sends nothing to the chase cars)."""
    server = setup.server
    if not config.chase.udp or server is None or setup.mode == "replay":
        return None
    keeper = LandingKeeper(config, setup, lambda: Client(server))
    return ChaseFeed(ChaseSender(config.chase.udp, "chase.udp"), keeper.points).start()
