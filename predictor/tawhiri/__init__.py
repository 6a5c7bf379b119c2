"""Our predictor behind Tawhiri's v1 API, so chase software asks it as it asks SondeHub.

``api`` answers the requests; ``ascent`` is Tawhiri's standard ascent profile, which that API needs.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .api import (
        ApiServer as ApiServer,
        PredictorService as PredictorService,
        WeatherSource as WeatherSource,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ApiServer": "api",
        "PredictorService": "api",
        "WeatherSource": "api",
    },
)
