"""`drs serve predictor` asked over real HTTP on loopback, the way chasemapper asks Tawhiri.

chasemapper (chasemapper/tawhiri.py) sends launch_longitude in 0…360 and launch_datetime as
``isoformat()``, then reads ``request.dataset`` and every stage's trajectory, folding longitudes above
180 back by 360. These tests do the same with urllib against the server the command line builds, and
hold the landing to what ``drs predict`` says for a release at the server's burst point.
"""

from __future__ import annotations

import csv
import io
import json
import threading
import urllib.error
import urllib.parse
import urllib.request
import xml.etree.ElementTree as ET
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from console.commands.main import build_parser, main
from console.commands.serve import build_server
from predictor.descent.model import DescentRateScale
from predictor.descent.payload import Payload
from predictor.prediction import CalibratedModel, save_model
from predictor.prediction.uncertainty import ErrorModel
from predictor.tawhiri import ApiServer
from tests.predictor.tawhiri.conftest import LAUNCH, LAUNCH_LAT, LAUNCH_LON


def chasemapper_query(**changes: Any) -> dict[str, Any]:
    """The parameters of chasemapper's get_tawhiri_prediction for a flight from the ground."""
    longitude = LAUNCH_LON + 360 if LAUNCH_LON < 0 else LAUNCH_LON
    params = {
        "launch_latitude": LAUNCH_LAT,
        "launch_longitude": longitude,
        "launch_altitude": 0,
        "launch_datetime": LAUNCH.isoformat(),
        "ascent_rate": 5.0,
        "descent_rate": 5.0,
        "burst_altitude": 30000.0,
        "profile": "standard_profile",
    }
    params.update(changes)
    return {k: v for k, v in params.items() if v is not None}


CAPSULE = "drs/DRS1/"
"""The path under /api/v1/ that flies the DRS capsule model."""


def get(api: ApiServer, params: dict[str, Any], path: str = "") -> tuple[int, str, bytes]:
    return get_with_headers(api, params, path)[:3]


def get_with_headers(api: ApiServer, params: dict[str, Any], path: str = "") -> tuple[int, str, bytes, Any]:
    url = f"{api.url}{path}?{urllib.parse.urlencode(params)}"
    try:
        with urllib.request.urlopen(url, timeout=60) as response:
            return response.status, response.headers["Content-Type"], response.read(), response.headers
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read(), exc.headers


def chasemapper_path(document: dict[str, Any]) -> list[tuple[float, float, float, float]]:
    """What chasemapper's parse_tawhiri_data makes of a response: (epoch s, lat, lon −180…180, alt)."""
    datetime.fromisoformat(document["request"]["dataset"])
    path = []
    for stage in document["prediction"]:
        for point in stage["trajectory"]:
            lon = point["longitude"] - 360 if point["longitude"] > 180 else point["longitude"]
            when = datetime.fromisoformat(point["datetime"]).timestamp()
            path.append((when, point["latitude"], lon, point["altitude"]))
    return path


