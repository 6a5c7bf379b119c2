"""The `drs` command: one entry point whose subcommands live next to the code they drive.

Each command module has ``register(subparsers)``; every subcommand sets ``func(args) -> int``.
Errors meant for an operator are raised as the packages' own error types and printed here as one
line with a non-zero exit, never as a traceback.

Only the module of the command being run is imported: ``drs predict`` never loads the SSH stack
or Textual, and a command module keeps its heavy imports (numba, xarray, eccodes, …) inside the
functions that need them, so ``drs --help`` and every ``drs X --help`` answer at once.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from drs_link.errors import LinkError
from predictor.errors import PredictorError

COMMAND_MODULES: dict[str, str] = {
    "predict": "predictor.cli",
    "weather": "predictor.weather_cli",
    "tracks": "predictor.calibration.cli",
    "plan": "predictor.plan_cli",
    "live": "predictor.plan_cli",
    "calibrate": "predictor.calibration.calibrate_cli",
    "model": "predictor.model_cli",
    "capsule": "drs_link.cli",
    "sync": "drs_link.cli",
    "mt": "drs_link.iridium.cli",
    "mo": "drs_link.iridium.cli",
    "recovery": "drs_link.iridium.cli",
    "balloon": "drs_link.balloon_cli",
    "serve": "predictor.serve_cli",
    "console": "console.console_cli",
    "demo": "console.console_cli",
}
"""Each `drs` command and the module that registers it (a module may register several)."""

OPERATOR_ERRORS = (PredictorError, LinkError)


def _command_in(argv: Sequence[str]) -> str | None:
    """The command word of ``argv`` (the first word that is not an option or ``--config``'s value)."""
    words = iter(argv)
    for word in words:
        if word == "--config":
            next(words, None)
        elif not word.startswith("-"):
            return word
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser with ``command``'s module registered, or every module when no known command is given
    (``drs --help`` lists them all; a mistyped command gets argparse's list of choices)."""
    parser = argparse.ArgumentParser(
        prog="drs",
        description="SuperBIT DRS operations: predict landings, talk to capsules, track descents.",
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        default=None,
        help="configuration TOML (default: ~/.config/drs/drs.toml)",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    if command in COMMAND_MODULES:
        modules = [COMMAND_MODULES[command]]
    else:
        modules = list(dict.fromkeys(COMMAND_MODULES.values()))
    for module_name in modules:
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser(_command_in(argv)).parse_args(argv)
        return int(args.func(args) or 0)
    except OPERATOR_ERRORS as exc:
        print(f"drs: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("drs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # `drs … | head` closed the pipe: the reader has what it wanted. Point stdout at /dev/null so the
        # interpreter's final flush does not raise again, and end quietly as other Unix tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141

if __name__ == "__main__":
    sys.exit(main())
