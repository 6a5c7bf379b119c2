"""The recovery pipeline (reports → track → landing → live re-prediction) as one typed value.

The screens and the chase feed read a ``RecoveryView``/``Descent`` instead of each running the pipeline;
these pin what it decides from real reports through the simulated gateway into a real store.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

from drs_link.iridium import TrackPoint
from drs_link.ops.recovery import LiveView, follow_descent, recovery_from
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from predictor.errors import PredictorError
from tests.drs_link.iridium.helpers import IMEI
from tests.drs_link.iridium.test_commanded import Rig, at
from tests.drs_link.ops.test_override import falling, overridden_send


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        yield Rig(store, gateway)
    store.close()


class LiveCalls:
    """Stands in for the console's prediction service (which needs weather): records what it is asked."""

    def __init__(self, answer: LiveView | None = None, error: str | None = None) -> None:
        self.answer, self.error = answer, error
        self.asked: list[tuple[str, tuple[TrackPoint, ...]]] = []

    def __call__(self, capsule: str, track: Sequence[TrackPoint]) -> LiveView | None:
        self.asked.append((capsule, tuple(track)))
        if self.error is not None:
            raise PredictorError(self.error)
        return self.answer


def answer_from(track: tuple[TrackPoint, ...]) -> LiveView:
    """A live re-prediction from the track's last fix, as ``PredictionService.live`` answers."""
    last = track[-1]
    return LiveView(
        report_time=last.time, report_alt_m=last.alt_m, landing_lat=46.61, landing_lon=6.72,
        landing_time=datetime(2026, 7, 1, 10, 31, 7, tzinfo=UTC), remaining_drift_km=7.25,
        sigma_parallel_km=1.5, sigma_perpendicular_km=0.75, measured_rate_factor=1.08, legs_used=2,
        correction="descent rate ×1.08", outline_2sigma=((6.7, 46.6), (6.74, 46.62)),
        path=((6.6, 46.5), (6.72, 46.61)),
    )  # fmt: skip


def reports(rig: Rig) -> list[Any]:
    return rig.reports.for_imei(IMEI)


def test_a_falling_capsule_gets_the_live_re_prediction_from_its_whole_track_as_typed_values(rig: Rig) -> None:
    falling(rig)
    track = follow_descent(reports(rig), "DRS1", None).track
    live = LiveCalls(answer_from(track))
    descent = follow_descent(reports(rig), "DRS1", live)
    assert descent.descending and descent.landing is None and descent.live_error is None
    assert live.asked == [("DRS1", track)] and [p.alt_m for p in track] == [19_900.0, 18_000.0, 16_100.0]
    assert descent.live == answer_from(track), "the live source's view, as it answered"


def test_a_landed_capsule_is_never_re_predicted(rig: Rig) -> None:
    falling(rig)
    for minute in (6, 8, 10, 12):  # then still on the ground at 500 m
        rig.cycle(at(minute))
    live = LiveCalls(error="must not be asked")
    descent = follow_descent(reports(rig), "DRS1", live)
    assert descent.landing is not None and len(descent.track) == 7
    assert not descent.descending and descent.live is None and live.asked == []


def test_a_failed_re_prediction_is_kept_in_words_with_the_track(rig: Rig) -> None:
    falling(rig)
    descent = follow_descent(reports(rig), "DRS1", LiveCalls(error="no weather covers 16100 m"))
    assert descent.live is None and descent.live_error == "no weather covers 16100 m"
    assert len(descent.track) == 3


def test_without_weather_or_fixes_there_is_nothing_to_re_predict(rig: Rig) -> None:
    assert follow_descent([], "DRS1", LiveCalls(error="must not be asked")).track == ()
    falling(rig)
    descent = follow_descent(reports(rig), "DRS1", None)
    assert descent.descending and descent.live is None and descent.live_error is None


def test_the_recovery_view_carries_the_commanded_settings_and_an_overridden_drop(rig: Rig) -> None:
    falling(rig)
    plain = recovery_from("DRS1", reports(rig), rig.life.for_imei(IMEI), rig.store.audit("DRS1"), None)
    assert plain.drop is None and plain.settings is not None
    assert plain.settings.parachute.value == "none"
    overridden_send(rig, (10, 6))
    parachutes = rig.store.audit("DRS1", action="mt.parachute")
    view = recovery_from("DRS1", reports(rig), rig.life.for_imei(IMEI), parachutes, None)
    assert view.drop is not None and view.drop.override.text == "[PARACHUTE=10:06]"
    assert view.drop.opens_at is not None and "next cycle" in view.drop.words
    assert view.settings is not None and "10:06" in view.settings.parachute.line
