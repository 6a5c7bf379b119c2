"""A Tawhiri v1 API in front of our predictor, so chase software asks it as it asks SondeHub.

chasemapper and the SondeHub predictor request ``GET /api/v1/?profile=standard_profile&launch_latitude=…``
and read back Tawhiri's response: ``request`` (the question echoed, with the dataset's time),
``prediction`` (an ``ascent`` and a ``descent`` stage of ``{datetime, latitude, longitude,
altitude}`` points, longitudes in 0…360 as Tawhiri gives them) and ``metadata``. Errors come as
Tawhiri's ``{"error": {"type", "description"}, "metadata"}`` with its status codes, so the clients'
own error handling reads ours.

What differs, and says so: the ascent is Tawhiri's idea (constant ``ascent_rate`` drifting with the
wind, ``predictor.tawhiri.ascent``), the descent is ours (the project's drag law with the selected model, the
same call as ``drs predict``), so ``descent_rate`` is echoed but not flown. Our extension, under
``drs`` in the same response, carries the landing ellipse, the model and the warnings (DEMO weather
among them). ``format=csv`` and ``format=kml`` answer the same prediction as a table or as the
project's KML.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from predictor.calibration import CalibratedModel
from predictor.environment import Terrain, WeatherCube, demo_weather_files, load_weather, weather_bbox
from predictor.errors import OutOfCoverageError, PredictorError, WeatherError
from predictor.prediction import Prediction, predict, to_kml
from predictor.tawhiri.ascent import Ascent, ascend

log = logging.getLogger(__name__)

API_PATH = "/api/v1/"
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
    rate = _number("ascent_rate", _required(query, "ascent_rate"), lambda x: x > 0, "must be above 0 m/s")
    burst = _number(
        "burst_altitude", _required(query, "burst_altitude"), lambda x: (alt is None or x > alt) and x < 60_000,
        "must be above launch_altitude and below 60000 m",
    )  # fmt: skip
    descent = _number(
        "descent_rate", _required(query, "descent_rate"), lambda x: x > 0, "must be above 0 m/s"
    )
    dataset_text = _single(query, "dataset")
    dataset = None if dataset_text is None else _rfc3339("dataset", dataset_text)
    return ApiRequest(lat, lon, when, alt, rate, burst, descent, dataset, output)


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

    def _cube_for(self, request: ApiRequest, ascent_s: float) -> WeatherCube:
        lat0, lon0 = round(request.launch_latitude), round(request.launch_longitude)
        hours = max(WEATHER_HOURS, math.ceil(ascent_s / 3600.0) + WEATHER_HOURS_AFTER_BURST)
        files = self.weather.files_for(lat0, lon0, request.launch_datetime, hours)
        box = weather_bbox(lat0, lon0, max(REGION_MINUTES, ascent_s / 60.0 + 60.0))
        key = (tuple((str(f), f.stat().st_mtime_ns) for f in files), box)
        if key != self._cube_key:
            self._cube = load_weather(files, bbox=box, cache_dir=self.cache_dir)
            self._cube_key = key
        assert self._cube is not None
        return self._cube

    def predict(self, request: ApiRequest) -> tuple[Ascent, Prediction, dict[str, Any]]:
        """The ascent, our descent from its burst, and the request as answered (Tawhiri's ``request``)."""
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
            cube = self._cube_for(request, ascent_s)
            if request.dataset is not None and request.dataset != dataset_time(cube):
                raise ApiError(
                    "InvalidDatasetException", 404,
                    f"No matching dataset found: this server has {iso(dataset_time(cube))}, "
                    f"not {iso(request.dataset)}.",
                )  # fmt: skip
            ascent = ascend(cube, request.launch_datetime, request.launch_latitude, request.launch_longitude,
                            launch_alt, request.ascent_rate, request.burst_altitude)  # fmt: skip
            burst = ascent.burst
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
        return ascent, descent, answered

    def extension(self, descent: Prediction) -> dict[str, Any]:
        """Ours, beside Tawhiri's fields: what a chase team needs to judge the landing point."""
        model: dict[str, Any] = {"label": self.flown.label(), "payload": self.flown.payload.to_dict()}
        if self.model_path is not None:
            model = {**self.flown.document(self.model_path), "payload": self.flown.payload.to_dict()}
        document = descent.to_dict()
        return {
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


def iso(moment: datetime) -> str:
    """RFC 3339 UTC with a Z; milliseconds only when there are some (Tawhiri's own style)."""
    text = moment.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    return text.replace(".000Z", "Z")


def dataset_time(cube: WeatherCube) -> datetime:
    """The forecast cycle of the cube's first valid time (what Tawhiri reports as ``dataset``)."""
    first = cube.times[0].astype("datetime64[s]").astype(int) - round(float(cube.lead_h[0]) * 3600.0)
    return datetime.fromtimestamp(int(first), UTC)


def _points(
    t_s: Sequence[float], lat: Sequence[float], lon: Sequence[float], alt: Sequence[float]
) -> list[dict[str, Any]]:
    return [
        {"datetime": iso(datetime.fromtimestamp(round(float(t), 3), UTC)), "latitude": float(la),
         "longitude": float(lo) % 360.0, "altitude": float(z)}
        for t, la, lo, z in zip(t_s, lat, lon, alt, strict=True)
    ]  # fmt: skip


def stages(ascent: Ascent, descent: Prediction) -> list[dict[str, Any]]:
    """Tawhiri's ``prediction``: the ascent, then the descent starting where the ascent ended."""
    track = descent.track
    start = descent.release.time.timestamp()
    return [
        {"stage": "ascent", "trajectory": _points(ascent.t_s, ascent.lat, ascent.lon, ascent.alt_m)},
        {"stage": "descent", "trajectory": _points(track.t_s + start, track.lat, track.lon, track.alt_m)},
    ]


def to_csv(prediction: list[dict[str, Any]], is_demo: bool) -> str:
    out = io.StringIO()
    if is_demo:
        out.write("# DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations.\n")
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["stage", "datetime", "latitude", "longitude", "altitude"])
    for stage in prediction:
        for p in stage["trajectory"]:
            writer.writerow([stage["stage"], p["datetime"], p["latitude"], p["longitude"], p["altitude"]])
    return out.getvalue()


def answer(service: PredictorService, query: Mapping[str, Sequence[str]]) -> tuple[int, str, str]:
    """(status, content type, body) for one request; every failure in Tawhiri's error shape."""
    started = datetime.now(UTC)
    try:
        request = parse_request(query)
        ascent, descent, answered = service.predict(request)
    except ApiError as exc:
        return _error(exc, started)
    except OutOfCoverageError as exc:
        return _error(ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started)
    except WeatherError as exc:
        return _error(ApiError("InvalidDatasetException", 404, f"No matching dataset found: {exc}"), started)
    except PredictorError as exc:
        return _error(ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started)
    prediction = stages(ascent, descent)
    if request.format == "csv":
        return 200, "text/csv; charset=utf-8", to_csv(prediction, descent.is_demo)
    if request.format == "kml":
        return 200, "application/vnd.google-earth.kml+xml", to_kml(descent)
    warnings = {}
    if descent.is_demo:
        warnings["drs_demo_weather"] = {
            "count": 1, "description": "DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations.",
        }  # fmt: skip
    document = {
        "request": answered,
        "prediction": prediction,
        "metadata": _metadata(started),
        "warnings": warnings,
        "drs": service.extension(descent),
    }
    return 200, "application/json", json.dumps(document)


def _metadata(started: datetime) -> dict[str, str]:
    return {"start_datetime": iso(started), "complete_datetime": iso(datetime.now(UTC))}


def _error(exc: ApiError, started: datetime) -> tuple[int, str, str]:
    body = {"error": {"type": exc.kind, "description": exc.description}, "metadata": _metadata(started)}
    return exc.status, "application/json", json.dumps(body)


class _Handler(BaseHTTPRequestHandler):
    server: ApiServer

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        began = time.monotonic()
        parts = urlsplit(self.path)
        if parts.path.rstrip("/") != API_PATH.rstrip("/"):
            error = ApiError(
                "RequestException", 404, f"No endpoint {parts.path}: the API answers GET {API_PATH}."
            )
            status, kind, body = _error(error, datetime.now(UTC))
        else:
            status, kind, body = answer(self.server.service, parse_qs(parts.query, keep_blank_values=True))
        data = body.encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Access-Control-Allow-Origin", "*")  # the SondeHub predictor is a web page
        self.end_headers()
        self.wfile.write(data)
        log.info(
            "%s %s → %d in %.0f ms",
            self.address_string(),
            self.path,
            status,
            1000 * (time.monotonic() - began),
        )

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (http.server's signature)
        log.debug(format, *args)


class ApiServer(ThreadingHTTPServer):
    """The HTTP server; ``port`` 0 takes a free one (``server_address`` then says which)."""

    daemon_threads = True

    def __init__(self, service: PredictorService, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__((host, port), _Handler)
        self.service = service

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}{API_PATH}"
