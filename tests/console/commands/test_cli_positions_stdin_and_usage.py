"""Command-line conventions of issue #25: southern and western positions written naturally, ``-`` for
standard input wherever a file is read, and exit status 2 for every command-line mistake."""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest

from console.commands.argparser import latitude, longitude, position_or_gpsd
from console.commands.main import build_parser, main
from drs_link.iridium.firmware import GnssFix, format_mo

REPO = Path(__file__).resolve().parents[3]
IMEI = "300234010753370"

# (argv, the parsed attribute, its value): each position option, once south, once west.
POSITIONS = [
    (["recovery", "DRS1", "--from", "-44.7,169.1"], "origin", "-44.7,169.1"),
    (["recovery", "DRS1", "--from", "51.5,-0.12"], "origin", "51.5,-0.12"),
    (["recovery", "DRS1", "--from", "-33.9,-70.6"], "origin", "-33.9,-70.6"),
    (["recovery", "DRS1", "--chase", "-44.7,169.1"], "chase", "-44.7,169.1"),
    (["recovery", "DRS1", "--chase", "51.5,-0.12"], "chase", "51.5,-0.12"),
    (["predict", "--lat", "-44.7", "--lon", "169.1"], "lat", -44.7),
    (["predict", "--lat", "51.5", "--lon", "-120.25"], "lon", -120.25),
    (["plan", "--lat", "-77.8", "--lon", "166.7"], "lat", -77.8),
    (["plan", "--lat", "34.5", "--lon", "-104.2"], "lon", -104.2),
    (["weather", "fetch", "--time", "now", "--lat", "-44.7", "--lon", "169.1"], "lat", -44.7),
    (["weather", "fetch", "--time", "now", "--lat", "51.5", "--lon", "-0.5"], "lon", -0.5),
]
POSITION_TYPES = (latitude, longitude, position_or_gpsd)


def drs(
    *argv: str, stdin: str | bytes = b"", env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[bytes]:
    data = stdin.encode() if isinstance(stdin, str) else stdin
    return subprocess.run(
        [sys.executable, "-m", "console.commands.main", *argv], cwd=REPO, capture_output=True, input=data,
        timeout=120, env={**os.environ, **(env or {})},
    )  # fmt: skip


@pytest.mark.parametrize(("argv", "attribute", "value"), POSITIONS)
def test_every_position_option_takes_southern_and_western_values_written_naturally(
    argv: list[str], attribute: str, value: object
) -> None:
    """``--from -44.7,169.1`` was "unrecognized option -44.7,169.1": argparse took it for an option."""
    assert getattr(build_parser(argv[0]).parse_args(argv), attribute) == value


def _position_options() -> set[tuple[str, str]]:
    """Every (command, option) whose value is a position, found in the parsers themselves."""
    found = set()

    def walk(parser: argparse.ArgumentParser, command: str) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, f"{command} {name}".strip())
            elif action.type in POSITION_TYPES:
                found.add((command.split()[0], action.option_strings[-1]))

    walk(build_parser(every_module=True), "")
    return found


def test_the_table_above_covers_every_position_option_with_a_south_and_a_west_example() -> None:
    tested: dict[tuple[str, str], set[str]] = {}
    for argv, _, _ in POSITIONS:
        for option, value in zip(argv, argv[1:], strict=False):
            if option.startswith("--") and value[:1] in "-0123456789":
                kind = "south" if option != "--lon" and value.startswith("-") else ""
                kind = "west" if option == "--lon" and value.startswith("-") else kind
                if option in ("--from", "--chase") and value.split(",")[1].startswith("-"):
                    kind = "west" if not value.startswith("-") else kind
                tested.setdefault((argv[0], option), set()).add(kind)
    options = _position_options()
    assert {("recovery", "--from"), ("predict", "--lat"), ("predict", "--lon")} <= options
    for command, option in options:
        kinds = tested.get((command, option), set())
        lat_or_lon = {"--lat": {"south"}, "--lon": {"west"}}.get(option, {"south", "west"})
        assert lat_or_lon <= kinds, f"{command} {option} lacks a {lat_or_lon - kinds} example"