def test_a_capsule_request_gets_tawhiris_shape_with_our_descent_landing_where_drs_predict_does(
    server: ApiServer, weather: list[Path], cache: str, capsys: pytest.CaptureFixture[str]
) -> None:
    status, kind, body = get(server, chasemapper_query(), CAPSULE)
    assert status == 200 and kind == "application/json"
    document = json.loads(body)
    assert set(document) >= {"request", "prediction", "metadata"}
    assert [s["stage"] for s in document["prediction"]] == ["ascent", "descent"]
    ascent, descent = (s["trajectory"] for s in document["prediction"])
    assert ascent[0]["altitude"] == 0.0 and ascent[-1]["altitude"] == 30000.0
    assert ascent[-1] == descent[0], "the descent starts at the burst"
    burst_time = datetime.fromisoformat(ascent[-1]["datetime"])
    assert burst_time == LAUNCH + timedelta(seconds=30000 / 5.0), "a constant 5 m/s ascent"
    path = chasemapper_path(document)
    assert all(-180 <= lon <= 180 for _, _, lon, _ in path)
    assert [t for t, *_ in path] == sorted(t for t, *_ in path)
    assert document["request"]["launch_longitude"] == pytest.approx(LAUNCH_LON + 360)
    assert document["request"]["dataset"] == "2024-05-01T06:00:00Z"

    burst = ascent[-1]
    burst_lon = burst["longitude"] - 360 if burst["longitude"] > 180 else burst["longitude"]
    assert main([
        "predict", "--weather", *map(str, weather), "--cache-dir", cache, "--json",
        "--lat", repr(burst["latitude"]), "--lon", repr(burst_lon), "--alt", "30000", "--time", burst["datetime"],
    ]) == 0  # fmt: skip
    predicted = json.loads(capsys.readouterr().out)["landing"]
    landing = descent[-1]
    assert landing["latitude"] == pytest.approx(predicted["lat"], abs=1e-9)
    assert path[-1][2] == pytest.approx(predicted["lon"], abs=1e-9)
    assert landing["altitude"] == pytest.approx(predicted["alt_m"], abs=1e-6)
    ours = document["drs"]
    assert ours["landing"]["lat"] == landing["latitude"]
    assert ours["ellipse"]["sigma_parallel_km"] > 0 and len(ours["ellipse"]["contours"]) == 3
    assert ours["model"]["label"] and ours["descent_rate_used"] is False and ours["capsule"] == "DRS1"
    assert ours["is_demo"] is True and "drs_demo_weather" in document["warnings"], "demo files must say DEMO"
    assert "DRS capsule model" in document["warnings"]["drs_descent"]["description"]


def test_a_descending_payload_is_predicted_from_where_it_is(server: ApiServer) -> None:
    """chasemapper's descent request: launch at the current altitude, burst one metre above it."""
    status, _, body = get(server, chasemapper_query(launch_altitude=12000, burst_altitude=12001))
    assert status == 200
    descent = json.loads(body)["prediction"][1]["trajectory"]
    assert descent[0]["altitude"] == 12001 and descent[-1]["altitude"] == 0.0


def test_without_a_launch_altitude_the_flight_starts_on_the_ground(server: ApiServer) -> None:
    """Tawhiri looks the launch altitude up in its elevation data; ours is the served terrain (sea level here)."""
    status, _, body = get(server, chasemapper_query(launch_altitude=None))
    document = json.loads(body)
    assert status == 200 and document["request"]["launch_altitude"] == 0.0
    assert document["prediction"][0]["trajectory"][0]["altitude"] == 0.0


def test_csv_is_tawhiris_table_and_kml_holds_the_whole_flight(server: ApiServer) -> None:
    """The SondeHub predictor page reads Tawhiri's CSV: one header line, then
    datetime,latitude,longitude,altitude rows with longitudes in −180…180; it saves it under the
    Content-Disposition name."""
    _, _, body = get(server, chasemapper_query())
    document = json.loads(body)
    points = [p for s in document["prediction"] for p in s["trajectory"]]
    status, kind, text, headers = get_with_headers(server, chasemapper_query(format="csv"))
    assert status == 200 and kind.startswith("text/csv")
    lines = text.decode().splitlines()
    assert lines[0] == "datetime,latitude,longitude,altitude"
    rows = list(csv.DictReader(io.StringIO(text.decode())))
    assert len(rows) == len(points)
    for row, point in zip(rows, points, strict=True):
        assert datetime.fromisoformat(row["datetime"]) == datetime.fromisoformat(point["datetime"])
        assert float(row["latitude"]) == pytest.approx(point["latitude"], abs=6e-6)
        assert -180 <= float(row["longitude"]) <= 180
        assert float(row["longitude"]) % 360 == pytest.approx(point["longitude"] % 360, abs=6e-6)
        assert float(row["altitude"]) == pytest.approx(point["altitude"], abs=0.06)
    disposition = headers["Content-Disposition"]
    assert disposition.startswith("attachment; filename=")
    assert "20240501-060000Z_52.2000_359.6000_standard_profile_2024050106Z" in disposition
    assert disposition.endswith('.csv"') and "DEMO" in disposition and "DEMO" in headers["Warning"]

    status, kind, kml, headers = get_with_headers(server, chasemapper_query(format="kml"))
    assert status == 200 and headers["Content-Disposition"].endswith('.kml"')
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    root = ET.fromstring(kml)
    line = root.find(".//k:LineString/k:coordinates", ns)
    assert line is not None and line.text is not None
    coords = [tuple(map(float, c.split(","))) for c in line.text.split()]
    assert len(coords) == len(points), "the KML holds the whole flight, ascent and descent"
    assert coords[0][2] == 0.0 and max(c[2] for c in coords) == 30000.0 and coords[-1][2] == 0.0
    names = [n.text for n in root.findall(".//k:Placemark/k:name", ns)]
    assert names == ["Flight path", "Launch", "Burst", "Landing"]


