"""Text an operator types is refused below the UI if it holds a control or format character, and text
another person typed is shown escaped wherever it reaches a terminal (issue #29 Why-4).

Every text field of the operations layer is tried with each kind of hidden character; the display side
is tried with rows written into the store past every rule (as an old row, or a hand edit, would be).
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.errors import RefusedError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.mt import MtComposer
from drs_link.link.backends import AuthorityStatus
from drs_link.ops.approval import ApprovalBook, Login
from drs_link.ops.arming import check_second_operator
from drs_link.ops.audit_log import AuditLog
from drs_link.ops.authorize import authorize_mt
from drs_link.ops.checklist import PROCEDURE_DIR, ChecklistRun, load_checklists
from drs_link.ops.gonogo import WaiverBook
from drs_link.ops.iridium_ops import IridiumOps
from drs_link.ops.override import parachute_override
from drs_link.ops.typed_text import shown, typed_text
from drs_link.store import Store, utc_now
from tests.clock import ManualClock
from tests.console.commands.test_cli_iridium import run, write_config
from tests.drs_link.iridium.test_parachute_gate import falling, recent
from tests.drs_link.ops.test_release_state_machine import START, InProcessPi, _machine

HIDDEN = {
    "escape sequence": "ok\x1b[2K(landed: verified)",
    "carriage return": "alone\rapproved by JM",
    "tab": "alone\tat the site",
    "newline": "alone\nat the site",
    "bidi override": "alone \u202eetis eht ta",
    "zero-width space": "al\u200bone",
    "line separator": "alone\u2028at the site",
    "C1 control": "alone\x9b2K",
}


@pytest.mark.parametrize("text", HIDDEN.values(), ids=HIDDEN.keys())
def test_the_one_rule_refuses_every_control_and_format_character_and_names_the_field(text: str) -> None:
    with pytest.raises(RefusedError) as refused:
        typed_text("the waiver reason", text)
    message = str(refused.value)
    assert (
        message.startswith("the waiver reason: character ")
        and "type it as one line of visible text" in message
    )
    assert message.isprintable(), "the error itself is safe to print"
    assert typed_text("the waiver reason", "alone at the site — 5 km/h, ±14 min, Zürich") == (
        "alone at the site — 5 km/h, ±14 min, Zürich"
    )


@pytest.fixture
def store(tmp_path: Path) -> Store:
    return Store.open(tmp_path / "drs.sqlite")


def fields(store: Store, tmp_path: Path) -> dict[str, Callable[[str], object]]:
    """Every place an operator's typed text enters the operations layer, each fed one text."""
    clock = ManualClock(START)
    (tmp_path / "m").mkdir()
    machine = _machine(tmp_path / "m", InProcessPi(clock), clock)
    book = ApprovalBook(store, clock)
    request = book.request("DRS1", "parachute", "[PARACHUTE=10:20]", "alice", Login("alice"), command="x")
    [checklist] = [c for c in load_checklists(PROCEDURE_DIR) if c.id == "after-drop"]
    parachute = MtComposer().add("PARACHUTE", (10, 20)).build()
    free = AuthorityStatus(None, 0, 0)
    life = lc.CommandLifecycle(store, "alice", clock)
    return {
        "the approval's reason": lambda t: book.decide(request.id, "bob", Login("bob"), False, t),
        "the waiver reason": lambda t: WaiverBook(store, "DRS1", clock).grant("gnss", "alice", t),
        "the single-operator waiver": lambda t: check_second_operator("alice", None, t, False),
        "the second operator's name": lambda t: check_second_operator("alice", t, None, False, ("bob",)),
        "the override reason": lambda t: authorize_mt(
            store,
            "DRS1",
            "alice",
            parachute,
            falling(recent(9)),
            single_operator_waiver="alone",
            override_landed=t,
        ),  # fmt: skip
        "the take-over reason": lambda t: machine.check_take_over(t, free),
        "the typed capsule name": lambda t: machine.confirm(t),
        "the release evidence": lambda t: machine.record_released("DRS1", t),
        "the reason for giving up release authority": lambda t: machine.release_authority(t),
        "the reason for skipping a step": lambda t: ChecklistRun(store, checklist, "DRS1").skip(
            checklist.steps[0].id, "alice", t
        ),
        "the note": lambda t: IridiumOps.resolve_mt(_resolving(life), "DRS1", 1, None, t),
    }