def _config(tmp_path: Path, chase: str = "") -> Path:
    path = tmp_path / "drs.toml"
    path.write_text(
        f'[data]\ndir = "{tmp_path / "data"}"\n{chase}\n'
        f'[[capsule]]\nname = "DRS1"\nhost = "10.0.0.1"\nimei = "{IMEI}"\n'
    )
    return path


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["predict", "--lat", "91", "--lon", "0"], "argument --lat: 91 is not a latitude"),
        (["predict", "--lat", "0", "--lon", "nan"], "argument --lon: 'nan' is not a longitude"),
        (["plan", "--lat", "-90.5"], "argument --lat: -90.5 is not a latitude"),
        (["plan", "--every-minutes", "0"], "argument --every-minutes: 0 is not a positive number of minutes"),
        (["chase", "--udp", "127.0.0.1:99999", "--once"], "'99999' in '127.0.0.1:99999' is not a UDP port"),
        (["chase", "--once"], "drs chase needs --udp HOST:PORT or [chase] udp"),
        (["weather", "prune"], "say what to prune"),
        (
            ["weather", "prune", "--keep-days", "-1"],
            "argument --keep-days: -1 is not between 0 and 36500 days",
        ),
        (["weather", "prune", "--max-gb", "0"], "argument --max-gb: 0 is not a positive number of gigabytes"),
        (["recovery", "DRS1", "--from", "91,0"], "argument --from: 91 is not a latitude"),
        (["recovery", "DRS1", "--from", "-44.7"], "is not LAT,LON"),
    ],
)
def test_a_command_line_mistake_exits_2_naming_it(
    tmp_path: Path, argv: list[str], says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    full = ["--config", str(_config(tmp_path)), *argv]
    try:
        status = main(full)
    except SystemExit as exc:
        status = exc.code
    assert status == 2
    assert says in capsys.readouterr().err


def test_tracks_summary_reads_standard_input(tmp_path: Path) -> None:
    track = tmp_path / "flight.csv"
    rows = [f"2024-05-01T06:{m:02d}:00Z,52.{m:02d},-0.{m:02d},{30000 - 500 * m}" for m in range(40)]
    track.write_text("time,lat,lon,alt_m\n" + "\n".join(rows) + "\n")
    from_file = drs("tracks", "summary", "--json", str(track))
    from_stdin = drs("tracks", "summary", "--json", "-", stdin=track.read_bytes())
    assert from_file.returncode == from_stdin.returncode == 0, from_stdin.stderr
    by_file, by_stdin = json.loads(from_file.stdout), json.loads(from_stdin.stdout)
    strip = {"file", "path", "name", "source"}

    def content(doc: object) -> object:
        if isinstance(doc, dict):
            return {k: content(v) for k, v in doc.items() if k not in strip}
        if isinstance(doc, list):
            return [content(v) for v in doc]
        return doc

    assert content(by_stdin) == content(by_file)


def test_mo_parse_reads_the_hex_from_standard_input() -> None:
    fix = GnssFix(datetime(2024, 5, 1, 6, 0, tzinfo=UTC), -44.7, 169.1, 1200.0, 3.0, 90.0, 1.0, 9)
    hex_text = format_mo(fix, 8.9, 1).hex()
    given, piped = (
        drs("mo", "parse", "--json", hex_text),
        drs("mo", "parse", "--json", "-", stdin=hex_text + "\n"),
    )
    assert given.returncode == piped.returncode == 0 and given.stdout == piped.stdout
    assert json.loads(piped.stdout)["report"]["fix"]["lat"] == pytest.approx(-44.7, abs=1e-4)


def test_recovery_reads_the_predicted_track_from_standard_input(tmp_path: Path) -> None:
    config = _config(tmp_path)
    predicted = {"type": "Feature", "properties": {}, "geometry": {
        "type": "LineString", "coordinates": [[169.1, -44.7, 3000.0], [169.25, -44.81, 400.0]]}}  # fmt: skip
    gpx = tmp_path / "out.gpx"
    done = drs("--config", str(config), "recovery", "DRS1", "--predicted", "-", "--gpx", str(gpx),
               stdin=json.dumps(predicted))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert 'lat="-44.810000" lon="169.250000"' in gpx.read_text(), (
        "the predicted path from stdin is in the GPX"
    )
    bad = drs("--config", str(config), "recovery", "DRS1", "--predicted", "-", stdin="not json")
    assert bad.returncode == 1 and b"cannot read GeoJSON" in bad.stderr


def test_standard_input_is_read_once() -> None:
    done = drs("plan", "--zones", "-", "--targets", "-", stdin="{}")
    assert done.returncode == 2 and b"standard input is already read for --zones" in done.stderr


@pytest.mark.parametrize(
    ("argv", "attribute"),
    [
        (["live", "--track", "-"], "track"),
        (["calibrate", "--tracks", "-"], "tracks"),
        (["plan", "--zones", "-"], "zones"),
        (["plan", "--targets", "-"], "targets"),
        (["tracks", "summary", "-"], "files"),
        (["recovery", "DRS1", "--predicted", "-"], "predicted"),
        (["weather", "info", "-"], "files"),
    ],
)
def test_every_file_input_reads_standard_input_for_a_dash(
    argv: list[str], attribute: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = b'{"type": "FeatureCollection", "features": []}\n'
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    value = getattr(build_parser(argv[0]).parse_args(argv), attribute)
    path = Path(value[0] if isinstance(value, list) else value)
    assert path.read_bytes() == data and path.suffix == ".json"
