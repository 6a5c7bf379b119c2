"""Recovery on the 30 real test-flight logs, distances, a fake gpsd on 127.0.0.1, GPX/KML export."""

from __future__ import annotations

import json
import math
import socket
import threading
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from drs_link.errors import LinkError
from drs_link.iridium.recovery import (
    detect_landing,
    distance_bearing,
    parse_position,
    phone_summary,
    read_gpsd_position,
    track_from_reports,
    write_gpx,
    write_kml,
)

from .flight_logs import flight_reports, summary

FLIGHTS = sorted(
    path.name
    for path in (
        Path(__file__).resolve().parents[4] / "shared" / "data" / "tracks" / "pyballoon_superbit"
    ).glob("*.csv")
    if path.name[0].isdigit()
)


def test_all_thirty_flight_logs_are_present() -> None:
    assert len(FLIGHTS) == 30


@pytest.mark.parametrize("flight", FLIGHTS)
def test_landing_estimate_is_the_landing_site_on_every_real_flight(shared_data: Path, flight: str) -> None:
    row = summary(shared_data)[flight]
    reports = flight_reports(shared_data / "tracks" / "pyballoon_superbit" / flight)
    track = track_from_reports(reports)
    landing = detect_landing(track)
    if int(row["rows_after_landing"]) == 0:
        assert landing is None, "a lone last fix must not be called a landing"
        return
    assert landing is not None
    distance, _ = distance_bearing(float(row["land_lat"]), float(row["land_lon"]), landing.lat, landing.lon)
    tolerance = max(100.0, 3 * landing.std_m) if landing.count > 1 else 100.0
    assert distance <= tolerance, (distance, landing)
    landed = datetime.fromisoformat(row["land_utc"] + "+00:00")
    assert abs((landing.landed_at - landed).total_seconds()) <= 15 * 60
    last = track[-1]
    if float(row["last_row_offset_from_landing_km"]) > 10:
        from_last, _ = distance_bearing(last.lat, last.lon, landing.lat, landing.lon)
        assert from_last > 10_000, "the estimate followed the car"
        assert landing.moved_at is not None
        assert "MOVED" in phone_summary("DRS1", landing, last, None)


def test_phone_summary_has_position_sigma_count_distance_and_bearing(shared_data: Path) -> None:
    track = track_from_reports(flight_reports(shared_data / "tracks" / "pyballoon_superbit" / "19-1-1.csv"))
    landing = detect_landing(track)
    assert landing is not None
    text = phone_summary("DRS1", landing, track[-1], (45.37, 8.41))
    assert text.startswith("DRS1 on ground 45.39")
    assert f"(n={landing.count})" in text and " E ±" in text
    distance, bearing = distance_bearing(45.37, 8.41, landing.lat, landing.lon)
    assert f"{distance / 1000:.1f} km at {round(bearing) % 360:03d}° from you" in text


def test_distance_and_bearing_are_geodesic() -> None:
    distance, bearing = distance_bearing(0.0, 0.0, 0.0, 1.0)
    assert distance == pytest.approx(111_319.5, abs=1) and bearing == pytest.approx(90.0)
    assert distance_bearing(10.0, 0.0, 9.0, 0.0)[1] == pytest.approx(180.0)


@pytest.mark.parametrize("text", ["46.5", "46.5,200", "north,east", "95,6", "nan,6"])
def test_typed_positions_are_checked(text: str) -> None:
    with pytest.raises(LinkError, match="LAT,LON"):
        parse_position(text)


def test_typed_position_is_read() -> None:
    assert parse_position("46.52, -6.63") == (46.52, -6.63)


class FakeGpsd:
    """A tiny gpsd speaking its JSON protocol on 127.0.0.1: VERSION, then TPVs after ?WATCH."""

    def __init__(self, reports: list[dict[str, object]]) -> None:
        self.reports = reports
        self.server = socket.create_server(("127.0.0.1", 0))
        self.address = self.server.getsockname()
        self.watch_commands: list[bytes] = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.server.accept()
        with conn:
            conn.sendall(b'{"class":"VERSION","release":"3.25","proto_major":3,"proto_minor":15}\n')
            self.watch_commands.append(conn.recv(1024))
            for report in self.reports:
                conn.sendall(json.dumps(report).encode() + b"\n")
            try:
                conn.recv(1)
            except OSError:
                pass

    def close(self) -> None:
        self.server.close()
        self.thread.join(timeout=5)


@pytest.fixture
def gpsd() -> Iterator[FakeGpsd]:
    fake = FakeGpsd(
        [
            {"class": "DEVICES", "devices": []},
            {"class": "TPV", "mode": 1},
            {"class": "TPV", "mode": 3, "lat": 46.51234, "lon": 6.62345, "alt": 410.0},
        ]
    )
    yield fake
    fake.close()


