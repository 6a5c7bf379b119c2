"""Landing predictions for the console: "release now" and "release in N minutes" from the balloon's position.

Also the release-window sweep (when to drop, as a go/no-go timeline) and the live re-prediction
of a descending capsule from its reports (``predictor.planning`` and ``predictor.prediction.live``).

Blocking (weather files, numba), so the app calls it from a worker thread. Each answer becomes a
``PredictionSample`` telemetry record carrying what the screens and go/no-go need (landing, σ∥/σ⊥,
bearing, the 1/2/3σ contours with their probabilities, the 2σ outline, a thinned path), so a
replayed session shows the same numbers without recomputing them.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime
from pathlib import Path

from drs_link.ops import (
    Contour,
    LiveView,
    PredictionSample,
    ReleaseCandidate,
    ReleaseOrigin,
    ReleaseWindow,
    TelemetryRecord,
)
from predictor import Prediction, Terrain, WeatherCube, load_weather, predict
from predictor.descent import PROFILES
from predictor.errors import PredictorError
from predictor.planning import Criteria, Sweep, plan_release
from predictor.prediction import (
    CalibratedModel,
    Feature,
    FlightSetup,
    LivePrediction,
    LivePredictor,
    Report,
    load_model,
    load_zones,
    write_geojson,
    write_gpx,
    write_kml,
)

PATH_POINTS = 60
WINDOW_HOURS = 2.0
WINDOW_STEP_MIN = 5.0
"""The console's sweep: parametric only (no ensemble members) so a refresh stays well under a second."""


Points = tuple[tuple[float, float], ...]


