"""The console with ``[chase] udp`` set: its capsules and predictions reach a real UDP listener (chasemapper's
side), and each capsule's latest prediction is kept as KML at its fixed path for ``[kml_overlays]``."""

from __future__ import annotations

import json
import socket
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest

from console.app import ConsoleSetup
from console.chase import started_chase_feed
from console.predictions import PredictionService, ReleaseOrigin
from drs_link.config import Config, parse_config
from drs_link.feeds.chase import chase_kml_path
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.server import InProcessServer
from drs_link.store import Store
from predictor import Terrain
from predictor.environment.demo_weather import demo_weather_files
from tests.console.conftest import SITE, T0

IMEI = "300434060000001"
LANDED_IMEI = "300434060000003"
NOW = T0 + timedelta(minutes=10)


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(120.0)  # the first live prediction may compile the descent kernels
    yield sock
    sock.close()


def console_with_three_capsules(
    tmp_path: Path, port: int, request: pytest.FixtureRequest
) -> tuple[Config, ConsoleSetup, PredictionService]:
    """DRS1 descending (three Iridium fixes), DRS2 on the balloon (release-now only), DRS3 landed; the
    console's operations server in this process, ended with the test."""
    config = parse_config({
        "data": {"dir": str(tmp_path / "data")},
        "chase": {"udp": f"127.0.0.1:{port}"},
        "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9, "imei": IMEI},
                    {"name": "DRS2", "host": "127.0.0.1", "port": 9},
                    {"name": "DRS3", "host": "127.0.0.1", "port": 9, "imei": LANDED_IMEI}],
    })  # fmt: skip
    store = Store.open(config.store_path)
    for minutes, alt in ((4, 25_000.0), (6, 20_000.0), (8, 15_000.0)):
        moment = T0 + timedelta(minutes=minutes)
        fix = GnssFix(moment, SITE[0] + 0.01 * minutes, SITE[1] + 0.02 * minutes, alt, 15.0, 80.0, 1.0, 9)
        ReportStore(store).add(Delivery(IMEI, minutes, format_mo(fix, 8.9, minutes).hex(), "test", moment))
    for step, alt in enumerate((3000.0, 1500.0, 300.0, 300.0, 300.0, 300.0)):
        moment = T0 + timedelta(minutes=step - 2)
        fix = GnssFix(moment, SITE[0] - 0.3, SITE[1], alt, 0.0 if step >= 2 else 10.0, 0.0, 1.0, 9)
        ReportStore(store).add(
            Delivery(LANDED_IMEI, 100 + step, format_mo(fix, 8.9, step).hex(), "test", moment)
        )
    store.close()
    files = demo_weather_files(SITE[0], SITE[1], T0, cache_dir=tmp_path / "wx", hours=6)
    service = PredictionService(lambda: files, Terrain.sea_level, lambda: NOW)
    for name in ("DRS2", "DRS3"):
        service.predict(name, ReleaseOrigin(SITE[0], SITE[1], 31_500.0, "balloon feed"))
    server = InProcessServer(config, clock=lambda: NOW)
    request.addfinalizer(server.stop)
    setup = ConsoleSetup(
        mode="live", capsules=["DRS1", "DRS2", "DRS3"], clock=lambda: NOW, server=server.socket,
        predictions=service,
    )  # fmt: skip
    return config, setup, service


def one_round(
    listener: socket.socket, config: Config, setup: ConsoleSetup, count: int
) -> list[dict[str, Any]]:
    """The ``count`` packets of the feed's first round, and proof there are no more before the next."""
    feed = started_chase_feed(config, setup)
    assert feed is not None
    try:
        packets = [json.loads(listener.recv(32768)) for _ in range(count)]
        listener.settimeout(2.0)  # the rest of the round, well before the next one 10 s later
        with pytest.raises(TimeoutError):
            packets.append(json.loads(listener.recv(32768)))
    finally:
        feed.stop()
    return packets


def test_the_console_sends_its_capsules_and_their_live_and_release_now_landings_but_none_once_landed(
    tmp_path: Path, listener: socket.socket, request: pytest.FixtureRequest
) -> None:
    config, setup, service = console_with_three_capsules(tmp_path, listener.getsockname()[1], request)
    packets = one_round(listener, config, setup, 4)
    by_name = {p["callsign"]: p for p in packets}
    assert set(by_name) == {"DRS1", "DRS1_LAND", "DRS2_LAND", "DRS3"}, "DRS2 has no fix yet, DRS3 has landed"
    assert (
        by_name["DRS1"]["altitude"] == 15_000.0
        and by_name["DRS1"]["time"] == f"{T0 + timedelta(minutes=8):%H:%M:%S}"
    )
    live, release_now = service.live_latest["DRS1"], service.latest["DRS2"]
    for name, prediction, kind in (
        ("DRS1_LAND", live, "live re-prediction"),
        ("DRS2_LAND", release_now, "release now"),
    ):
        packet = by_name[name]
        assert (packet["latitude"], packet["longitude"]) == (prediction.landing.lat, prediction.landing.lon)
        assert kind in packet["comment"] and "DEMO" in packet["comment"]
        kml = chase_kml_path(config.data.dir, name.removesuffix("_LAND"))
        assert ET.parse(kml).getroot().tag.endswith("kml")
    assert live.release.alt_m == 15_000.0, "the live prediction starts from the newest fix"


def test_no_chase_feed_without_its_configuration(tmp_path: Path) -> None:
    config = parse_config(
        {"data": {"dir": str(tmp_path)}, "capsule": [{"name": "DRS1", "host": "127.0.0.1"}]}
    )
    setup = ConsoleSetup(mode="live", capsules=["DRS1"])
    assert started_chase_feed(config, setup) is None


def test_a_kml_that_cannot_be_written_does_not_stop_the_positions(
    tmp_path: Path, listener: socket.socket, request: pytest.FixtureRequest
) -> None:
    config, setup, _ = console_with_three_capsules(tmp_path, listener.getsockname()[1], request)
    chase_kml_path(config.data.dir, "DRS1").parent.write_text("a file where the directory should be")
    packets = one_round(listener, config, setup, 2)
    assert [p["callsign"] for p in packets] == ["DRS1", "DRS3"], "no landing is sent that was not kept"
