"""A Tawhiri v1 API in front of our predictor, so chase software asks it as it asks SondeHub.

chasemapper and the SondeHub predictor request ``GET /api/v1/?profile=standard_profile&launch_latitude=…``
and read back Tawhiri's response: ``request`` (the question echoed, with the dataset's time),
``prediction`` (an ``ascent`` and a ``descent`` stage of ``{datetime, latitude, longitude,
altitude}`` points, longitudes in 0…360 as Tawhiri gives them) and ``metadata``. Errors come as
Tawhiri's ``{"error": {"type", "description"}, "metadata"}`` with its status codes, so the clients'
own error handling reads ours.

Two descents, said in the response's Tawhiri-level ``warnings`` (``drs_descent``):

- ``GET /api/v1/`` flies Tawhiri's semantics, as SondeHub does for every payload chasemapper tracks:
  ``descent_rate`` is the sea-level rate of a drag descent (``predictor.tawhiri.descent``);
- ``GET /api/v1/drs/`` (or ``/api/v1/drs/<CAPSULE>/``, the name only labels the answer) flies the DRS
  capsule: the project's drag law with the selected model, the same call as ``drs predict``;
  ``descent_rate`` is echoed but not flown, and our extension under ``drs`` carries the landing
  ellipse and the model.

The ascent is Tawhiri's idea in both (``predictor.tawhiri.ascent``). Rates below 0.2 m/s are raised to
0.2 as Tawhiri does (with a warning); rates no balloon or parachute has, and flights whose ascent or
descent would last more than a day, are refused before any weather is read or made, so one request
cannot fill the disk or hold the predictor. ``format=csv`` is Tawhiri's table and file name,
``format=kml`` the whole flight. Connections are bounded (``MAX_CONNECTIONS``) and a request must
arrive within ``REQUEST_READ_S``.
"""

from __future__ import annotations

import json
import logging
import math
import socket
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from predictor.calibration import CalibratedModel
from predictor.environment import Terrain, WeatherCube, demo_weather_files, load_weather, weather_bbox
from predictor.errors import OutOfCoverageError, PredictorError, WeatherError
from predictor.prediction import Prediction, predict
from predictor.tawhiri.ascent import Ascent, ascend
from predictor.tawhiri.descent import descend, nasa_density

log = logging.getLogger(__name__)

API_PATH = "/api/v1/"
CAPSULE_PATH = "/api/v1/drs/"
API_VERSION = 1
STANDARD_PROFILE = "standard_profile"
FLOAT_PROFILE = "float_profile"
FORMATS = ("json", "csv", "kml")
WEATHER_HOURS = 12
"""Demo weather generated for at least this long from the launch: long enough that a whole flight and a
descent from where the payload is now use the same files (and the same cube)."""
REGION_MINUTES = 240.0
"""The weather region is sized for this long a drift (or the ascent's, if longer) around the launch: the
same region for a whole flight and for a descent from where the payload is, so both reuse one cube."""
WEATHER_HOURS_AFTER_BURST = 6
"""Demo weather generated past the burst: a descent from 40 km under a small canopy lasts ~1.5 h."""
MIN_RATE_MS = 0.2
"""Tawhiri raises slower ascent and descent rates to this (its ``rate_clip``); chasemapper sends 0.1."""
MAX_ASCENT_RATE_MS = 50.0
MAX_DESCENT_RATE_MS = 150.0
"""Faster than any balloon rises or any payload falls at sea level: a typo or an attack."""
MAX_STAGE_S = 24 * 3600.0
"""An ascent or a descent longer than a day is refused: it would need days of weather (the demo
writes files for all of it) and hold the one predictor for minutes."""
MAX_CONNECTIONS = 32
"""Connections served at once; more are answered 503 at once, so stalled clients cannot take every thread."""
REQUEST_READ_S = 10.0
"""A client must send its whole request (line and headers) within this; then the socket is closed."""
TAWHIRI_DESCENT = "tawhiri"
CAPSULE_DESCENT = "capsule"


