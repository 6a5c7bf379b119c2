"""Hostile model files are refused before they are parsed, or by the one schema every command reads them
with (issue #31 item 2). On main: deep nesting, a 5,000-digit integer, /dev/zero and /dev/urandom were
tracebacks, and ``"scale": []`` passed `drs model show` and crashed `drs predict --model`."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from console.commands.main import main

REPO = Path(__file__).resolve().parents[3]
COMMITTED = REPO / "docs/planning/superbit-2018-2019-model.json"
TRACK = REPO / "../shared/data/tracks/pyballoon_superbit/18-10-28.csv"


def _edited(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _mutants(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    """name → (file, what the one-line refusal says)."""
    good = json.loads(COMMITTED.read_text())
    empty_scale = json.loads(COMMITTED.read_text())
    empty_scale["terms"][0]["parameters"]["scale"] = []
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    deep = '{"kind": "drs-calibrated-model", "schema": 3, "provenance": ' + "[" * 50_000 + "]" * 50_000 + "}"
    big = json.dumps({**good, "provenance": {"padding": "x" * 1_100_000}})
    digits = re.sub(r'"schema": \d+', '"schema": ' + "9" * 5000, COMMITTED.read_text())
    assert digits != COMMITTED.read_text(), "the mutant must change the file"
    return {
        "deep-nesting": (_edited(tmp_path, "deep.json", deep), "nests 50001 levels deep"),
        "5000-digits": (_edited(tmp_path, "digits.json", digits), "holds a number of 5,000 characters"),
        "nan": (
            _edited(tmp_path, "nan.json", json.dumps(good).replace("1.608", "NaN")),
            "payload.mass_kg: must be a finite number, got nan",
        ),
        "dev-zero": (Path("/dev/zero"), "is not a regular file"),
        "dev-urandom": (Path("/dev/urandom"), "is not a regular file"),
        "fifo": (fifo, "is not a regular file"),
        "directory": (tmp_path, "is not a regular file"),
        "over-size": (_edited(tmp_path, "big.json", big), "is over 1,000,000 bytes"),
        "scale-empty-list": (
            _edited(tmp_path, "scale.json", json.dumps(empty_scale)),
            "terms[0].parameters.scale: must be a finite number, got []",
        ),
    }


COMMANDS = {
    "model show": ["model", "show", "{}"],
    "predict": ["predict", "--demo-weather", "--lat", "46", "--lon", "7", "--alt", "20000",
                "--time", "2026-07-01T09:00Z", "--model", "{}"],
    "plan": ["plan", "--weather", "/nonexistent.grib2", "--lat", "46", "--lon", "7", "--alt", "20000",
             "--from", "2026-07-01T09:00Z", "--model", "{}"],
    "live": ["live", "--track", str(TRACK), "--ascent-winds", "--model", "{}"],
}  # fmt: skip


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_hostile_model_file_is_one_line_from_every_command(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    wrong = {}
    for name, (path, says) in _mutants(tmp_path).items():
        argv = [str(path) if word == "{}" else word for word in COMMANDS[command]]
        status = main(argv)
        err = capsys.readouterr().err.strip()
        if (
            status != 1
            or "\n" in err
            or not err.startswith(f"drs: error: model file {path}")
            or says not in err
        ):
            wrong[name] = (status, err[-300:])
    assert wrong == {}


def test_the_committed_model_still_loads_everywhere(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "show", str(COMMITTED)]) == 0
    assert "superbit-test" in capsys.readouterr().out
