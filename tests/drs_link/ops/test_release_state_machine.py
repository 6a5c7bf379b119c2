"""The release state machine's domain rules, with an in-process Pi and a controllable clock."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError, RefusedError, StoreError
from drs_link.link.backends import GoResult, PowerOnResult
from drs_link.link.nmea import format_gga
from drs_link.ops.capsule import (
    ConfirmationToken,
    ReleaseState,
    ReleaseStateMachine,
    default_holder,
    record_as_dict,
)
from drs_link.store import Store, iso_utc
from tests.clock import ManualClock

START = datetime(2026, 6, 1, 12, 0, 0, tzinfo=UTC)


@dataclass
class InProcessPi:
    """The stock scripts' observable results, without SSH: what the state machine reacts to."""

    clock: ManualClock
    nmea_after_s: float | None = 23.0
    go_outcome: GoResult = field(
        default_factory=lambda: GoResult(
            True, True, True, None, "Dropping in 30 seconds!\nShutting down...\n"
        )
    )
    power_on_error: LinkError | None = None
    serial_error: LinkError | None = None
    """Raised by ``read_serial``: a Pi that no longer answers (shut down, or dropped with the capsule)."""
    calls: list[str] = field(default_factory=list)
    powered_at: datetime | None = None

    def power_on(self, holder: str, lease_s: float) -> PowerOnResult:
        self.calls.append("power_on")
        if self.power_on_error:
            raise self.power_on_error
        self.powered_at = self.clock()
        return PowerOnResult(log_offset=120, output="drs-log-offset 120\n")

    def read_serial(self, offset: int) -> list[str]:
        self.calls.append(f"read_serial {offset}")
        if self.serial_error:
            raise self.serial_error
        if self.powered_at is None or self.nmea_after_s is None:
            return []
        if (self.clock() - self.powered_at).total_seconds() < self.nmea_after_s:
            return []
        return [format_gga(self.clock(), 1.0, 2.0, 1, 7, 1.1, 30000.0)]

    def go(self, holder: str) -> GoResult:
        self.calls.append("go")
        return self.go_outcome


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(START)


@pytest.fixture
def pi(clock: ManualClock) -> InProcessPi:
    return InProcessPi(clock)


@pytest.fixture
def machine(tmp_path: Path, pi: InProcessPi, clock: ManualClock) -> ReleaseStateMachine:
    return _machine(tmp_path, pi, clock)


def _machine(tmp_path: Path, pi: InProcessPi, clock: ManualClock) -> ReleaseStateMachine:
    capsule = CapsuleConfig(name="DRS1", host="drs1.local")
    return ReleaseStateMachine(
        Store.open(tmp_path / "drs.sqlite"), capsule, pi, "EL", clock=clock, sleep=clock.advance
    )


def _ready(machine: ReleaseStateMachine) -> None:
    machine.power_on(confirmed=True)
    assert machine.wait_for_microcontroller().waiting_for_go