def test_by_default_the_descent_is_tawhiris_with_the_requested_sea_level_rate(server: ApiServer) -> None:
    """chasemapper has one URL for the balloon, radiosondes and the capsules: /api/v1/ flies Tawhiri."""
    documents = {
        rate: json.loads(get(server, chasemapper_query(descent_rate=rate))[2]) for rate in (5.0, 10.0)
    }
    for rate, document in documents.items():
        descent = document["prediction"][1]["trajectory"]
        assert "Tawhiri" in document["warnings"]["drs_descent"]["description"]
        assert document["drs"] == {"descent": "tawhiri", "descent_rate_used": True,
                                   "weather": document["drs"]["weather"], "is_demo": True}  # fmt: skip
        last, before = descent[-1], descent[-2]
        seconds = (
            datetime.fromisoformat(last["datetime"]) - datetime.fromisoformat(before["datetime"])
        ).total_seconds()
        near_ground = (before["altitude"] - last["altitude"]) / seconds
        assert near_ground == pytest.approx(rate, rel=0.06), "the requested rate is the rate near sea level"
        assert last["altitude"] == 0.0
    duration = {
        rate: (datetime.fromisoformat(d["prediction"][1]["trajectory"][-1]["datetime"])
               - datetime.fromisoformat(d["prediction"][1]["trajectory"][0]["datetime"])).total_seconds()
        for rate, d in documents.items()
    }  # fmt: skip
    assert duration[5.0] == pytest.approx(2 * duration[10.0], rel=0.01), "a drag descent: time ∝ 1/rate"
    capsule = json.loads(get(server, chasemapper_query(descent_rate=5.0), CAPSULE)[2])
    capsule_too = json.loads(get(server, chasemapper_query(descent_rate=10.0), CAPSULE)[2])
    assert capsule["prediction"][1] == capsule_too["prediction"][1], "the capsule path ignores descent_rate"


def test_post_is_refused_405_in_tawhiris_error_shape(server: ApiServer) -> None:
    request = urllib.request.Request(server.url, data=b"launch_latitude=52", method="POST")
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=10)
    assert refused.value.code == 405 and refused.value.headers["Allow"] == "GET, HEAD"
    document = json.loads(refused.value.read())
    assert set(document) == {"error", "metadata"} and document["error"]["type"] == "MethodNotAllowed"


