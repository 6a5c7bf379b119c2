"""Checklists as data: manual ticks with operator and time, live auto steps, command steps by command only."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest

from drs_link.errors import ConfigError, RefusedError
from drs_link.ops.checklist import (
    PROCEDURE_DIR,
    ChecklistRun,
    StepState,
    load_checklist,
    load_checklists,
    parse_checklist,
)
from drs_link.store import Store

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)
DEFAULTS = PROCEDURE_DIR

DOC = {
    "id": "release-day",
    "title": "Release day",
    "step": [
        {"id": "apply-24v", "kind": "manual", "text": "24 V applied"},
        {
            "id": "link",
            "kind": "auto",
            "text": "link up",
            "when": {"fact": "link_up", "op": "==", "value": True},
        },
        {
            "id": "sats",
            "kind": "auto",
            "text": "4+ sats",
            "when": {"fact": "gnss_sats", "op": ">=", "value": 4},
        },
        {"id": "power-on", "kind": "command", "text": "power on", "command": "power-on"},
    ],
}


@pytest.fixture
def run(tmp_path: Path) -> ChecklistRun:
    return ChecklistRun(Store.open(tmp_path / "drs.sqlite"), parse_checklist(DOC, "test"), "DRS1", lambda: T0)


def test_the_default_checklists_load_in_procedure_order() -> None:
    ids = [c.id for c in load_checklists(DEFAULTS)]
    assert ids == ["preflight", "release-day", "descent-recovery", "after-drop"]


def test_a_manual_tick_records_operator_and_time_and_is_audited(run: ChecklistRun) -> None:
    run.tick("apply-24v", "EL")
    status = run.statuses({})[0]
    assert (status.state, status.operator, status.at) == (StepState.DONE, "EL", T0)
    audit = run.store.audit("DRS1")
    assert [(a.operator, a.action, a.result) for a in audit] == [
        ("EL", "checklist.done", "release-day/apply-24v")
    ]


def test_auto_steps_follow_the_telemetry_live(run: ChecklistRun) -> None:
    states = {s.step.id: s.state for s in run.statuses({"link_up": True, "gnss_sats": 3})}
    assert states["link"] is StepState.MET and states["sats"] is StepState.NOT_MET
    states = {s.step.id: s.state for s in run.statuses({"link_up": None, "gnss_sats": 9})}
    assert states["link"] is StepState.NO_DATA and states["sats"] is StepState.MET


def test_auto_and_command_steps_cannot_be_ticked_by_hand(run: ChecklistRun) -> None:
    with pytest.raises(RefusedError, match="follows the telemetry"):
        run.tick("link", "EL")
    with pytest.raises(RefusedError, match="running 'power-on'"):
        run.tick("power-on", "EL")
    run.command_done("power-on", "EL", "relay latched")
    assert run.statuses({})[3].state is StepState.DONE


def test_a_skip_needs_a_reason_and_a_tick_needs_a_name(run: ChecklistRun) -> None:
    with pytest.raises(RefusedError, match="reason"):
        run.skip("apply-24v", "EL", "")
    with pytest.raises(RefusedError, match="operator"):
        run.tick("apply-24v", " ")
    run.skip("apply-24v", "EL", "bench test on USB power")
    assert run.statuses({})[0].note == "bench test on USB power"


def test_progress_survives_a_restart_and_completion_needs_every_step(tmp_path: Path) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    checklist = parse_checklist(DOC, "test")
    first = ChecklistRun(store, checklist, "DRS1", lambda: T0)
    first.tick("apply-24v", "EL")
    first.command_done("power-on", "EL", "ok")
    again = ChecklistRun(Store.open(tmp_path / "drs.sqlite"), checklist, "DRS1", lambda: T0)
    assert not again.complete({"link_up": True, "gnss_sats": 2})
    assert again.complete({"link_up": True, "gnss_sats": 5})


@pytest.mark.parametrize(
    ("step", "message"),
    [
        ({"id": "x", "kind": "auto", "text": "t"}, r"step\[0\].when: an auto step needs a predicate"),
        (
            {"id": "x", "kind": "auto", "text": "t", "when": {"fact": "warp", "op": "==", "value": 1}},
            "unknown fact",
        ),
        ({"id": "x", "kind": "auto", "text": "t", "when": {"fact": "vbat", "op": "=~", "value": 1}}, "'=~'"),
        (
            {"id": "x", "kind": "auto", "text": "t", "when": {"fact": "link_up", "op": "==", "value": 1}},
            "bool",
        ),
        ({"id": "x", "kind": "command", "text": "t", "command": "self-destruct"}, "command: 'self-destruct'"),
        ({"id": "x", "kind": "sometimes", "text": "t"}, "kind: 'sometimes'"),
        ({"id": "x", "kind": "manual", "text": "t", "colour": "red"}, r"step\[0\].colour: unknown key"),
        (
            {"id": "x", "kind": "manual", "text": "t", "when": {"fact": "landed", "op": "==", "value": True}},
            "only auto and command steps have a predicate",
        ),
    ],
)
def test_a_bad_step_is_refused_with_the_file_and_key(step: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_checklist({"id": "c", "title": "C", "step": [step]}, "mine.toml")


def test_a_broken_toml_file_names_itself(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("id = 'x\n")
    with pytest.raises(ConfigError, match="bad.toml: not valid TOML"):
        load_checklist(path)
