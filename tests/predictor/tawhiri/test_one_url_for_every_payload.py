"""chasemapper's one prediction URL flies a DRS capsule with its model and everything else as Tawhiri (#32 item 1).

The capsule's Iridium fix reaches chasemapper as ``drs chase`` sends it (real UDP); the request is built
the way chasemapper 1.6.0 builds it (``horusmapper.py`` ``run_prediction`` and ``chasemapper/tawhiri.py``
``get_tawhiri_prediction``, re-implemented, GPL: the shape, not the code): the packet's floats as they
came, its ``HH:MM:SS`` completed with today's UTC date, longitude moved to 0…360, ``isoformat()`` time,
``burst_altitude`` one metre above a descending payload, ascent rate at least 0.1, ``urlencode`` of the
parameters (as ``requests`` does). On main every such request flew Tawhiri's law.
"""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from console.commands.main import build_parser, main
from console.commands.serve import build_server
from drs_link.store import Store
from predictor.descent.model import DescentRateScale
from predictor.descent.payload import Payload
from predictor.environment.demo_weather import demo_weather_files
from predictor.prediction import CalibratedModel, save_model
from predictor.prediction.uncertainty import ErrorModel
from predictor.tawhiri import ApiServer
from tests.drs_link.feeds.test_chase import add_fix, write_config
from tests.predictor.tawhiri.test_tawhiri_api import get

NOW = datetime.now(UTC).replace(microsecond=0)
FIX_TIME = NOW - timedelta(seconds=40)
LAT, LON, ALT = 52.31234, -0.41234, 12000.0


@pytest.fixture(scope="module")
def chase(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ApiServer, Path, Path]]:
    """A server with the configuration of a capsule DRS1 (its own model) whose fix is in the store."""
    root = tmp_path_factory.mktemp("chase")
    hour = NOW.replace(minute=0, second=0) - timedelta(hours=1)
    weather = demo_weather_files(52, 0, hour, cache_dir=root / "wx")
    model = CalibratedModel(
        Payload(6.0, 1.36, name="drs1-fitted", source="fitted"), (DescentRateScale(scale=1.2),),
        ErrorModel(1.2, 5e-4, 0.0, 1.3, name="calibrated"), {"flights": ["test"]},
    )  # fmt: skip
    model_path = save_model(model, root / "drs1.json")
    config = write_config(root)
    config.write_text(config.read_text().replace('imei = "', f'model = "{model_path}"\nimei = "', 1))
    store = Store.open(root / "data" / "drs.sqlite")
    add_fix(store, FIX_TIME, LAT, LON, ALT, 20.0, 90.0)
    argv = ["--config", str(config), "serve", "predictor", "--port", "0", "--weather", *map(str, weather),
            "--cache-dir", str(root / "cache")]  # fmt: skip
    api = build_server(build_parser("serve").parse_args(argv))
    thread = threading.Thread(target=api.serve_forever, daemon=True)
    thread.start()
    yield api, config, model_path
    api.shutdown()
    api.server_close()