def _resolving(life: lc.CommandLifecycle) -> IridiumOps:
    """Just enough of IridiumOps for ``resolve_mt`` to reach its rule (it refuses before reading more)."""
    iridium = IridiumOps.__new__(IridiumOps)
    iridium.lifecycle = life
    return iridium


def test_every_typed_text_field_refuses_hidden_characters_naming_itself(store: Store, tmp_path: Path) -> None:
    for field, enter in fields(store, tmp_path).items():
        for kind, text in HIDDEN.items():
            with pytest.raises(RefusedError, match=f"^{field}: character ") as refused:
                enter(text)
            assert "\x1b" not in str(refused.value), (field, kind)
    assert not store.query("SELECT * FROM approval WHERE state != 'pending'"), "nothing was decided"
    assert not [a for a in store.audit() if a.action == "waiver" and a.result == "granted"]


def test_a_stored_row_with_control_characters_is_shown_escaped_by_the_approver_history_and_banner(
    store: Store,
) -> None:
    """Rows written past the rule (an old store, a hand edit): what reaches a terminal is visible escapes."""
    clock = ManualClock(utc_now())
    book = ApprovalBook(store, clock)
    request = book.request("DRS1", "parachute", "[PARACHUTE=10:20]", "alice", Login("alice"), command="x")
    evil = "\r\x1b[2K(landed: verified, 0 m/s on the ground)"
    store.write(
        "UPDATE approval SET summary = ?, requested_by = ? WHERE id = ?", (evil, "al\u202eice", request.id)
    )
    shown_lines = book.get(request.id).for_approver(clock())
    assert all("\x1b" not in line and "\r" not in line and "\u202e" not in line for line in shown_lines)
    assert "\\x0d\\x1b[2K(landed: verified" in shown_lines[0] and "al\\u202eice" in shown_lines[0]
    store.append_audit("al\x1bice", "DRS1", "waiver", "granted", {"reason": evil, "nested": [evil]})
    [entry] = [r for r in AuditLog(store).newest() if r.action == "waiver"]
    assert entry.operator == "al\\x1bice" and entry.detail == {"reason": shown(evil), "nested": [shown(evil)]}
    message = MtComposer().add("PARACHUTE", (10, 20)).build()
    store.append_audit("eve\x1b[2K", "DRS1", "mt.parachute", "authorised",
                       {"text": message.text, "override_landed": evil, "second_operator": "b\rob"})  # fmt: skip
    sent = lc.Command(1, "DRS1", "300234060000000", "eve", message.text, False, lc.QUEUED,
                      clock(), clock() + timedelta(seconds=1), clock(), 7, None, {}, "")  # fmt: skip
    override = parachute_override("DRS1", store.audit("DRS1"), [sent])
    assert override is not None
    for text in (override.banner(), override.reason, override.approved_by):
        assert "\x1b" not in text and "\r" not in text, text


def test_drs_approve_refuses_a_reason_with_an_escape_and_lists_a_stored_one_escaped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path)
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    book = ApprovalBook(store)
    request = book.request(
        "DRS1", "parachute", "[PARACHUTE=10:20]", "alice", Login("someone-else"), command="x"
    )
    store.write("UPDATE approval SET summary = ? WHERE id = ?", ("\x1b[2Kall clear", request.id))
    assert run(config, "approve") == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\\x1b[2Kall clear" in out
    assert run(config, "approve", str(request.id), "--reject", "--reason", "no\x1b[2K") == 1
    err = capsys.readouterr().err
    assert err.startswith(
        "drs: error: the approval's reason: character 3 is the control or format character \\x1b"
    )
    assert err.count("\n") == 1 and book.get(request.id).state == "pending"
