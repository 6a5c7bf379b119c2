"""The calibration loop against a world it did not make (``tests/independent_world.py``).

Each world's flights are flown by the generator's own RK4, atmosphere and physics, each flight with its
own rate factor λᵢ (sd of ln λ 0.06), and read back from its GRIB2 files and CSV tracks. Per case:
the right family or nothing, and a real held-out cut: the model the calibration ships (the shape × the
rate prior's median λ) flown on EIGHT MORE flights of the same world that no fit saw, against the
plain law and against the strongest simple baseline, the plain law × the training flights' median λ.

What a cut can be asked of: on the shape record (each unseen flight's own λ profiled out) the shape's
gain is large and the same on every flight; before the flight, the scatter of λ (6 %, about 80 s of a
45-minute fall) swamps a gain of 20–40 s, so there the model is asked only never to be worse than λ
alone by more than 10 % + 10 s (the issue's own tolerance), and the gain is stated, not promised.

Statistics: noise only is three seeds, each effect one (training 11, unseen 29); the selection's own false-selection
rate is its test's (α = 0.05 one-sided, Bonferroni over the candidates, plus the floor); the shape-record
assertions hold with margins of 3–10× on these worlds (numbers in the comments). About 20 s for the
four cases on one core.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from predictor.calibration.effects import LIBRARY
from predictor.calibration.report import speed_finding
from predictor.calibration.residuals import FlightCase, flight_case, run, score
from predictor.calibration.selection import Calibration, calibrate
from predictor.descent.model import DescentRateScale, Term
from predictor.descent.payload import Payload
from predictor.environment import WeatherCube, load_weather
from predictor.tracks import clean, read_track
from tests.independent_world import (
    CDA_M2,
    MASS_KG,
    NOISE_ONLY,
    TWO_REGIME,
    UPDRAFT,
    WIND_RAMP,
    Effects,
    make_world,
    write_weather,
)

PAYLOAD = Payload(MASS_KG, CDA_M2, name="independent", source="tests/independent_world.py")
STEP_M = 200.0


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Path], WeatherCube]:
    root = tmp_path_factory.mktemp("independent-weather")
    files = list(write_weather(root / "gfs"))
    return files, load_weather(files, cache_dir=root / "cache")


def _cases(
    directory: Path, effects: Effects, seed: int, flights: int, weather: tuple[list[Path], WeatherCube]
) -> list[FlightCase]:
    files, cube = weather
    world = make_world(directory, effects, flights=flights, seed=seed, weather=files)
    return [flight_case(clean(read_track(path)), cube) for path in world.tracks]


def _flown(cases: list[FlightCase], terms: tuple[Term, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time-at-altitude RMS s, the same with the flight's own λ profiled out s, landing error km) of each
    flight flown with the terms."""
    scores = [score(c, run(c, PAYLOAD, terms, 1, STEP_M)) for c in cases]
    return (np.array([s.time_rms_s[0] for s in scores]), np.array([s.shape_time_rms_s[0] for s in scores]),
            np.array([s.landing_error_km[0] for s in scores]))  # fmt: skip


def _world(
    tmp_path: Path, effects: Effects, weather: tuple[list[Path], WeatherCube], seed: int = 11
) -> tuple[Calibration, list[FlightCase]]:
    trained = _cases(tmp_path / "train", effects, seed, 6, weather)
    unseen = _cases(tmp_path / "unseen", effects, 29, 8, weather)
    return calibrate(trained, PAYLOAD, LIBRARY, step_m=STEP_M), unseen


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_noise_only_selects_nothing_and_its_speed_shows_no_systematic_difference(
    tmp_path: Path, weather: tuple[list[Path], WeatherCube], seed: int
) -> None:
    """Three draws (measured on seeds 11–15: nothing selected in any, shape record 0.8–1.0 s, sd of ln λ
    0.027–0.09 from a true 0.06 over 6 flights)."""
    cal, _ = _world(tmp_path, NOISE_ONLY, weather, seed)
    assert cal.selected == () and not cal.unexplained
    assert "no systematic difference" in speed_finding(cal)
    # The shape (the drag law) is exact up to the weather's sampling: under 10 s once λ is profiled.
    assert cal.after.shape_time_rms_s.mean() < 10.0
    assert 0.02 < cal.rate_prior.log_sigma < 0.12, "the flights' own λ scatter (0.06) is seen"


