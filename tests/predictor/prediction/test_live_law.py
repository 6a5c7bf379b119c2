"""Live re-prediction with the flown model's descent law: synthetic descents whose density law is known.

The truth falls with a density exponent the textbook ρ^-½ lacks and 20 % faster than the payload's
drag law. A live predictor that knows the law (a calibrated model's term) and fits only the rate must
predict the remaining time far better than one that carries the measured rate down with ρ^-½.

Every synthetic flight and every random draw here is seeded, so each test is deterministic; where a
tolerance guards an estimate, the comment gives how many standard errors it is (false-failure rate
under a fresh seed far below 10⁻⁶).
"""

from __future__ import annotations

import math
from datetime import timedelta

import numpy as np
import pytest

from predictor.descent import RatePrior, Release
from predictor.descent.model import DeploymentDelay, DescentRateScale, DragDensityExponent, TwoRegimeRate
from predictor.descent.payload import PROFILES
from predictor.prediction import CalibratedModel, FlightSetup
from predictor.prediction.landings import predict
from predictor.prediction.live import (
    DEFAULT_DISCREPANCY,
    DEFAULT_ELLIPSE_NOTE,
    OWN_RATE,
    RECORD_WINDOW_M,
    LiveCorrection,
    LivePredictor,
    RateDiscrepancy,
    fit_rate,
    update_rate,
)
from predictor.tracks.cleaning import clean
from predictor.tracks.reading import Fix
from tests.predictor.predict_helpers import RELEASE, isothermal_cube
from tests.predictor.synthetic_flights import synthetic_flight

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


def fed_to(live: LivePredictor, fixes: list[Fix], report_alt_m: float = REPORT_ALT_M) -> Fix:
    """Observe the fixes down to the first at or below the report altitude, which is the report."""
    for fix in fixes:
        live.observe(fix)
        if fix.alt_m <= report_alt_m:
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
    fit = with_law.record.rate_fit(report.alt_m)
    assert fit is not None
    assert fit.factor == pytest.approx(TRUE_RATE, rel=0.01)


def test_every_fix_of_the_record_within_its_window_is_fitted() -> None:
    fixes, _ = descent(1.0, 10.0)
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,))
    report = fed_to(live, fixes)
    # The record starts at the highest report (GNSS noise can put it a few fixes after the first).
    top = int(np.argmax([f.alt_m for f in live.reports]))
    record = live.reports[top:]
    whole = live.record.rate_fit(report.alt_m, window_m=math.inf)
    assert whole is not None and whole.fixes == len(record)
    recent = live.record.rate_fit(report.alt_m)
    in_window = sum(f.alt_m <= report.alt_m + RECORD_WINDOW_M for f in record)
    assert recent is not None and recent.fixes == in_window < len(record)
    rate = live.predict_from(report, WHOLE_DESCENT_RATE).rate
    assert rate is not None and rate.fixes == recent.fixes


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


def test_one_descent_logged_every_second_or_every_minute_gives_the_same_lambda() -> None:
    # The same flight (same seed, GNSS noise 3 m) logged at 1 Hz, every 10 s and once a minute, down to
    # 12 km (6 km of record at ~23 m/s): each fix weighs the height it spans, so the three give the same
    # integral over height. λ within 0.5 % (the logs' noise differs fix by fix; measured on EOSS and V4
    # records thinned from 15 s to 180 s and from 1 s to 60 s, ln λ moved 0.014 and 0.006 on average).
    # And the record counts at most one independent fix per 250 m of fall: logged every 10 s (a fix per
    # ~230 m) it already holds them all, so 1 Hz claims no more than a factor 1.5 on σ (counted fix by
    # fix, 1 Hz claimed a σ √(260/26) ≈ 3× smaller, and far smaller still on a slow descent).
    fits = {}
    for cadence_s in (1.0, 10.0, 60.0):
        flown = synthetic_flight(
            isothermal_cube(u=10.0, v=2.0), launch_time=RELEASE - timedelta(hours=2), lat=46.0, lon=6.0,
            payload=PAYLOAD, effects=[LAW, DescentRateScale(scale=TRUE_RATE)], cadence_s=cadence_s,
            noise_m=3.0, ground_fixes=3, seed=3,
        )  # fmt: skip
        live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,))
        report = fed_to(live, list(clean(flown.track).descent[:-1]), 12000.0)
        fits[cadence_s] = live.record.rate_fit(report.alt_m)
    dense, ten, sparse = fits[1.0], fits[10.0], fits[60.0]
    assert dense is not None and ten is not None and sparse is not None
    assert dense.fixes > 40 * sparse.fixes
    assert dense.factor == pytest.approx(sparse.factor, rel=0.005)
    assert dense.factor == pytest.approx(ten.factor, rel=0.005)
    assert 1 / 1.5 < dense.log_sigma / ten.log_sigma < 1.5


