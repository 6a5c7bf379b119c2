"""The `drs` command: one entry point whose subcommands live next to the code they drive.

Each package contributes a module with ``register(subparsers)``; every subcommand sets
``func(args) -> int``. Errors meant for an operator are raised as the packages' own error
types and printed here as one line with a non-zero exit, never as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from drs_link.errors import LinkError
from predictor.errors import PredictorError

COMMAND_MODULES: tuple[str, ...] = (
    "predictor.cli",
    "predictor.weather_cli",
    "predictor.calibration.cli",
    "predictor.plan_cli",
    "predictor.calibration.calibrate_cli",
    "drs_link.cli",
    "drs_link.iridium.cli",
    "drs_link.balloon_cli",
    "console.console_cli",
)

OPERATOR_ERRORS = (PredictorError, LinkError)


def build_parser() -> argparse.ArgumentParser:
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
    for module_name in COMMAND_MODULES:
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except OPERATOR_ERRORS as exc:
        print(f"drs: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("drs: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
