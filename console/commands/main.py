"""The `drs` command: one entry point whose subcommands live next to the code they drive.

Each command module has ``register(subparsers)``; every subcommand sets ``func(args) -> int``.
Errors meant for an operator are raised as the packages' own error types and printed here as one
line, never as a traceback. The exit status says which kind of failure it was, so scripts and
systemd can tell a typo from a refusal: 0 done, 1 the command ran and failed or refused
(``EXIT_FAILED``), 2 the command line itself is wrong (``EXIT_USAGE``, argparse's own status).

Only the module of the command being run is imported: ``drs predict`` never loads the SSH stack
or Textual, and a command module keeps its heavy imports (numba, xarray, eccodes, …) inside the
functions that need them, so every ``drs X --help`` answers at once. ``drs --help`` imports no command
module at all: it lists the commands from ``COMMAND_HELP`` (a test holds it to what each module
registers), since importing all eighteen once cost 22× a bare Python start.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence

from console.commands.argparser import DrsArgumentParser
from console.commands.logs import LEVELS, configure_logging, level_from
from drs_link.errors import LinkError
from predictor.errors import PredictorError, UsageError

COMMAND_MODULES: dict[str, str] = {
    "predict": "console.commands.predict",
    "weather": "console.commands.weather",
    "tracks": "console.commands.tracks",
    "plan": "console.commands.plan",
    "live": "console.commands.plan",
    "calibrate": "console.commands.calibrate",
    "model": "console.commands.model",
    "capsule": "console.commands.capsule",
    "sync": "console.commands.sync",
    "mt": "console.commands.iridium",
    "mo": "console.commands.iridium",
    "recovery": "console.commands.recovery",
    "balloon": "console.commands.balloon",
    "approve": "console.commands.approve",
    "setup": "console.commands.setup",
    "chase": "console.commands.chase",
    "serve": "console.commands.serve",
    "server": "console.commands.server",
    "console": "console.commands.console",
    "demo": "console.commands.console",
}
"""Each `drs` command and the module that registers it (a module may register several)."""

COMMAND_HELP: dict[str, str] = {
    "predict": "predict a capsule's landing (or `drs predict bench` to measure speed)",
    "weather": "get, inspect and benchmark GFS weather files",
    "tracks": "measured flight tracks: read, clean, summarise",
    "plan": "sweep release times: landing strip, zone risk, go/no-go (or `drs plan bench`)",
    "live": "re-predict the landing from each fix of a descent track (or `drs live evaluate`)",
    "calibrate": "find the effect the model lacks from measured descents (leave-one-flight-out) and report "
    "the error before and after",
    "model": "calibrated model files written by drs calibrate --save-model",
    "capsule": "talk to a capsule's Pi over SSH: status, power-on, go",
    "sync": "upload a directory to a capsule's storage mount (verified)",
    "mt": "commands to a capsule over Iridium (RockBLOCK MT)",
    "mo": "capsule reports over Iridium (RockBLOCK MO)",
    "recovery": "landing estimate, distance from you, GPX/KML export",
    "balloon": "the balloon's position from a ground-station feed",
    "approve": "list hazardous commands waiting for a second operator, or approve/reject one",
    "setup": "prepare this machine for operations (the team's server)",
    "chase": "send the capsules (and their predicted landings) to chasemapper as Horus UDP",
    "serve": "serve predictions over HTTP (a Tawhiri v1 API)",
    "server": "the operations server: holds the store, the capsule links and the gateway credentials",
    "console": "the operator console (full-screen terminal app)",
    "demo": "the console with everything simulated (= drs console --demo)",
}
"""What ``drs --help`` lists: each command's own ``help``, without importing its module."""

OPERATOR_ERRORS = (PredictorError, LinkError)
EXIT_FAILED = 1
EXIT_USAGE = 2
_OPTIONS_WITH_VALUES = ("--config", "--log-level")


class _VersionAction(argparse.Action):
    """argparse's own version action needs the text when the parser is built: importing importlib.metadata
    and reading the installed distribution's metadata then cost every `drs` run 60 ms, so it is done only
    when asked for."""

    def __init__(self, option_strings: Sequence[str], dest: str, help: str | None = None) -> None:  # noqa: A002
        super().__init__(
            option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, nargs=0, help=help
        )

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        import importlib.metadata

        print(f"drs {importlib.metadata.version('drs-console')}")
        parser.exit()


def _command_in(argv: Sequence[str]) -> str | None:
    """The command word of ``argv`` (the first word that is not an option or a global option's value)."""
    words = iter(argv)
    for word in words:
        if word in _OPTIONS_WITH_VALUES:
            next(words, None)
        elif not word.startswith("-"):
            return word
    return None


def _config_help() -> str:
    """``--config``'s help (``drs_link.config.config_help``'s text, which a test holds it to), without
    importing the configuration module and the link backends it names."""
    import platformdirs

    return (
        f"configuration TOML (default: $DRS_CONFIG, else {platformdirs.user_config_path('drs') / 'drs.toml'})"
    )


def build_parser(command: str | None = None, *, every_module: bool = False) -> argparse.ArgumentParser:
    """The parser with ``command``'s module registered; with no known command, each command as a bare
    name with its help (``drs --help`` lists them; a mistyped command gets argparse's list of choices),
    or, with ``every_module``, every module registered (for tests that walk every option)."""
    parser = DrsArgumentParser(
        prog="drs",
        description="SuperBIT DRS operations: predict landings, talk to capsules, track descents.",
        epilog="exit status: 0 done, 1 the command failed or refused, 2 the command line is wrong",
    )
    parser.add_argument("--version", action=_VersionAction, help="print the installed version and exit")
    parser.add_argument("--config", metavar="FILE", default=None, help=_config_help())
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="log more: -v for info, -vv for debug (to stderr)"
    )
    parser.add_argument(
        "--log-level", choices=LEVELS, type=str.lower, default=None,
        help="log records from this level up (default warning; info for servers)",
    )  # fmt: skip
    parser.set_defaults(log_default=logging.WARNING)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    if command in COMMAND_MODULES:
        modules = [COMMAND_MODULES[command]]
    elif every_module:
        modules = list(dict.fromkeys(COMMAND_MODULES.values()))
    else:
        for name, said in COMMAND_HELP.items():
            subparsers.add_parser(name, help=said)
        return parser
    for module_name in modules:
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser(_command_in(argv)).parse_args(argv)
        configure_logging(level_from(args.log_level, args.verbose, args.log_default))
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"drs: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OPERATOR_ERRORS as exc:
        print(f"drs: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
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
