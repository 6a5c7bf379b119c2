"""Field interoperability on the LAN: the balloon's position in, the capsules on the chase map out.

``balloon_feed`` reads a ground station's NMEA, OziMux or Horus feed; ``chase`` sends Horus
``PAYLOAD_SUMMARY`` packets to chasemapper.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .balloon_feed import (
        BalloonFeed as BalloonFeed,
        BalloonFix as BalloonFix,
        FeedStatus as FeedStatus,
        Rejection as Rejection,
        format_ozimux as format_ozimux,
    )
    from .chase import (
        CHASE_PERIOD_S as CHASE_PERIOD_S,
        ChaseFeed as ChaseFeed,
        ChaseSender as ChaseSender,
        ChaseStore as ChaseStore,
        StoredFixes as StoredFixes,
        chase_kml_path as chase_kml_path,
        chase_points as chase_points,
        write_chase_kml as write_chase_kml,
    )
    from .chase_point import (
        KINDS as KINDS,
        LIVE as LIVE,
        RELEASE_NOW as RELEASE_NOW,
        ChasePoint as ChasePoint,
        KeptLanding as KeptLanding,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "BalloonFeed": "balloon_feed",
        "BalloonFix": "balloon_feed",
        "CHASE_PERIOD_S": "chase",
        "ChaseFeed": "chase",
        "ChasePoint": "chase_point",
        "KINDS": "chase_point",
        "LIVE": "chase_point",
        "RELEASE_NOW": "chase_point",
        "KeptLanding": "chase_point",
        "ChaseSender": "chase",
        "ChaseStore": "chase",
        "FeedStatus": "balloon_feed",
        "Rejection": "balloon_feed",
        "StoredFixes": "chase",
        "chase_kml_path": "chase",
        "chase_points": "chase",
        "write_chase_kml": "chase",
        "format_ozimux": "balloon_feed",
    },
)