def test_a_dense_record_moves_the_prior_no_further_than_the_measured_spread_allows() -> None:
    # A 1 Hz record that says λ = 1.2 against a prior of the law ± 10 %, with a measured record-to-
    # remaining spread of 10 %: the posterior is the precision-weighted mean, close to half-way in ln λ
    # (the record's own σ adds a little), never the record alone, and its σ is never below the two
    # combined, however many fixes the record has.
    fixes, _ = descent(1.0, 10.0)
    table = RateDiscrepancy((1.0, 30.0), (0.0, 0.0), (0.1, 0.1), (0.0, 0.0), (0.1, 0.1), (20, 20))
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,), discrepancy=table)
    report = fed_to(live, fixes, 12000.0)
    rate = live.rate(report)
    fit = live.record.rate_fit(report.alt_m)
    assert fit is not None and fit.fixes > 200 and fit.factor == pytest.approx(TRUE_RATE, rel=0.01)
    noise = fit.log_sigma**2 + 0.1**2
    expected = math.log(fit.factor) * 0.1**2 / (0.1**2 + noise)
    assert math.log(rate.factor) == pytest.approx(expected, rel=1e-6)
    assert 0.4 * math.log(TRUE_RATE) < math.log(rate.factor) < 0.55 * math.log(TRUE_RATE)
    assert rate.log_sigma == pytest.approx(1 / math.sqrt(1 / 0.1**2 + 1 / noise), rel=1e-6)
    assert rate.log_sigma >= 0.1 / math.sqrt(2.0) - 1e-9


def test_a_record_too_short_gives_no_rate() -> None:
    assert fit_rate(np.array([0.0]), np.array([0.0])) is None
    assert fit_rate(np.array([0.0, 10.0]), np.array([5.0, 5.0])) is None
    fixes, _ = descent(180.0, 3.0)
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD)
    live.observe(fixes[0])
    assert live.record.rate_fit(fixes[0].alt_m) is None
    alone = live.rate(fixes[0])
    assert alone.factor == 1.0 and alone.measured is None and math.isinf(alone.log_sigma)
    prior = RatePrior(median=1.1, log_sigma=0.05, flights=12)
    with_prior = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, prior=prior)
    with_prior.observe(fixes[0])
    assert with_prior.rate(fixes[0]).factor == pytest.approx(1.1), "no record: the prior's median"
    assert with_prior.rate(fixes[0]).log_sigma == pytest.approx(0.05)


def test_a_departure_every_flight_shares_is_taken_out_and_its_spread_leans_on_the_prior() -> None:
    # The synthetic flight falls 20 % faster than the law. If the evaluation flights' records also
    # showed 20 % more than their whole descents at this height, nothing of it is this flight's own:
    # λ comes back to 1.
    fixes, _ = descent(120.0, 3.0)
    live = LivePredictor(
        isothermal_cube(u=10.0, v=2.0),
        PAYLOAD,
        effects=(LAW,),
        discrepancy=RateDiscrepancy((5.0, 25.0), (math.log(TRUE_RATE),) * 2, (0.0, 0.0)),
    )
    report = fed_to(live, fixes)
    assert live.rate(report).factor == pytest.approx(1.0, abs=0.01)
    assert live.rate(report).measured == pytest.approx(TRUE_RATE, rel=0.01)
    # A record whose departure spreads widely across flights says little: λ stays near the prior.
    prior = RatePrior(median=1.0, log_sigma=0.05, flights=20)
    vague = LivePredictor(
        isothermal_cube(u=10.0, v=2.0),
        PAYLOAD,
        effects=(LAW,),
        prior=prior,
        discrepancy=RateDiscrepancy((5.0, 25.0), (0.0, 0.0), (0.5, 0.5)),
    )
    sharp = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,), prior=prior)
    fed_to(vague, fixes)
    fed_to(sharp, fixes)
    assert vague.rate(report).factor < 1.01
    assert sharp.rate(report).factor == pytest.approx(TRUE_RATE, rel=0.02)
    assert sharp.rate(report).log_sigma < prior.log_sigma


