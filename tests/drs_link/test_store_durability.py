"""The store keeps every record it acknowledged: through SIGKILL, and through a full disk."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from drs_link.errors import StoreError
from drs_link.store import Store

WRITER = textwrap.dedent(
    """
    import sys
    from drs_link.store import Store
    store = Store.open(sys.argv[1])
    n = 0
    while True:
        record = store.append_audit("EL", "DRS1", "power-on", "ok", {"n": n})
        print(record.id, flush=True)
        n += 1
    """
)


def _acknowledged_ids(output: bytes) -> list[int]:
    """Only complete lines count: a line cut by the kill was never acknowledged."""
    lines = output.split(b"\n")
    return [int(line) for line in lines[:-1] if line.strip()]


@pytest.mark.slow
def test_sigkill_at_random_moments_loses_no_acknowledged_record(tmp_path: Path) -> None:
    db = tmp_path / "drs.sqlite"
    rng = random.Random(20261122)
    acknowledged: list[int] = []
    for _ in range(6):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(db)], stdout=subprocess.PIPE)
        time.sleep(0.3 + rng.random() * 0.5)
        proc.send_signal(signal.SIGKILL)
        output, _ = proc.communicate(timeout=10)
        assert proc.returncode == -signal.SIGKILL
        acknowledged.extend(_acknowledged_ids(output))
    assert len(acknowledged) > 6, "the writer acknowledged too few records for the test to mean anything"
    stored = {record.id for record in Store.open(db).audit()}
    missing = sorted(set(acknowledged) - stored)
    assert not missing, f"acknowledged but lost: {missing[:10]}"


def test_full_database_raises_store_error_and_keeps_what_was_acknowledged(tmp_path: Path) -> None:
    db = tmp_path / "drs.sqlite"
    store = Store.open(db)
    page_count = store.conn.execute("PRAGMA page_count").fetchone()[0]
    store.conn.execute(f"PRAGMA max_page_count = {page_count + 2}")
    acknowledged = []
    with pytest.raises(StoreError, match="cannot be written"):
        for n in range(10_000):
            acknowledged.append(
                store.append_audit("EL", "DRS1", "sync", "ok", {"padding": "x" * 200, "n": n}).id
            )
    store.close()
    assert len(acknowledged) > 0
    reopened = Store.open(db)
    assert [r.id for r in reopened.audit()] == acknowledged
    assert reopened.append_audit("EL", "DRS1", "after", "ok").id > acknowledged[-1]


def test_unwritable_data_directory_is_a_store_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with pytest.raises(StoreError, match="cannot create the data directory"):
        Store.open(blocker / "sub" / "drs.sqlite")


def test_the_store_and_its_journal_are_readable_by_the_owner_only(tmp_path: Path) -> None:
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    store.append_audit("EL", "DRS1", "test", "ok", {})
    for name in ("drs.sqlite", "drs.sqlite-wal"):
        assert (tmp_path / "data" / name).stat().st_mode & 0o777 == 0o600, name
    assert (tmp_path / "data").stat().st_mode & 0o777 == 0o700


def test_wal_and_full_synchronous_writes_are_in_force(tmp_path: Path) -> None:
    """Without them an acknowledged record can be lost at power loss; these pin that they are set."""
    store = Store.open(tmp_path / "drs.sqlite")
    assert store.query("PRAGMA journal_mode")[0][0] == "wal"
    assert store.query("PRAGMA synchronous")[0][0] == 2  # FULL


def test_a_full_disk_inside_a_transaction_reports_the_disk_not_a_failed_rollback(tmp_path: Path) -> None:
    """SQLite rolls back by itself on SQLITE_FULL; a second ROLLBACK used to hide the real error."""
    store = Store.open(tmp_path / "drs.sqlite")
    store.conn.execute("CREATE TABLE blob (data TEXT)")
    page_count = store.conn.execute("PRAGMA page_count").fetchone()[0]
    store.conn.execute(f"PRAGMA max_page_count = {page_count + 1}")
    with pytest.raises(StoreError, match="database or disk is full") as failed:
        with store.transaction() as conn:
            conn.execute("INSERT INTO blob VALUES (?)", ("x" * 100_000,))
    assert "no transaction is active" not in str(failed.value)
    assert not store.conn.in_transaction
