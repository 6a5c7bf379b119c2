"""One clock for a store: a demo's simulated time is the time of every process that opens its store.

The demo once wrote its audit with two clocks (wall and ×4): History came out of order and the demo
console and `drs approve` (another process) disagreed about when an approval expires.
"""

from __future__ import annotations

import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

from drs_link.ops.approval import ApprovalBook, Login
from drs_link.store import Store, parse_iso_utc, utc_now

START = datetime(2020, 9, 1, 12, 0, tzinfo=UTC)


def test_another_process_on_a_demo_store_writes_and_judges_in_the_demo_s_time(tmp_path: Path) -> None:
    path = tmp_path / "drs.sqlite"
    demo = Store.open(path)
    demo.run_clock(START, 4.0)
    demo.append_audit("EL", "DRS1", "arm", "armed")
    request = ApprovalBook(demo).request("DRS1", "go", "release DRS1", "EL", Login("el"))
    other = (
        "import sys; from drs_link.store import Store; from drs_link.ops.approval import ApprovalBook; "
        "s = Store.open(sys.argv[1]); s.append_audit('JM', 'DRS1', 'approval.note', 'ok'); "
        "print(ApprovalBook(s).get(1).expires_utc.isoformat(), ApprovalBook(s).clock().isoformat())"
    )
    out = subprocess.run(
        [sys.executable, "-c", other, str(path)], check=True, capture_output=True, text=True
    ).stdout
    expires, their_now = (parse_iso_utc(word) for word in out.split())
    assert expires == request.expires_utc
    assert abs((their_now - demo.clock()).total_seconds()) < 60.0, (
        "the same simulated time (a start-up apart)"
    )
    assert their_now < START + timedelta(hours=1) and utc_now() - their_now > timedelta(days=1), (
        "not the wall"
    )
    times = [row.time_utc for row in Store.open(path).audit("DRS1")]
    assert times == sorted(times) and all(t < START + timedelta(hours=1) for t in times), (
        "one clock, in order"
    )


def test_a_store_without_a_clock_keeps_the_wall_clock(tmp_path: Path) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    row = store.append_audit("EL", None, "session.started", "started")
    assert abs((row.time_utc - utc_now()).total_seconds()) < 60.0
