"""Measured flights: the input of calibration and of every evaluation on real data.

``reading`` reads every track format into one ``Track`` of ``Fix`` es, ``cleaning`` turns a track into a
``Flight`` by stated rules (ascent, descent, landing, and why anything was dropped), ``ascent_winds``
turns a flight's own ascent into a ``WeatherCube``, and ``standard_atmosphere`` fills pressure where none
was logged.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .ascent_winds import MIN_ASCENT_FIXES as MIN_ASCENT_FIXES, ascent_weather_cube as ascent_weather_cube
    from .cleaning import Flight as Flight, clean as clean
    from .reading import (
        Fix as Fix,
        TrackError as TrackError,
        read_track as read_track,
        write_canonical_csv as write_canonical_csv,
    )
    from .standard_atmosphere import pressure_temperature as pressure_temperature

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "Fix": "reading",
        "Flight": "cleaning",
        "MIN_ASCENT_FIXES": "ascent_winds",
        "TrackError": "reading",
        "ascent_weather_cube": "ascent_winds",
        "clean": "cleaning",
        "pressure_temperature": "standard_atmosphere",
        "read_track": "reading",
        "write_canonical_csv": "reading",
    },
)
