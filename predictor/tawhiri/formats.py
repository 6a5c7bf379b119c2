"""Tawhiri's answer formats: the JSON ``prediction`` stages, its CSV table and the whole flight as KML.

Why here: the SondeHub predictor page and chasemapper read these shapes byte for byte (longitudes in
0…360 in JSON, −180…180 in CSV and KML, RFC 3339 times with a Z), whatever profile was flown.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from predictor.environment import WeatherCube
from predictor.prediction import Prediction
from predictor.tawhiri.ascent import Ascent

DEMO_WARNING = "DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations."
Stage = tuple[str, Ascent | Prediction]
"""A stage's Tawhiri name (``ascent``, ``descent``, ``float``) and its path."""


def iso(moment: datetime) -> str:
    """RFC 3339 UTC with a Z; milliseconds only when there are some (Tawhiri's own style)."""
    text = moment.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    return text.replace(".000Z", "Z")


def dataset_time(cube: WeatherCube) -> datetime:
    """The forecast cycle of the cube's first valid time (what Tawhiri reports as ``dataset``)."""
    first = cube.times[0].astype("datetime64[s]").astype(int) - round(float(cube.lead_h[0]) * 3600.0)
    return datetime.fromtimestamp(int(first), UTC)


def _points(
    t_s: Iterable[float], lat: Iterable[float], lon: Iterable[float], alt: Iterable[float]
) -> list[dict[str, Any]]:
    return [
        {"datetime": iso(datetime.fromtimestamp(round(float(t), 3), UTC)), "latitude": float(la),
         "longitude": float(lo) % 360.0, "altitude": float(z)}
        for t, la, lo, z in zip(t_s, lat, lon, alt, strict=True)
    ]  # fmt: skip


def stages(flown: Sequence[Stage]) -> list[dict[str, Any]]:
    """Tawhiri's ``prediction``: each stage's trajectory, each starting where the one before ended."""
    answer = []
    for name, path in flown:
        if isinstance(path, Prediction):
            track, start = path.track, path.release.time.timestamp()
            points = _points(track.t_s + start, track.lat, track.lon, track.alt_m)
        else:
            points = _points(path.t_s, path.lat, path.lon, path.alt_m)
        answer.append({"stage": name, "trajectory": points})
    return answer


def _lon180(lon: float) -> float:
    return lon - 360.0 if lon > 180.0 else lon


def file_name(answered: Mapping[str, Any], extension: str, is_demo: bool) -> str:
    """Tawhiri's download name: launch time, place (as requested), profile, dataset; DEMO said in it."""
    launch = datetime.fromisoformat(str(answered["launch_datetime"]))
    dataset = datetime.fromisoformat(str(answered["dataset"]))
    demo = "_DEMO-WEATHER" if is_demo else ""
    return (f"{launch:%Y%m%d-%H%M%S}Z_{answered['launch_latitude']:.4f}_{answered['launch_longitude']:.4f}_"
            f"{answered['profile']}_{dataset:%Y%m%d%H}Z{demo}.{extension}")  # fmt: skip


def to_csv(prediction: list[dict[str, Any]]) -> str:
    """Tawhiri's table: one header, then every point of every stage, longitudes in −180…180."""
    lines = ["datetime,latitude,longitude,altitude"]
    for stage in prediction:
        for p in stage["trajectory"]:
            lon = _lon180(p["longitude"])
            lines.append(f"{p['datetime']},{p['latitude']:.5f},{lon:.5f},{p['altitude']:.1f}")
    return "\n".join(lines) + "\n"


MARKS = {
    "standard_profile": ("Launch", "Burst", "Landing"),
    "float_profile": ("Launch", "Float", "Stop"),
    "reverse_profile": ("Position", None, "Launch estimate"),
}
"""The placemarks of a flight: its start, the end of its first stage, the end of its last."""


def to_kml(
    answered: Mapping[str, Any], description: str, prediction: list[dict[str, Any]], is_demo: bool
) -> str:
    """The whole flight as one line, with its start, turn and end marked (Tawhiri's layout)."""
    kml = ET.Element("kml", xmlns="http://www.opengis.net/kml/2.2")
    document = ET.SubElement(kml, "Document")
    demo = f" {DEMO_WARNING}" if is_demo else ""
    ET.SubElement(document, "name").text = f"Flight from {answered['launch_datetime']}{demo}"
    ET.SubElement(document, "description").text = f"{description}{demo}"
    points = [p for stage in prediction for p in stage["trajectory"]]

    def coordinates(p: Mapping[str, Any]) -> str:
        return f"{_lon180(p['longitude']):.6f},{p['latitude']:.6f},{p['altitude']:.1f}"

    path = ET.SubElement(document, "Placemark")
    ET.SubElement(path, "name").text = "Flight path"
    line = ET.SubElement(path, "LineString")
    ET.SubElement(line, "altitudeMode").text = "absolute"
    ET.SubElement(line, "coordinates").text = " ".join(coordinates(p) for p in points)
    start, turn, end = MARKS[str(answered["profile"])]
    marks = [(start, prediction[0]["trajectory"][0]), (turn, prediction[0]["trajectory"][-1]),
             (end, prediction[-1]["trajectory"][-1])]  # fmt: skip
    for name, p in marks:
        if name is None:
            continue
        mark = ET.SubElement(document, "Placemark")
        ET.SubElement(mark, "name").text = name
        where = f"{p['latitude']:.5f},{_lon180(p['longitude']):.5f}"
        ET.SubElement(mark, "description").text = f"{name} at {where}, {p['datetime']}."
        point = ET.SubElement(mark, "Point")
        ET.SubElement(point, "altitudeMode").text = "absolute"
        ET.SubElement(point, "coordinates").text = coordinates(p)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode")