class ApiError(Exception):
    """One of Tawhiri's error types, with its HTTP status."""

    def __init__(self, kind: str, status: int, description: str) -> None:
        super().__init__(description)
        self.kind = kind
        self.status = status
        self.description = description


def request_error(description: str) -> ApiError:
    return ApiError("RequestException", 400, description)


@dataclass(frozen=True)
class ApiRequest:
    """A standard-profile question, checked; ``launch_longitude`` in degrees east as given."""

    launch_latitude: float
    launch_longitude: float
    launch_datetime: datetime
    launch_altitude: float | None
    ascent_rate: float
    burst_altitude: float
    descent_rate: float
    dataset: datetime | None
    format: str
    descent: str = TAWHIRI_DESCENT
    """``TAWHIRI_DESCENT`` or ``CAPSULE_DESCENT``, from the path."""
    capsule: str | None = None
    clipped: tuple[str, ...] = ()
    """The rate parameters raised to ``MIN_RATE_MS``."""


def _single(query: Mapping[str, Sequence[str]], name: str) -> str | None:
    values = query.get(name)
    if not values:
        return None
    if len(values) > 1:
        raise request_error(f"Parameter '{name}' given {len(values)} times; give it once.")
    return values[0]


def _required(query: Mapping[str, Sequence[str]], name: str) -> str:
    value = _single(query, name)
    if value is None:
        raise request_error(f"Parameter '{name}' not provided in request.")
    return value