@pytest.mark.parametrize(
    ("changes", "status", "kind", "says"),
    [
        (
            {"launch_datetime": None},
            400,
            "RequestException",
            "Parameter 'launch_datetime' not provided in request.",
        ),
        ({"ascent_rate": "fast"}, 400, "RequestException", "Unable to parse parameter 'ascent_rate'"),
        ({"burst_altitude": 0}, 400, "RequestException", "Invalid value for parameter 'burst_altitude'"),
        ({"launch_datetime": "2024-05-01T06:00:00"}, 400, "RequestException", "no time zone"),
        ({"dataset": "2020-01-01T00:00:00Z"}, 404, "InvalidDatasetException", "2024-05-01T06:00:00Z"),
        ({"ascent_rate": "5e-324"}, 400, "RequestException", "must be at least 0.05"),
        ({"ascent_rate": "1e-9"}, 400, "RequestException", "must be at least 0.05"),
        ({"ascent_rate": "0.1"}, 400, "RequestException", "would last"),
        ({"ascent_rate": "1e300"}, 400, "RequestException", "at most 50 m/s"),
        ({"descent_rate": "1e-9", "burst_altitude": 60000}, 400, "RequestException", "Invalid value"),
        ({"descent_rate": "1e9"}, 400, "RequestException", "at most 150 m/s"),
        ({"launch_datetime": "2024-06-01T06:00:00Z"}, 500, "PredictionException", "weather covers"),
    ],
)
def test_bad_requests_get_tawhiris_error_shape(
    server: ApiServer, changes: dict[str, Any], status: int, kind: str, says: str
) -> None:
    code, content, body = get(server, chasemapper_query(**changes))
    document = json.loads(body)
    assert (code, content) == (status, "application/json")
    assert set(document) == {"error", "metadata"}
    assert document["error"]["type"] == kind
    assert says in document["error"]["description"]


def test_another_path_is_refused_in_the_same_shape(server: ApiServer) -> None:
    try:
        urllib.request.urlopen(server.url.replace("/api/v1/", "/tawhiri"), timeout=10)
    except urllib.error.HTTPError as exc:
        assert exc.code == 404
        assert "GET /api/v1/" in json.loads(exc.read())["error"]["description"]
    else:
        pytest.fail("an unknown path was answered")


def test_the_command_refuses_a_weather_dir_that_is_not_there(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["serve", "predictor", "--port", "0", "--weather-dir", str(tmp_path / "none")]) != 0
    assert "--weather-dir" in capsys.readouterr().err


