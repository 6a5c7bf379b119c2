"""A Tawhiri v1 API in front of our predictor, so chase software asks it as it asks SondeHub.

chasemapper and the SondeHub predictor request ``GET /api/v1/?profile=standard_profile&launch_latitude=…``
and read back Tawhiri's response: ``request`` (the question echoed, with the dataset's time),
``prediction`` (stages of ``{datetime, latitude, longitude, altitude}`` points, longitudes in 0…360 as
Tawhiri gives them) and ``metadata``. Errors come as Tawhiri's ``{"error": {"type", "description"},
"metadata"}`` with its status codes, so the clients' own error handling reads ours.

Which descent a standard flight gets, said in the response's ``warnings`` (``drs_descent``):

- at ``GET /api/v1/``, a flight that starts at one of a DRS capsule's latest position reports is that
  capsule (``predictor.tawhiri.capsules``) and falls with its calibrated model; every other payload
  falls with Tawhiri's law (``predictor.tawhiri.descent``), as SondeHub flies it;
- ``GET /api/v1/drs/`` (or ``/api/v1/drs/<CAPSULE>/``) flies the capsule model whatever the flight.

The weather is loaded, and the compiled code warmed by one flight, before the server listens
(``PredictorService.warm``), so the first question after the ready line is answered in milliseconds.
A weather file that cannot be read is refused by name and the others are served.
"""

from __future__ import annotations

import importlib.metadata
import json
import logging
import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from predictor.descent import Release
from predictor.environment import Terrain, WeatherCube, demo_weather_files, load_weather, weather_bbox
from predictor.errors import OutOfCoverageError, PredictorError, WeatherError
from predictor.prediction import CalibratedModel, FlightSetup, Prediction, predict
from predictor.tawhiri.ascent import Ascent, as_stage, ascend, drift
from predictor.tawhiri.capsules import (
    MATCH_ALTITUDE_M,
    MATCH_DISTANCE_M,
    MATCH_TIME_S,
    CapsuleFix,
    FixSource,
    matching_fix,
)
from predictor.tawhiri.descent import descend, nasa_density
from predictor.tawhiri.formats import (
    DEMO_WARNING,
    Stage,
    dataset_time,
    file_name,
    iso,
    stages,
    to_csv,
    to_kml,
)
from predictor.tawhiri.request import (
    CAPSULE_DESCENT,
    FLOAT_PROFILE,
    MAX_FLIGHT_S,
    MIN_RATE_MS,
    REVERSE_PROFILE,
    STANDARD_PROFILE,
    TAWHIRI_DESCENT,
    ApiError,
    ApiRequest,
    parse_request,
    request_error,
)
from predictor.tawhiri.reverse import trace_back

log = logging.getLogger(__name__)

API_PATH = "/api/v1/"
CAPSULE_PATH = "/api/v1/drs/"
HEALTH_PATH = "/health"
API_VERSION = 1
WEATHER_HOURS = 12
"""Demo weather generated for at least this long from the launch: long enough that a whole flight and a
descent from where the payload is now use the same files (and the same cube)."""
REGION_MINUTES = 240.0
"""The demo weather region is sized for this long a drift (or the flight's, if longer) around the launch:
the same region for a whole flight and for a descent from where the payload is, so both reuse one cube."""
WEATHER_HOURS_AFTER_BURST = 6
"""Demo weather generated past the burst: a descent from 40 km under a small canopy lasts ~1.5 h."""
CAPSULE_DESCENT_S = 3 * 3600.0
"""Longest the capsule's own descent is budgeted (~40 min from 30 km) when sizing a flight."""
WARM_DEMO_POINT = (52.0, 0.0)
"""Where the DEMO weather is first generated to warm the compiled code (any place on Earth would do)."""


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
class FlownModel:
    """A calibrated model a capsule falls with, and the file it came from (None: a payload profile)."""

    model: CalibratedModel
    path: Path | None = None

    def setup(self, terrain: Terrain) -> FlightSetup:
        """A prediction before release: the model's pre-flight law (live-only terms left out)."""
        return self.model.flight_setup(terrain)

    def document(self) -> dict[str, Any]:
        payload = self.model.payload.to_dict()
        if self.path is None:
            return {"label": self.model.label(), "payload": payload}
        return {**self.model.document(self.path), "payload": payload}


