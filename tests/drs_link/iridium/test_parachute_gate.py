"""PARACHUTE is refused until the reports show the capsule on the ground: from the CLI and the console alike.

The CLI runs through `console.commands.main.main` against the simulated RockBLOCK on loopback; the gate itself
(`drs_link.ops.authorize`) is the one the console calls, pinned there in tests/console.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.config import parse_config
from drs_link.errors import RefusedError
from drs_link.iridium import recovery, reports as report_module
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.landed import LandedVerdicts, landed_evidence
from drs_link.iridium.lifecycle import NOT_SENT, CommandLifecycle
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.ops.authorize import authorize_mt
from drs_link.ops.operator_ops import OperatorOps
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store, utc_now
from tests.console.commands.test_cli_iridium import run, write_config
from tests.drs_link.iridium.flight_logs import flight_reports
from tests.drs_link.iridium.helpers import IMEI, T0, fix_at


def stored(index: int, moment: datetime, alt: float, speed: float, lat: float = 46.5) -> StoredReport:
    payload = format_mo(fix_at(moment, lat=lat, alt=alt, speed=speed), 8.9, index)
    return StoredReport(index, Delivery(IMEI, index, payload.hex(), "test", moment), parse_payload(payload))


def falling(start: datetime, count: int = 5) -> list[StoredReport]:
    """The demo's trial: released at 27 km, reports every 2 min falling at ~20 m/s to 17.5 km."""
    return [stored(i, start + timedelta(minutes=2 * i), 27_000.0 - 2_400.0 * i, 19.0) for i in range(count)]


def landed(start: datetime) -> list[StoredReport]:
    """Falling, then three still reports at 412 m."""
    reports = [stored(i, start + timedelta(minutes=2 * i), 9_000.0 - 3_000.0 * i, 6.0) for i in range(3)]
    return reports + [stored(3 + i, start + timedelta(minutes=6 + 2 * i), 412.0, 0.2) for i in range(3)]


def signed(reports: list[StoredReport]) -> list[StoredReport]:
    """The same reports, each as a delivery with a verified Ground Control JWT: evidence one operator may
    act on (UNVERIFIED evidence needs another login's approval, issue #31)."""
    return [replace(r, delivery=replace(r.delivery, jwt_verified=True)) for r in reports]


def test_a_falling_capsule_has_no_landed_evidence_and_the_reason_names_the_last_fix() -> None:
    evidence = landed_evidence(falling(T0))
    assert not evidence.on_ground
    assert evidence.summary.startswith(
        "NOT LANDED: last fix 10:08:07Z at 17,400 m, 19.0 m/s, falling 20.0 m/s"
    )
    assert evidence.audit()["last_fix"]["alt_m"] == 17_400.0


def test_still_reports_after_the_fall_are_landed_evidence() -> None:
    evidence = landed_evidence(landed(T0))
    assert evidence.on_ground and evidence.summary.startswith("landed 10:06:07Z at 412 m")


def test_a_capsule_that_left_its_landing_site_or_sits_far_above_the_terrain_is_not_landed() -> None:
    moved = [*landed(T0), stored(9, T0 + timedelta(minutes=14), 412.0, 0.5, lat=46.6)]
    assert not landed_evidence(moved).on_ground and "left the site" in landed_evidence(moved).summary
    in_a_tree = landed_evidence(landed(T0), ground_m=100.0)
    assert not in_a_tree.on_ground and "where the terrain is 100 m" in in_a_tree.summary
    assert landed_evidence(landed(T0), ground_m=380.0).on_ground


def test_no_report_with_a_fix_is_no_evidence() -> None:
    assert landed_evidence([]).summary == "no position report with a GNSS fix yet"


def real_flights(shared_data: Path) -> list[list[StoredReport]]:
    """The 30 real flight logs, each in time order as the store gives a capsule's reports."""
    folder = shared_data / "tracks" / "pyballoon_superbit"
    return [sorted(flight_reports(path), key=lambda r: r.time) for path in sorted(folder.glob("[0-9]*.csv"))]