def test_the_descent_flies_the_selected_model_as_drs_predict_does(
    server: ApiServer, weather: list[Path], cache: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = CalibratedModel(
        Payload(6.0, 1.36, name="fitted-test", source="fitted"), (DescentRateScale(scale=1.3),),
        ErrorModel(1.2, 5e-4, 0.0, 1.3, name="calibrated"), {"flights": ["test"]},
    )  # fmt: skip
    path = save_model(model, tmp_path / "model.json")
    argv = ["serve", "predictor", "--port", "0", "--weather", *map(str, weather), "--cache-dir", cache,
            "--model", str(path)]  # fmt: skip
    flown = build_server(build_parser("serve").parse_args(argv))
    thread = threading.Thread(target=flown.serve_forever, daemon=True)
    thread.start()
    try:
        document = json.loads(get(flown, chasemapper_query(), CAPSULE)[2])
    finally:
        flown.shutdown()
        flown.server_close()
    default = json.loads(get(server, chasemapper_query(), CAPSULE)[2])
    assert document["prediction"][0] == default["prediction"][0], "the ascent does not depend on the model"
    ours = document["drs"]
    assert ours["model"]["path"] == str(path) and ours["model"]["payload"]["name"] == "fitted-test"
    assert ours["ellipse"]["error_model"]["name"] == "calibrated"
    burst, landing = document["prediction"][1]["trajectory"][0], document["prediction"][1]["trajectory"][-1]
    assert landing != default["prediction"][1]["trajectory"][-1]
    assert main([
        "predict", "--weather", *map(str, weather), "--cache-dir", cache, "--json", "--model", str(path),
        "--lat", repr(burst["latitude"]), "--lon", repr(burst["longitude"] - 360 if burst["longitude"] > 180 else burst["longitude"]),
        "--alt", "30000", "--time", burst["datetime"],
    ]) == 0  # fmt: skip
    predicted = json.loads(capsys.readouterr().out)["landing"]
    assert (landing["latitude"], landing["longitude"] % 360) == pytest.approx(
        (predicted["lat"], predicted["lon"] % 360), abs=1e-9
    )


def test_stalled_connections_are_bounded_and_dropped_and_the_server_still_answers(
    weather: list[Path], cache: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """#24 item 6: 200 stalled connections once held 198 threads for ever."""
    import socket

    from predictor.tawhiri import server as api

    monkeypatch.setattr(api, "REQUEST_READ_S", 1.0)
    argv = ["serve", "predictor", "--port", "0", "--weather", *map(str, weather), "--cache-dir", cache]
    served = build_server(build_parser("serve").parse_args(argv))
    thread = threading.Thread(target=served.serve_forever, daemon=True)
    thread.start()
    threads_before = threading.active_count()
    stalled = [
        socket.create_connection(served.server_address[:2], timeout=5)
        for _ in range(api.MAX_CONNECTIONS + 20)
    ]
    try:
        for sock in stalled[:3]:
            sock.sendall(b"GET /api/v1/?laun")  # drip-fed: half a request line, then nothing
        answers = []
        for sock in stalled:
            try:
                answers.append(sock.recv(4096))
            except TimeoutError:
                answers.append(None)
        assert None not in answers, "every connection is answered or closed within the deadline"
        busy = [a for a in answers if a.startswith(b"HTTP/1.0 503")]
        assert len(busy) >= 20, "the connections beyond the bound get 503 at once"
        assert b"ServiceUnavailable" in busy[0]
        assert threading.active_count() - threads_before <= 2 * api.MAX_CONNECTIONS
        status, _, body = get(served, chasemapper_query())
        assert status == 200 and json.loads(body)["prediction"], (
            "the stalled clients are gone: answered again"
        )
    finally:
        for sock in stalled:
            sock.close()
        served.shutdown()
        served.server_close()


def test_serve_demo_weather_and_predict_demo_weather_see_the_same_air(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """#25 item 12: the two commands once landed 857 m apart for the same release."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    argv = ["serve", "predictor", "--port", "0", "--demo-weather", "--cache-dir", str(tmp_path / "cache")]
    demo = build_server(build_parser("serve").parse_args(argv))
    thread = threading.Thread(target=demo.serve_forever, daemon=True)
    thread.start()
    try:
        query = chasemapper_query(launch_altitude=30000, burst_altitude=30001, launch_latitude=-44.7,
                                  launch_longitude=169.13)  # fmt: skip
        status, _, body = get(demo, query, CAPSULE)
    finally:
        demo.shutdown()
        demo.server_close()
    assert status == 200, body
    descent = json.loads(body)["prediction"][1]["trajectory"]
    burst, landing = descent[0], descent[-1]
    assert main([
        "predict", "--demo-weather", "--cache-dir", str(tmp_path / "cache"), "--json",
        "--lat", repr(burst["latitude"]), "--lon", repr(burst["longitude"] - 360 if burst["longitude"] > 180 else burst["longitude"]),
        "--alt", repr(burst["altitude"]), "--time", burst["datetime"],
    ]) == 0  # fmt: skip
    predicted = json.loads(capsys.readouterr().out)["landing"]
    assert (landing["latitude"], landing["longitude"] % 360) == pytest.approx(
        (predicted["lat"], predicted["lon"] % 360), abs=1e-9
    )


@pytest.mark.parametrize(("method", "status"), [("OPTIONS", 405), ("BREW", 501)])
def test_other_methods_are_refused_in_tawhiris_error_shape(
    server: ApiServer, method: str, status: int
) -> None:
    request = urllib.request.Request(server.url, method=method)
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=10)
    assert refused.value.code == status and refused.value.headers["Content-Type"] == "application/json"
    assert set(json.loads(refused.value.read())) == {"error", "metadata"}
