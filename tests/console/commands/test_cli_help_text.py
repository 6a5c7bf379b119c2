"""What `drs --help` and each command's `--help` say without importing the modules behind them (#25 item
11: help loads none of the heavy modules, `test_cli_startup.py`) is what those modules define."""

from __future__ import annotations

import argparse

from console.commands.main import COMMAND_HELP, _config_help, build_parser


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