def test_the_verdict_after_each_report_is_landed_evidence_on_the_reports_up_to_it(shared_data: Path) -> None:
    """One pass says what ``landed_evidence`` says of every prefix: on the 30 real flights, and on a capsule
    that lands, is carried off (one fix away is an outlier until the next fix stays away) and comes back."""
    away = stored(6, T0 + timedelta(minutes=12), 412.0, 0.5, lat=46.6)
    back = [stored(7 + i, T0 + timedelta(minutes=14 + 2 * i), 412.0, 0.2) for i in range(2)]
    carried = [*landed(T0), away, back[0], away, stored(9, T0 + timedelta(minutes=20), 412.0, 0.5, lat=46.7)]
    verdicts = []
    for reports in [*real_flights(shared_data), [*landed(T0), away, *back], carried]:
        fed = LandedVerdicts()
        verdicts += [fed.add(report) for report in reports]
        assert verdicts[-len(reports) :] == [
            landed_evidence(reports[: i + 1]).on_ground for i in range(len(reports))
        ]
    assert 0 < sum(verdicts) < len(verdicts)


def test_the_console_reads_each_report_once_and_runs_the_landing_rule_once_per_fix(
    tmp_path: Path, shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The console marks each report with the landed verdict on the reports up to it. It asked
    ``landed_evidence`` of every prefix (0.24 s for 400 reports at start-up, growing with the square) and
    re-read and re-parsed every report whenever one was new; work is counted here, not timed. Only an
    old report imported late, sorting before what was read, makes it read the history again."""
    flight = max(real_flights(shared_data), key=len)
    config = parse_config({"operator": {"name": "alice"}, "data": {"dir": str(tmp_path / "data")},
                           "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9, "imei": IMEI}]})  # fmt: skip
    store = seed(tmp_path, flight)
    work = {"fixes": 0, "parsed": 0}
    add, parse_hex = recovery.LandingWatch.add, report_module.parse_hex

    def counted_add(watch: recovery.LandingWatch, point: recovery.TrackPoint) -> None:
        work["fixes"] += 1
        add(watch, point)

    def counted_parse(text: str):  # type: ignore[no-untyped-def]
        work["parsed"] += 1
        return parse_hex(text)

    monkeypatch.setattr(recovery.LandingWatch, "add", counted_add)
    monkeypatch.setattr(report_module, "parse_hex", counted_parse)
    ops = OperatorOps(config, store)
    assert len(ops.iridium.new_reports("DRS1")) == len(flight)
    assert work == {"fixes": sum(r.report is not None and r.report.fix is not None for r in flight),
                    "parsed": len(flight)}  # fmt: skip
    work.update(fixes=0, parsed=0)
    assert ops.iridium.new_reports("DRS1") == [] and work == {"fixes": 0, "parsed": 0}
    for added, read_again in ((stored(10_001, flight[-1].time + timedelta(minutes=2), 412.0, 0.2), False),
                              (stored(10_002, flight[0].time - timedelta(minutes=2), 400.0, 0.0), True)):  # fmt: skip
        ReportStore(store).add(added.delivery)
        work.update(fixes=0, parsed=0)
        [record] = ops.iridium.new_reports("DRS1")
        done = dict(work)
        everything = ReportStore(store).for_imei(IMEI)
        fixes = sum(r.report is not None and r.report.fix is not None for r in everything)
        assert done == (
            {"fixes": fixes, "parsed": 1 + len(everything)} if read_again else {"fixes": 1, "parsed": 1}
        )
        upto = [r.delivery.momsn for r in everything].index(added.delivery.momsn) + 1
        assert record.data.landed == landed_evidence(everything[:upto]).on_ground  # type: ignore[union-attr]


@pytest.fixture
def gateway() -> SimulatedRockblock:
    with SimulatedRockblock(username="ops", password="pw") as simulated:
        yield simulated


def seed(tmp_path: Path, reports: list[StoredReport]) -> Store:
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    for report in reports:
        ReportStore(store).add(report.delivery)
    return store


def audit_of(store: Store, action: str) -> list[dict]:
    return [{"result": r.result, **(r.detail or {})} for r in store.audit() if r.action == action]


def recent(minutes_ago: float) -> datetime:
    return utc_now().replace(microsecond=0) - timedelta(minutes=minutes_ago)


def test_cli_refuses_parachute_in_flight_and_nothing_reaches_the_gateway(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw")
    config = write_config(tmp_path, gateway.url)
    store = seed(tmp_path, falling(recent(9)))
    argv = ["mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--confirm", "DRS1"]
    assert run(config, *argv, "--single-operator-waiver", "alone at the landing site") == 1
    err = capsys.readouterr().err
    assert err.startswith("drs: error: DRS1: PARACHUTE refused: no landed evidence (NOT LANDED: last fix")
    assert err.count("\n") == 1
    assert gateway.requests == []
    [refused] = audit_of(store, "mt.parachute")
    assert refused["result"] == "refused" and refused["landed"]["last_fix"]["alt_m"] == 17_400.0
    assert store.query("SELECT COUNT(*) AS n FROM mt_command")[0]["n"] == 0, (
        "a refused PARACHUTE leaves no row"
    )


def test_cli_override_needs_a_reason_and_a_second_operator_and_is_audited_with_the_evidence(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw")
    config = write_config(tmp_path, gateway.url)
    config.write_text(
        config.read_text().replace("[[capsule]]", '[console]\ncrew = ["alice", "bob"]\n[[capsule]]')
    )
    store = seed(tmp_path, falling(recent(9)))
    argv = ["mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--confirm", "DRS1",
            "--override-landed", "capsule seen on the ground by the chase team; GNSS frozen"]  # fmt: skip
    assert run(config, *argv) == 1
    assert "overriding the landed check needs a second operator" in capsys.readouterr().err
    assert gateway.requests == []
    assert run(config, *argv, "--second-operator", "alice") == 1, "the operator cannot be their own second"
    assert run(config, *argv, "--second-operator", "Bobby") == 1, "#23: a name nobody configured"
    assert "'Bobby' is not in the crew list ([console] crew: alice, bob)" in capsys.readouterr().err
    assert run(config, *argv, "--second-operator", "bob") == 0
    assert len(gateway.requests) == 1
    authorised = audit_of(store, "mt.parachute")[-1]
    assert authorised["result"] == "authorised" and authorised["second_operator"] == "bob"
    assert authorised["override_landed"].startswith("capsule seen on the ground")
    assert (
        authorised["landed"]["on_ground"] is False and authorised["landed"]["last_fix"]["alt_m"] == 17_400.0
    )


def test_cli_queues_parachute_once_the_reports_show_the_landing(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw")
    config = write_config(tmp_path, gateway.url)
    store = seed(tmp_path, signed(landed(recent(10.5))))
    argv = ["mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--confirm", "DRS1"]
    assert run(config, *argv, "--single-operator-waiver", "alone at the landing site") == 0
    out = capsys.readouterr().out
    assert "landed: landed " in out and len(gateway.requests) == 1
    assert audit_of(store, "mt.parachute")[-1]["landed"]["on_ground"] is True


def test_a_send_refused_for_the_wrong_name_is_recorded_as_not_sent_not_left_requested(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("DRS_TEST_RB", "pw")
    config = write_config(tmp_path, gateway.url)
    assert run(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "drs1") == 1
    assert "confirmation must name the capsule" in capsys.readouterr().err
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    [command] = CommandLifecycle(store, "alice").for_imei(IMEI)
    assert command.state == NOT_SENT and "refused" in command.detail and gateway.requests == []


def test_a_queue_before_deadline_that_passed_while_a_dialog_was_open_is_refused_at_submit(
    tmp_path: Path,
) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    message = MtComposer().add("PARACHUTE", (10, 20)).build()
    deadline = T0 + timedelta(minutes=12)
    with pytest.raises(RefusedError, match=r"queue-before deadline 10:12:07Z passed \(30 s ago\)"):
        authorize_mt(store, "DRS1", "alice", message, signed(landed(T0)), single_operator_waiver="alone",
                     queue_by=deadline, now=deadline + timedelta(seconds=30))  # fmt: skip
    details = authorize_mt(store, "DRS1", "alice", message, signed(landed(T0)), single_operator_waiver="alone",
                           queue_by=deadline, now=deadline - timedelta(seconds=1))  # fmt: skip
    assert details["landed"]["on_ground"] is True
    assert [a.result for a in store.audit() if a.action == "mt.parachute"] == ["refused", "authorised"]


def test_an_override_reason_longer_than_the_stated_cap_is_refused(tmp_path: Path) -> None:
    """#23: reasons are capped at a stated length wherever an operator types one."""
    reports = falling(recent(10))
    store = seed(tmp_path, reports)
    message = MtComposer().add("PARACHUTE", (12, 0)).build()
    with pytest.raises(RefusedError, match=r"override reason is at most 200 characters \(this one has 201\)"):
        authorize_mt(
            store, "DRS1", "EL", message, reports, single_operator_waiver="alone", override_landed="y" * 201
        )
