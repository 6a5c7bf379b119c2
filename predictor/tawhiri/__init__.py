"""Our predictor behind Tawhiri's v1 API, so chase software asks it as it asks SondeHub.

``request`` reads and checks a question before any weather; ``capsules`` tells a DRS capsule's request
from any other payload's; ``ascent`` and ``descent`` are Tawhiri's motions (and the float and reverse
flights); ``api`` answers a question; ``server`` is the HTTP server. A lazy door: the chase feed reads
``capsules`` (no numpy) without loading the descent engine.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .api import (
        FlownModel as FlownModel,
        PredictorService as PredictorService,
        WeatherSource as WeatherSource,
    )
    from .capsules import (
        FIXES_PER_CAPSULE as FIXES_PER_CAPSULE,
        CapsuleFix as CapsuleFix,
        FixSource as FixSource,
        surface_distance_m as surface_distance_m,
    )
    from .server import ApiServer as ApiServer

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ApiServer": "server",
        "CapsuleFix": "capsules",
        "FIXES_PER_CAPSULE": "capsules",
        "FixSource": "capsules",
        "FlownModel": "api",
        "PredictorService": "api",
        "WeatherSource": "api",
        "surface_distance_m": "capsules",
    },
)