@dataclass(frozen=True)
class Flight:
    """One answered request: Tawhiri's stages, and what the response says about them."""

    request: ApiRequest
    stages: tuple[Stage, ...]
    answered: dict[str, Any]
    is_demo: bool
    weather_source: str
    flown: FlownModel | None = None
    """The capsule model of a capsule descent."""
    matched: CapsuleFix | None = None
    """The capsule position report the request started from, when that chose the capsule's model."""

    @property
    def capsule_descent(self) -> Prediction | None:
        last = self.stages[-1][1]
        return last if isinstance(last, Prediction) else None


@dataclass(frozen=True)
class WeatherSource:
    """Where the server's weather comes from: fixed files, a directory re-read per request, or DEMO."""

    files: tuple[Path, ...] = ()
    directory: Path | None = None
    demo: bool = False

    @property
    def kind(self) -> str:
        return "demo" if self.demo else "directory" if self.directory is not None else "files"

    def listed(self) -> list[Path]:
        """The served files now (the directory listed again: a newer forecast is used without a restart)."""
        if self.directory is None:
            return list(self.files)
        return sorted(
            p for p in self.directory.iterdir()
            if p.is_file() and not p.name.startswith(".") and not p.name.endswith(".partial")
        )  # fmt: skip


def _stamp(path: Path) -> tuple[str, int, int]:
    try:
        stat = path.stat()
    except OSError:
        return str(path), -1, -1
    return str(path), stat.st_size, stat.st_mtime_ns


@dataclass
class _Served:
    """The cube of the served (non-demo) files, and the files refused, keyed by the files' stamps."""

    key: tuple[tuple[str, int, int], ...] = ()
    cube: WeatherCube | None = None
    refused: dict[tuple[str, int, int], str] = field(default_factory=dict)
    error: str | None = None