def test_team_position_comes_from_a_local_gpsd_fix(gpsd: FakeGpsd) -> None:
    assert read_gpsd_position(gpsd.address, timeout_s=3) == (46.51234, 6.62345)
    assert gpsd.watch_commands[0].startswith(b'?WATCH={"enable":true')


def test_gpsd_without_a_fix_or_absent_is_a_clear_error() -> None:
    silent = FakeGpsd([{"class": "TPV", "mode": 1}])
    try:
        with pytest.raises(LinkError, match="no fix"):
            read_gpsd_position(silent.address, timeout_s=0.5)
    finally:
        silent.close()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        free = probe.getsockname()
    with pytest.raises(LinkError, match="no gpsd at 127.0.0.1"):
        read_gpsd_position(free, timeout_s=0.5)


def test_gpx_and_kml_hold_measured_and_predicted_tracks_and_the_landing(
    shared_data: Path, tmp_path: Path
) -> None:
    track = track_from_reports(flight_reports(shared_data / "tracks" / "pyballoon_superbit" / "18-5-6.csv"))
    landing = detect_landing(track)
    predicted = [(46.63, 7.05, 25000.0), (46.60, 6.90, 5000.0), (46.57, 6.79, 700.0)]
    write_gpx(tmp_path / "t.gpx", "DRS1", track, predicted, landing)
    write_kml(tmp_path / "t.kml", "DRS1", track, predicted, landing)
    ns = {"g": "http://www.topografix.com/GPX/1/1"}
    gpx = ET.parse(tmp_path / "t.gpx").getroot()
    tracks = gpx.findall("g:trk", ns)
    assert [t.find("g:name", ns).text for t in tracks] == ["DRS1 measured", "DRS1 predicted"]  # type: ignore[union-attr]
    assert len(tracks[0].findall(".//g:trkpt", ns)) == len(track)
    assert len(tracks[1].findall(".//g:trkpt", ns)) == 3
    assert landing is not None
    wpt = gpx.find("g:wpt", ns)
    assert wpt is not None and math.isclose(float(wpt.get("lat", "0")), landing.lat, abs_tol=1e-6)
    kml = (tmp_path / "t.kml").read_text()
    assert kml.count("<LineString") == 2 and "DRS1 landing" in kml and "<altitudeMode>absolute" in kml


def test_without_any_fix_the_summary_gives_the_iridium_position_and_cep() -> None:
    moment = datetime(2026, 7, 1, 10, 2, tzinfo=UTC)
    text = phone_summary("DRS1", None, None, (46.0, 6.0), (46.5, 6.6, 3000.0, moment))
    assert text.startswith(
        "DRS1: no GNSS fix yet; Iridium position 46.50000 N 6.60000 E ±3.0 km (CEP), 10:02Z"
    )
    assert text.endswith("° from you")
    assert phone_summary("DRS1", None, None, None) == "DRS1: no report with a position yet"


def test_a_prediction_on_demo_weather_is_named_demo_in_both_recovery_files(
    shared_data: Path, tmp_path: Path
) -> None:
    track = track_from_reports(flight_reports(shared_data / "tracks" / "pyballoon_superbit" / "18-5-6.csv"))
    predicted = [(46.63, 7.05, 25000.0), (46.57, 6.79, 700.0)]
    write_gpx(tmp_path / "t.gpx", "DRS1", track, predicted, detect_landing(track), predicted_is_demo=True)
    write_kml(tmp_path / "t.kml", "DRS1", track, predicted, detect_landing(track), predicted_is_demo=True)
    ns = {"g": "http://www.topografix.com/GPX/1/1", "k": "http://www.opengis.net/kml/2.2"}
    gpx = ET.parse(tmp_path / "t.gpx").getroot()
    names = [w.findtext("g:name", namespaces=ns) for w in gpx.findall("g:wpt", ns)]
    assert names == ["DRS1 LAND", "DEMO PRED LAND"]
    kml = ET.parse(tmp_path / "t.kml").getroot()
    assert "DEMO WEATHER" in kml.findtext("k:Document/k:name", namespaces=ns)
    names = [p.findtext("k:name", namespaces=ns) for p in kml.iter(f"{{{ns['k']}}}Placemark")]
    assert [n for n in names if "DEMO" in n] == [
        "DRS1 predicted (DEMO WEATHER, NOT A FORECAST)",
        "DRS1 predicted (DEMO WEATHER, NOT A FORECAST) landing",
    ]
