"""The screens and widgets are clients of the operations server (issue #29): nothing they import through
``drs_link.ops``'s door is a store, a controller, the approval book, the operations layer, a checklist
run, the audit log, a session's record or a login of their own. import-linter sees only the door (the
contract in pyproject.toml); this reads the names."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import console.screens
import console.widgets
import drs_link.ops

FACES = sorted(
    path
    for package in (console.screens, console.widgets)
    for path in Path(package.__file__).parent.glob("*.py")
    if path.name != "__init__.py"
)
BEHIND_THE_SERVER = {
    "arming", "arm_window", "approval", "operator_ops", "ops_state", "links", "release", "iridium_ops",
    "enrolment", "session", "authorize", "checklist", "audit_log", "views",
}  # fmt: skip
"""``drs_link.ops`` modules whose names a client must not hold: the server holds them."""
PLAIN_DATA = {"ACTIONS", "StepKind", "StepState", "IridiumHealthView"}
"""Labels and values of those modules, no store behind them: how an action is named on screen, a step's
kind and state, the Iridium view the server answers with."""


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


@pytest.mark.parametrize("face", FACES, ids=lambda path: f"{path.parent.name}/{path.name}")
def test_a_screen_or_widget_takes_no_controller_store_run_or_login_through_the_door(face: Path) -> None:
    modules = door_map()
    held = [
        f"{name} ({modules[name]})"
        for name in names_through_the_door(face)
        if modules[name].removeprefix(".") in BEHIND_THE_SERVER and name not in PLAIN_DATA
    ]
    assert held == [], f"{face} holds what the server holds: {held}"


def test_the_check_sees_a_controller_taken_through_the_door(tmp_path: Path) -> None:
    """The check is not empty: a screen of before the server (ARM through its own controller) fails it."""
    before = tmp_path / "release.py"
    before.write_text(
        "from drs_link.ops import ArmingController, ApprovalBook, ChecklistRun, AuditLog, StepState\n"
    )
    modules = door_map()
    held = [
        n
        for n in names_through_the_door(before)
        if modules[n].removeprefix(".") in BEHIND_THE_SERVER and n not in PLAIN_DATA
    ]
    assert held == ["ArmingController", "ApprovalBook", "ChecklistRun", "AuditLog"]