def test_the_prior_is_the_law_as_wide_as_the_remaining_descents_were_from_it_at_the_reports_height() -> None:
    # The evaluation flights' remaining descent at 5 km fell 1.3× the law, at 25 km 0.9×: a report with
    # no record yet flies the law itself (the plain restart), and the height's measured departure from
    # it (mean and spread, in quadrature) is how far the record may move it; the whole-descent prior is
    # not used when the height has its own.
    fixes, _ = descent(120.0, 3.0)
    table = RateDiscrepancy(
        (5.0, 25.0), (0.0, 0.0), (0.05, 0.05), (math.log(1.3), math.log(0.9)), (0.04, 0.2), (25, 9)
    )
    whole = RatePrior(median=1.2, log_sigma=0.05, flights=30)
    live = LivePredictor(
        isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,), prior=whole, discrepancy=table
    )
    live.observe(fixes[0])
    height_km = fixes[0].alt_m / 1000.0
    mean = np.interp(height_km, (5.0, 25.0), (math.log(1.3), math.log(0.9)))
    sigma = np.interp(height_km, (5.0, 25.0), (0.04, 0.2))
    start = live.rate(fixes[0])
    assert start.measured is None
    assert start.factor == pytest.approx(1.0, rel=1e-12)
    assert start.log_sigma == pytest.approx(math.hypot(mean, sigma), rel=1e-9)
    assert start.prior is not None and start.prior.flights == 9
    # Without the table the whole-descent prior stands in.
    plain = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,), prior=whole)
    plain.observe(fixes[0])
    assert plain.rate(fixes[0]).factor == pytest.approx(1.2)


def test_the_window_follows_a_canopy_whose_rate_changes_with_height() -> None:
    # 1.0× the law above 20 km, 1.3× below (a canopy that opens further lower down): from 12 km the
    # last 6 km of the record say 1.3, the record from its top a blend (1.22 here) that would carry too
    # slow a fall to the ground.
    flown = synthetic_flight(
        isothermal_cube(u=10.0, v=2.0), launch_time=RELEASE - timedelta(hours=2), lat=46.0, lon=6.0,
        payload=PAYLOAD, effects=[LAW, DescentRateScale(scale=1.3), TwoRegimeRate(height_m=20000.0, factor=1 / 1.3)], cadence_s=60.0,
        noise_m=3.0, ground_fixes=3, seed=5,
    )  # fmt: skip
    live = LivePredictor(isothermal_cube(u=10.0, v=2.0), PAYLOAD, effects=(LAW,))
    for report in clean(flown.track).descent:
        live.observe(report)
        if report.alt_m <= 12000.0:
            break
    recent = live.record.rate_fit(report.alt_m)
    whole = live.record.rate_fit(report.alt_m, window_m=math.inf)
    assert recent is not None and whole is not None
    assert recent.factor == pytest.approx(1.3, rel=0.03)
    assert abs(whole.factor - 1.3) > 2.0 * abs(recent.factor - 1.3)


def test_the_update_is_the_product_of_two_normals_in_ln_lambda() -> None:
    prior = RatePrior(median=1.0, log_sigma=0.1, flights=10)
    fit = fit_rate(np.linspace(0.0, 1000.0, 50) / 1.2, np.linspace(0.0, 1000.0, 50))
    assert fit is not None
    equal = update_rate(prior, fit, log_bias=0.0, log_spread=math.sqrt(0.1**2 - fit.log_sigma**2))
    # Equal variances: the posterior mean is half-way in ln λ, its variance halved.
    assert math.log(equal.factor) == pytest.approx(0.5 * math.log(1.2), rel=1e-6)
    assert equal.log_sigma == pytest.approx(0.1 / math.sqrt(2.0), rel=1e-6)


