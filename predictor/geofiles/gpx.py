"""GPX 1.1 for handheld GPS units: short ASCII waypoint names with a symbol, and no NaN.

gpsbabel and Garmin units truncate long names and mangle anything outside ASCII (``±`` becomes
garbage on the screen), and a NaN in ``<ele>`` makes some readers drop the whole file. Names are
therefore short ASCII labels; the details a person needs go in ``<desc>``, also ASCII.

A track that crosses ±180° is split into one ``<trkseg>`` per side: GDAL and QGIS join the points of
a segment with straight lines in longitude, and drew a 360°-wide line across the map.
"""

from __future__ import annotations

import math
import re
import unicodedata
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

NS = "http://www.topografix.com/GPX/1/1"
NAME_LENGTH = 14
"""The longest waypoint name current Garmin handhelds show whole (gpsbabel's default for them)."""
RELEASE_SYMBOL = "Flag, Green"
PREDICTED_LANDING_SYMBOL = "Flag, Blue"
LANDING_SYMBOL = "Flag, Red"
"""Garmin symbol names, which other units and apps (OsmAnd, Locus) also map to a flag."""


@dataclass(frozen=True)
class Waypoint:
    lat: float
    lon: float
    alt_m: float
    name: str
    symbol: str
    description: str
    time: datetime | None = None


@dataclass(frozen=True)
class TrackPoint:
    lat: float
    lon: float
    alt_m: float
    time: datetime | None = None


def ascii_text(text: str) -> str:
    """``text`` with accents dropped and anything else outside printable ASCII spelled or removed."""
    spelled = text.replace("±", "+/-").replace("σ", "sigma").replace("°", " deg").replace("²", "2")
    decomposed = unicodedata.normalize("NFKD", spelled).encode("ascii", "ignore").decode("ascii")
    return re.sub(r"[^\x20-\x7e]", "", decomposed)


def short_name(owner: str, label: str) -> str:
    """``OWNER LABEL`` in upper-case ASCII, at most NAME_LENGTH characters, the owner cut first.

    The owner is the capsule's name (or DEMO) and the label says what the point is, which is the
    part a searcher must not lose.
    """
    label = " ".join(re.sub(r"[^A-Z0-9-]", "", w) for w in ascii_text(label).upper().split())
    owner = re.sub(r"[^A-Z0-9-]", "", ascii_text(owner).upper().replace(" ", "-"))
    owner = owner[: max(NAME_LENGTH - len(label) - 1, 0)]
    return " ".join(w for w in (owner, label) if w)[:NAME_LENGTH]


def _position(parent: ET.Element, tag: str, lat: float, lon: float, alt_m: float) -> ET.Element | None:
    if not (math.isfinite(lat) and math.isfinite(lon)):
        return None
    lon = (lon + 180.0) % 360.0 - 180.0
    element = ET.SubElement(parent, f"{{{NS}}}{tag}", {"lat": f"{lat:.6f}", "lon": f"{lon:.6f}"})
    if math.isfinite(alt_m):
        ET.SubElement(element, f"{{{NS}}}ele").text = f"{alt_m:.1f}"
    return element


def _time(parent: ET.Element, moment: datetime | None) -> None:
    if moment is not None:
        ET.SubElement(parent, f"{{{NS}}}time").text = moment.strftime("%Y-%m-%dT%H:%M:%SZ")


def antimeridian_segments(points: Sequence[TrackPoint]) -> list[list[TrackPoint]]:
    """The points in runs that stay on one side of ±180°: a new run where a step's longitude jumps by
    more than 180° (the short way round crosses the antimeridian). Positions that are not numbers are
    kept in the run (``_position`` leaves them out) and do not break it."""
    runs: list[list[TrackPoint]] = [[]]
    last: float | None = None
    for p in points:
        if math.isfinite(p.lat) and math.isfinite(p.lon):
            lon = (p.lon + 180.0) % 360.0 - 180.0
            if last is not None and abs(lon - last) > 180.0:
                runs.append([])
            last = lon
        runs[-1].append(p)
    return [run for run in runs if run]


def to_gpx(
    description: str, waypoints: Sequence[Waypoint], tracks: Sequence[tuple[str, Sequence[TrackPoint]]]
) -> str:
    """Waypoints, then a track per (name, points) with points; a position that is not a number is left out."""
    ET.register_namespace("", NS)
    root = ET.Element(f"{{{NS}}}gpx", {"version": "1.1", "creator": "drs-console"})
    metadata = ET.SubElement(root, f"{{{NS}}}metadata")
    ET.SubElement(metadata, f"{{{NS}}}desc").text = ascii_text(description)
    for w in waypoints:
        element = _position(root, "wpt", w.lat, w.lon, w.alt_m)
        if element is None:
            continue
        _time(element, w.time)
        ET.SubElement(element, f"{{{NS}}}name").text = w.name
        ET.SubElement(element, f"{{{NS}}}desc").text = ascii_text(w.description)
        ET.SubElement(element, f"{{{NS}}}sym").text = w.symbol
    for name, points in tracks:
        if not points:
            continue
        trk = ET.SubElement(root, f"{{{NS}}}trk")
        ET.SubElement(trk, f"{{{NS}}}name").text = ascii_text(name)
        for side in antimeridian_segments(points):
            segment = ET.SubElement(trk, f"{{{NS}}}trkseg")
            for p in side:
                element = _position(segment, "trkpt", p.lat, p.lon, p.alt_m)
                if element is not None:
                    _time(element, p.time)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True)
