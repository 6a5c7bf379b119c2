"""The commanding screens are clients of the operations server (issue #29): nothing they import through
``drs_link.ops``'s door is a store, a controller, the approval book, the operations layer or a login of
their own. import-linter sees only the door (the contract in pyproject.toml); this reads the names."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import console.screens
import drs_link.ops

SCREENS = ("release", "approvals", "commanding")
BEHIND_THE_SERVER = {"arming", "arm_window", "approval", "operations", "session", "authorize"}
"""``drs_link.ops`` modules whose names a client must not hold: the server holds them."""
ALLOWED_FROM_APPROVAL = {"ACTIONS"}
"""A label table of ``approval``, plain data: how an action is named on screen."""


def names_through_the_door(path: Path) -> list[str]:
    return [
        alias.name
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ImportFrom) and node.module == "drs_link.ops"
        for alias in node.names
    ]


def door_map() -> dict[str, str]:
    """Each name the door opens, with its module, as the door's own ``lazy_door`` table lists it."""
    tree = ast.parse(Path(drs_link.ops.__file__).read_text())
    call = next(
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "lazy_door"
    )
    assert isinstance(call.args[1], ast.Dict)
    return {
        ast.literal_eval(k): ast.literal_eval(v)
        for k, v in zip(call.args[1].keys, call.args[1].values, strict=True)
    }


@pytest.mark.parametrize("screen", SCREENS)
def test_a_commanding_screen_takes_no_controller_store_or_login_through_the_door(screen: str) -> None:
    path = Path(console.screens.__file__).parent / f"{screen}.py"
    modules = door_map()
    held = [
        f"{name} ({modules[name]})"
        for name in names_through_the_door(path)
        if modules[name].removeprefix(".") in BEHIND_THE_SERVER and name not in ALLOWED_FROM_APPROVAL
    ]
    assert held == [], f"console/screens/{screen}.py holds what the server holds: {held}"


def test_the_check_sees_a_controller_taken_through_the_door(tmp_path: Path) -> None:
    """The check is not empty: a screen of before the server (ARM through its own controller) fails it."""
    before = tmp_path / "release.py"
    before.write_text("from drs_link.ops import ArmingController, ApprovalBook, Verdict\n")
    modules = door_map()
    held = [n for n in names_through_the_door(before) if modules[n].removeprefix(".") in BEHIND_THE_SERVER]
    assert held == ["ArmingController", "ApprovalBook"]
