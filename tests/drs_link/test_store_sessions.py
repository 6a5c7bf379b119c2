"""Several consoles share one store: each can tell, cheaply, that another wrote, and who it was."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

from drs_link.store import Store, session_name


def test_another_connection_s_commit_moves_the_data_version_and_nothing_else_does(tmp_path: Path) -> None:
    mine = Store.open(tmp_path / "drs.sqlite")
    seen = mine.data_version()
    mine.audit("DRS1")
    assert mine.data_version() == seen, "reading changes nothing"
    mine.append_audit("alice", "DRS1", "waiver", "granted")
    assert mine.data_version() == seen, "this connection's own commit is not news to it"
    writer = f"from drs_link.store import Store; Store.open({str(tmp_path / 'drs.sqlite')!r}).append_audit('bob', 'DRS1', 'mt.queued', 'queued')"
    subprocess.run([sys.executable, "-c", writer], check=True)
    assert mine.data_version() != seen, "another console's commit is"


def test_every_audit_row_names_the_process_that_wrote_it(tmp_path: Path) -> None:
    path = tmp_path / "drs.sqlite"
    writer = f"from drs_link.store import Store; Store.open({str(path)!r}).append_audit('bob', 'DRS1', 'mt.queued', 'queued')"
    subprocess.run([sys.executable, "-c", writer], check=True)
    mine = Store.open(path)
    mine.append_audit("alice", "DRS1", "waiver", "granted")
    theirs, ours = mine.audit("DRS1")
    assert ours.session == mine.session == session_name()
    assert theirs.session is not None and theirs.session != ours.session
    assert theirs.session.split(" pid ")[0] == ours.session.split(" pid ")[0], (
        "same account and host, other process"
    )


def test_a_store_made_before_the_session_column_gets_it_and_keeps_its_rows(tmp_path: Path) -> None:
    path = tmp_path / "old.sqlite"
    with sqlite3.connect(path) as old:
        old.execute(
            "CREATE TABLE audit (id INTEGER PRIMARY KEY AUTOINCREMENT, time_utc TEXT NOT NULL, operator TEXT NOT NULL, "
            "capsule TEXT, action TEXT NOT NULL, result TEXT NOT NULL, detail TEXT)"
        )
        old.execute("INSERT INTO audit (time_utc, operator, capsule, action, result) "
                    "VALUES ('2026-11-01T00:00:00.000Z', 'el', 'DRS1', 'arm', 'armed')")  # fmt: skip
    store = Store.open(path)
    store.append_audit("el", "DRS1", "fire", "authorised")
    assert [(r.action, r.session) for r in store.audit("DRS1")] == [("arm", None), ("fire", store.session)]
    Store.open(path)  # a second open finds the column there
