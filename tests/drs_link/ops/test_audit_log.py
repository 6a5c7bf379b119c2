"""The audit log as History reads it: newest first, searched, cut to a limit, exported whole as JSON lines."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

from drs_link.ops import AuditLog
from drs_link.store import Store

T0 = datetime(2026, 6, 20, 12, 0, tzinfo=UTC)


def filled(tmp_path: Path) -> Store:
    store = Store.open(tmp_path / "drs.sqlite")
    for minute, (capsule, action, detail) in enumerate([
        ("DRS1", "power-on", {"by": "console"}),
        ("DRS1", "waiver", {"item": "gnss", "reason": "no fix, dropping anyway"}),
        ("DRS2", "arm", None),
    ]):  # fmt: skip
        store.append_audit("EL", capsule, action, "ok", detail, when=T0 + timedelta(minutes=minute))
    return store


def test_newest_first_searched_and_cut_to_the_limit(tmp_path: Path) -> None:
    log = AuditLog(filled(tmp_path))
    assert [r.action for r in log.newest()] == ["arm", "waiver", "power-on"]
    assert [r.action for r in log.newest(limit=2)] == ["arm", "waiver"]
    assert [r.action for r in log.newest("dropping")] == ["waiver"]
    assert [r.action for r in log.newest("")] == ["arm", "waiver", "power-on"]
    assert [r.action for r in log.newest("DRS2")] == ["arm"], "a capsule's name finds its entries"


def test_the_export_holds_every_matching_entry_oldest_first_with_its_detail(tmp_path: Path) -> None:
    log = AuditLog(filled(tmp_path))
    path = tmp_path / "exports" / "audit.jsonl"
    assert log.export(path) == 3
    rows = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]
    assert [(r["capsule"], r["action"]) for r in rows] == [
        ("DRS1", "power-on"),
        ("DRS1", "waiver"),
        ("DRS2", "arm"),
    ]
    assert rows[1]["detail"] == {"item": "gnss", "reason": "no fix, dropping anyway"}
    assert rows[0]["time_utc"].startswith("2026-06-20T12:00:00")
    assert log.export(path, "dropping") == 1
    assert [json.loads(line)["action"] for line in path.read_text(encoding="utf-8").splitlines()] == [
        "waiver"
    ]


def test_an_entry_of_another_console_names_it_and_one_of_this_console_does_not(tmp_path: Path) -> None:
    store = filled(tmp_path)
    other = Store.open(tmp_path / "drs.sqlite")
    other.session = "jm@ground pid 4242"  # another process: what session_name() would call it
    other.append_audit("JM", "DRS1", "disarm", "ok", when=T0 + timedelta(minutes=5))
    log = AuditLog(store)
    mine, theirs = log.newest()[1], log.newest()[0]
    assert log.elsewhere(mine) is None
    assert log.elsewhere(theirs) == "jm@ground pid 4242"
