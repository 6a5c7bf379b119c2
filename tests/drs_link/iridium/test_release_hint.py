"""Recovery's hint of a release from the descent rate: not where denser air slowed an intact canopy.

Issue #23 found "a release or a landing both do that" under a canopy that was only reaching denser
air: its rate halves from 18 km to 5 km (a canopy falls at a speed ∝ 1/√ρ). The fixes here are made
by integrating that law in the 1976 standard atmosphere (``predictor.tracks``'s own table) and flown
through the simulated gateway and firmware, so the test fails if the hint still judges raw rates.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.iridium.mt import MtComposer
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from predictor.tracks import pressure_temperature
from tests.drs_link.iridium.helpers import IMEI
from tests.drs_link.iridium.test_commanded import Rig, at

SEA_LEVEL_RATE_MS = 5.0
"""The DRS under its 4 ft canopy falls ~5 m/s near the ground (Sirks et al. 2020, docs/predictor.md)."""


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        yield Rig(store, gateway)
    store.close()


def canopy_speed(alt_m: float) -> float:
    (pressure, temperature), (p0, t0) = pressure_temperature(alt_m), pressure_temperature(0.0)
    return SEA_LEVEL_RATE_MS / math.sqrt(float((pressure / temperature) / (p0 / t0)))


def fall(alt_m: float, seconds: float, speed_factor: float = 1.0) -> float:
    """The altitude after ``seconds`` under the canopy law (1-s steps), ``speed_factor`` times faster."""
    for _ in range(int(seconds)):
        alt_m -= canopy_speed(alt_m) * speed_factor
    return alt_m


def descend(rig: Rig, free_fall_from_minute: int | None) -> None:
    """Reports every 2 min from 24 km down to ~2 km; PARACHUTE for 10:06 goes down with the 10:06 report."""
    alt = 24_000.0
    for minute in range(0, 40, 2):
        rig.cycle(at(minute), alt=alt)
        if minute == 4:
            rig.send(MtComposer().add("PARACHUTE", (10, 6)).build(), at(5))
        falling_free = free_fall_from_minute is not None and minute >= free_fall_from_minute
        alt = fall(alt, 120.0, 3.0 if falling_free else 1.0)


def test_an_intact_canopy_slowing_in_denser_air_gives_no_release_hint(rig: Rig) -> None:
    descend(rig, free_fall_from_minute=None)
    reports = rig.reports.for_imei(IMEI)
    first, last = reports[0].report.fix, reports[-1].report.fix  # type: ignore[union-attr]
    assert first is not None and last is not None
    assert first.alt_m == 24_000.0 and last.alt_m < 4_000.0, "the fall reaches dense air"
    alts = [r.report.fix.alt_m for r in reports]  # type: ignore[union-attr]
    raw = [(a - b) / 120.0 for a, b in zip(alts, alts[1:], strict=False)]
    assert raw[2] > 2.5 * raw[-1], "the raw rate falls to a third after delivery (what misled the hint)"
    detail = rig.settings().parachute.detail
    assert "hint only" not in detail, detail


def test_a_fall_three_times_faster_after_delivery_is_still_hinted(rig: Rig) -> None:
    """3× the canopy's speed: less than a capsule without its canopy would fall, so the least to catch."""
    descend(rig, free_fall_from_minute=6)
    detail = rig.settings().parachute.detail
    assert (
        "hint only: the descent rate went from" in detail
        and "(a release or a landing both do that)" in detail
    )


def test_the_step_is_one_second_so_the_law_is_followed_closely() -> None:
    """The integration error of the fixes, against halving the step: under 1 m over two minutes."""
    coarse = fall(18_000.0, 120.0)
    fine = 18_000.0
    for _ in range(240):
        fine -= canopy_speed(fine) * 0.5
    assert abs(coarse - fine) < 1.0
