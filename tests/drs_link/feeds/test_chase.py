"""`drs chase`: the capsules reach a real UDP listener as chasemapper would read them.

The listener parses each datagram as chasemapper's UDPListener and udp_listener_summary_callback do
(JSON, ``type`` PAYLOAD_SUMMARY, float latitude/longitude/altitude, ``callsign``, ``time`` HH:MM:SS).
The store holds Iridium reports written by the firmware's own MO format and a kept landing.
"""

from __future__ import annotations

import json
import socket
import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from console.commands.main import main
from drs_link.config import BalloonFeedConfig, load_config
from drs_link.errors import ConfigError
from drs_link.feeds.balloon_feed import BalloonFeed
from drs_link.feeds.chase import (
    LIVE_LANDING_S,
    ChasePoint,
    ChaseSender,
    ChaseStore,
    KeptLanding,
    chase_points,
)
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.store import Store
from tests.ports import free_port

IMEI = "300234010753370"
NOW = datetime.now(UTC).replace(microsecond=0)


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    """chasemapper's side: a UDP socket on loopback."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(5.0)
    yield sock
    sock.close()


def received(sock: socket.socket, count: int) -> list[dict[str, object]]:
    packets = []
    for _ in range(count):
        packet = json.loads(sock.recv(32768).decode())
        assert packet["type"] == "PAYLOAD_SUMMARY"
        float(packet["latitude"]), float(packet["longitude"]), float(packet["altitude"])
        datetime.strptime(str(packet["time"]), "%H:%M:%S")
        packets.append(packet)
    sock.settimeout(0.3)
    with pytest.raises(TimeoutError):
        sock.recv(32768)
    return packets


def write_config(tmp_path: Path, chase: str = "") -> Path:
    path = tmp_path / "drs.toml"
    path.write_text(
        f'[data]\ndir = "{tmp_path / "data"}"\n{chase}\n'
        f'[[capsule]]\nname = "DRS1"\nhost = "10.0.0.1"\nimei = "{IMEI}"\n'
        '[[capsule]]\nname = "DRS2"\nhost = "10.0.0.2"\n'
    )
    return path


def add_fix(
    store: Store, moment: datetime, lat: float, lon: float, alt: float, speed: float, course: float
) -> None:
    payload = format_mo(GnssFix(moment, lat, lon, alt, speed, course, 1.0, 9), 8.9, 1)
    ReportStore(store).add(Delivery(IMEI, int(moment.timestamp()) % 65536, payload.hex(), "test", moment))


def test_drs_chase_once_sends_each_capsule_with_a_fix_and_its_live_landing(
    tmp_path: Path, listener: socket.socket, capsys: pytest.CaptureFixture[str]
) -> None:
    # `drs chase` reads the wall clock: the test's own now, taken when it runs, not when its module was
    # imported (a parallel run collects every file first; 15 min later the landing is no longer live).
    now = datetime.now(UTC).replace(microsecond=0)
    config_path = write_config(tmp_path)
    config = load_config(config_path)
    store = Store.open(config.store_path)
    add_fix(store, now - timedelta(minutes=4), 51.40, -0.60, 9000, 20.0, 80)
    add_fix(store, now - timedelta(minutes=2), 51.41, -0.55, 8000, 12.5, 95)
    ReportStore(store).add(Delivery(IMEI, 7, b"not a DRS report".hex(), "test", now - timedelta(minutes=1)))
    ChaseStore(store).record(KeptLanding(
        "DRS1", now - timedelta(minutes=1), now + timedelta(minutes=20), 51.45, -0.30, 35.0, "live re-prediction", True
    ))  # fmt: skip
    store.close()
    port = listener.getsockname()[1]
    assert main(["--config", str(config_path), "chase", "--udp", f"127.0.0.1:{port}", "--once"]) == 0
    capsule, landing = received(listener, 2)
    assert capsule["callsign"] == "DRS1", "DRS2 has no position and is not sent"
    assert (capsule["latitude"], capsule["longitude"], capsule["altitude"]) == (51.41, -0.55, 8000.0)
    assert capsule["speed"] == pytest.approx(12.5 * 3.6) and capsule["heading"] == 95
    assert capsule["time"] == f"{now - timedelta(minutes=2):%H:%M:%S}"
    assert str(capsule["comment"]).startswith("drs-console")
    assert landing["callsign"] == "DRS1_LAND"
    assert (landing["latitude"], landing["longitude"], landing["altitude"]) == (51.45, -0.30, 35.0)
    assert (landing["speed"], landing["heading"]) == (-1, -1)
    assert "DEMO" in str(landing["comment"]), "a landing on demo weather says so"
    printed = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert printed == [capsule, landing]


def test_a_landing_predicted_long_ago_is_not_sent(tmp_path: Path) -> None:
    config = load_config(write_config(tmp_path))
    store = Store.open(config.store_path)
    old = NOW - timedelta(seconds=LIVE_LANDING_S + 60)
    ChaseStore(store).record(KeptLanding("DRS1", old, old, 51.45, -0.30, 35.0, "release now", False))
    assert chase_points(config, store, NOW) == []
    assert [p.callsign for p in chase_points(config, store, old)] == ["DRS1_LAND"]
    store.close()


def test_drs_chase_sends_to_the_configured_address_and_says_when_there_is_none(
    tmp_path: Path, listener: socket.socket, capsys: pytest.CaptureFixture[str]
) -> None:
    port = listener.getsockname()[1]
    configured = write_config(tmp_path, f'[chase]\nudp = "127.0.0.1:{port}"\n')
    store = Store.open(load_config(configured).store_path)
    add_fix(store, NOW - timedelta(minutes=1), 51.40, -0.60, 500, 0.0, 0)
    store.close()
    assert main(["--config", str(configured), "chase", "--once"]) == 0
    assert [p["callsign"] for p in received(listener, 1)] == ["DRS1"]
    assert main(["--config", str(write_config(tmp_path)), "chase", "--once"]) != 0
    assert "drs chase needs --udp HOST:PORT or [chase] udp" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("udp", "says"),
    [
        ("55672", "must be HOST:PORT"),
        ("host:0", "not a UDP port"),
        ("host:port", "not a UDP port"),
        ("a b:1", "HOST:PORT"),
    ],
)
def test_a_bad_chase_address_is_refused_naming_the_key(tmp_path: Path, udp: str, says: str) -> None:
    with pytest.raises(ConfigError, match=f"chase.udp: .*{says}"):
        load_config(write_config(tmp_path, f'[chase]\nudp = "{udp}"\n'))


def test_our_own_balloon_feed_on_the_same_port_does_not_take_a_capsule_for_the_balloon() -> None:
    """A chase laptop may run the console's balloon feed on 55672 too: it hears our packets as well."""
    port = free_port(socket.SOCK_DGRAM)
    feed = BalloonFeed(BalloonFeedConfig(kind="udp", port=port), lambda: NOW)
    feed.start()
    sender = ChaseSender(f"127.0.0.1:{port}")
    try:
        sender.send([ChasePoint("DRS1", NOW, 51.4, -0.6, 8000.0, None, None, "drs-console capsule DRS1")])
        balloon = {"type": "PAYLOAD_SUMMARY", "callsign": "HORUS", "latitude": 51.0, "longitude": -1.0,
                   "altitude": 30000, "time": f"{NOW:%H:%M:%S}", "comment": "HorusDemodLib"}  # fmt: skip
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as station:
            station.sendto(json.dumps(balloon).encode(), ("127.0.0.1", port))
        deadline = time.monotonic() + 5.0
        while feed.status().accepted < 1 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        sender.close()
        feed.stop()
    status = feed.status()
    assert (status.accepted, status.ignored, status.rejected) == (1, 1, 0)
    record = feed.latest()
    assert record is not None and record.time == NOW


def test_an_ipv6_target_is_written_back_in_brackets() -> None:
    """#25: `drs chase` printed "::1:55683", which reads as one address."""
    v6 = ChaseSender("[::1]:55683")
    v4 = ChaseSender("127.0.0.1:55683")
    try:
        assert (v6.target, v4.target) == ("[::1]:55683", "127.0.0.1:55683")
    finally:
        v6.close()
        v4.close()
