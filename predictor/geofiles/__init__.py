"""Geographic files other tools open (KML, GeoJSON, GPX), written once for every product that exports.

Predictions, release plans and recovery tracks all draw lines, rings and points; the rules that make
those files open correctly elsewhere (the antimeridian, ring direction, schema order, ASCII names
for handhelds, ``-`` for stdout) live here so that no exporter can get one of them wrong alone.
"""

DEMO_LABEL = "DEMO WEATHER, NOT A FORECAST"
