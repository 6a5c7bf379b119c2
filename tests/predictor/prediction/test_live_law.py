"""Live re-prediction with the flown model's descent law: synthetic descents whose density law is known.

The truth falls with a density exponent the textbook ρ^-½ lacks and 20 % faster than the payload's
drag law. A live predictor that knows the law (a calibrated model's term) and fits only the rate must
predict the remaining time far better than one that carries the measured rate down with ρ^-½.

Every synthetic flight and every random draw here is seeded, so each test is deterministic; where a
tolerance guards an estimate, the comment gives how many standard errors it is (false-failure rate
under a fresh seed far below 10⁻⁶).
"""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest

from predictor.descent.model import DescentRateScale, DragDensityExponent
from predictor.descent.payload import PROFILES
from predictor.prediction.live import LiveCorrection, LivePredictor, TypicalRate, fit_rate
from predictor.tracks.cleaning import clean
from predictor.tracks.reading import Fix
from predictor.tracks.synthetic import synthetic_flight
from tests.predictor.predict_helpers import RELEASE, isothermal_cube

PAYLOAD = PROFILES["drs"]
LAW = DragDensityExponent(exponent=0.1)
TRUE_RATE = 1.2
WHOLE_DESCENT_RATE = LiveCorrection.everywhere(True, None)
REPORT_ALT_M = 20000.0


def descent(cadence_s: float, noise_m: float) -> tuple[list[Fix], Fix]:
    """The logged descent (cleaned, without its landing fix) and the true touchdown."""
    flown = synthetic_flight(
        isothermal_cube(u=10.0, v=2.0), launch_time=RELEASE - timedelta(hours=2), lat=46.0, lon=6.0,
        payload=PAYLOAD, effects=[LAW, DescentRateScale(scale=TRUE_RATE)], cadence_s=cadence_s,
        noise_m=noise_m, ground_fixes=90 if cadence_s < 10 else 3, seed=3,
    )  # fmt: skip
    return list(clean(flown.track).descent[:-1]), flown.landing


def fed_to(live: LivePredictor, fixes: list[Fix]) -> Fix:
    """Observe the fixes down to the first at or below the report altitude, which is the report."""
    for fix in fixes:
        live.observe(fix)
        if fix.alt_m <= REPORT_ALT_M:
            return fix
    raise AssertionError("the descent never reached the report altitude")


def remaining_error_s(live: LivePredictor, report: Fix, touchdown: Fix) -> float:
    p = live.predict_from(report, WHOLE_DESCENT_RATE).prediction
    return p.descent_s - (touchdown.time - report.time).total_seconds()


@pytest.mark.parametrize(("cadence_s", "noise_m"), [(120.0, 3.0), (1.0, 10.0)], ids=["2 min", "1 Hz noisy"])
def test_with_the_model_law_the_remaining_time_error_shrinks(cadence_s: float, noise_m: float) -> None:
    fixes, touchdown = descent(cadence_s, noise_m)
    cube = isothermal_cube(u=10.0, v=2.0)
    with_law = LivePredictor(cube, PAYLOAD, effects=(LAW,))
    textbook = LivePredictor(cube, PAYLOAD)
    report = fed_to(with_law, fixes)
    fed_to(textbook, fixes)
    assert REPORT_ALT_M - 3000.0 < report.alt_m <= REPORT_ALT_M
    law_error = remaining_error_s(with_law, report, touchdown)
    textbook_error = remaining_error_s(textbook, report, touchdown)
    # ρ^-½ carries the fast upper descent to the ground: the remaining time comes out too short.
    assert textbook_error < -60.0
    assert abs(law_error) < 0.2 * abs(textbook_error)
    fit = with_law.rate_fit(report.alt_m)
    assert fit is not None
    assert fit.factor == pytest.approx(TRUE_RATE, rel=0.01)