def test_power_on_without_confirmation_is_refused_and_nothing_runs(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    with pytest.raises(RefusedError, match="not confirmed"):
        machine.power_on(confirmed=False)
    assert pi.calls == [] and machine.record().state is ReleaseState.IDLE
    assert machine.store.audit("DRS1")[-1].result == "refused"


def test_go_without_power_on_is_refused(machine: ReleaseStateMachine, pi: InProcessPi) -> None:
    with pytest.raises(RefusedError, match="power-on has not succeeded"):
        machine.confirm("DRS1")
    forged = ConfirmationToken("forged", "DRS1", START)
    with pytest.raises(RefusedError, match="power-on has not succeeded"):
        machine.go(forged)
    assert "go" not in pi.calls


def test_confirmation_must_name_this_capsule(machine: ReleaseStateMachine) -> None:
    _ready(machine)
    for typed in ("DRS2", "drs1", "DRS1 ", ""):
        with pytest.raises(RefusedError, match="does not name 'DRS1'"):
            machine.confirm(typed)


def test_token_not_minted_by_the_store_is_refused(machine: ReleaseStateMachine, pi: InProcessPi) -> None:
    _ready(machine)
    with pytest.raises(RefusedError, match="not minted for this capsule"):
        machine.go(ConfirmationToken("made-up", "DRS1", START))
    assert "go" not in pi.calls


def test_token_older_than_sixty_seconds_is_refused(
    machine: ReleaseStateMachine, pi: InProcessPi, clock: ManualClock
) -> None:
    _ready(machine)
    token = machine.confirm("DRS1")
    clock.advance(60.5)
    with pytest.raises(RefusedError, match="61 s old|60 s old"):
        machine.go(token)
    assert "go" not in pi.calls


def test_fresh_token_within_sixty_seconds_releases(machine: ReleaseStateMachine, clock: ManualClock) -> None:
    _ready(machine)
    token = machine.confirm("DRS1")
    clock.advance(59.0)
    assert machine.go(token).state is ReleaseState.RELEASED


def test_token_from_an_earlier_power_on_session_is_refused(machine: ReleaseStateMachine) -> None:
    _ready(machine)
    token = machine.confirm("DRS1")
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    with pytest.raises(RefusedError, match="earlier power-on session"):
        machine.go(token)


def test_token_cannot_be_used_twice(machine: ReleaseStateMachine, pi: InProcessPi) -> None:
    _ready(machine)
    pi.go_outcome = GoResult(False, False, True, None, "")
    token = machine.confirm("DRS1")
    with pytest.raises(LinkError, match="may or may not"):
        machine.go(token)
    with pytest.raises(RefusedError, match="already used"):
        machine.go(token)


def test_token_for_another_capsule_is_refused(tmp_path: Path, clock: ManualClock) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    one = ReleaseStateMachine(
        store, CapsuleConfig("DRS1", "a"), InProcessPi(clock), "EL", clock=clock, sleep=clock.advance
    )
    two = ReleaseStateMachine(
        store, CapsuleConfig("DRS2", "b"), InProcessPi(clock), "EL", clock=clock, sleep=clock.advance
    )
    _ready(one)
    _ready(two)
    token_for_one = one.confirm("DRS1")
    with pytest.raises(RefusedError, match="not minted for this capsule"):
        two.go(ConfirmationToken(token_for_one.value, "DRS2", token_for_one.minted_at))


def test_go_refused_until_nmea_has_been_seen(
    machine: ReleaseStateMachine, pi: InProcessPi, clock: ManualClock
) -> None:
    machine.power_on(confirmed=True)
    token = machine.confirm("DRS1")
    with pytest.raises(RefusedError, match="no NMEA seen"):
        machine.go(token)
    assert "go" not in pi.calls


def test_silence_after_25_seconds_gives_the_checks_to_make(
    machine: ReleaseStateMachine, pi: InProcessPi, clock: ManualClock
) -> None:
    pi.nmea_after_s = None
    machine.power_on(confirmed=True)
    early = machine.check_microcontroller()
    assert not early.waiting_for_go and "still booting" in early.diagnosis
    report = machine.wait_for_microcontroller()
    assert not report.waiting_for_go and report.seconds_since_power_on is not None
    assert report.seconds_since_power_on >= 25
    for check in ("batteries", "relay latched", "booting", "Gone mode", "four-button reset"):
        assert check in report.diagnosis


def test_link_drop_after_shutting_down_is_recorded_as_released_pi_shut_down(
    machine: ReleaseStateMachine,
) -> None:
    _ready(machine)
    record = machine.go(machine.confirm("DRS1"))
    assert record.state is ReleaseState.RELEASED and record.note == "released, Pi shut down"
    assert machine.store.audit("DRS1")[-1].result == "released, Pi shut down"


def test_go_written_but_no_shutdown_seen_is_still_released(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    _ready(machine)
    pi.go_outcome = GoResult(True, False, True, None, "Dropping in 30 seconds!\n")
    assert machine.go(machine.confirm("DRS1")).note == "released, Pi shutdown not seen"


def test_second_go_to_a_released_capsule_is_refused(machine: ReleaseStateMachine, pi: InProcessPi) -> None:
    _ready(machine)
    token = machine.confirm("DRS1")
    machine.go(token)
    with pytest.raises(RefusedError, match="already released"):
        machine.go(token)
    with pytest.raises(RefusedError, match="already released"):
        machine.confirm("DRS1")
    with pytest.raises(RefusedError, match="reset it after recovery"):
        machine.power_on(confirmed=True)
    assert pi.calls.count("go") == 1


def test_restarted_process_resumes_the_release(tmp_path: Path, pi: InProcessPi, clock: ManualClock) -> None:
    _ready(_machine(tmp_path, pi, clock))
    restarted = _machine(tmp_path, pi, clock)
    record = restarted.record()
    assert (
        record.state is ReleaseState.POWERED and record.log_offset == 120 and record.nmea_seen_at is not None
    )
    assert restarted.go(restarted.confirm("DRS1")).state is ReleaseState.RELEASED


def test_serial_log_is_read_from_the_offset_taken_at_power_on(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    _ready(machine)
    assert all(call == "read_serial 120" for call in pi.calls if call.startswith("read_serial"))


def test_a_power_on_whose_link_fails_is_outcome_unknown_until_reset_or_power_on_again(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    """The link may fail after the Pi latched the relay, so 'idle' would be a guess (and once was the
    record over a latched relay): the outcome is recorded unknown, Go is refused, and the operator
    settles it by resetting (relay found off) or by powering on again."""
    pi.power_on_error = LinkError("DRS1: the link dropped during power-on")
    with pytest.raises(
        LinkError, match="the link dropped during power-on; power-on outcome unknown: check the relay"
    ):
        machine.power_on(confirmed=True)
    record = machine.record()
    assert (
        record.state is ReleaseState.POWER_ON_UNKNOWN
        and record.note is not None
        and "check the relay" in record.note
    )
    assert [a.result for a in machine.store.audit("DRS1")] == ["started", "outcome unknown"]
    with pytest.raises(RefusedError, match="power-on has not succeeded"):
        machine.confirm("DRS1")
    assert machine.reset("DRS1").state is ReleaseState.IDLE
    with pytest.raises(LinkError):
        machine.power_on(confirmed=True)
    pi.power_on_error = None
    assert machine.power_on(confirmed=True).state is ReleaseState.POWERED


def test_a_power_on_the_pi_refuses_puts_the_previous_state_back(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    """The Pi's release-authority lock refuses before the relay is touched: nothing happened."""
    _ready(machine)
    session = machine.record().session
    pi.power_on_error = RefusedError("DRS1: release authority is held by JM@laptop2")
    with pytest.raises(RefusedError, match="held by JM@laptop2"):
        machine.power_on(confirmed=True)
    assert (machine.record().state, machine.record().session) == (ReleaseState.POWERED, session)
    assert [a.result for a in machine.store.audit("DRS1")][-2:] == ["started", "refused"]


def test_reset_after_recovery_allows_a_new_release_only_when_named(machine: ReleaseStateMachine) -> None:
    _ready(machine)
    machine.go(machine.confirm("DRS1"))
    with pytest.raises(RefusedError):
        machine.reset("DRS2")
    assert machine.reset("DRS1").state is ReleaseState.IDLE
    machine.power_on(confirmed=True)


def test_a_go_refused_while_another_console_released_the_capsule_leaves_it_released(
    tmp_path: Path, pi: InProcessPi, clock: ManualClock
) -> None:
    """Each step is a compare-and-set: the refused Go once wrote its stale ``powered`` over ``released``."""
    first, second = _machine(tmp_path, InProcessPi(clock), clock), _machine(tmp_path, pi, clock)
    _ready(first)
    token = second.confirm("DRS1")

    def the_other_console_releases_first(holder: str) -> GoResult:
        first.go(first.confirm("DRS1"))
        raise RefusedError("DRS1: another console holds the release authority")

    pi.go = the_other_console_releases_first  # type: ignore[method-assign]
    with pytest.raises(RefusedError, match="another console holds"):
        second.go(token)
    assert first.record().state is ReleaseState.RELEASED and second.record().state is ReleaseState.RELEASED


def test_a_verified_retry_records_its_own_go_time_and_keeps_the_failed_attempts_beside_it(
    machine: ReleaseStateMachine, pi: InProcessPi, clock: ManualClock
) -> None:
    """While unverified the record keeps the first Go's time (the capsule may have left then); a retry the
    Pi confirms shows it was still up to take it, so the release time is the verified Go's and the failed
    attempt's is kept beside it, in the store and the audit (issue #29)."""
    _ready(machine)
    pi.go_outcome = GoResult(False, True, False, None, "")
    with pytest.raises(LinkError, match="may or may not"):
        machine.go(machine.confirm("DRS1"))
    first_go = machine.record().go_at
    assert machine.record().state is ReleaseState.GO_SENT and first_go is not None
    clock.advance(40)
    pi.go_outcome = GoResult(True, True, True, None, "Dropping in 30 seconds!\nShutting down...\n")
    record = machine.go(machine.confirm("DRS1"))
    assert (
        record.state is ReleaseState.RELEASED and record.go_at == clock() and record.failed_go_at == first_go
    )
    assert machine.record() == record, "as stored"
    assert record_as_dict(record)["failed_go_at"] == iso_utc(first_go)
    released = machine.store.audit("DRS1")[-1].detail or {}
    assert (released["go_at"], released["failed_go_at"]) == (iso_utc(clock()), iso_utc(first_go))


def test_a_store_failure_after_the_pi_powered_on_says_the_relay_is_latched(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    """A full disk here once crashed with a raw traceback after the Pi had run its power-on script
    (a full disk itself is pinned in ``test_store_durability``; here the store just stops writing)."""
    powered_on = pi.power_on

    def the_store_stops_writing_while_the_pi_powers_on(holder: str, lease_s: float) -> PowerOnResult:
        machine.store.conn.execute("PRAGMA query_only = ON")
        return powered_on(holder, lease_s)

    pi.power_on = the_store_stops_writing_while_the_pi_powers_on  # type: ignore[method-assign]
    with pytest.raises(
        StoreError, match=r"power-on ran on the Pi \(the relay is latched\) but was not recorded"
    ):
        machine.power_on(confirmed=True)
    assert pi.calls == ["power_on"]


def test_a_store_failure_after_the_pi_released_says_the_capsule_is_released_and_not_to_go_again(
    machine: ReleaseStateMachine, pi: InProcessPi
) -> None:
    """#24: after a store failure Go did not say that the Pi had already acted."""
    _ready(machine)
    go = pi.go

    def the_store_stops_writing_while_the_pi_releases(holder: str) -> GoResult:
        machine.store.conn.execute("PRAGMA query_only = ON")
        return go(holder)

    pi.go = the_store_stops_writing_while_the_pi_releases  # type: ignore[method-assign]
    with pytest.raises(
        StoreError,
        match=r"Go reached the Pi \(released, .*\) but was not recorded.*IS released, do not Go again",
    ):
        machine.go(machine.confirm("DRS1"))
    machine.store.conn.execute("PRAGMA query_only = OFF")
    assert pi.calls.count("go") == 1 and machine.record().state is ReleaseState.GO_SENT


def test_reset_is_refused_while_a_go_is_unverified(machine: ReleaseStateMachine, pi: InProcessPi) -> None:
    _ready(machine)
    pi.go_outcome = GoResult(False, True, False, None, "")
    with pytest.raises(LinkError):
        machine.go(machine.confirm("DRS1"))
    with pytest.raises(RefusedError, match="Go was sent and not verified"):
        machine.reset("DRS1")
    assert machine.record().state is ReleaseState.GO_SENT


def test_an_unverified_go_is_settled_as_released_only_by_a_named_operator_with_evidence(
    machine: ReleaseStateMachine, pi: InProcessPi, clock: ManualClock
) -> None:
    """After a Go whose answer was lost the Pi halts, so no retry can confirm it and reset is refused:
    the operator records the release with what shows it, and the release time is the Go's."""
    with pytest.raises(RefusedError, match="only an unverified Go"):
        machine.record_released("DRS1", "reports show the fall")
    _ready(machine)
    pi.go_outcome = GoResult(False, True, False, None, "")
    with pytest.raises(LinkError):
        machine.go(machine.confirm("DRS1"))
    go_at = machine.record().go_at
    clock.advance(3600)
    for typed, evidence, refusal in (("DRS2", "reports show the fall", "does not name"),
                                     ("DRS1", "  ", "evidence"), ("DRS1", "fell\nok", "evidence")):  # fmt: skip
        with pytest.raises(RefusedError, match=refusal):
            machine.record_released(typed, evidence)
        assert machine.record().state is ReleaseState.GO_SENT
    record = machine.record_released("DRS1", "Iridium reports from 27 km down to 400 m")
    assert (
        record.state is ReleaseState.RELEASED and record.released_at == go_at == machine.record().released_at
    )
    assert machine.store.audit("DRS1")[-1].detail == {"evidence": "Iridium reports from 27 km down to 400 m"}
    assert machine.reset("DRS1").state is ReleaseState.IDLE


def test_reset_needs_an_operator_name(tmp_path: Path, pi: InProcessPi, clock: ManualClock) -> None:
    capsule = CapsuleConfig(name="DRS1", host="drs1.local")
    anonymous = ReleaseStateMachine(Store.open(tmp_path / "drs.sqlite"), capsule, pi, "", clock=clock)
    with pytest.raises(RefusedError, match="no operator name"):
        anonymous.reset("DRS1")


def test_every_audit_record_names_operator_capsule_and_utc_time(machine: ReleaseStateMachine) -> None:
    _ready(machine)
    machine.go(machine.confirm("DRS1"))
    records = machine.store.audit("DRS1")
    assert records and all(r.operator == "EL" and r.capsule == "DRS1" for r in records)
    assert all(r.time_utc.tzinfo is not None for r in records)


def test_holder_name_is_safe_for_the_pi_lock_file() -> None:
    holder = default_holder("Eve Lee; rm -rf /")
    assert " " not in holder and ";" not in holder and holder.startswith("Eve_Lee__rm_-rf__@")
