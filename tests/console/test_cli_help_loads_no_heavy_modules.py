"""`drs --help` and each command's `--help`, in a fresh process, load none of numpy, pyproj, paramiko
and jwt (issue #25 item 11): they made `drs --help` 22× a bare Python start. The speed itself is
measured by `drs predict bench` ("whole process"), not here."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from console.commands.main import COMMAND_HELP, COMMAND_MODULES, _config_help, build_parser

REPO = Path(__file__).resolve().parents[2]
HEAVY = ("numpy", "pyproj", "paramiko", "jwt")
PROBE = """
import json, sys
from console.commands.main import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


def loaded_by(*argv: str) -> list[str]:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(heavy=HEAVY), *argv],
        cwd=REPO, capture_output=True, text=True, timeout=120, check=True,
    )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_drs_help_loads_none_of_numpy_pyproj_paramiko_jwt() -> None:
    assert loaded_by("--help") == []


@pytest.mark.parametrize("command", list(COMMAND_MODULES))
def test_each_command_help_loads_none_of_them(command: str) -> None:
    assert loaded_by(command, "--help") == []


def test_the_command_list_drs_help_shows_is_what_each_module_registers() -> None:
    parser = build_parser(every_module=True)
    [commands] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    registered = {action.dest: action.help for action in commands._choices_actions}
    assert registered == COMMAND_HELP


def test_the_config_help_is_the_configuration_modules_own() -> None:
    from drs_link.config import config_help

    assert _config_help() == config_help()


def test_predicts_error_model_choices_are_the_error_models() -> None:
    from console.commands.predict import ERROR_MODEL_NAMES
    from predictor.prediction import ERROR_MODELS

    assert ERROR_MODEL_NAMES == tuple(sorted(ERROR_MODELS))


def test_capsules_waivable_items_are_the_go_no_go_polls() -> None:
    from console.commands.capsule import WAIVABLE_ITEMS
    from drs_link.ops import WAIVABLE

    assert WAIVABLE_ITEMS == WAIVABLE