@pytest.mark.parametrize(
    ("effects", "family"),
    [(TWO_REGIME, "vertical"), (UPDRAFT, "vertical"), (WIND_RAMP, "horizontal")],
    ids=["two-regime-canopy", "updraft-band", "wind-ramp"],
)
def test_an_effect_outside_the_library_gets_its_family_and_cuts_the_error_on_unseen_flights(
    tmp_path: Path, weather: tuple[list[Path], WeatherCube], effects: Effects, family: str
) -> None:
    cal, unseen = _world(tmp_path, effects, weather)
    families = {f.candidate.family for f in cal.selected}
    passed_binned = {t.record for t in cal.binned_tests if t.passed}
    assert families | passed_binned, "the effect is there: something must take it up"
    assert families <= {family} and passed_binned <= {family}, (families, passed_binned)
    plain = _flown(unseen, ())
    # λ alone: the plain law × the median of the training flights' own λ under the plain law.
    rate_only = _flown(
        unseen, (DescentRateScale(scale=float(np.exp(np.median(np.log(cal.baseline.rate_factor))))),)
    )
    model = _flown(unseen, cal.terms())
    preflight = _flown(unseen, cal.preflight_terms())
    assert preflight[0].mean() <= 1.1 * rate_only[0].mean() + 10.0, "pre-flight: never worse than λ alone"
    if effects is TWO_REGIME:
        _assert_the_canopy_is_found(cal, TWO_REGIME)
    if family == "vertical":
        # The shape record of every unseen flight: measured 0.7–1.5 s against 17–34 s (two regimes), 14–15
        # against 49–64 s (updraft); asked: under half, on every flight.
        assert (model[1] < 0.5 * plain[1]).all(), (model[1], plain[1])
    else:
        # Landing error: the ramp carries a descent 10 km off (measured 10.6 km mean); the model takes
        # most of it (2.2 km): asked, under half on average and better on every flight.
        assert model[2].mean() < 0.5 * plain[2].mean()
        assert (model[2] < plain[2]).all()


def _assert_the_canopy_is_found(cal: Calibration, truth: Effects) -> None:
    """The two-regime fit against the world's truth: height within 300 m, factor within 0.03.

    Measured (6 training flights, seeds 11-13 at 20 km × 1.3; 17.6 km × 1.4, 23.3 km × 1.25, 14.2 km × 1.5
    and 9.5 km × 1.2 on seed 11): 1-76 m and 0.001-0.007 off on all flights. The tolerance is 4× that and
    still a tenth of the coarse grid's 3 km step: the coarse height alone fitted 21 km × 1.45 here,
    1 km and 0.15 off, which fails it (and made live re-prediction from 20 km worse than a restart)."""
    fitted = next(f for f in cal.selected if f.candidate.name == "two_regime_rate").describe()["parameters"]
    assert isinstance(fitted, dict)
    assert truth.faster_above_m is not None
    assert abs(fitted["height_m"] - truth.faster_above_m) < 300.0, fitted
    assert abs(fitted["factor"] - truth.faster_factor) < 0.03, fitted


def test_a_canopy_break_between_the_coarse_heights_is_fitted_where_it_is(
    tmp_path: Path, weather: tuple[list[Path], WeatherCube]
) -> None:
    """A break at 17.6 km (between the coarse 15 and 18 km, off the fine 1 km heights) × 1.4: the fine
    pass is not tuned to 20 km."""
    truth = Effects(faster_above_m=17_600.0, faster_factor=1.4)
    cal, _ = _world(tmp_path, truth, weather)
    assert [f.candidate.name for f in cal.selected] == ["two_regime_rate"]
    _assert_the_canopy_is_found(cal, truth)
