"""`drs` starts fast: help never loads the descent engine, the GRIB library or the data-frame stack."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from console.commands.main import COMMAND_MODULES, _command_in

REPO = Path(__file__).resolve().parents[3]
HEAVY = (
    "numba",
    "xarray",
    "pandas",
    "eccodes",
    "gribapi",
    "matplotlib",
    "textual",
    "numpy",
    "pyproj",
    "paramiko",
    "jwt",
    "aiohttp",
)
"""Each costs 0.1–0.5 s to import; the first seven made `drs --help` take 2.9 s, and the last four
kept it at 22× a bare Python start (#25 item 11)."""

PROBE = """
import json, sys
from console.commands.main import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


def heavy_modules_loaded_by(*argv: str) -> list[str]:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(heavy=HEAVY), *argv],
        cwd=REPO, capture_output=True, text=True, timeout=120, check=True,
    )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_drs_help_imports_none_of_the_heavy_modules() -> None:
    assert heavy_modules_loaded_by("--help") == []


@pytest.mark.parametrize("command", sorted(COMMAND_MODULES))
def test_every_command_help_imports_none_of_the_heavy_modules(command: str) -> None:
    assert heavy_modules_loaded_by(command, "--help") == []


def test_a_command_loads_only_its_own_module() -> None:
    """`drs predict` never imports the SSH stack or the console's modules."""
    probe = (
        "import sys; from console.commands.main import build_parser; build_parser('predict'); "
        "print(sorted(m for m in ('paramiko', 'console.commands.capsule', 'console.commands.console') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize(
    ("argv", "command"),
    [
        (["predict", "--lat", "1"], "predict"),
        (["--config", "x.toml", "mt", "send"], "mt"),
        (["--help"], None),
        (["--config", "predict"], None),
    ],
)
def test_the_command_word_is_found_after_the_global_options(argv: list[str], command: str | None) -> None:
    assert _command_in(argv) == command


def test_a_mistyped_command_lists_the_real_ones() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "console.commands.main", "predcit"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert "invalid choice: 'predcit'" in done.stderr and "predict" in done.stderr


def test_a_closed_pipe_ends_quietly_without_a_traceback(tmp_path: Path) -> None:
    """`drs … | head`: the reader leaves early; no BrokenPipeError reaches the operator."""
    from predictor.descent.payload import PROFILES
    from predictor.prediction import CalibratedModel, save_model

    model = save_model(CalibratedModel(PROFILES["drs"], (), None), tmp_path / "m.json")
    for argv, status in ((["model", "show", str(model)], 141), (["predict", "--help"], 0)):
        probe = (
            "import os, sys; r, w = os.pipe(); os.close(r); os.dup2(w, 1); "
            f"from console.commands.main import main; sys.exit(main({argv!r}))"
        )
        done = subprocess.run(
            [sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, timeout=120
        )
        assert (done.returncode, done.stderr) == (status, ""), argv


def test_ensemble_size_is_bounded_and_the_bound_is_in_help(capsys: pytest.CaptureFixture[str]) -> None:
    from console.commands.main import main

    assert main(["predict", "--demo-weather", "--lat", "1", "--lon", "1", "--alt", "28000",
                 "--time", "2026-01-01T00:00Z", "--members", "10000000"]) == 2  # fmt: skip
    assert "--members 10000000: give 1 to 100,000" in capsys.readouterr().err
