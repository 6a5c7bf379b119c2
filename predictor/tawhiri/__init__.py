"""Our predictor behind Tawhiri's v1 API, so chase software asks it as it asks SondeHub.

``api`` answers the requests; ``ascent`` is Tawhiri's standard ascent profile, which that API needs.
A plain door: only ``drs serve`` enters this room, and it runs the API, so there is nothing to defer.
"""

from .api import ApiServer, PredictorService, WeatherSource

__all__ = ["ApiServer", "PredictorService", "WeatherSource"]
