"""Our predictor behind Tawhiri's v1 API, so chase software asks it as it asks SondeHub.

``request`` reads and checks a question before any weather; ``capsules`` tells a DRS capsule's request
from any other payload's; ``ascent`` and ``descent`` are Tawhiri's motions (and the float and reverse
flights); ``api`` answers a question; ``server`` is the HTTP server. A lazy door: the chase feed reads
``capsules`` (no numpy) without loading the descent engine.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .api import PredictorService as PredictorService, WeatherSource as WeatherSource
    from .capsules import CapsuleFix as CapsuleFix, FixSource as FixSource
    from .server import ApiServer as ApiServer

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ApiServer": "server",
        "CapsuleFix": "capsules",
        "FixSource": "capsules",
        "PredictorService": "api",
        "WeatherSource": "api",
    },
)
