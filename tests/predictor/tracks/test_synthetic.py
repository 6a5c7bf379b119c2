"""Synthetic flights: known truth, logged like a tracker, cleaned like a real file, and measured back."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from predictor.descent.model import DescentRateScale
from predictor.descent.payload import PROFILES
from predictor.environment.cube import WeatherCube
from predictor.errors import PredictorError
from predictor.tracks.ascent_winds import ascent_wind_profile
from predictor.tracks.cleaning import clean, distance_m
from predictor.tracks.standard_atmosphere import R_DRY_AIR, pressure_temperature
from predictor.tracks.synthetic import synthetic_flight

LAUNCH = datetime(2024, 5, 1, 8, 0, 0, tzinfo=UTC)
PAYLOAD = PROFILES["superbit-test"]


def uniform_cube(u: float, v: float) -> WeatherCube:
    """A standard atmosphere with one wind everywhere, around 46°N 6°E, for a day."""
    z = np.arange(-500.0, 40_001.0, 500.0)
    p, t = pressure_temperature(z)
    start = LAUNCH.replace(tzinfo=None)
    times = np.array([start - timedelta(hours=6), start + timedelta(hours=18)], dtype="datetime64[s]")
    shape = (2, len(z), 2, 2)

    def spread(values: np.ndarray | float) -> np.ndarray:
        return np.broadcast_to(
            np.asarray(values, dtype=float)[..., None, None] * np.ones(shape[1:]), shape
        ).copy()

    return WeatherCube(
        times=times, lead_h=np.zeros(2), levels_hpa=p / 100.0, lats=np.array([44.0, 49.0]),
        lons=np.array([3.0, 10.0]), z_m=spread(z), u=spread(np.full(len(z), u)), v=spread(np.full(len(z), v)),
        temperature_k=spread(t), density=spread(p / (R_DRY_AIR * t)), source="uniform test atmosphere",
    )  # fmt: skip


@pytest.fixture(scope="module")
def cube() -> WeatherCube:
    return uniform_cube(8.0, 3.0)


def test_a_synthetic_flight_cleans_like_a_real_one_and_its_fixes_bracket_the_truth(cube: WeatherCube) -> None:
    flight = synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, seed=3)
    cleaned = clean(flight.track)
    assert cleaned.usable and cleaned.flags == ()
    assert cleaned.peak is not None and cleaned.descent_start is not None and cleaned.landing is not None
    assert cleaned.peak.time <= flight.burst.time < cleaned.descent_start.time
    assert (cleaned.descent_start.time - flight.burst.time).total_seconds() < 180
    assert flight.landing.time <= cleaned.landing.time < flight.landing.time + timedelta(seconds=180)
    assert distance_m(cleaned.landing, flight.landing) < 30
    assert [r.rule for r in cleaned.removals] == ["before-launch", "after-landing"]


def test_the_ascent_of_a_synthetic_flight_measures_the_wind_it_was_flown_in(cube: WeatherCube) -> None:
    profile = ascent_wind_profile(clean(synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1,
                                                         payload=PAYLOAD, seed=5).track))  # fmt: skip
    assert np.max(np.abs(profile.u - 8.0)) < 0.1 and np.max(np.abs(profile.v - 3.0)) < 0.1


def test_fixes_carry_the_weathers_pressure_at_their_true_altitude(cube: WeatherCube) -> None:
    track = synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, noise_m=0.0).track
    for fix in track.fixes[::7]:
        assert fix.pressure_pa == pytest.approx(float(pressure_temperature(fix.alt_m)[0]), rel=2e-3)
    no_pressure = synthetic_flight(
        cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, with_pressure=False
    )
    assert all(f.pressure_pa is None for f in no_pressure.track.fixes)


def test_an_effect_switched_on_changes_the_true_descent_and_the_logged_one(cube: WeatherCube) -> None:
    """λ = 0.8 makes every descent rate 20 % slower: the fall takes 1/0.8 as long."""
    plain = synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, seed=1)
    slow = synthetic_flight(
        cube,
        launch_time=LAUNCH,
        lat=46.2,
        lon=6.1,
        payload=PAYLOAD,
        seed=1,
        effects=[DescentRateScale(scale=0.8)],
    )
    assert slow.effects == (DescentRateScale(scale=0.8),) and "descent_rate_scale" in slow.track.source

    def true_fall(f: object) -> float:
        return (f.landing.time - f.burst.time).total_seconds()  # type: ignore[attr-defined]

    assert true_fall(slow) / true_fall(plain) == pytest.approx(1 / 0.8, rel=0.01)
    measured = [clean(f.track).descent_time_s for f in (plain, slow)]
    assert measured[1] - measured[0] == pytest.approx(true_fall(slow) - true_fall(plain), abs=2 * 180)


def test_a_one_hertz_logger_flight_with_gnss_noise_still_cleans_to_the_true_landing(
    cube: WeatherCube,
) -> None:
    flight = synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, cadence_s=1.0,
                              noise_m=4.0, ground_fixes=120, seed=2)  # fmt: skip
    assert len(flight.track.fixes) > 8000
    cleaned = clean(flight.track)
    assert cleaned.usable and cleaned.landing is not None and cleaned.descent_start is not None
    assert abs((cleaned.landing.time - flight.landing.time).total_seconds()) < 10
    assert distance_m(cleaned.landing, flight.landing) < 60
    assert abs((cleaned.descent_start.time - flight.burst.time).total_seconds()) <= 3


def test_a_flight_across_the_antimeridian_keeps_longitudes_in_range() -> None:
    z = uniform_cube(25.0, 0.0)
    cube = WeatherCube(**{**z.__dict__, "lons": np.array([178.0, 184.0])})
    flight = synthetic_flight(cube, launch_time=LAUNCH, lat=46.0, lon=179.5, payload=PAYLOAD, noise_m=0.0)
    assert flight.landing.lon < 0 and all(-180 <= f.lon < 180 for f in flight.track.fixes)
    assert clean(flight.track).usable


def test_a_naive_launch_time_is_refused(cube: WeatherCube) -> None:
    with pytest.raises(PredictorError, match="launch_time must be timezone-aware"):
        synthetic_flight(cube, launch_time=LAUNCH.replace(tzinfo=None), lat=46.2, lon=6.1, payload=PAYLOAD)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cadence_s": 0.0}, "cadence_s > 0"),
        ({"noise_m": -1.0}, "noise_m >= 0"),
        ({"burst_alt_m": 500.0}, "must be at least 1000 m above the launch"),
    ],
)
def test_impossible_settings_are_refused(cube: WeatherCube, kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(PredictorError, match=message):
        synthetic_flight(cube, launch_time=LAUNCH, lat=46.2, lon=6.1, payload=PAYLOAD, **kwargs)
