"""``float_profile`` as Tawhiri serves it and SondeHub's ``reverse_profile`` (#32 item 2); main answered 501.

Tawhiri (cuspaceflight/tawhiri ``api.py``, ``models.py``): a float flight takes ``ascent_rate``,
``float_altitude`` (above the launch) and ``stop_datetime`` (after the launch) and answers the stages
``ascent`` and ``float``, the float ending at ``stop_datetime``. SondeHub's fork (projecthorus/tawhiri)
adds ``reverse_profile``: from where an ascending balloon is now, back to its launch, answered as the
stages ``ascent`` and ``descent`` plus a ``launch_estimate``.
"""

from __future__ import annotations

import json
import math
from datetime import datetime, timedelta
from typing import Any

import pytest

from predictor.tawhiri import ApiServer, surface_distance_m
from tests.predictor.tawhiri.conftest import LAUNCH, LAUNCH_LAT, LAUNCH_LON
from tests.predictor.tawhiri.test_tawhiri_api import get


def float_query(**changes: Any) -> dict[str, Any]:
    params = {
        "profile": "float_profile",
        "launch_latitude": LAUNCH_LAT,
        "launch_longitude": LAUNCH_LON + 360,
        "launch_datetime": LAUNCH.isoformat(),
        "launch_altitude": 0,
        "ascent_rate": 5,
        "float_altitude": 20000,
        "stop_datetime": (LAUNCH + timedelta(hours=3)).isoformat(),
    }
    params.update(changes)
    return {k: v for k, v in params.items() if v is not None}


def when(point: dict[str, Any]) -> datetime:
    return datetime.fromisoformat(point["datetime"])


def test_a_float_flight_rises_then_drifts_at_its_altitude_until_the_stop_time(server: ApiServer) -> None:
    status, _, body = get(server, float_query())
    assert status == 200, body
    document = json.loads(body)
    assert [s["stage"] for s in document["prediction"]] == ["ascent", "float"]
    ascent, floating = (s["trajectory"] for s in document["prediction"])
    assert ascent[-1] == floating[0], "the float starts where the ascent ended"
    assert ascent[-1]["altitude"] == 20000 and when(ascent[-1]) == LAUNCH + timedelta(seconds=4000)
    assert {p["altitude"] for p in floating} == {20000.0}
    assert when(floating[-1]) == LAUNCH + timedelta(hours=3), "the float ends at stop_datetime"
    steps = [(when(b) - when(a)).total_seconds() for a, b in zip(floating, floating[1:], strict=False)]
    assert max(steps) <= 60 and min(steps) > 0
    moved = surface_distance_m(floating[0]["latitude"], floating[0]["longitude"], floating[-1]["latitude"],
                               floating[-1]["longitude"])  # fmt: skip
    assert moved > 1_000, "carried by the wind for 1 h 53 min"
    answered = document["request"]
    assert answered["profile"] == "float_profile" and answered["float_altitude"] == 20000
    assert answered["stop_datetime"] == "2024-05-01T09:00:00Z" and "burst_altitude" not in answered
    assert "drs_descent" not in document["warnings"] and "drs_demo_weather" in document["warnings"]


def test_a_float_flight_comes_as_csv_and_kml_too(server: ApiServer) -> None:
    points = sum(len(s["trajectory"]) for s in json.loads(get(server, float_query())[2])["prediction"])
    status, _, text = get(server, float_query(format="csv"))
    assert status == 200 and len(text.decode().splitlines()) == points + 1
    status, _, kml = get(server, float_query(format="kml"))
    assert status == 200 and b"<name>Float</name>" in kml and b"<name>Stop</name>" in kml


@pytest.mark.parametrize(
    ("changes", "says"),
    [
        ({"float_altitude": None}, "Parameter 'float_altitude' not provided in request."),
        ({"stop_datetime": None}, "Parameter 'stop_datetime' not provided in request."),
        ({"float_altitude": 0}, "Invalid value for parameter 'float_altitude'"),
        ({"stop_datetime": LAUNCH.isoformat()}, "Invalid value for parameter 'stop_datetime'"),
        ({"ascent_rate": "fast"}, "Unable to parse parameter 'ascent_rate'"),
    ],
)
def test_a_bad_float_request_is_tawhiris_request_exception(
    server: ApiServer, changes: dict[str, Any], says: str
) -> None:
    status, _, body = get(server, float_query(**changes))
    error = json.loads(body)["error"]
    assert (status, error["type"]) == (400, "RequestException") and says in error["description"]


def test_a_reverse_flight_finds_where_a_rising_balloon_was_launched(server: ApiServer) -> None:
    now = LAUNCH + timedelta(hours=3)
    query = {"profile": "reverse_profile", "launch_latitude": LAUNCH_LAT, "launch_longitude": LAUNCH_LON + 360,
             "launch_altitude": 10000, "launch_datetime": now.isoformat(), "ascent_rate": 5}  # fmt: skip
    status, _, body = get(server, query)
    assert status == 200, body
    document = json.loads(body)
    assert [s["stage"] for s in document["prediction"]] == ["ascent", "descent"]
    back = document["prediction"][1]["trajectory"]
    assert [when(p) for p in back] == sorted((when(p) for p in back), reverse=True), "back in time"
    estimate = document["launch_estimate"]
    assert estimate == {k: back[-1][k] for k in ("latitude", "longitude", "altitude", "datetime")}
    assert estimate["altitude"] == 0.0 and when(estimate) == now - timedelta(seconds=2000)
    forward = json.loads(get(server, {
        "profile": "standard_profile", "launch_latitude": estimate["latitude"],
        "launch_longitude": estimate["longitude"], "launch_altitude": 0, "launch_datetime": estimate["datetime"],
        "ascent_rate": 5, "burst_altitude": 10000, "descent_rate": 5,
    })[2])  # fmt: skip
    top = forward["prediction"][0]["trajectory"][-1]
    assert when(top) == now
    missed = surface_distance_m(top["latitude"], top["longitude"], LAUNCH_LAT, LAUNCH_LON)
    assert missed < 200, f"rising from the estimate reaches the balloon again ({missed:.0f} m off)"
    assert not math.isclose(estimate["latitude"], LAUNCH_LAT, abs_tol=1e-3), "the wind moved it"