class PredictorService:
    """Answers API requests with the selected weather, terrain and models; one prediction at a time.

    Served files are decoded whole, once (``drs weather fetch`` writes regional subsets), and every
    request is flown on that cube until the files change. DEMO weather is generated around each launch
    point rounded to a degree; the cube of the last one is kept, as chasemapper asks again every few
    seconds from nearly the same place.
    """

    def __init__(
        self,
        weather: WeatherSource,
        terrain: Terrain,
        flown: CalibratedModel,
        model_path: Path | None = None,
        cache_dir: str | None = None,
        fixes: FixSource | None = None,
        capsule_models: Mapping[str, FlownModel] | None = None,
    ) -> None:
        self.weather = weather
        self.terrain = terrain
        self.default = FlownModel(flown, model_path)
        self.capsule_models = dict(capsule_models or {})
        self.fixes = fixes
        self.cache_dir = cache_dir
        self._lock = threading.Lock()
        self._demo_key: tuple[Any, ...] | None = None
        self._demo_cube: WeatherCube | None = None
        self._served = _Served()
        self.warmed_s: float | None = None
        """How long ``warm`` took; None until the compiled code has flown once."""

    # -- weather -------------------------------------------------------------------------------

    def _served_cube(self) -> WeatherCube:
        """The cube of the served files, loaded again when the listing or a file changed; a file that
        cannot be read is refused (logged once, named on /health) and the others are served."""
        files = self.weather.listed()
        if not files:
            raise WeatherError(
                f"no weather files in {self.weather.directory} (fetch some with drs weather fetch --dir)"
            )
        key = tuple(_stamp(f) for f in files)
        served = self._served
        if key == served.key and served.cube is not None:
            return served.cube
        if key == served.key and served.error is not None:
            raise WeatherError(served.error)
        refused = {stamp: why for stamp, why in served.refused.items() if stamp in key}
        usable = [f for f, stamp in zip(files, key, strict=True) if stamp not in refused]
        cube: WeatherCube | None = None
        error: str | None = None
        try:
            cube = load_weather(usable, bbox=None, cache_dir=self.cache_dir) if usable else None
        except WeatherError as exc:
            error = str(exc)
            for file, stamp in zip(files, key, strict=True):
                if stamp not in refused and file in usable and (why := self._unreadable(file)) is not None:
                    refused[stamp] = why
                    log.warning("weather file refused: %s", why)
            usable = [f for f, stamp in zip(files, key, strict=True) if stamp not in refused]
            cube = None
            if usable and len(usable) < len(files):
                try:
                    cube = load_weather(usable, bbox=None, cache_dir=self.cache_dir)
                    error = None
                except WeatherError as again:
                    error = str(again)
        if cube is None and error is None:
            error = f"every weather file was refused: {'; '.join(refused.values())}"
        self._served = _Served(key, cube, refused, error)
        if cube is None:
            raise WeatherError(error or "no weather")
        return cube

    def _unreadable(self, file: Path) -> str | None:
        """Why ``file`` alone cannot be read (one line naming it), or None when it can."""
        try:
            load_weather([file], bbox=None, cache_dir=self.cache_dir)
        except WeatherError as exc:
            text = str(exc)
            return text if str(file) in text else f"{file}: {text}"
        return None

    def _demo_cube_for(
        self, request: ApiRequest, start: datetime, flight_s: float, drift_minutes: float
    ) -> WeatherCube:
        lat0, lon0 = round(request.launch_latitude), round(request.launch_longitude)
        hours = max(WEATHER_HOURS, math.ceil(flight_s / 3600.0))
        files = demo_weather_files(lat0, lon0, start, hours=hours)
        box = weather_bbox(lat0, lon0, max(REGION_MINUTES, drift_minutes))
        key = (tuple(_stamp(f) for f in files), box)
        if key != self._demo_key or self._demo_cube is None:
            self._demo_cube = load_weather(files, bbox=box, cache_dir=self.cache_dir)
            self._demo_key = key
        return self._demo_cube

    def _cube(self, request: ApiRequest, start: datetime, flight_s: float) -> WeatherCube:
        if self.weather.demo:
            return self._demo_cube_for(request, start, flight_s, flight_s / 60.0)
        return self._served_cube()

    # -- flights -------------------------------------------------------------------------------

    def predict(self, request: ApiRequest) -> Flight:
        """The request's stages and the request as answered (Tawhiri's ``request``). Its length is
        checked before any weather is read or made."""
        with self._lock:
            launch_alt = request.launch_altitude
            if launch_alt is None:
                launch_alt = float(self.terrain.elevation(request.launch_latitude, request.launch_longitude))
            if request.profile == REVERSE_PROFILE:
                return self._reverse(request, launch_alt)
            top = request.burst_altitude if request.profile == STANDARD_PROFILE else request.float_altitude
            assert top is not None, "parse_request sets the top of a standard or float flight"
            name = "burst_altitude" if request.profile == STANDARD_PROFILE else "float_altitude"
            if top <= launch_alt:
                raise request_error(
                    f"Invalid value for parameter '{name}': {top:g} (must be above the ground at launch, "
                    f"{launch_alt:.0f} m)."
                )
            ascent_s = (top - launch_alt) / request.ascent_rate
            if request.profile == FLOAT_PROFILE:
                assert request.stop_datetime is not None
                flight_s = max(ascent_s, (request.stop_datetime - request.launch_datetime).total_seconds())
                self._check_length("ascent_rate", request.ascent_rate, ascent_s, f"the ascent to {top:g} m")
                return self._float(request, launch_alt, flight_s)
            request, matched = self._which_descent(request, launch_alt)
            if request.descent == TAWHIRI_DESCENT:
                assert request.descent_rate is not None
                descent_s = tawhiri_descent_s(top, request.descent_rate, min(launch_alt, 0.0))
                self._check_length("descent_rate", request.descent_rate, descent_s, "the descent")
            else:
                descent_s = CAPSULE_DESCENT_S
            self._check_length("ascent_rate", request.ascent_rate, ascent_s, f"the ascent to {top:g} m")
            self._check_length("ascent_rate", request.ascent_rate, ascent_s + descent_s, "the flight")
            cube = self._cube(request, request.launch_datetime, ascent_s + descent_s + 3600.0)
            self._check_dataset(request, cube)
            ascent = ascend(cube, request.launch_datetime, request.launch_latitude, request.launch_longitude,
                            launch_alt, request.ascent_rate, top)  # fmt: skip
            burst = ascent.burst
            descent: Ascent | Prediction
            flown = None
            if request.descent == TAWHIRI_DESCENT:
                assert request.descent_rate is not None
                descent = descend(cube, self.terrain, burst.time, burst.lat, burst.lon, burst.alt_m,
                                  request.descent_rate)  # fmt: skip
            else:
                flown = self.capsule_models.get(request.capsule or "", self.default)
                descent = predict(cube, Release(burst.time, burst.lat, burst.lon, burst.alt_m),
                                  flown.setup(self.terrain))  # fmt: skip
            answered = self._answered(request, launch_alt, cube)
            answered |= {"burst_altitude": top, "descent_rate": request.descent_rate}
            return Flight(request, (("ascent", ascent), ("descent", descent)), answered, cube.is_demo,
                          cube.source, flown, matched)  # fmt: skip

    def _which_descent(self, request: ApiRequest, launch_alt: float) -> tuple[ApiRequest, CapsuleFix | None]:
        """At ``/api/v1/``, a flight from one of a capsule's latest position reports is that capsule's."""
        if request.descent != TAWHIRI_DESCENT or self.fixes is None or request.launch_altitude is None:
            return request, None
        try:
            fixes = self.fixes()
        except Exception:  # the capsules' store unreadable: every payload still gets Tawhiri's answer
            log.exception("cannot read the capsules' position reports; flying Tawhiri's descent")
            return request, None
        fix = matching_fix(fixes, request.launch_latitude, request.launch_longitude, launch_alt,
                           request.launch_datetime)  # fmt: skip
        if fix is None:
            return request, None
        return replace(request, descent=CAPSULE_DESCENT, capsule=fix.capsule), fix

    def _float(self, request: ApiRequest, launch_alt: float, flight_s: float) -> Flight:
        assert request.float_altitude is not None and request.stop_datetime is not None
        cube = self._cube(request, request.launch_datetime, flight_s + 3600.0)
        self._check_dataset(request, cube)
        ascent = ascend(cube, request.launch_datetime, request.launch_latitude, request.launch_longitude,
                        launch_alt, request.ascent_rate, request.float_altitude)  # fmt: skip
        top = ascent.burst
        floating = drift(cube, top.time, top.lat, top.lon, top.alt_m, request.stop_datetime)
        answered = self._answered(request, launch_alt, cube)
        answered |= {"float_altitude": request.float_altitude, "stop_datetime": iso(request.stop_datetime)}
        return Flight(request, (("ascent", ascent), ("float", floating)), answered, cube.is_demo, cube.source)

    def _reverse(self, request: ApiRequest, alt: float) -> Flight:
        ground = float(self.terrain.elevation(request.launch_latitude, request.launch_longitude))
        back_s = max(0.0, alt - min(ground, 0.0)) / request.ascent_rate
        self._check_length(
            "ascent_rate", request.ascent_rate, back_s, f"the ascent from the ground to {alt:g} m"
        )
        start = request.launch_datetime - timedelta(seconds=back_s + 3600.0)
        cube = self._cube(request, start, back_s + 2 * 3600.0)
        self._check_dataset(request, cube)
        here = as_stage([(request.launch_datetime.timestamp(), request.launch_latitude,
                          request.launch_longitude, alt)])  # fmt: skip
        back = trace_back(cube, self.terrain, request.launch_datetime, request.launch_latitude,
                          request.launch_longitude, alt, request.ascent_rate)  # fmt: skip
        return Flight(request, (("ascent", here), ("descent", back)), self._answered(request, alt, cube),
                      cube.is_demo, cube.source)  # fmt: skip

    @staticmethod
    def _check_length(name: str, value: float, seconds: float, what: str) -> None:
        if seconds > MAX_FLIGHT_S:
            raise request_error(
                f"Invalid value for parameter '{name}': {value:g} ({what} would last {seconds / 3600:.0f} h; "
                f"at most {MAX_FLIGHT_S / 3600:.0f} h is flown)."
            )

    @staticmethod
    def _check_dataset(request: ApiRequest, cube: WeatherCube) -> None:
        if request.dataset is not None and request.dataset != dataset_time(cube):
            raise ApiError(
                "InvalidDatasetException", 404,
                f"No matching dataset found: this server has {iso(dataset_time(cube))}, not {iso(request.dataset)}.",
            )  # fmt: skip

    @staticmethod
    def _answered(request: ApiRequest, launch_alt: float, cube: WeatherCube) -> dict[str, Any]:
        return {
            "profile": request.profile,
            "launch_latitude": request.launch_latitude,
            "launch_longitude": request.launch_longitude % 360.0,
            "launch_datetime": iso(request.launch_datetime),
            "launch_altitude": launch_alt,
            "ascent_rate": request.ascent_rate,
            "dataset": iso(dataset_time(cube)),
            "format": request.format,
            "version": API_VERSION,
        }

    # -- what the answer says ------------------------------------------------------------------

    def extension(self, flight: Flight) -> dict[str, Any]:
        """Ours, beside Tawhiri's fields: what a chase team needs to judge the landing point."""
        descent = flight.capsule_descent
        if descent is None:
            return {"descent": TAWHIRI_DESCENT if flight.request.profile == STANDARD_PROFILE else None,
                    "descent_rate_used": flight.request.profile == STANDARD_PROFILE,
                    "weather": flight.weather_source, "is_demo": flight.is_demo}  # fmt: skip
        assert flight.flown is not None
        document = descent.to_dict()
        ours = {
            "descent": CAPSULE_DESCENT,
            "capsule": flight.request.capsule,
            "landing": document["landing"],
            "burst": document["release"],
            "descent_s": document["descent_s"],
            "ellipse": document["ellipse"],
            "model": flight.flown.document(),
            "descent_rate_used": False,
            "weather": document["weather"],
            "terrain_source": descent.terrain_source,
            "is_demo": descent.is_demo,
            "warnings": document["warnings"],
        }
        if flight.matched is not None:
            fix = flight.matched
            ours["position_report"] = {"capsule": fix.capsule, "time": iso(fix.time), "lat": fix.lat,
                                       "lon": fix.lon, "alt_m": fix.alt_m}  # fmt: skip
        return ours

    def warnings(self, flight: Flight) -> dict[str, dict[str, Any]]:
        """Tawhiri's ``warnings`` (``{name: {count, description}}``): which descent, and what was changed."""
        request = flight.request
        said = None
        if flight.matched is not None and flight.flown is not None:
            fix = flight.matched
            said = (
                f"Descent flown with {fix.capsule}'s DRS capsule model ({flight.flown.model.label()}): the "
                f"launch point and time are its position report of {iso(fix.time)} (within "
                f"{MATCH_DISTANCE_M:g} m, {MATCH_ALTITUDE_M:g} m up or down and {MATCH_TIME_S:g} s); "
                "descent_rate is not used."
            )
        elif flight.flown is not None:
            said = (
                f"Descent flown with the DRS capsule model ({flight.flown.model.label()}) for "
                f"{request.capsule or 'a DRS capsule'}: descent_rate is not used."
            )
        elif request.profile == STANDARD_PROFILE:
            said = (
                f"Descent flown as Tawhiri's: descent_rate {request.descent_rate:g} m/s at sea level, faster "
                "in thinner air; no DRS capsule reported this launch point and time."
            )
        warnings = {} if said is None else {"drs_descent": {"count": 1, "description": said}}
        for name in request.clipped:
            warnings[f"drs_{name}_raised"] = {
                "count": 1, "description": f"{name} below {MIN_RATE_MS:g} m/s was flown at {MIN_RATE_MS:g}.",
            }  # fmt: skip
        if flight.is_demo:
            warnings["drs_demo_weather"] = {"count": 1, "description": DEMO_WARNING}
        return warnings

    # -- readiness -----------------------------------------------------------------------------

    def warm(self) -> float:
        """Load the weather and fly once with every model, so the compiled code is ready before the
        server listens; how long it took. Weather that cannot be read is said on /health, not fatal."""
        began = time.monotonic()
        with self._lock:
            try:
                if self.weather.demo:
                    lat, lon = WARM_DEMO_POINT
                    when = datetime.now(UTC).replace(minute=0, second=0, microsecond=0)
                    probe = ApiRequest(STANDARD_PROFILE, lat, lon, when, 0.0, 5.0, None, "json")
                    cube = self._demo_cube_for(probe, when, 3 * 3600.0, REGION_MINUTES)
                else:
                    cube = self._served_cube()
            except WeatherError as exc:
                log.warning("weather not loaded at start: %s", exc)
                return time.monotonic() - began
            lat = float(cube.lats[len(cube.lats) // 2])
            lon = float(cube.lons[len(cube.lons) // 2])
            when = datetime.fromtimestamp(int(cube.times[0].astype("datetime64[s]").astype(int)), UTC)
            try:
                ascent = ascend(cube, when, lat, lon, 0.0, 5.0, 1000.0)
                top = ascent.burst
                descend(cube, self.terrain, top.time, top.lat, top.lon, top.alt_m, 5.0)
                drift(cube, top.time, top.lat, top.lon, top.alt_m, top.time + timedelta(minutes=2))
                for flown in {id(m): m for m in (self.default, *self.capsule_models.values())}.values():
                    predict(cube, Release(top.time, top.lat, top.lon, top.alt_m), flown.setup(self.terrain))
            except PredictorError as exc:  # a region too small to fly in: served, said on /health
                log.warning("the warm-up flight did not complete: %s", exc)
                return time.monotonic() - began
        self.warmed_s = time.monotonic() - began
        return self.warmed_s

    def health(self) -> dict[str, Any]:
        """What /health says: is the weather loaded, is the compiled code warm, which version serves."""
        served = self._served
        cube = self._demo_cube if self.weather.demo else served.cube
        weather: dict[str, Any] = {"kind": self.weather.kind, "loaded": cube is not None}
        if cube is not None:
            weather |= {
                "source": cube.source, "is_demo": cube.is_demo, "dataset": iso(dataset_time(cube)),
                "valid_from": iso(datetime.fromtimestamp(int(cube.times[0].astype("datetime64[s]").astype(int)), UTC)),
                "valid_to": iso(datetime.fromtimestamp(int(cube.times[-1].astype("datetime64[s]").astype(int)), UTC)),
            }  # fmt: skip
        if served.refused:
            weather["refused"] = sorted(served.refused.values())
        if served.error is not None and not self.weather.demo:
            weather["error"] = served.error
        ready = cube is not None and self.warmed_s is not None
        return {
            "status": "ok" if ready else "degraded",
            "version": importlib.metadata.version("drs-console"),
            "weather": weather,
            "warm": self.warmed_s is not None,
            "warmed_in_s": None if self.warmed_s is None else round(self.warmed_s, 2),
            "capsules": sorted(self.capsule_models) if self.fixes is not None else [],
        }


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
        return error_answer(exc, started)
    except OutOfCoverageError as exc:
        return error_answer(
            ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started
        )
    except WeatherError as exc:
        return error_answer(
            ApiError("InvalidDatasetException", 404, f"No matching dataset found: {exc}"), started
        )
    except PredictorError as exc:
        return error_answer(
            ApiError("PredictionException", 500, f"Prediction did not complete: {exc}"), started
        )
    except Exception:  # the client still gets Tawhiri's shape; the operator gets the traceback
        log.exception("prediction failed for %s", dict(query))
        return error_answer(ApiError("InternalException", 500, "Internal exception experienced."), started)
    prediction = stages(flight.stages)
    warnings = service.warnings(flight)
    headers = {}
    if flight.is_demo:
        headers["Warning"] = f'299 drs "{DEMO_WARNING}"'
    if request.format in ("csv", "kml"):
        name = file_name(flight.answered, request.format, flight.is_demo)
        headers["Content-Disposition"] = f'attachment; filename="{name}"'
        if request.format == "csv":
            return 200, "text/csv; charset=utf-8", to_csv(prediction), headers
        said = warnings.get("drs_descent", {}).get("description", f"{request.profile} flight.")
        return (
            200,
            "application/vnd.google-earth.kml+xml",
            to_kml(flight.answered, said, prediction, flight.is_demo),
            headers,
        )
    document: dict[str, Any] = {
        "request": flight.answered,
        "prediction": prediction,
        "metadata": metadata(started),
        "warnings": warnings,
        "drs": service.extension(flight),
    }
    if request.profile == REVERSE_PROFILE:
        launch = prediction[-1]["trajectory"][-1]
        document["launch_estimate"] = {
            key: launch[key] for key in ("latitude", "longitude", "altitude", "datetime")
        }
    return 200, "application/json", json.dumps(document), headers


def metadata(started: datetime) -> dict[str, str]:
    return {"start_datetime": iso(started), "complete_datetime": iso(datetime.now(UTC))}


def error_answer(exc: ApiError, started: datetime) -> Answer:
    body = {"error": {"type": exc.kind, "description": exc.description}, "metadata": metadata(started)}
    return exc.status, "application/json", json.dumps(body), {}


def route(path: str) -> tuple[str, str | None] | None:
    """(descent, capsule) for a served path: ``/api/v1/`` Tawhiri's, ``/api/v1/drs/[NAME/]`` the capsule's."""
    parts = [part for part in path.split("/") if part]
    if parts == ["api", "v1"]:
        return TAWHIRI_DESCENT, None
    if parts[:3] == ["api", "v1", "drs"] and len(parts) <= 4:
        return CAPSULE_DESCENT, parts[3] if len(parts) == 4 else None
    return None