def test_the_stated_sigma_of_lambda_covers_the_truth_under_correlated_1hz_noise() -> None:
    # A 1 Hz record whose time errors are AR(1) with 30 s memory (a slow swing and GNSS drift):
    # counted as independent fixes the σ would be ~8× too small and cover the truth in ~25 % of the
    # draws. With the (1+ρ)/(1−ρ) widening the 2σ interval should hold it in ~95 %; 20 seeded draws,
    # at least 16 inside (false-failure rate under fresh seeds 0.3 % for a true 95 % coverage).
    inside = 0
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        model_s = np.arange(0.0, 1200.0)
        noise = np.zeros(model_s.size)
        for i in range(1, model_s.size):
            noise[i] = math.exp(-1.0 / 30.0) * noise[i - 1] + rng.normal(0.0, 2.0)
        fit = fit_rate(model_s / TRUE_RATE + 25.0 + noise, model_s)
        assert fit is not None
        inside += abs(math.log(fit.factor / TRUE_RATE)) <= 2.0 * fit.log_sigma
    assert inside >= 16


def test_a_canopy_delay_counts_from_the_release_not_from_the_report() -> None:
    # The model and the truth open the canopy 90 s after release, falling 3× faster until then. A live
    # report from 10 km must not open it again 90 s after the report: that would end the fall early.
    delay = DeploymentDelay(delay_s=90.0, speed_factor=3.0)
    cube = isothermal_cube(u=10.0, v=2.0)
    flown = synthetic_flight(
        cube, launch_time=RELEASE - timedelta(hours=2), lat=46.0, lon=6.0, payload=PAYLOAD, effects=[delay],
        cadence_s=60.0, noise_m=0.0, ground_fixes=3, seed=3,
    )  # fmt: skip
    fixes = list(clean(flown.track).descent[:-1])
    live = LivePredictor(cube, PAYLOAD, effects=(delay,), correction=LiveCorrection())
    for fix in fixes:
        live.observe(fix)
        if fix.alt_m <= 10000.0:
            break
    truth_s = (flown.landing.time - fix.time).total_seconds()
    live_s = live.predict_from(fix).prediction.descent_s
    restarted_s = predict(
        cube, Release(fix.time, fix.lat, fix.lon, fix.alt_m), FlightSetup(PAYLOAD, effects=(delay,))
    ).descent_s
    assert abs(live_s - truth_s) < 15.0
    assert truth_s - restarted_s > 40.0, "the delay re-applied at the report must show, or this shows nothing"


def test_a_model_without_live_settings_flies_its_shape_with_its_own_lambda_and_says_so() -> None:
    cube = isothermal_cube(u=10.0, v=2.0)
    bare = CalibratedModel(PAYLOAD, (LAW,), None).live_predictor(cube)
    assert bare.correction == OWN_RATE and bare.discrepancy == DEFAULT_DISCREPANCY and bare.prior is None
    assert any(
        n.startswith("no live settings of its own") and "conservative default discrepancy and prior" in n
        for n in bare.notes
    )
    # No prior of its own, yet never λ from the descent alone: the default's prior by height (the law,
    # as wide as several payloads' flights were from it).
    assert DEFAULT_ELLIPSE_NOTE in bare.notes and not any(
        "λ from this descent alone" in n for n in bare.notes
    )
    assert bare.rate(Fix(RELEASE, 46.0, 6.0, 20000.0)).log_sigma < 0.5
    # The calibration's convention: the prior's median flies as a descent_rate_scale among the terms, so
    # the live update (a factor on those terms) starts from 1 with the prior's spread.
    prior = RatePrior(median=0.95, log_sigma=0.1, flights=9)
    calibrated = CalibratedModel(PAYLOAD, (DescentRateScale(scale=0.95), LAW), None, rate_prior=prior)
    live = calibrated.live_predictor(cube)
    assert live.prior is not None and live.prior.median == pytest.approx(1.0) and live.prior.log_sigma == 0.1
    assert not any(n.startswith(("λ prior", "no λ prior")) for n in live.notes)
    plain = calibrated.live_predictor(cube, corrected=False)
    assert plain.correction == LiveCorrection(), "--no-correction: the plain restart from each report"
