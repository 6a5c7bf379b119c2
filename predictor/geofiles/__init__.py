"""Geographic files other tools open (KML, GeoJSON, GPX), written once for every product that exports.

Predictions, release plans and recovery tracks all draw lines, rings and points; the rules that make
those files open correctly elsewhere (the antimeridian, ring direction, schema order, ASCII names
for handhelds, ``-`` for stdout) live here so that no exporter can get one of them wrong alone.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from . import geojson as geojson, gpx as gpx, kml as kml
    from .geometry import line_parts as line_parts, polygon_parts as polygon_parts, position as position
    from .output import (
        EXPORT_MODE as EXPORT_MODE,
        is_stdout as is_stdout,
        piped as piped,
        write_text as write_text,
    )

DEMO_LABEL = "DEMO WEATHER, NOT A FORECAST"

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "geojson": "geojson",
        "gpx": "gpx",
        "kml": "kml",
        "EXPORT_MODE": "output",
        "is_stdout": "output",
        "line_parts": "geometry",
        "piped": "output",
        "polygon_parts": "geometry",
        "position": "geometry",
        "write_text": "output",
    },
)
