"""`drs console` / `drs demo` at the command line, and the telemetry recordings that `--replay` reads."""

from __future__ import annotations

import shlex
import subprocess
import sys
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from console.commands.console import ReplayFeed, replay_command, replay_setup
from drs_link.config import parse_config
from drs_link.errors import ConfigError
from drs_link.ops.telemetry import (
    GnssSample,
    LinkSample,
    TelemetryFormatError,
    TelemetryRecord,
    TelemetryRecorder,
    read_recording,
)

REPO = Path(__file__).resolve().parents[3]
T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def test_drs_demo_without_a_terminal_says_so_in_one_line_and_fails() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "console.commands.main", "demo"], cwd=REPO, stdin=subprocess.DEVNULL,
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1 and "not a terminal" in result.stderr
    assert result.stdout == ""


def test_console_refuses_demo_and_replay_together() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "console.commands.main", "console", "--demo", "--replay", "x.jsonl"], cwd=REPO,
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 2 and "not allowed with argument" in result.stderr


def test_a_recording_round_trips_in_time_order(tmp_path: Path) -> None:
    recorder = TelemetryRecorder(tmp_path / "rec" / "t.jsonl")
    later = TelemetryRecord(T0 + timedelta(seconds=5), "DRS1", LinkSample(up=False))
    first = TelemetryRecord(T0, "DRS1", GnssSample(has_fix=True, sats=9))
    recorder.append(later)
    recorder.append(first)
    recorder.close()
    assert read_recording(tmp_path / "rec" / "t.jsonl") == [first, later]


def test_a_computed_prediction_round_trips_through_a_recording(
    tmp_path: Path, canned_prediction: list[TelemetryRecord]
) -> None:
    recorder = TelemetryRecorder(tmp_path / "t.jsonl")
    for record in canned_prediction:
        recorder.append(record)
    recorder.close()
    assert read_recording(tmp_path / "t.jsonl") == canned_prediction


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("not json", "t.jsonl:2: not JSON"),
        ('{"v": 2, "t": "2026-09-01T12:00:00Z", "capsule": "DRS1", "kind": "link", "data": {}}', "version 2"),
        (
            '{"v": 1, "t": "2026-09-01T12:00:00Z", "capsule": "DRS1", "kind": "weather", "data": {}}',
            "kind 'weather'",
        ),
        ('{"v": 1, "t": "noon", "capsule": "DRS1", "kind": "link", "data": {}}', "t 'noon'"),
        (
            '{"v": 1, "t": "2026-09-01T12:00:00Z", "capsule": "DRS1", "kind": "link", "data": []}',
            "data must be",
        ),
    ],
)
def test_a_bad_line_in_a_recording_is_named_by_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "t.jsonl"
    path.write_text(TelemetryRecord(T0, "DRS1", LinkSample(up=True)).to_json() + "\n" + line + "\n")
    with pytest.raises(TelemetryFormatError, match=message):
        read_recording(path)


def test_an_empty_or_missing_recording_is_refused(tmp_path: Path) -> None:
    (tmp_path / "empty.jsonl").write_text("\n")
    with pytest.raises(TelemetryFormatError, match="no telemetry records"):
        read_recording(tmp_path / "empty.jsonl")
    with pytest.raises(TelemetryFormatError, match="cannot read"):
        read_recording(tmp_path / "missing.jsonl")


def test_replay_hands_out_records_as_its_clock_passes_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    records = [TelemetryRecord(T0 + timedelta(seconds=s), "DRS1", LinkSample(up=True)) for s in (0, 1, 3600)]
    feed = ReplayFeed(records, speed=100.0)
    assert feed.due() == records[:1]
    time.sleep(0.05)
    assert feed.due() == records[1:2]
    with pytest.raises(ConfigError, match="positive"):
        ReplayFeed(records, 0.0)
    path = tmp_path / "t.jsonl"
    path.write_text("".join(r.to_json() + "\n" for r in records))
    monkeypatch.setenv(
        "DRS_PRIVATE_SERVER", "thread"
    )  # the replay's History is read from this account's server
    setup, _ = replay_setup(path, 1.0, parse_config({"data": {"dir": str(tmp_path / "data")}}))
    assert setup.mode == "replay" and setup.capsules == ["DRS1"] and setup.server is not None


def test_a_bad_exclusion_zone_file_is_refused_naming_the_key(tmp_path: Path) -> None:
    from drs_link.ops.ops_state import load_exclusion_zones

    path = tmp_path / "zones.geojson"
    path.write_text('{"type": "FeatureCollection", "features": [{"geometry": {"type": "Point"}}]}')
    with pytest.raises(
        ConfigError, match=r"console.exclusion_zones_file: .* feature 0 \(#0\): geometry type 'Point'"
    ):
        load_exclusion_zones(path)
    path.write_text("{")
    with pytest.raises(ConfigError, match="console.exclusion_zones_file: zone file .*: not JSON"):
        load_exclusion_zones(path)


def test_live_console_without_capsules_says_what_to_do(tmp_path: Path) -> None:
    from console.commands.console import live_setup

    config = parse_config({"data": {"dir": str(tmp_path)}})
    with pytest.raises(ConfigError, match=r"no \[\[capsule\]\].*drs demo"):
        live_setup(config, None, None)


def test_the_demos_replay_line_works_in_a_fresh_shell_without_drs_on_its_path(tmp_path: Path) -> None:
    """The demo's last line said `drs console --replay …`, and `drs` is not on a fresh shell's PATH
    (make demo installs it into .venv): the printed command is run as printed, from another directory."""
    line = replay_command(tmp_path / "telemetry.jsonl")
    words = shlex.split(line)
    assert words[-3:] == ["console", "--replay", str(tmp_path / "telemetry.jsonl")]
    fresh_shell = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    ran = subprocess.run(
        [*words[:-3], "--version"], cwd=tmp_path, env=fresh_shell, capture_output=True, text=True, timeout=60
    )
    assert ran.returncode == 0 and ran.stdout.startswith("drs "), ran.stderr
