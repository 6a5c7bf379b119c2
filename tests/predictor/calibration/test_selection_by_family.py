"""Each family is found on the record that shows it, whatever the other records carry.

The flights are synthetic (``conftest.make_cases``): each in its own weather, logged like a tracker,
cleaned like a real file. Two things make these tests honest:

* **A random wind error on every flight.** Real weather is wrong by a few m/s, differently for each
  flight; on the 3-D track that error is larger than a vertical effect's. Here each flight's truth also
  carries its own constant wind error (east and north each N(0, 3 m/s)) that no library effect can
  share across flights. The vertical record (time against altitude) does not contain the wind at all,
  so the density exponent must still be selected, with its value.
* **Not one lucky seed.** The vertical test runs on five seeds and four cadences. Its false-failure
  rate: the vertical record does not see the wind (the synthetic weather is the same over the whole
  area and the wind error adds horizontal velocity only); its only randomness is the GNSS altitude
  noise and the phase of the fixes. Measured over seeds 0–9 at 3-min cadence (4 flights): the
  exponent's held-out time-RMS improvement 293–335 s, its bootstrap lower bound 273–309 s against a
  floor of 10 s, the runner-up (λ) 60–70 s behind it, the fitted exponent 0.1501–0.1505 (tolerance
  0.02). A failure would need the noise to close a 60 s gap that a 3 m altitude noise (under a second
  of time at the slowest descent) cannot: we put the false-failure rate below 1e-6 per run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from predictor.calibration.effects import LIBRARY, library
from predictor.calibration.report import verdict
from predictor.calibration.residuals import FlightCase
from predictor.calibration.selection import calibrate
from predictor.descent.model import (
    DescentRateScale,
    DragDensityExponent,
    WeatherTimeOffset,
    WindBandScale,
    WindOffset,
)
from predictor.descent.payload import PROFILES

PAYLOAD = PROFILES["superbit-test"]
Cases = Callable[..., list[FlightCase]]
WIND_ERROR_MS = 3.0
MIXED = ("descent_rate_scale", "drag_density_exponent", "deployment_delay", "wind_scale", "wind_rotation")


@pytest.mark.parametrize(
    ("cadence_s", "seed"), [(180.0, 0), (180.0, 1), (120.0, 2), (300.0, 3), (1.0, 4)],
    ids=["3min-seed0", "3min-seed1", "2min-seed2", "5min-seed3", "1Hz-seed4"],
)  # fmt: skip
def test_a_density_exponent_is_selected_from_the_vertical_record_despite_a_random_wind_error(
    synthetic_cases: Cases, cadence_s: float, seed: int
) -> None:
    cases = synthetic_cases(
        (DragDensityExponent(exponent=0.15),), n=4, cadence_s=cadence_s, noise_m=2.0 if cadence_s < 10 else 3.0,
        seed=seed, wind_error_ms=WIND_ERROR_MS,
    )  # fmt: skip
    cal = calibrate(cases, PAYLOAD, library(MIXED))
    vertical = [f for f in cal.selected if f.candidate.family == "vertical"]
    assert [f.candidate.name for f in vertical] == ["drag_density_exponent"]
    assert vertical[0].value == pytest.approx(0.15, abs=0.02)
    family = next(f for f in cal.families if f.family == "vertical")
    # The wind error dominates the 3-D track, yet the vertical record is cut to a fraction.
    assert cal.baseline.horizontal_rms_km.mean() > 1.0
    assert family.after.time_rms_s.mean() < 0.2 * family.before.time_rms_s.mean()
    assert (
        np.abs(family.after.descent_time_error_s).mean() < np.abs(family.before.descent_time_error_s).mean()
    )


@pytest.mark.parametrize("cadence_s", [180.0, 1.0], ids=["3min", "1Hz"])
def test_a_wind_band_is_found_on_the_replayed_record_while_a_descent_rate_error_is_put_to_the_vertical(
    synthetic_cases: Cases, cadence_s: float
) -> None:
    """A 10 % slower descent moves the capsule through the jet at the wrong times; scored on the 3-D
    track, a wind effect could soak that up. Replayed, the horizontal record sees only the wind."""
    truth = (DescentRateScale(scale=0.9), WindBandScale(bottom_m=9000.0, top_m=15000.0, scale=1.8))
    cases = synthetic_cases(truth, n=4, cadence_s=cadence_s, noise_m=2.0 if cadence_s < 10 else 3.0)
    cal = calibrate(cases, PAYLOAD, library(["descent_rate_scale", "wind_scale", "wind_band_scale"]))
    found = {f.candidate.name: f for f in cal.selected}
    # λ = 0.9 on every flight is the rate prior, not a shape the shape record could see.
    assert set(found) == {"wind_band_scale"}
    assert cal.rate_prior.median == pytest.approx(0.9, abs=0.01)
    band = found["wind_band_scale"].describe()["parameters"]
    assert (band["bottom_m"], band["top_m"]) == (9000.0, 15000.0)
    assert band["scale"] == pytest.approx(1.8, abs=0.1)
    horizontal = next(f for f in cal.families if f.family == "horizontal")
    assert horizontal.after.horizontal_rms_km.mean() < 0.3 * horizontal.before.horizontal_rms_km.mean()
    assert cal.after.landing_error_km.mean() < 0.2 * cal.baseline.landing_error_km.mean()


def test_a_time_offset_both_records_show_is_timing(synthetic_cases: Cases) -> None:
    """The air high up is 100 % denser over 12 h (and the ground's less dense) as well as windier: an hour's
    offset changes both records."""
    cases = synthetic_cases((WeatherTimeOffset(offset_s=3600.0),), n=4, cadence_s=300.0, density_change=1.0)
    cal = calibrate(cases, PAYLOAD, library(["wind_scale", "descent_rate_scale", "weather_time_offset"]))
    assert [f.candidate.name for f in cal.selected] == ["weather_time_offset"]
    # 5-min fixes replayed piecewise linearly leave the horizontal record a 0.1–0.3 km residual of its
    # own, which blurs the offset; the shape record sees the density change only through its change with
    # altitude (a uniform one is each flight's λ), so it pins the offset less: 10 %.
    assert cal.selected[0].value == pytest.approx(3600.0, abs=400.0)
    timing = cal.rounds[0][-1]
    assert [t.record for t in timing.tests] == ["vertical", "horizontal"] and timing.passed


def test_a_time_offset_only_the_horizontal_record_shows_is_not_blamed_on_timing(
    synthetic_cases: Cases,
) -> None:
    """Density constant in time: the offset only changes the wind met, a wind story, not a timing one."""
    cases = synthetic_cases((WeatherTimeOffset(offset_s=3600.0),), n=4, cadence_s=300.0)
    cal = calibrate(cases, PAYLOAD, library(["wind_scale", "descent_rate_scale", "weather_time_offset"]))
    names = [f.candidate.name for f in cal.selected]
    assert "weather_time_offset" not in names
    timing = next(r for r in cal.rounds[0] if r.full.candidate.name == "weather_time_offset")
    vertical, horizontal = timing.tests
    assert horizontal.passed and not vertical.passed


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_with_only_a_random_wind_error_nothing_is_selected(synthetic_cases: Cases, seed: int) -> None:
    """Each flight's own wind error is not an effect of the set: no family may claim it. Measured with
    5 flights and the whole library: nothing selected for any of seeds 0–7. With only 4 flights the
    bootstrap is weak (4⁴ resamples): with five candidates, seed 3 of 0–9 kept a wind scale."""
    cases = synthetic_cases((), n=5, wind_error_ms=WIND_ERROR_MS, seed=seed)
    cal = calibrate(cases, PAYLOAD, LIBRARY)
    assert cal.selected == ()
    assert cal.baseline.horizontal_rms_km.mean() > 1.0


def test_an_effect_outside_the_library_is_left_to_the_binned_wind_on_the_horizontal_record(
    synthetic_cases: Cases,
) -> None:
    cal = calibrate(
        synthetic_cases((WindOffset(east_ms=4.0, north_ms=0.0),), n=4, cadence_s=240.0), PAYLOAD, LIBRARY
    )
    assert cal.selected == ()
    passed = {t.record: t.passed for t in cal.binned_tests}
    assert passed == {"vertical": False, "horizontal": True}
    assert [t.name for t in cal.binned_terms()] == ["binned_wind"]
    assert "No library effect explains it" in verdict(cal)
