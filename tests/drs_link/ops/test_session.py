"""A session lost to SIGHUP or SIGTERM leaves the record a quit would, and the next console reads it."""

from __future__ import annotations

from pathlib import Path

from drs_link.ops.session import record_loss, record_start
from drs_link.store import Store
from tests.clock import ManualClock
from tests.drs_link.ops.test_arming import T0, controller, go_report


def test_a_lost_session_names_what_was_disarmed_and_says_so_once_to_the_next_console(tmp_path: Path) -> None:
    """The console has its windows closed through the operations server, then writes the loss."""
    store = Store.open(tmp_path / "drs.sqlite")
    clock = ManualClock(T0)
    armed = controller(store, clock)
    armed.arm(go_report(clock))
    assert record_start(store, "EL") is None, "a first start has nothing to report"
    armed.disarm("session lost (SIGHUP)")  # as the server's disarm does
    loss = record_loss(store, "EL", "SIGHUP", ["DRS1"], go_in_flight=[])
    assert loss.disarmed == ("DRS1",) and loss.session == store.session
    assert [(a.action, a.result) for a in store.audit("DRS1")][-1] == ("disarm", "session lost (SIGHUP)")
    shown = record_start(Store.open(tmp_path / "drs.sqlite"), "JM")
    assert shown is not None and shown.describe().endswith("(SIGHUP); while ARMED DRS1: disarmed")
    assert record_start(store, "EL") is None, "once a console has started after it, the loss is history"


def test_a_go_in_flight_is_named_and_left_to_its_worker(tmp_path: Path) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    loss = record_loss(store, "EL", "SIGTERM", [], go_in_flight=["DRS3"])
    assert loss.describe().endswith("(SIGTERM); with Go in flight to DRS3: see its record in History")
    [row] = [a for a in store.audit() if a.action == "session.lost"]
    assert row.result == "recorded" and row.detail == {
        "signal": "SIGTERM",
        "disarmed": [],
        "go_in_flight": ["DRS3"],
    }