def _number(name: str, text: str, check: Callable[[float], bool], rule: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise request_error(f"Unable to parse parameter '{name}': {text} (not a number).") from None
    if not math.isfinite(value) or not check(value):
        raise request_error(f"Invalid value for parameter '{name}': {text} ({rule}).")
    return value


def _rfc3339(name: str, text: str) -> datetime:
    try:
        moment = datetime.fromisoformat(text.strip().replace(" ", "+"))
    except ValueError:
        raise request_error(
            f"Unable to parse parameter '{name}': {text} (an RFC 3339 time such as 2024-05-01T06:30:00Z)."
        ) from None
    if moment.tzinfo is None:
        raise request_error(f"Invalid value for parameter '{name}': {text} (no time zone; end it with Z).")
    return moment.astimezone(UTC)


def parse_request(query: Mapping[str, Sequence[str]]) -> ApiRequest:
    """The query string's parameters, checked one by one: the first bad one is named, as Tawhiri does."""
    profile = _single(query, "profile") or STANDARD_PROFILE
    if profile == FLOAT_PROFILE:
        raise ApiError(
            "NotYetImplementedException", 501,
            "The float_profile is not served here: drs predicts a capsule's descent (use standard_profile).",
        )  # fmt: skip
    if profile != STANDARD_PROFILE:
        raise request_error(f"Unknown profile '{profile}'.")
    output = _single(query, "format") or "json"
    if output not in FORMATS:
        raise request_error(f"Invalid value for parameter 'format': {output} (one of {', '.join(FORMATS)}).")
    lat = _number(
        "launch_latitude", _required(query, "launch_latitude"), lambda x: -90 <= x <= 90, "-90 to 90"
    )
    lon = _number(
        "launch_longitude", _required(query, "launch_longitude"), lambda x: -180 <= x < 360, "0 to 360, or -180 to 180"
    )  # fmt: skip
    when = _rfc3339("launch_datetime", _required(query, "launch_datetime"))
    alt_text = _single(query, "launch_altitude")
    alt = (
        None if alt_text is None else _number("launch_altitude", alt_text, lambda x: -500 <= x < 60_000, "m")
    )
    rate = _number(
        "ascent_rate", _required(query, "ascent_rate"), lambda x: 0 < x <= MAX_ASCENT_RATE_MS,
        f"must be above 0 and at most {MAX_ASCENT_RATE_MS:g} m/s",
    )  # fmt: skip
    burst = _number(
        "burst_altitude", _required(query, "burst_altitude"), lambda x: (alt is None or x > alt) and x < 60_000,
        "must be above launch_altitude and below 60000 m",
    )  # fmt: skip
    descent = _number(
        "descent_rate", _required(query, "descent_rate"), lambda x: 0 < x <= MAX_DESCENT_RATE_MS,
        f"must be above 0 and at most {MAX_DESCENT_RATE_MS:g} m/s",
    )  # fmt: skip
    dataset_text = _single(query, "dataset")
    dataset = None if dataset_text is None else _rfc3339("dataset", dataset_text)
    rates = (("ascent_rate", rate), ("descent_rate", descent))
    clipped = tuple(name for name, value in rates if value < MIN_RATE_MS)
    return ApiRequest(lat, lon, when, alt, max(rate, MIN_RATE_MS), burst, max(descent, MIN_RATE_MS), dataset,
                      output, clipped=clipped)  # fmt: skip


def tawhiri_descent_s(burst_alt_m: float, sea_level_rate_ms: float, ground_m: float) -> float:
    """How long Tawhiri's drag descent takes from the burst to ``ground_m`` (100 m slices), to size the
    weather before flying it."""
    slices = max(1, math.ceil((burst_alt_m - ground_m) / 100.0))
    dz = (burst_alt_m - ground_m) / slices
    rho0 = nasa_density(0.0)
    return sum(
        dz / (sea_level_rate_ms * math.sqrt(rho0 / nasa_density(ground_m + (k + 0.5) * dz)))
        for k in range(slices)
    )


@dataclass(frozen=True)
class Flight:
    """One answered request: Tawhiri's two stages, and what the response says about them."""

    request: ApiRequest
    ascent: Ascent
    descent: Ascent | Prediction
    """Tawhiri's drag descent, or the capsule's prediction (with its ellipse)."""
    answered: dict[str, Any]
    is_demo: bool
    weather_source: str


@dataclass(frozen=True)
class WeatherSource:
    """Where the server's weather comes from: fixed files, a directory re-read per request, or DEMO."""

    files: tuple[Path, ...] = ()
    directory: Path | None = None
    demo: bool = False

    def files_for(self, lat: float, lon: float, when: datetime, hours: int) -> list[Path]:
        if self.demo:
            return demo_weather_files(lat, lon, when, hours=hours)
        if self.directory is not None:
            found = sorted(
                p for p in self.directory.iterdir()
                if p.is_file() and not p.name.startswith(".") and not p.name.endswith(".partial")
            )  # fmt: skip
            if not found:
                raise WeatherError(
                    f"no weather files in {self.directory} (fetch some with drs weather fetch --dir)"
                )
            return found
        return list(self.files)


class PredictorService:
    """Answers API requests with the selected weather, terrain and model; one prediction at a time.

    The cube of the last request is kept: chasemapper asks again every few seconds from nearly the
    same place, and the weather region is centred on the launch point rounded to a whole degree,
    so those requests reuse it (and the weather cache gets one entry per degree, not per request).
    """

    def __init__(
        self,
        weather: WeatherSource,
        terrain: Terrain,
        flown: CalibratedModel,
        model_path: Path | None = None,
        cache_dir: str | None = None,
    ) -> None:
        self.weather = weather
        self.terrain = terrain
        self.flown = flown
        self.model_path = model_path
        self.error_model = flown.chosen_ellipse(None)
        self.cache_dir = cache_dir
        self._lock = threading.Lock()
        self._cube_key: tuple[Any, ...] | None = None
        self._cube: WeatherCube | None = None

    def _cube_for(
        self, request: ApiRequest, ascent_s: float, after_burst_s: float, descent_minutes: float
    ) -> WeatherCube:
        """The weather for ``after_burst_s`` past the burst, over the region a flight of the ascent and
        ``descent_minutes`` can drift across."""
        lat0, lon0 = round(request.launch_latitude), round(request.launch_longitude)
        hours = max(WEATHER_HOURS, math.ceil((ascent_s + after_burst_s) / 3600.0))
        files = self.weather.files_for(lat0, lon0, request.launch_datetime, hours)
        box = weather_bbox(lat0, lon0, max(REGION_MINUTES, ascent_s / 60.0 + descent_minutes))
        key = (tuple((str(f), f.stat().st_mtime_ns) for f in files), box)
        if key != self._cube_key:
            self._cube = load_weather(files, bbox=box, cache_dir=self.cache_dir)
            self._cube_key = key
        assert self._cube is not None
        return self._cube

    def predict(self, request: ApiRequest) -> Flight:
        """The ascent, the descent from its burst, and the request as answered (Tawhiri's ``request``)."""
        with self._lock:
            launch_alt = request.launch_altitude
            if launch_alt is None:
                launch_alt = float(self.terrain.elevation(request.launch_latitude, request.launch_longitude))
                if request.burst_altitude <= launch_alt:
                    raise request_error(
                        f"Invalid value for parameter 'burst_altitude': {request.burst_altitude:g} "
                        f"(must be above the ground at launch, {launch_alt:.0f} m)."
                    )
            ascent_s = (request.burst_altitude - launch_alt) / request.ascent_rate
            if ascent_s > MAX_STAGE_S:
                raise request_error(
                    f"Invalid value for parameter 'ascent_rate': {request.ascent_rate:g} (the ascent to "
                    f"{request.burst_altitude:g} m would last {ascent_s / 3600:.0f} h; at most "
                    f"{MAX_STAGE_S / 3600:.0f} h is flown)."
                )
            after_burst_s = WEATHER_HOURS_AFTER_BURST * 3600.0
            descent_minutes = 60.0  # the capsule's: ~40 min from 30 km, and the drift law is generous
            if request.descent == TAWHIRI_DESCENT:
                ground = min(launch_alt, 0.0)
                descent_s = tawhiri_descent_s(request.burst_altitude, request.descent_rate, ground)
                if descent_s > MAX_STAGE_S:
                    raise request_error(
                        f"Invalid value for parameter 'descent_rate': {request.descent_rate:g} (the descent "
                        f"would last {descent_s / 3600:.0f} h; at most {MAX_STAGE_S / 3600:.0f} h is flown)."
                    )
                after_burst_s = max(after_burst_s, descent_s + 3600.0)
                descent_minutes = descent_s / 60.0 + 30.0
            cube = self._cube_for(request, ascent_s, after_burst_s, descent_minutes)
            if request.dataset is not None and request.dataset != dataset_time(cube):
                raise ApiError(
                    "InvalidDatasetException", 404,
                    f"No matching dataset found: this server has {iso(dataset_time(cube))}, "
                    f"not {iso(request.dataset)}.",
                )  # fmt: skip
            ascent = ascend(cube, request.launch_datetime, request.launch_latitude, request.launch_longitude,
                            launch_alt, request.ascent_rate, request.burst_altitude)  # fmt: skip
            burst = ascent.burst
            descent: Ascent | Prediction
            if request.descent == TAWHIRI_DESCENT:
                descent = descend(cube, self.terrain, burst.time, burst.lat, burst.lon, burst.alt_m,
                                  request.descent_rate)  # fmt: skip
            else:
                descent = predict(
                    cube, burst.time, burst.lat, burst.lon, burst.alt_m, payload=self.flown.payload,
                    terrain=self.terrain, effects=self.flown.terms, error_model=self.error_model,
                )  # fmt: skip
        answered = {
            "profile": STANDARD_PROFILE,
            "launch_latitude": request.launch_latitude,
            "launch_longitude": request.launch_longitude % 360.0,
            "launch_datetime": iso(request.launch_datetime),
            "launch_altitude": launch_alt,
            "ascent_rate": request.ascent_rate,
            "burst_altitude": request.burst_altitude,
            "descent_rate": request.descent_rate,
            "dataset": iso(dataset_time(cube)),
            "format": request.format,
            "version": API_VERSION,
        }
        return Flight(request, ascent, descent, answered, cube.is_demo, cube.source)

    def extension(self, flight: Flight) -> dict[str, Any]:
        """Ours, beside Tawhiri's fields: what a chase team needs to judge the landing point."""
        descent = flight.descent
        if not isinstance(descent, Prediction):
            return {"descent": TAWHIRI_DESCENT, "descent_rate_used": True, "weather": flight.weather_source,
                    "is_demo": flight.is_demo}  # fmt: skip
        model: dict[str, Any] = {"label": self.flown.label(), "payload": self.flown.payload.to_dict()}
        if self.model_path is not None:
            model = {**self.flown.document(self.model_path), "payload": self.flown.payload.to_dict()}
        document = descent.to_dict()
        return {
            "descent": CAPSULE_DESCENT,
            "capsule": flight.request.capsule,
            "landing": document["landing"],
            "burst": document["release"],
            "descent_s": document["descent_s"],
            "ellipse": document["ellipse"],
            "model": model,
            "descent_rate_used": False,
            "weather": document["weather"],
            "terrain_source": descent.terrain_source,
            "is_demo": descent.is_demo,
            "warnings": document["warnings"],
        }

    def warnings(self, flight: Flight) -> dict[str, dict[str, Any]]:
        """Tawhiri's ``warnings`` (``{name: {count, description}}``): which descent, and what was changed."""
        request = flight.request
        if request.descent == TAWHIRI_DESCENT:
            said = (
                f"Descent flown as Tawhiri's: descent_rate {request.descent_rate:g} m/s at sea level, "
                f"faster in thinner air. For a DRS capsule's own model ask {CAPSULE_PATH}<CAPSULE>/."
            )
        else:
            said = (
                f"Descent flown with the DRS capsule model ({self.flown.label()}) for "
                f"{request.capsule or 'a DRS capsule'}: descent_rate is not used."
            )
        warnings = {"drs_descent": {"count": 1, "description": said}}
        for name in request.clipped:
            warnings[f"drs_{name}_raised"] = {
                "count": 1, "description": f"{name} below {MIN_RATE_MS:g} m/s was flown at {MIN_RATE_MS:g}.",
            }  # fmt: skip
        if flight.is_demo:
            warnings["drs_demo_weather"] = {"count": 1, "description": DEMO_WARNING}
        return warnings


DEMO_WARNING = "DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations."


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


def stages(ascent: Ascent, descent: Ascent | Prediction) -> list[dict[str, Any]]:
    """Tawhiri's ``prediction``: the ascent, then the descent starting where the ascent ended."""
    if isinstance(descent, Prediction):
        track = descent.track
        start = descent.release.time.timestamp()
        path = _points(track.t_s + start, track.lat, track.lon, track.alt_m)
    else:
        path = _points(descent.t_s, descent.lat, descent.lon, descent.alt_m)
    return [
        {"stage": "ascent", "trajectory": _points(ascent.t_s, ascent.lat, ascent.lon, ascent.alt_m)},
        {"stage": "descent", "trajectory": path},
    ]


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
    """Tawhiri's table: one header, then every point of both stages, longitudes in −180…180."""
    lines = ["datetime,latitude,longitude,altitude"]
    for stage in prediction:
        for p in stage["trajectory"]:
            lon = _lon180(p["longitude"])
            lines.append(f"{p['datetime']},{p['latitude']:.5f},{lon:.5f},{p['altitude']:.1f}")
    return "\n".join(lines) + "\n"


def to_kml(flight: Flight, prediction: list[dict[str, Any]]) -> str:
    """The whole flight as one line, with the launch, the burst and the landing marked (Tawhiri's layout)."""
    kml = ET.Element("kml", xmlns="http://www.opengis.net/kml/2.2")
    document = ET.SubElement(kml, "Document")
    answered = flight.answered
    demo = f" {DEMO_WARNING}" if flight.is_demo else ""
    ET.SubElement(document, "name").text = f"Flight from {answered['launch_datetime']}{demo}"
    ET.SubElement(document, "description").text = (
        f"Ascent at {answered['ascent_rate']:g} m/s to {answered['burst_altitude']:g} m; "
        f"{'DRS capsule descent' if isinstance(flight.descent, Prediction) else 'Tawhiri descent'}.{demo}"
    )
    points = [p for stage in prediction for p in stage["trajectory"]]

    def coordinates(p: Mapping[str, Any]) -> str:
        return f"{_lon180(p['longitude']):.6f},{p['latitude']:.6f},{p['altitude']:.1f}"

    path = ET.SubElement(document, "Placemark")
    ET.SubElement(path, "name").text = "Flight path"
    line = ET.SubElement(path, "LineString")
    ET.SubElement(line, "altitudeMode").text = "absolute"
    ET.SubElement(line, "coordinates").text = " ".join(coordinates(p) for p in points)
    marks = (("Launch", prediction[0]["trajectory"][0]), ("Burst", prediction[0]["trajectory"][-1]),
             ("Landing", prediction[-1]["trajectory"][-1]))  # fmt: skip
    for name, p in marks:
        mark = ET.SubElement(document, "Placemark")
        ET.SubElement(mark, "name").text = name
        where = f"{p['latitude']:.5f},{_lon180(p['longitude']):.5f}"
        ET.SubElement(mark, "description").text = f"{name} at {where}, {p['datetime']}."
        point = ET.SubElement(mark, "Point")
        ET.SubElement(point, "altitudeMode").text = "absolute"
        ET.SubElement(point, "coordinates").text = coordinates(p)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode")


Answer = tuple[int, str, str, dict[str, str]]
"""(status, content type, body, extra headers)."""


def answer(
    service: PredictorService,
    query: Mapping[str, Sequence[str]],
    descent: str = TAWHIRI_DESCENT,
    capsule: str | None = None,
) -> Answer:
    """One request answered; every failure in Tawhiri's error shape."""
    started = datetime.now(UTC)
    try:
        request = replace(parse_request(query), descent=descent, capsule=capsule)
        flight = service.predict(request)
    except ApiError as exc:
        return _error(exc, started)
    except OutOfCoverageError as exc:
        return _error(ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started)
    except WeatherError as exc:
        return _error(ApiError("InvalidDatasetException", 404, f"No matching dataset found: {exc}"), started)
    except PredictorError as exc:
        return _error(ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started)
    except Exception:  # the client still gets Tawhiri's shape; the operator gets the traceback
        log.exception("prediction failed for %s", dict(query))
        return _error(ApiError("InternalException", 500, "Internal exception experienced."), started)
    prediction = stages(flight.ascent, flight.descent)
    warnings = service.warnings(flight)
    headers = {}
    if flight.is_demo:
        headers["Warning"] = f'299 drs "{DEMO_WARNING}"'
    if request.format in ("csv", "kml"):
        name = file_name(flight.answered, request.format, flight.is_demo)
        headers["Content-Disposition"] = f'attachment; filename="{name}"'
        if request.format == "csv":
            return 200, "text/csv; charset=utf-8", to_csv(prediction), headers
        return 200, "application/vnd.google-earth.kml+xml", to_kml(flight, prediction), headers
    document = {
        "request": flight.answered,
        "prediction": prediction,
        "metadata": _metadata(started),
        "warnings": warnings,
        "drs": service.extension(flight),
    }
    return 200, "application/json", json.dumps(document), headers


def _metadata(started: datetime) -> dict[str, str]:
    return {"start_datetime": iso(started), "complete_datetime": iso(datetime.now(UTC))}


def _error(exc: ApiError, started: datetime) -> Answer:
    body = {"error": {"type": exc.kind, "description": exc.description}, "metadata": _metadata(started)}
    return exc.status, "application/json", json.dumps(body), {}


def route(path: str) -> tuple[str, str | None] | None:
    """(descent, capsule) for a served path: ``/api/v1/`` Tawhiri's, ``/api/v1/drs/[NAME/]`` the capsule's."""
    parts = [part for part in path.split("/") if part]
    if parts == ["api", "v1"]:
        return TAWHIRI_DESCENT, None
    if parts[:3] == ["api", "v1", "drs"] and len(parts) <= 4:
        return CAPSULE_DESCENT, parts[3] if len(parts) == 4 else None
    return None


class _Handler(BaseHTTPRequestHandler):
    server: ApiServer
    timeout = REQUEST_READ_S
    """Per read; the whole request is bounded by ``_deadline``."""

    def setup(self) -> None:
        super().setup()
        self._deadline = threading.Timer(REQUEST_READ_S, self._hang_up)
        self._deadline.daemon = True
        self._deadline.start()

    def _hang_up(self) -> None:
        """A client that has not sent its whole request in time is disconnected: a drip-feed holds nothing."""
        try:
            self.connection.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def parse_request(self) -> bool:
        ok = super().parse_request()
        self._deadline.cancel()  # the request is in: the prediction may take its time
        return ok

    def finish(self) -> None:
        self._deadline.cancel()
        super().finish()

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        began = time.monotonic()
        parts = urlsplit(self.path)
        served = route(parts.path)
        if served is None:
            error = ApiError(
                "RequestException", 404,
                f"No endpoint {parts.path}: the API answers GET {API_PATH} and GET {CAPSULE_PATH}<CAPSULE>/.",
            )  # fmt: skip
            reply = _error(error, datetime.now(UTC))
        else:
            query = parse_qs(parts.query, keep_blank_values=True)
            reply = answer(self.server.service, query, *served)
        self._reply(reply)
        log.info("%s %s → %d in %.0f ms", self.address_string(), self.path, reply[0],
                 1000 * (time.monotonic() - began))  # fmt: skip

    def _not_allowed(self) -> None:
        said = f"The method {self.command} is not allowed: the API answers GET."
        error = ApiError("MethodNotAllowed", 405, said)
        status, kind, body, headers = _error(error, datetime.now(UTC))
        self._reply((status, kind, body, {**headers, "Allow": "GET"}))

    do_POST = do_PUT = do_DELETE = do_PATCH = do_OPTIONS = _not_allowed  # noqa: N815 (http.server's names)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (an unknown method, a malformed request line, a header too long)
        in Tawhiri's error shape too, never its HTML page."""
        said = message or self.responses.get(code, ("Error",))[0]
        kind = "NotYetImplementedException" if code == 501 else "RequestException"
        _, content, body, _ = _error(ApiError(kind, code, f"{said}."), datetime.now(UTC))
        data = body.encode("utf-8")
        self.send_response(code, said)
        self.send_header("Content-Type", content)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Connection", "close")
        self.end_headers()
        if getattr(self, "command", None) != "HEAD":
            self.wfile.write(data)

    def _reply(self, reply: Answer) -> None:
        status, kind, body, headers = reply
        data = body.encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Access-Control-Allow-Origin", "*")  # the SondeHub predictor is a web page
        for name, value in headers.items():
            self.send_header(name, value)
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (http.server's signature)
        log.debug(format, *args)


DRAIN_S = 20.0
"""How long a stopping server waits for the predictions in flight (one takes seconds at most)."""

BUSY = (
    b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: application/json\r\nRetry-After: 5\r\n"
    b"Connection: close\r\n\r\n"
    b'{"error": {"type": "ServiceUnavailable", "description": "Too many connections; try again in 5 s."}}'
)


class ApiServer(ThreadingHTTPServer):
    """The HTTP server; ``port`` 0 takes a free one (``server_address`` then says which).

    At most ``MAX_CONNECTIONS`` connections are served at once; one more is answered 503 and closed
    at once, so stalled clients cannot hold a thread each for ever."""

    daemon_threads = True
    request_queue_size = 128
    """Connections waiting to be accepted: a burst is answered (or told 503) instead of left retrying SYNs."""

    def __init__(self, service: PredictorService, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__((host, port), _Handler)
        self.service = service
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            try:
                request.sendall(BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def drain(self, timeout_s: float = DRAIN_S) -> int:
        """Stop accepting and wait up to ``timeout_s`` for the requests in flight to be answered (SIGTERM
        once cut them off); how many were still running. Call it from another thread than the server's."""
        self.shutdown()
        deadline = time.monotonic() + timeout_s
        finished = 0
        while finished < MAX_CONNECTIONS and self._slots.acquire(
            timeout=max(0.0, deadline - time.monotonic())
        ):
            finished += 1
        self.server_close()
        return MAX_CONNECTIONS - finished

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        assert isinstance(host, str), "an IP socket's own address names its host as text, never bytes"
        return f"http://{host}:{port}{API_PATH}"
