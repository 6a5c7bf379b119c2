"""Field interoperability on the LAN: the balloon's position in, the capsules on the chase map out.

``balloon_feed`` reads a ground station's NMEA, OziMux or Horus feed; ``chase`` sends Horus
``PAYLOAD_SUMMARY`` packets to chasemapper.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .balloon_feed import BalloonFeed as BalloonFeed
    from .balloon_feed import BalloonFix as BalloonFix
    from .balloon_feed import FeedStatus as FeedStatus
    from .balloon_feed import Rejection as Rejection
    from .balloon_feed import format_ozimux as format_ozimux
    from .chase import CHASE_PERIOD_S as CHASE_PERIOD_S
    from .chase import ChaseFeed as ChaseFeed
    from .chase import ChasePoint as ChasePoint
    from .chase import ChaseSender as ChaseSender
    from .chase import ChaseStore as ChaseStore
    from .chase import chase_kml_path as chase_kml_path
    from .chase import chase_points as chase_points

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "BalloonFeed": "balloon_feed",
        "BalloonFix": "balloon_feed",
        "CHASE_PERIOD_S": "chase",
        "ChaseFeed": "chase",
        "ChasePoint": "chase",
        "ChaseSender": "chase",
        "ChaseStore": "chase",
        "FeedStatus": "balloon_feed",
        "Rejection": "balloon_feed",
        "chase_kml_path": "chase",
        "chase_points": "chase",
        "format_ozimux": "balloon_feed",
    },
)