def test_every_fix_of_the_record_is_fitted_and_a_window_narrows_it() -> None:
    fixes, _ = descent(1.0, 10.0)
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,))
    report = fed_to(live, fixes)
    whole = live.rate_fit(report.alt_m)
    recent = live.rate_fit(report.alt_m, window_m=3000.0)
    assert whole is not None and recent is not None
    # The record starts at the highest report (GNSS noise can put it a few fixes after the first).
    top = int(np.argmax([f.alt_m for f in live.reports]))
    assert whole.fixes == len(live.reports) - top
    assert recent.fixes == sum(1 for f in live.reports[top:] if f.alt_m - report.alt_m < 3000.0) < whole.fixes
    assert live.predict_from(report, WHOLE_DESCENT_RATE).rate_fixes == whole.fixes


def test_the_rate_fit_shrugs_off_swinging_and_wild_fixes_that_pull_least_squares() -> None:
    rng = np.random.default_rng(11)
    model_s = np.linspace(0.0, 1500.0, 1500)  # 25 minutes of a 1 Hz record, in the law's seconds
    swing = 4.0 * np.sin(2 * np.pi * np.arange(model_s.size) / 5.0)  # a 5 s pendulum, ±4 s in time
    observed = model_s / TRUE_RATE + 40.0 + swing + rng.normal(0.0, 2.0, model_s.size)
    wild = rng.choice(np.arange(model_s.size - 300, model_s.size), size=60, replace=False)
    observed[wild] += 300.0  # 4 % of the fixes, all late in the record: a receiver that lost its lock
    fit = fit_rate(observed, model_s)
    assert fit is not None
    # Standard error of λ from ~1,440 clean fixes with ~4 s scatter over 1,250 s: ~2e-4 relative;
    # 0.3 % is > 10 of them.
    assert fit.factor == pytest.approx(TRUE_RATE, rel=0.003)
    assert fit.offset_s == pytest.approx(40.0, abs=2.0)
    least_squares = 1.0 / np.polyfit(model_s, observed, 1)[0]
    assert abs(least_squares / TRUE_RATE - 1.0) > 0.03, "the outliers must matter, or this test shows nothing"


def test_a_record_too_short_gives_no_rate() -> None:
    assert fit_rate(np.array([0.0]), np.array([0.0])) is None
    assert fit_rate(np.array([0.0, 10.0]), np.array([5.0, 5.0])) is None
    fixes, _ = descent(180.0, 3.0)
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD)
    live.observe(fixes[0])
    assert live.rate_fit(fixes[0].alt_m) is None
    assert live.measured(fixes[0].alt_m)[0] == 1.0


def test_a_factor_every_flight_shares_is_taken_out_and_only_the_flights_own_is_carried_down() -> None:
    # The synthetic flight falls 20 % faster than the law. If the typical flight at that height also
    # fell 20 % faster, nothing of it is particular to this flight: the relative rate flies the law as
    # it is (factor 1), and with a typical factor of 1 the whole-descent rate is flown unchanged.
    fixes, _ = descent(120.0, 3.0)
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,))
    report = fed_to(live, fixes)
    shared = TypicalRate(heights_km=(5.0, 25.0), factors=(1.0, TRUE_RATE))
    at_report = shared.at(report.alt_m / 1000.0)
    assert 1.0 < at_report < TRUE_RATE, "linear in height between the typical factors"
    relative = live.predict_from(report, LiveCorrection.everywhere(True, None, typical_rate=shared))
    whole = live.predict_from(report, WHOLE_DESCENT_RATE)
    fit = live.rate_fit(report.alt_m)
    assert fit is not None
    assert whole.rate_factor == pytest.approx(fit.factor)
    assert relative.rate_factor == pytest.approx(fit.factor / at_report)
    plain = live.predict_from(report, LiveCorrection()).prediction.descent_s
    assert whole.prediction.descent_s < relative.prediction.descent_s < plain
    assert TypicalRate(heights_km=(5.0, 25.0), factors=(0.9, 1.1)).at(40.0) == pytest.approx(1.1), "held beyond"
