"""The predicted landing reaches chasemapper as a marker it shows but never flies (issue #25 item 1).

``Chasemapper`` below re-implements, line for line in what matters here, chasemapper 1.6.0
(github.com/projecthorus/chasemapper, GPL-3.0, read at commit 8c8622e):

- ``chasemapper/listeners.py`` ``UDPListener.handle_udp_packet``: JSON, ``type`` PAYLOAD_SUMMARY;
- ``horusmapper.py`` ``udp_listener_summary_callback``: float lat/lon/alt, ``callsign``, and ``time``
  through ``fix_datetime`` (HH:MM:SS on today's UTC date);
- ``horusmapper.py`` ``handle_new_payload_position``: a packet not newer than the callsign's last track
  point is dropped; otherwise it is appended and ``server_time`` set to now;
- ``horusmapper.py`` ``run_prediction``: a payload is skipped when its newest accepted packet is more
  than 30 s old or its track holds one point; every other payload is flown (and its landing drawn).

The packets come from ``drs chase`` over a real UDP socket, as the console's live re-predictions move.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from console.commands.main import main
from drs_link.config import load_config
from drs_link.feeds.chase import MARKER_MOVE_M, ChaseStore, KeptLanding, surface_distance_m
from drs_link.store import Store

IMEI = "300234010753370"


def start_now() -> datetime:
    """Two minutes before the test runs: taken when it runs, never at import (collected at a parallel
    run's start, a test could run 20 minutes later and find its "live" landings stale)."""
    return datetime.now(UTC).replace(microsecond=0) - timedelta(minutes=2)


class Chasemapper:
    """The part of chasemapper 1.6.0 that decides what is on its map and what it predicts."""

    def __init__(self) -> None:
        self.tracks: dict[str, list[tuple[datetime, float, float, float]]] = {}
        self.server_time: dict[str, float] = {}

    def handle_udp_packet(self, packet: bytes, now: float) -> None:
        data = json.loads(packet.decode())
        if data["type"] != "PAYLOAD_SUMMARY":
            return
        lat, lon, alt = float(data["latitude"]), float(data["longitude"]), float(data["altitude"])
        hms = datetime.strptime(str(data["time"]), "%H:%M:%S")
        today = datetime.fromtimestamp(now, UTC)
        time_dt = today.replace(hour=hms.hour, minute=hms.minute, second=hms.second, microsecond=0)
        track = self.tracks.setdefault(str(data["callsign"]), [])
        if track and time_dt <= track[-1][0]:
            return  # "Discarding duplicate/out-of-order telemetry"
        track.append((time_dt, lat, lon, alt))
        self.server_time[str(data["callsign"])] = now

    def flown(self, now: float) -> set[str]:
        """The callsigns ``run_prediction`` would request a flight for at ``now``."""
        return {
            call for call, track in self.tracks.items()
            if now - self.server_time[call] <= 30.0 and len(track) > 1
        }  # fmt: skip


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(5.0)
    yield sock
    sock.close()


def test_landings_moving_with_each_re_prediction_are_shown_and_never_flown(
    tmp_path: Path, listener: socket.socket
) -> None:
    config_path = tmp_path / "drs.toml"
    config_path.write_text(
        f'[data]\ndir = "{tmp_path / "data"}"\n[[capsule]]\nname = "DRS1"\nhost = "10.0.0.1"\n'
        f'imei = "{IMEI}"\n'
    )
    config = load_config(config_path)
    port = listener.getsockname()[1]
    mapper = Chasemapper()
    # Twenty minutes of live re-predictions, one a minute, the landing walking east 600 m each time
    # (a 36 km/h jump) with a 300 m north-south jitter: chasemapper heard each round twice.
    start = start_now()
    landings = [(51.45 + 0.0027 * (-1) ** k, -0.30 + 0.0086 * k) for k in range(20)]
    shown: list[tuple[str, float, float]] = []
    for minute, (lat, lon) in enumerate(landings):
        predicted = start + timedelta(minutes=minute)
        store = Store.open(config.store_path)
        ChaseStore(store).record(KeptLanding(
            "DRS1", predicted, predicted + timedelta(minutes=30), lat, lon, 40.0, "live re-prediction", False
        ))  # fmt: skip
        store.close()
        for repeat in range(2):
            now = predicted.timestamp() + 10.0 * repeat
            assert main(["--config", str(config_path), "chase", "--udp", f"127.0.0.1:{port}", "--once"]) == 0
            mapper.handle_udp_packet(listener.recv(32768), now)
            assert mapper.flown(now) == set(), f"minute {minute}: chasemapper would fly {mapper.flown(now)}"
        call, track = max(mapper.tracks.items(), key=lambda item: item[1][-1][0])
        shown.append((call, track[-1][1], track[-1][2]))
        assert surface_distance_m(track[-1][1], track[-1][2], lat, lon) <= MARKER_MOVE_M, (
            "the newest marker is within the stated distance of the newest prediction"
        )
    assert all(len(track) == 1 for track in mapper.tracks.values())
    calls = sorted(mapper.tracks)
    assert calls[0] == "DRS1_LAND" and 4 <= len(calls) <= 8, calls  # 11.4 km walked in 2 km steps


def test_the_old_form_a_moving_landing_under_one_callsign_would_be_flown() -> None:
    """The gate above can fail: the packets sent before this change are flown at the second prediction."""
    mapper = Chasemapper()
    start = start_now()
    now = start.timestamp()
    for minute, lon in enumerate((-0.30, -0.29)):
        moment = start + timedelta(minutes=minute)
        packet = {
            "type": "PAYLOAD_SUMMARY",
            "callsign": "DRS1_LAND",
            "latitude": 51.45,
            "longitude": lon,
            "altitude": 40.0,
            "speed": -1,
            "heading": -1,
            "time": f"{moment:%H:%M:%S}",
            "comment": "",
        }
        mapper.handle_udp_packet(json.dumps(packet).encode(), now + 60 * minute)
    assert mapper.flown(now + 60) == {"DRS1_LAND"}
