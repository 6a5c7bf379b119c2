"""Every geographic file the project writes, built once per session for the tests that read them.

Each product is written from a real computation: predictions and plans from analytic atmospheres
(one of them at Wanaka-like latitudes astride ±180°), and recovery files from the real flight
18-8-3, whose landing rests on a single fix, plus the same flight moved onto the antimeridian.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from drs_link.iridium import recovery
from predictor import EnsemblePrediction, Payload, Prediction, WeatherCube, predict, predict_ensemble
from predictor.descent import Release
from predictor.geofiles.geojson import dumps
from predictor.planning import Sweep, strip
from predictor.planning.sweep import plan_release
from predictor.prediction import EnsembleSpread, FlightSetup, export as prediction_files
from tests.drs_link.iridium.flight_logs import flight_reports
from tests.predictor.predict_helpers import RELEASE, isothermal_cube

PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)
FLIGHT = "18-8-3.csv"


@dataclass(frozen=True)
class Written:
    """One product's files as text, as a user's tool receives them (GeoJSON is absent for recovery)."""

    kml: str
    gpx: str | None
    geojson: str | None
    crosses_antimeridian: bool
    is_demo: bool


def _antimeridian_cube(is_demo: bool = False) -> WeatherCube:
    """Eastward wind over 170° E – 170° W at Wanaka's latitude: a release at 179.64° E lands just past
    180°, so the path crosses it and the landing ellipses straddle it."""
    return isothermal_cube(
        lats=np.arange(-50.0, -39.0, 1.0), lons=np.arange(170.0, 191.0, 1.0), u=8.4, v=1.0, is_demo=is_demo
    )


def _prediction_files(result: Prediction | EnsemblePrediction, crosses: bool, is_demo: bool) -> Written:
    return Written(
        prediction_files.to_kml(result),
        prediction_files.to_gpx(result),
        dumps(prediction_files.to_geojson(result)),
        crosses,
        is_demo,
    )


@pytest.fixture(scope="session")
def products(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Written]:
    shared = Path(__file__).resolve().parents[4].parent / "shared" / "data"
    out: dict[str, Written] = {}
    alps = isothermal_cube(u=8.0, v=3.0)
    out["predict single"] = _prediction_files(
        predict(alps, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD)), False, False
    )
    demo = isothermal_cube(u=8.0, is_demo=True)
    ensemble = predict_ensemble(
        demo, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD), EnsembleSpread(members=20, seed=0)
    )
    out["predict ensemble DEMO"] = _prediction_files(ensemble, False, True)
    wanaka = _antimeridian_cube(is_demo=True)
    single = predict(wanaka, Release(RELEASE, -44.7, 179.64, 28000.0), FlightSetup(PAYLOAD))
    out["predict single across 180"] = _prediction_files(single, True, True)
    members = predict_ensemble(
        wanaka,
        Release(RELEASE, -44.7, 179.64, 28000.0),
        FlightSetup(PAYLOAD),
        EnsembleSpread(members=30, seed=1),
    )
    out["predict ensemble across 180"] = _prediction_files(members, True, True)
    for name, cube, lat, lon, crosses in (
        ("plan DEMO", isothermal_cube(u=8.0, v=2.0, hours=(-6.0, 18.0), is_demo=True), 46.0, 6.0, False),
        ("plan across 180", _antimeridian_cube(), -45.0, 179.4, True),
    ):
        plan = plan_release(cube, Release(RELEASE, lat, lon, 30000.0), Sweep(1.0, 20.0))
        out[name] = Written(strip.to_kml(plan), None, dumps(strip.to_geojson(plan)), crosses, plan.is_demo)
    track = recovery.track_from_reports(flight_reports(shared / "tracks" / "pyballoon_superbit" / FLIGHT))
    for name, shift in (("recovery 18-8-3", 0.0), ("recovery 18-8-3 moved across 180", 228.5)):
        moved = [replace(p, lon=(p.lon + shift + 180.0) % 360.0 - 180.0) for p in track]
        landing = recovery.detect_landing(moved)
        predicted = [(p.lat, p.lon, p.alt_m) for p in moved[:: max(len(moved) // 10, 1)]]
        folder = tmp_path_factory.mktemp("recovery")
        out[name] = Written(
            recovery.write_kml(folder / "r.kml", "DRS1", moved, predicted, landing).read_text(
                encoding="utf-8"
            ),
            recovery.write_gpx(folder / "r.gpx", "DRS1", moved, predicted, landing).read_text(
                encoding="utf-8"
            ),
            None,
            shift != 0.0,
            False,
        )
    return out


PRODUCTS = [
    "predict single",
    "predict ensemble DEMO",
    "predict single across 180",
    "predict ensemble across 180",
    "plan DEMO",
    "plan across 180",
    "recovery 18-8-3",
    "recovery 18-8-3 moved across 180",
]
