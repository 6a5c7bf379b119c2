"""``-`` reads standard input for every option that reads a file, ``--weather -`` and ``--model -`` included,
with a size limit and the same checks as a file (issue #32 item 3: on main they said "file - does not
exist" while `drs weather info -` read the same bytes)."""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from console.commands import argparser
from console.commands.main import build_parser

REPO = Path(__file__).resolve().parents[3]
MODEL = REPO / "docs/planning/superbit-2018-2019-model.json"
GRIB_BASE = REPO / "tests/predictor/environment/grib_mutants/base.grib2"

DASHES = [
    (["predict", "--weather", "-"], "weather"),
    (["predict", "--model", "-"], "model"),
    (["plan", "--weather", "-"], "weather"),
    (["plan", "--model", "-"], "model"),
    (["live", "--weather", "-"], "weather"),
    (["live", "--model", "-"], "model"),
    (["live", "evaluate", "-"], "tracks"),
    (["calibrate", "--tracks", "x.csv", "--weather", "-"], "weather"),
    (["calibrate", "vertical", "--tracks", "x.csv", "--model", "-"], "model"),
    (["serve", "predictor", "--weather", "-"], "weather"),
    (["serve", "predictor", "--demo-weather", "--model", "-"], "model"),
    (["model", "show", "-"], "path"),
    (["tracks", "bench", "-"], "files"),
]
"""Every file-reading option of issue #25's list was already covered; these are the rest."""

NOT_STDIN = {
    ("drs", "--config"): "the configuration's relative paths are resolved against its own folder",
    ("mo import", "files"): "the SBD attachment's name carries the IMEI and MOMSN",
    ("console", "--replay"): "the full-screen console needs standard input for the keyboard",
    ("live", "--save-model"): "an output",
    ("calibrate", "--save-model"): "an output",
}
"""File options that keep a path: what a spooled copy would lose."""


@pytest.mark.parametrize(("argv", "attribute"), DASHES, ids=[" ".join(a) for a, _ in DASHES])
def test_a_dash_reads_standard_input_into_a_file_the_reader_opens(
    argv: list[str], attribute: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = MODEL.read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    value = getattr(build_parser(argv[0]).parse_args(argv), attribute)
    path = Path(value[0] if isinstance(value, list) else value)
    assert path.read_bytes() == data and path.suffix == ".json"


def _input_actions() -> list[tuple[str, str]]:
    """(command path, option) of every argument whose metavar says it names an input file."""
    found = []

    def walk(parser: argparse.ArgumentParser, where: str) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, f"{where} {name}".strip())
            elif action.metavar in ("FILE", "PATH", "TRACK") or (
                action.dest == "files" and not action.option_strings
            ):
                found.append(
                    (where or "drs", action.option_strings[-1] if action.option_strings else action.dest)
                )

    walk(build_parser(every_module=True), "")
    return found


def test_every_input_file_option_takes_a_dash_or_says_why_not(monkeypatch: pytest.MonkeyPatch) -> None:
    refused = []
    for where, option in _input_actions():
        if (where, option) in NOT_STDIN:
            continue
        monkeypatch.setattr(argparser, "_stdin_taken", [])
        monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"x")))
        parser = build_parser(every_module=True)
        for word in where.split()[:]:
            action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            parser = action.choices[word]
        action = next(a for a in parser._actions if (a.option_strings[-1:] or [a.dest]) == [option])
        value = action.type("-") if action.type is not None else "-"
        if not Path(str(value)).is_file():
            refused.append((where, option))
    assert refused == []
    assert len(_input_actions()) >= 15


def drs(*argv: str, stdin: bytes, tmp_path: Path) -> subprocess.CompletedProcess[bytes]:
    env = {**os.environ, "HOME": str(tmp_path), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    return subprocess.run(
        [sys.executable, "-m", "console.commands.main", *argv], cwd=REPO, capture_output=True, input=stdin,
        timeout=180, env=env,
    )  # fmt: skip


RELEASE = ("--lat", "46", "--lon", "7", "--alt", "10000", "--time", "2026-07-01T09:00Z", "--json")


def test_predict_reads_weather_and_model_from_standard_input_as_from_files(tmp_path: Path) -> None:
    by_file = drs("predict", "--weather", str(GRIB_BASE), *RELEASE, stdin=b"", tmp_path=tmp_path)
    by_pipe = drs("predict", "--weather", "-", *RELEASE, stdin=GRIB_BASE.read_bytes(), tmp_path=tmp_path)
    assert by_file.returncode == by_pipe.returncode == 0, by_pipe.stderr
    assert json.loads(by_pipe.stdout)["landing"] == json.loads(by_file.stdout)["landing"]
    model = drs("predict", "--weather", str(GRIB_BASE), *RELEASE, "--model", "-", stdin=MODEL.read_bytes(),
                tmp_path=tmp_path)  # fmt: skip
    assert model.returncode == 0, model.stderr


def test_a_bad_model_on_standard_input_is_refused_as_from_a_file(tmp_path: Path) -> None:
    bad = json.loads(MODEL.read_text())
    bad["terms"][0]["parameters"]["scale"] = []
    done = drs("model", "show", "-", stdin=json.dumps(bad).encode(), tmp_path=tmp_path)
    assert done.returncode == 1
    assert b"terms[0].parameters.scale: must be a finite number, got []" in done.stderr
    assert len(done.stderr.splitlines()) == 1


def test_standard_input_over_the_limit_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(argparser, "MAX_STDIN_BYTES", 1000)
    monkeypatch.setattr(argparser, "_stdin_taken", [])
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"G" * 5000)))
    with pytest.raises(argparse.ArgumentTypeError, match="standard input is over 1,000 bytes"):
        argparser.input_file("--weather")("-")
