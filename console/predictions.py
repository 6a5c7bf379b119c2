"""Landing predictions for the console: "release now" and "release in N minutes" from the balloon's position.

Blocking (weather files, numba), so the app calls it from a worker thread. Each answer becomes a
``prediction`` telemetry record carrying what the screens and go/no-go need (landing, σ∥/σ⊥,
bearing, the 1/2/3σ contours with their probabilities, the 2σ outline, a thinned path), so a
replayed session shows the same numbers without recomputing them.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from datetime import datetime
from pathlib import Path

from drs_link.telemetry import TelemetryRecord
from predictor import Prediction, Terrain, WeatherCube, load_weather, predict
from predictor.export import write_geojson, write_kml

PATH_POINTS = 60


def prediction_data(prediction: Prediction, release_in_min: int) -> dict[str, object]:
    ellipse = prediction.ellipse
    two_sigma = next(c for c in ellipse.contours if round(c.n_sigma) == 2)
    step = max(1, len(prediction.track.lat) // PATH_POINTS)
    return {
        "release_in_min": release_in_min,
        "release_lat": prediction.release.lat,
        "release_lon": prediction.release.lon,
        "release_time": prediction.release.time.isoformat(),
        "landing_lat": prediction.landing.lat,
        "landing_lon": prediction.landing.lon,
        "landing_time": prediction.landing.time.isoformat(),
        "descent_s": prediction.descent_s,
        "distance_km": prediction.drift_km,
        "bearing_deg": prediction.bearing_deg,
        "sigma_par_km": ellipse.sigma_parallel_km,
        "sigma_perp_km": ellipse.sigma_perpendicular_km,
        "major_axis_bearing_deg": ellipse.major_axis_bearing_deg,
        "contours": [
            {"n_sigma": c.n_sigma, "probability": c.probability, "major_km": c.semi_major_km,
             "minor_km": c.semi_minor_km}
            for c in ellipse.contours
        ],  # fmt: skip
        "outline_2sigma": [list(p) for p in ellipse.outline(two_sigma, points=36)],
        "path": [
            [float(lon), float(lat)]
            for lat, lon in zip(prediction.track.lat[::step], prediction.track.lon[::step], strict=True)
        ],
        "warnings": list(prediction.warnings),
        "is_demo": prediction.is_demo,
    }


class PredictionService:
    """Holds the weather and terrain once loaded, and the latest prediction per capsule for export."""

    def __init__(
        self,
        weather_files: Callable[[], Sequence[Path]],
        terrain: Callable[[], Terrain],
        clock: Callable[[], datetime],
    ) -> None:
        self._weather_files = weather_files
        self._terrain_factory = terrain
        self.clock = clock
        self._cube: WeatherCube | None = None
        self._terrain: Terrain | None = None
        self._lock = threading.Lock()
        self.latest: dict[str, Prediction] = {}

    def _inputs(self) -> tuple[WeatherCube, Terrain]:
        with self._lock:
            if self._cube is None:
                self._cube = load_weather(list(self._weather_files()))
            if self._terrain is None:
                self._terrain = self._terrain_factory()
            return self._cube, self._terrain

    def predict(
        self, capsule: str, lat: float, lon: float, alt_m: float, release_in: Sequence[int] = (0,)
    ) -> list[TelemetryRecord]:
        cube, terrain = self._inputs()
        now = self.clock()
        records = []
        for minutes in release_in:
            result = predict(cube, now, lat, lon, alt_m, terrain=terrain, drift_minutes=float(minutes))
            if minutes == 0:
                self.latest[capsule] = result
            records.append(TelemetryRecord(now, capsule, "prediction", prediction_data(result, minutes)))
        return records

    def export(self, capsule: str, directory: Path) -> list[Path]:
        prediction = self.latest.get(capsule)
        if prediction is None:
            return []
        stamp = prediction.release.time.strftime("%Y%m%dT%H%M%SZ")
        return [
            write_kml(prediction, directory / f"{capsule}-{stamp}.kml"),
            write_geojson(prediction, directory / f"{capsule}-{stamp}.geojson"),
        ]
