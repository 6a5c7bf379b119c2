"""The `drs mt|mo|recovery` commands through the real entry point, against the simulated gateway."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest

import console.commands.main as entry
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.sim.rockblock import MoDelivery, Scripted, SimulatedCapsule, SimulatedRockblock, post_mo
from drs_link.store import Store, utc_now
from tests.drs_link.iridium.helpers import IMEI, T0, fix_at, fly

REPO = Path(__file__).resolve().parents[3]
DRS = "import sys, console.commands.main as c; sys.exit(c.main())"


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw-123", imeis=(IMEI,)) as simulated:
        yield simulated


def write_config(tmp_path: Path, mt_url: str = "http://127.0.0.1:9/rockblock/MT") -> Path:
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "alice"\n[data]\ndir = "{tmp_path / "data"}"\n'
        f'[rockblock]\nmt_url = "{mt_url}"\nusername = "ops"\npassword_env = "DRS_TEST_RB"\ntimeout_s = 2.0\n'
        f'[mo]\nlisten_host = "127.0.0.1"\nlisten_port = 0\nrequire_jwt = false\n'  # posts unsigned
        f'[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nimei = "{IMEI}"\nrockblock_serial = 11800\n'
    )
    return config


def run(config: Path, *argv: str) -> int:
    return entry.main(["--config", str(config), *argv])


def test_dry_run_prints_text_and_hex_and_sends_nothing(
    tmp_path: Path, gateway: SimulatedRockblock, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path, gateway.url)
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--sounder", "off", "--dry-run") == 0
    out = capsys.readouterr().out
    assert "text: [INTERVAL=5][SOUNDER_OFF]" in out
    assert "hex:  5B494E54455256414C3D355D5B534F554E4445525F4F46465D (25 bytes)" in out
    assert "dry run: nothing sent" in out
    assert gateway.requests == []


def test_real_send_needs_the_capsule_name_and_then_queues_once(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw-123")
    config = write_config(tmp_path, gateway.url)
    assert run(config, "mt", "send", "DRS1", "--interval", "5") == 1
    assert "drs: error: a real send needs --confirm DRS1" in capsys.readouterr().err
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS2") == 1
    assert "confirmation must name the capsule 'DRS1'" in capsys.readouterr().err
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1") == 0
    out = capsys.readouterr().out
    assert "queued: queued at the gateway as MT 4114652" in out and "pw-123" not in out
    assert len(gateway.requests) == 1
    assert run(config, "mt", "status", "DRS1") == 0
    assert "[INTERVAL=5] queued" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--interval", "0"], "INTERVAL 0 is outside 1-1440"),
        (["--parachute", "25:00"], "not a time of day"),
        (["--parachute", "next"], "no reports from this capsule"),
        ([], "no command given"),
    ],
)
def test_bad_commands_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    config = write_config(tmp_path)
    assert run(config, "mt", "send", "DRS1", *argv, "--dry-run") == 1
    err = capsys.readouterr().err
    assert err.startswith("drs: error:") and message in err and err.count("\n") == 1


def test_parachute_next_uses_the_report_history(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    last = utc_now().replace(microsecond=0) - timedelta(seconds=20)
    for i in range(4):
        fix_time = last - timedelta(minutes=2 * (3 - i))
        reports.add(Delivery(IMEI, i, format_mo(fix_at(fix_time), 8.9, i).hex(), "test", fix_time))
    code = run(config, "mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--dry-run")
    out = capsys.readouterr().out
    assert code == 0, out
    assert "window: [PARACHUTE=" in out and "text: [PARACHUTE=" in out


def test_mo_parse_prints_fields_json_and_rejections(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config = write_config(tmp_path)
    payload = format_mo(fix_at(T0), 8.91, 3, 16366, 11800)
    assert run(config, "mo", "parse", payload.hex()) == 0
    out = capsys.readouterr().out
    assert "fix: 2026-07-01 10:00:07Z 46.500000,6.600000" in out and "forwarding: to RockBLOCK 16366" in out
    assert run(config, "mo", "parse", "5B49", "--json") == 1
    assert (
        '"reason": "not a DRS report: 1 comma-separated field(s), not the firmware\'s 12"'
        in capsys.readouterr().out
    )
    assert run(config, "mo", "parse", "zz") == 1
    assert capsys.readouterr().err == "drs: error: not a DRS report: data is not valid hex\n"


def test_mo_import_then_health_and_recovery_with_exports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    files = []
    for i in range(6):
        moment = T0 + timedelta(minutes=2 * i)
        alt, speed = (3000 - 1000 * i, 5.0) if i < 3 else (500, 0.0)
        path = tmp_path / f"{IMEI}-{i}.bin"
        path.write_bytes(format_mo(fix_at(moment, alt=alt, speed=speed), 8.9, i))
        files.append(str(path))
    assert run(config, "mo", "import", *files, str(tmp_path / "bad.bin")) == 1
    out = capsys.readouterr().out
    assert out.count(": new: stored") == 6 and "bad.bin: error" in out
    assert run(config, "mo", "health", "DRS1") == 0
    assert "DRS1: 6 reports" in capsys.readouterr().out
    gpx, kml = tmp_path / "out.gpx", tmp_path / "out.kml"
    assert run(config, "recovery", "DRS1", "--from", "46.49,6.60", "--gpx", str(gpx), "--kml", str(kml)) == 0
    out = capsys.readouterr().out
    assert out.startswith("DRS1 on ground 46.50000 N 6.60000 E ±0 m (n=3), 1.1 km at 000° from you")
    assert gpx.exists() and kml.exists()
    assert capsys.readouterr().err == ""
    assert run(config, "recovery", "DRS1", "--from", "6.60,46.49") == 0
    err = capsys.readouterr().err
    assert err.startswith("drs: warning: your position is ") and err.count("\n") == 1
    assert "as LON,LAT it would be 1 km away: --from takes LAT,LON" in err


def test_health_status_and_recovery_report_as_json_with_the_numbers_the_text_shows(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw-123")
    config = write_config(tmp_path, gateway.url)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1") == 0
    start = utc_now().replace(microsecond=0) - timedelta(minutes=30)
    fly(SimulatedCapsule(imei=IMEI, rb_source=11800), gateway, reports, start + timedelta(hours=1), 5)
    capsys.readouterr()

    assert run(config, "mo", "health", "DRS1", "--json") == 0
    health = json.loads(capsys.readouterr().out)
    assert (health["capsule"], health["imei"], health["reports"], health["last_vbat"]) == (
        "DRS1",
        IMEI,
        5,
        8.9,
    )
    assert health["last_report_utc"].endswith("Z") and health["findings"] == []

    assert run(config, "mt", "status", "DRS1", "--json") == 0
    [command] = json.loads(capsys.readouterr().out)["commands"]
    assert (command["text"], command["state"], command["operator"]) == (
        "[INTERVAL=5]",
        "effect_confirmed",
        "alice",
    )
    assert command["gateway_id"] is not None and command["delivered_report_id"] is not None

    gpx = tmp_path / "out.gpx"
    assert run(config, "recovery", "DRS1", "--from", "46.49,6.60", "--gpx", str(gpx), "--json") == 0
    captured = capsys.readouterr()
    document = json.loads(captured.out)  # the whole of stdout is one document: "wrote" went to stderr
    assert captured.err == f"wrote {gpx}\n" and gpx.exists()
    assert document["summary"].startswith("DRS1 not landed: last fix 46.50000 N 6.60000 E at 500 m")
    assert document["landing"] is None and document["from"] == {"lat": 46.49, "lon": 6.60}
    assert (document["last_fix"]["lat"], document["last_fix"]["alt_m"]) == (46.5, 500.0)
    assert round(document["distance_m"] / 100) == 11 and round(document["bearing_deg"]) in (0, 360)


def test_mo_serve_stores_gateway_posts_until_interrupted(tmp_path: Path) -> None:
    config = write_config(tmp_path)
    process = subprocess.Popen(
        [sys.executable, "-c", DRS, "--config", str(config), "mo", "serve"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        assert line.startswith("listening on http://127.0.0.1:"), line + (
            process.stderr.read() if process.stderr else ""
        )
        url = line.split()[2]
        delivery = MoDelivery(IMEI, 11800, 41, format_mo(fix_at(T0), 8.9, 1), T0, 46.5, 6.6, 2.0)
        assert post_mo(url, delivery) == 200
        assert post_mo(url, delivery, as_json=True) == 200
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=10)
    assert process.returncode == 0
    assert process.stdout is not None
    assert (
        "MO 300234010753370 #41: 46.50000,6.60000 500 m at 10:00:07Z, battery 8.90 V" in process.stdout.read()
    )
    [stored] = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite")).for_imei(IMEI)
    assert stored.delivery.momsn == 41 and stored.report is not None


def test_mo_bench_measures_a_burst_and_counts_what_went_wrong(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    assert run(config, "mo", "bench", "--posts", "5", "--clients", "3", "--per-client", "4") == 0
    out = capsys.readouterr().out
    assert "one POST at a time over 5: median" in out and "MO parse:" in out
    assert "3 clients at once, 12 POSTs:" in out and "0 failed, 0 lost, 0 stored twice" in out
    for option in ("--posts", "--clients", "--per-client"):
        assert run(config, "mo", "bench", option, "0") == 2
        assert f"{option} must be from 1 to" in capsys.readouterr().err


def test_health_uses_the_interval_the_capsule_was_sent(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw-123")
    config = write_config(tmp_path, gateway.url)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    start = utc_now().replace(microsecond=0) - timedelta(minutes=30)
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1") == 0
    fly(capsule, gateway, reports, start + timedelta(hours=1), 5)
    capsys.readouterr()
    assert run(config, "mo", "health", "DRS1") == 0
    out = capsys.readouterr().out
    assert "DRS1: 5 reports" in out and "spacing" not in out
    assert run(config, "mt", "status", "DRS1") == 0
    assert "[INTERVAL=5] effect_confirmed" in capsys.readouterr().out


def test_recovery_exports_a_predicted_geojson_track_and_refuses_a_bad_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    for i in range(3):
        moment = T0 + timedelta(minutes=2 * i)
        reports.add(
            Delivery(IMEI, i, format_mo(fix_at(moment, alt=9000 - 3000 * i), 8.9, i).hex(), "t", moment)
        )
    predicted = tmp_path / "prediction.geojson"
    predicted.write_text(
        '{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"kind": "path"}, '
        '"geometry": {"type": "LineString", "coordinates": [[6.6, 46.5, 9000.0], [6.7, 46.6, 600.0]]}}]}'
    )
    gpx = tmp_path / "out.gpx"
    assert run(config, "recovery", "DRS1", "--predicted", str(predicted), "--gpx", str(gpx)) == 0
    assert capsys.readouterr().out.startswith("DRS1 not landed: last fix 46.50000 N 6.60000 E at 3000 m")
    assert "DRS1 predicted" in gpx.read_text() and 'lat="46.600000" lon="6.700000"' in gpx.read_text()
    predicted.write_text('{"type": "Point", "coordinates": [6.6, 46.5]}')
    assert run(config, "recovery", "DRS1", "--predicted", str(predicted)) == 1
    assert "no LineString in the GeoJSON" in capsys.readouterr().err


def test_recovery_carries_a_long_predicted_track_to_the_server_and_back_into_the_gpx(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The predicted track goes to the operations server in the request: 20 000 points (about 1 MB of
    JSON) is more than every other request may carry (64 KiB), and the recovery request takes it."""
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    reports.add(Delivery(IMEI, 0, format_mo(fix_at(T0, alt=9000.0), 8.9, 0).hex(), "t", T0))
    points = [[6.6 + i * 1e-5, 46.5 + i * 1e-5, 30000.0 - i] for i in range(20_000)]
    predicted = tmp_path / "prediction.geojson"
    predicted.write_text(json.dumps({"type": "LineString", "coordinates": points}))
    gpx = tmp_path / "out.gpx"
    assert run(config, "recovery", "DRS1", "--predicted", str(predicted), "--gpx", str(gpx)) == 0, (
        capsys.readouterr().err
    )
    assert gpx.read_text().count("<trkpt ") == 20_000 + 1, "every predicted point and the one fix"


