"""A PARACHUTE queued WITHOUT landed evidence stays loud, and its drop time is the firmware's.

The override goes through the real gate (``authorize_mt``), the MT through the real lifecycle to the
simulated gateway on loopback, and the simulated capsule downloads and obeys it with the firmware's
rules, so the drop time said here is checked against what the unit model did (``parachute_open``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.iridium import lifecycle as lc
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.parachute import plan_parachute
from drs_link.ops.authorize import authorize_mt
from drs_link.ops.checklist import PROCEDURE_DIR, load_checklists
from drs_link.ops.override import ParachuteOverride, after_drop, drop_schedule, parachute_override
from drs_link.ops.procedure import complete_mt_steps
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from tests.drs_link.iridium.helpers import IMEI
from tests.drs_link.iridium.test_commanded import CAPSULE, Rig, at

WAIVER = "alone in the field"
REASON = "chase team sees it on the ground; GNSS frozen"


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        yield Rig(store, gateway)
    store.close()


def falling(rig: Rig) -> None:
    """Three reports two minutes apart falling through 18 km at ~16 m/s: no landed evidence."""
    for minute, alt in ((0, 19_900.0), (2, 18_000.0), (4, 16_100.0)):
        rig.cycle(at(minute), alt=alt)


def overridden_send(rig: Rig, hhmm: tuple[int, int]) -> lc.Command:
    message = MtComposer().add("PARACHUTE", hhmm).build()
    reports = rig.reports.for_imei(IMEI)
    authorize_mt(
        rig.store,
        "DRS1",
        "alice",
        message,
        reports,
        single_operator_waiver=WAIVER,
        require_second_operator=False,
        override_landed=REASON,
    )
    return rig.send(message, at(5))


def override_now(rig: Rig) -> ParachuteOverride | None:
    return parachute_override("DRS1", rig.store.audit("DRS1"), rig.life.for_imei(IMEI))


def test_the_banner_names_who_overrode_and_who_approved_until_the_drop(rig: Rig) -> None:
    falling(rig)
    assert override_now(rig) is None
    overridden_send(rig, (10, 6))
    override = override_now(rig)
    assert override is not None
    assert override.banner() == (
        f"DRS1: PARACHUTE queued WITHOUT landed evidence (override by alice, approved by nobody: "
        f"single-operator waiver “{WAIVER}”)"
    )
    drop, words = drop_schedule(override, rig.reports.for_imei(IMEI))
    assert drop == at(6), "the next cycle on the 2-minute grid"
    assert words == "scheduled drop at the end of the next cycle, expected 10:06:07Z (accepted until 10:20Z)"
    assert "falls WITHOUT its parachute" in after_drop(drop, at(30))
    assert "comes before the drop" in after_drop(drop, at(5.5))

    rig.cycle(at(6), alt=14_200.0)
    assert rig.capsule.parachute_open, "the firmware model obeyed it in flight"
    override = override_now(rig)
    assert override is not None, "the banner stays after the drop"
    drop, words = drop_schedule(override, rig.reports.for_imei(IMEI))
    assert drop == at(6) and words == "release B opened at the end of the 10:06:07Z cycle (after its report)"


def test_recovery_and_the_iridium_helper_agree_on_the_cycle_after_a_missed_one(rig: Rig) -> None:
    """The 10:06 session failed; at 10:06:12 the helper plans 10:21 for the 10:08 cycle and the MT is queued
    at 10:07. Recovery said "the next cycle (expected 10:06Z) is outside ±14 min: it will be rejected",
    counting from the last report instead of from when the MT was queued; the firmware model takes it."""
    falling(rig)
    plan = plan_parachute(rig.reports.for_imei(IMEI), at(6.2), rig.life.for_imei(IMEI), requested=(10, 21))
    assert plan.cycles[0].fix_earliest < at(8.5) and plan.hhmm == "10:21"
    message = MtComposer().add("PARACHUTE", (10, 21)).build()
    authorize_mt(
        rig.store, "DRS1", "alice", message, rig.reports.for_imei(IMEI), single_operator_waiver=WAIVER,
        require_second_operator=False, override_landed=REASON,
    )  # fmt: skip
    rig.send(message, at(7))
    override = override_now(rig)
    assert override is not None
    drop, words = drop_schedule(override, rig.reports.for_imei(IMEI))
    assert drop == at(8) and "rejected" not in words, words
    rig.cycle(at(8), alt=12_000.0)
    assert rig.capsule.parachute_open, "the firmware model took it at the 10:08 cycle, as both now say"


def test_a_parachute_outside_the_window_of_its_cycle_is_said_to_be_rejected_as_the_firmware_does(
    rig: Rig,
) -> None:
    falling(rig)
    overridden_send(rig, (10, 30))
    override = override_now(rig)
    assert override is not None
    drop, words = drop_schedule(override, rig.reports.for_imei(IMEI))
    assert drop is None and "outside ±14 min of 10:30: it will be rejected" in words
    rig.cycle(at(6), alt=14_200.0)
    assert not rig.capsule.parachute_open
    override = override_now(rig)
    assert override is not None
    drop, words = drop_schedule(override, rig.reports.for_imei(IMEI))
    assert drop is None and words.startswith("downloaded with the 10:06Z fix, outside ±14 min")


def test_an_overridden_parachute_does_not_tick_landing_confirmed(rig: Rig) -> None:
    falling(rig)
    command = overridden_send(rig, (10, 6))
    checklists = load_checklists(PROCEDURE_DIR)
    assert complete_mt_steps(rig.store, checklists, "alice", command, rig.reports.for_imei(IMEI)) == []


def test_a_later_parachute_with_landed_evidence_ends_the_banner(rig: Rig) -> None:
    falling(rig)
    overridden_send(rig, (10, 6))
    assert override_now(rig) is not None
    for minute in (8, 10, 12, 14):
        rig.cycle(at(minute), alt=420.0)
    message = MtComposer().add("PARACHUTE", (10, 16)).build()
    signed = [replace(r, delivery=replace(r.delivery, jwt_verified=True)) for r in rig.reports.for_imei(IMEI)]
    authorize_mt(  # signed reports: UNVERIFIED evidence would need another login's approval (issue #31)
        rig.store,
        "DRS1",
        "alice",
        message,
        signed,
        single_operator_waiver=WAIVER,
        require_second_operator=False,
    )
    assert override_now(rig) is None


def test_nothing_is_said_when_the_overridden_mt_never_reached_the_gateway(rig: Rig) -> None:
    falling(rig)
    message = MtComposer().add("PARACHUTE", (10, 6)).build()
    authorize_mt(
        rig.store,
        "DRS1",
        "alice",
        message,
        rig.reports.for_imei(IMEI),
        single_operator_waiver=WAIVER,
        require_second_operator=False,
        override_landed=REASON,
    )
    rig.clock.now = at(5) + timedelta(seconds=1)
    rig.life.request(CAPSULE, message)  # and never sent
    assert override_now(rig) is None, "requested, never sent: it cannot drop anything"