def map_geometry(prediction: Prediction) -> tuple[Points, Points]:
    """The 2σ outline and a thinned path as (lon, lat): what the terminal map draws."""
    two_sigma = next(c for c in prediction.ellipse.contours if round(c.n_sigma) == 2)
    step = max(1, len(prediction.track.lat) // PATH_POINTS)
    outline = tuple((float(lon), float(lat)) for lon, lat in prediction.ellipse.outline(two_sigma, points=36))
    path = tuple(
        (float(lon), float(lat))
        for lat, lon in zip(prediction.track.lat[::step], prediction.track.lon[::step], strict=True)
    )
    return outline, path


def prediction_sample(
    prediction: Prediction, release_in_min: int, source: str, model: str
) -> PredictionSample:
    ellipse = prediction.ellipse
    outline, path = map_geometry(prediction)
    return PredictionSample(
        release_in_min=release_in_min,
        origin_source=source,
        release_lat=prediction.release.lat,
        release_lon=prediction.release.lon,
        release_time=prediction.release.time,
        landing_lat=prediction.landing.lat,
        landing_lon=prediction.landing.lon,
        landing_time=prediction.landing.time,
        descent_s=prediction.descent_s,
        distance_km=prediction.drift_km,
        bearing_deg=prediction.bearing_deg,
        sigma_par_km=ellipse.sigma_parallel_km,
        sigma_perp_km=ellipse.sigma_perpendicular_km,
        major_axis_bearing_deg=ellipse.major_axis_bearing_deg,
        contours=tuple(
            Contour(c.n_sigma, c.probability, c.semi_major_km, c.semi_minor_km) for c in ellipse.contours
        ),
        outline_2sigma=outline,
        path=path,
        warnings=tuple(prediction.warnings),
        is_demo=prediction.is_demo,
        model=model,
    )


class PredictionService:
    """Holds the weather and terrain once loaded, and the latest prediction per capsule for export."""

    def __init__(
        self,
        weather_files: Callable[[], Sequence[Path]],
        terrain: Callable[[], Terrain],
        clock: Callable[[], datetime],
        models: Mapping[str, CalibratedModel] | None = None,
    ) -> None:
        self._weather_files = weather_files
        self.models = dict(models or {})
        """Each capsule's calibrated model (its ``model`` key); the others fly the drs profile."""
        self._terrain_factory = terrain
        self.clock = clock
        self._cube: WeatherCube | None = None
        self._terrain: Terrain | None = None
        self._lock = threading.Lock()
        self.latest: dict[str, Prediction] = {}
        self._live: dict[str, LivePredictor] = {}
        self._live_latest: dict[str, LiveView] = {}
        self.live_latest: dict[str, Prediction] = {}
        """Each descending capsule's latest live re-prediction (the chase feed keeps it for chasemapper)."""
        self._live_lock = threading.Lock()

    def _inputs(self) -> tuple[WeatherCube, Terrain]:
        with self._lock:
            if self._cube is None:
                self._cube = load_weather(list(self._weather_files()))
            if self._terrain is None:
                self._terrain = self._terrain_factory()
            return self._cube, self._terrain

    def predict(
        self, capsule: str, origin: ReleaseOrigin, release_in: Sequence[int] = (0,)
    ) -> list[TelemetryRecord]:
        cube, terrain = self._inputs()
        now = self.clock()
        records = []
        setup, label = self._flown(capsule, terrain)
        for minutes in release_in:
            result = predict(cube, origin.release(now, drift_minutes=float(minutes)), setup)
            if minutes == 0:
                self.latest[capsule] = result
            records.append(
                TelemetryRecord(now, capsule, prediction_sample(result, minutes, origin.source, label))
            )
        return records

    def _flown(self, capsule: str | None, terrain: Terrain) -> tuple[FlightSetup, str]:
        """What a capsule's predictions and sweeps fly (its model's payload, terms and ellipse, or the
        default profile) and how they name it: one rule for the release prediction and the window."""
        model = self.models.get(capsule) if capsule is not None else None
        if model is None:
            return FlightSetup(terrain=terrain), "drs profile"
        return model.flight_setup(terrain), model.label()

    def export(self, capsule: str, directory: Path) -> list[Path]:
        prediction = self.latest.get(capsule)
        if prediction is None:
            return []
        stamp = prediction.release.time.strftime("%Y%m%dT%H%M%SZ")
        return [
            write_kml(prediction, directory / f"{capsule}-{stamp}.kml"),
            write_geojson(prediction, directory / f"{capsule}-{stamp}.geojson"),
            write_gpx(prediction, directory / f"{capsule}-{stamp}.gpx"),
        ]

    def release_window(
        self,
        origin: ReleaseOrigin,
        zones_file: Path | None,
        hours: float = WINDOW_HOURS,
        every_minutes: float = WINDOW_STEP_MIN,
        capsule: str | None = None,
    ) -> ReleaseWindow:
        """The sweep from now, typed: one candidate per time with its verdict, and the recommended one.
        It flies ``capsule``'s model as its release prediction does (the go/no-go depends on it)."""
        cube, terrain = self._inputs()
        setup, label = self._flown(capsule, terrain)
        zones: tuple[Feature, ...] = load_zones(zones_file) if zones_file is not None else ()
        now = self.clock()
        plan = plan_release(
            cube, origin.release(now), Sweep(hours, every_minutes), setup, criteria=Criteria(zones)
        )
        candidates = tuple(
            ReleaseCandidate(c.release_time, c.go, c.status is None, tuple(c.reasons), c.landing_time)
            for c in plan.candidates
        )
        recommended = plan.windows[0].recommended if plan.windows else None
        return ReleaseWindow(now, every_minutes, recommended, candidates, label)

    def live(self, capsule: str, reports: Sequence[Report]) -> LiveView | None:
        """Feed the reports not seen yet to the capsule's live predictor; the prediction from the latest.

        One predictor per capsule keeps the legs measured so far, so each new report costs one
        leg and one prediction, not a replay of the whole descent.
        """
        if not reports:
            return None
        cube, terrain = self._inputs()
        with self._live_lock:
            live = self._live.get(capsule)
            if live is None or (live.reports and reports[0].time < live.reports[0].time):
                model = self.models.get(capsule)
                # A capsule without a model flies the default payload's law the same way, and says so.
                flown = model if model is not None else CalibratedModel(PROFILES["drs"], (), None)
                live = self._live[capsule] = flown.live_predictor(cube, terrain)
            fresh: list[Report] = []
            for (
                report
            ) in reports:  # strictly later than the last one fed: a repeated fix is skipped, not refused
                last = fresh[-1].time if fresh else live.reports[-1].time if live.reports else None
                if last is None or report.time > last:
                    fresh.append(report)
            if not fresh:
                return self._live_latest.get(capsule)
            for report in fresh[:-1]:
                live.observe(report)
            result = live.update(fresh[-1])
            self.live_latest[capsule] = result.prediction
            view = self._live_latest[capsule] = live_view(result)
            return view


def live_view(result: LivePrediction) -> LiveView:
    """The live re-prediction as the screens show it, read from the typed result (never from its JSON)."""
    prediction, ellipse = result.prediction, result.prediction.ellipse
    outline, path = map_geometry(prediction)
    return LiveView(
        report_time=result.report.time, report_alt_m=result.report.alt_m, landing_lat=prediction.landing.lat,
        landing_lon=prediction.landing.lon, landing_time=prediction.landing.time,
        remaining_drift_km=prediction.drift_km, sigma_parallel_km=ellipse.sigma_parallel_km,
        sigma_perpendicular_km=ellipse.sigma_perpendicular_km,
        measured_rate_factor=result.rate.measured if result.rate is not None else None,
        legs_used=len(result.legs), correction=live_correction_text(result), outline_2sigma=outline, path=path,
        sigma_major_km=ellipse.sigma_major_km, sigma_minor_km=ellipse.sigma_minor_km,
        major_axis_bearing_deg=ellipse.major_axis_bearing_deg,
    )  # fmt: skip


def live_correction_text(result: LivePrediction) -> str:
    """Which measured correction the prediction used, in words (the operator must know what changed),
    and what it flies that is not the model's own (its notes)."""
    parts = []
    if result.rate is not None:
        parts.append(result.rate.describe())
    east, north = result.wind_error_ms
    if result.decay_m is not None and (east, north) != (0.0, 0.0):
        gain = "" if result.wind_gain is None else f", {result.wind_gain:.0%} of it carried"
        parts.append(f"wind error E {east:+.1f} N {north:+.1f} m/s{gain} fading over {result.decay_m:.0f} m")
    return "; ".join([", ".join(parts) if parts else "none (forecast only)", *result.notes])


def capsule_models(capsules: Sequence[tuple[str, Path | None]]) -> dict[str, CalibratedModel]:
    """Each capsule's ``model`` file, loaded once at start: a bad file stops the console with the key named,
    rather than every prediction of that capsule failing (or, worse, flying the default profile)."""
    models = {}
    for index, (name, path) in enumerate(capsules):
        if path is None:
            continue
        try:
            models[name] = load_model(path)
        except PredictorError as exc:
            raise PredictorError(f"capsule[{index}].model ({name}): {exc}") from None
    return models