def chasemapper_hears(config: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    """The DRS1 packet as chasemapper's UDP listener gets it from ``drs chase --once``."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(10)
        assert (
            main(["--config", str(config), "chase", "--once", "--udp", f"127.0.0.1:{sock.getsockname()[1]}"])
            == 0
        )
        capsys.readouterr()
        while True:
            packet = json.loads(sock.recv(32768))
            if packet["callsign"] == "DRS1":
                return packet


def telemetry_time(hhmmss: str, now: datetime) -> datetime:
    """chasemapper's ``fix_datetime``: today's UTC date, a day back or on across midnight."""
    moment = datetime.strptime(hhmmss, "%H:%M:%S").replace(
        year=now.year, month=now.month, day=now.day, tzinfo=UTC
    )
    if moment.hour == 23 and now.hour == 0:
        moment -= timedelta(days=1)
    elif moment.hour == 0 and now.hour == 23:
        moment += timedelta(days=1)
    return moment


def chasemapper_request(
    lat: float, lon: float, alt: float, when: datetime, landing_rate: float
) -> dict[str, Any]:
    """The parameters chasemapper sends for a descending payload (``run_prediction`` → ``get_tawhiri_prediction``)."""
    return {
        "launch_latitude": lat,
        "launch_longitude": lon + 360 if lon < 0 else lon,
        "launch_altitude": alt,
        "launch_datetime": when.isoformat(),
        "ascent_rate": 0.1,  # a descending payload's ascent rate, raised to chasemapper's minimum
        "descent_rate": landing_rate,
        "burst_altitude": alt + 1,
        "profile": "standard_profile",
    }


def landing(document: dict[str, Any]) -> tuple[float, float]:
    point = document["prediction"][-1]["trajectory"][-1]
    return point["latitude"], point["longitude"]


def test_a_capsule_heard_by_chasemapper_is_flown_with_its_model_at_the_one_url(
    chase: tuple[ApiServer, Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    api, config, model_path = chase
    packet = chasemapper_hears(config, capsys)
    when = telemetry_time(str(packet["time"]), datetime.now(UTC))
    params = chasemapper_request(float(packet["latitude"]), float(packet["longitude"]), float(packet["altitude"]),
                                 when, 6.0)  # fmt: skip
    status, _, body = get(api, params)
    assert status == 200, body
    document = json.loads(body)
    said = document["warnings"]["drs_descent"]["description"]
    assert "DRS1" in said and "position report" in said and "descent_rate is not used" in said
    ours = document["drs"]
    assert ours["descent"] == "capsule" and ours["capsule"] == "DRS1"
    assert ours["model"]["path"] == str(model_path) and ours["model"]["payload"]["name"] == "drs1-fitted"
    assert ours["position_report"]["time"] == FIX_TIME.isoformat().replace("+00:00", "Z")
    capsule_path = json.loads(get(api, params, "drs/DRS1/")[2])
    assert landing(document) == landing(capsule_path), "the same model as the capsule's own path"
    tawhiri_law = json.loads(
        get(api, {**params, "launch_altitude": ALT + 200, "burst_altitude": ALT + 201})[2]
    )
    assert tawhiri_law["drs"]["descent"] == "tawhiri"
    assert landing(tawhiri_law) != landing(document)


@pytest.mark.parametrize(
    ("what", "lat", "lon", "alt", "seconds"),
    [
        ("a radiosonde 10 km away", LAT + 0.09, LON, ALT, 0),
        ("a payload 100 m above the capsule's fix", LAT, LON, ALT + 100, 0),
        ("a payload 60 m across from it", LAT + 0.00054, LON, ALT, 0),
        ("a payload there 5 s later", LAT, LON, ALT, 5),
    ],
)
def test_every_other_payload_is_flown_with_tawhiris_law(
    chase: tuple[ApiServer, Path, Path], what: str, lat: float, lon: float, alt: float, seconds: int
) -> None:
    api, _, _ = chase
    params = chasemapper_request(lat, lon, alt, FIX_TIME + timedelta(seconds=seconds), 6.0)
    document = json.loads(get(api, params)[2])
    assert document["drs"]["descent"] == "tawhiri", what
    assert "Tawhiri's" in document["warnings"]["drs_descent"]["description"]


def test_a_request_from_the_fix_before_the_newest_is_still_the_capsule(
    chase: tuple[ApiServer, Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """chasemapper may ask from the fix it has while a newer report has just reached the store."""
    api, config, _ = chase
    packet = chasemapper_hears(config, capsys)
    store = Store.open(Path(str(config).replace("drs.toml", "data")) / "drs.sqlite")
    add_fix(store, FIX_TIME + timedelta(seconds=30), LAT + 0.01, LON, ALT - 900, 20.0, 90.0)
    when = telemetry_time(str(packet["time"]), datetime.now(UTC))
    params = chasemapper_request(float(packet["latitude"]), float(packet["longitude"]), float(packet["altitude"]),
                                 when, 6.0)  # fmt: skip
    assert json.loads(get(api, params)[2])["drs"]["capsule"] == "DRS1"