def test_recovery_before_any_fix_shows_the_iridium_position(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    no_fix = format_mo(None, 8.95, 4).hex()
    reports.add(Delivery(IMEI, 4, no_fix, "t", T0, T0, 11800, 46.51, 6.62, 4.0))
    assert run(config, "recovery", "DRS1") == 0
    assert capsys.readouterr().out.strip() == (
        "DRS1: no GNSS fix yet; Iridium position 46.51000 N 6.62000 E ±4.0 km (CEP), 10:00Z"
    )


def test_mt_resolve_records_the_portal_outcome_once(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw-123")
    config = write_config(tmp_path, gateway.url)
    gateway.script(Scripted("reset"), Scripted("reset"))
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1") == 1
    assert run(config, "mt", "send", "DRS1", "--sounder", "off", "--confirm", "DRS1") == 1
    assert "delivery_unknown" in capsys.readouterr().out
    assert run(config, "mt", "resolve", "DRS1", "1", "--not-sent", "--note", "not in the portal") == 0
    out = capsys.readouterr().out
    assert out.startswith("MT 1 [INTERVAL=5]: not_sent: resolved by alice") and "not in the portal" in out
    assert run(config, "mt", "resolve", "DRS1", "1", "--queued", "4114700") == 1
    err = capsys.readouterr().err
    assert err == (
        "drs: error: MT 1 is not_sent: only a command in delivery_unknown can be resolved, and only once\n"
    )
    assert run(config, "mt", "resolve", "DRS1", "2", "--queued", "4114700") == 0
    assert "MT 2 [SOUNDER_OFF]: queued: resolved by alice" in capsys.readouterr().out
    assert run(config, "mt", "status", "DRS1") == 0
    out = capsys.readouterr().out
    assert "[INTERVAL=5] not_sent" in out and "[SOUNDER_OFF] queued" in out
    assert len(gateway.requests) == 2


@pytest.mark.parametrize(
    "argv", [["DRS1", "1"], ["DRS1", "1", "--queued", "5", "--not-sent"], ["DRS1", "x", "--not-sent"]]
)
def test_mt_resolve_needs_one_outcome_and_a_command_number(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        run(write_config(tmp_path), "mt", "resolve", *argv)
    assert exit_info.value.code == 2 and "drs mt resolve: error:" in capsys.readouterr().err


def test_mo_export_writes_the_capsule_fixes_as_a_canonical_track(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    for i in range(4):
        moment = T0 + timedelta(minutes=2 * i)
        fix = None if i == 2 else fix_at(moment, alt=3000 - 1000 * i)
        reports.add(Delivery(IMEI, i, format_mo(fix, 8.9, i).hex(), "test", moment))
    out = tmp_path / "drs1.csv"
    assert run(config, "mo", "export", "DRS1", "--out", str(out)) == 0
    assert capsys.readouterr().out == (
        f"wrote {out}: 3 fixes of DRS1; skipped 1 report(s) without a fix and 0 rejected\n"
    )
    assert out.read_text().splitlines() == [
        "time,lat,lon,alt_m,pressure_pa,speed_mps",
        "2026-07-01T10:00:07Z,46.5000000,6.6000000,3000.00,,0.00",
        "2026-07-01T10:02:07Z,46.5000000,6.6000000,2000.00,,0.00",
        "2026-07-01T10:06:07Z,46.5000000,6.6000000,0.00,,0.00",
    ]
    by_imei = tmp_path / "by-imei.csv"
    assert run(config, "mo", "export", "--imei", IMEI, "--out", str(by_imei)) == 0
    assert f"3 fixes of IMEI {IMEI}" in capsys.readouterr().out
    assert by_imei.read_text() == out.read_text()


@pytest.mark.parametrize(
    ("argv", "message", "status"),
    [
        (["--out", "OUT"], "give either a capsule NAME or --imei IMEI, not both or neither", 2),
        (["DRS1", "--imei", IMEI, "--out", "OUT"], "give either a capsule NAME or --imei IMEI", 2),
        (["--imei", "30023401075337", "--out", "OUT"], "--imei '30023401075337': an IMEI is 15 digits", 2),
        (["DRS9", "--out", "OUT"], "DRS9", 1),
        (["DRS1", "--out", "OUT"], "no position fix stored for DRS1 (0 report(s)", 1),
    ],
)
def test_mo_export_bad_requests_are_one_line_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str, status: int
) -> None:
    """A request that cannot mean anything is a usage error (2); one the store cannot answer failed (1)."""
    config = write_config(tmp_path)
    out = tmp_path / "t.csv"
    assert run(config, "mo", "export", *(str(out) if arg == "OUT" else arg for arg in argv)) == status
    err = capsys.readouterr().err
    assert err.startswith("drs: error:") and message in err and err.count("\n") == 1
    assert not out.exists()


def test_mt_resolve_without_an_operator_name_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    config.write_text(config.read_text().replace('name = "alice"', 'name = ""'))
    assert run(config, "mt", "resolve", "DRS1", "1", "--not-sent") == 1
    assert "drs: error: operator.name: set [operator] name" in capsys.readouterr().err


def test_a_retry_over_a_command_of_unknown_delivery_warns_that_it_may_be_sent_twice(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw-123")
    config = write_config(tmp_path, gateway.url)
    gateway.script(Scripted("slow", delay_s=5.0))  # past the config's 2 s timeout: delivery unknown
    argv = ["mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1"]
    assert run(config, *argv) == 1
    assert "delivery_unknown" in capsys.readouterr().out
    assert run(config, *argv) == 0
    out = capsys.readouterr().out
    assert out.count("warning: MT 1 [INTERVAL=5] is delivery_unknown: if the gateway did queue it") == 1
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    requested = [r.detail for r in store.audit() if r.action == "mt.requested"]
    assert requested[-1]["retry_over_unresolved"] == [1]  # type: ignore[index]
