"""Live re-prediction on synthetic descents whose truth differs from the forecast in a known way."""

from __future__ import annotations

from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import pytest

from console.commands.main import main
from predictor.descent.model import BinnedWind, DescentRateScale, Term
from predictor.descent.payload import PROFILES
from predictor.environment.cube import WeatherCube
from predictor.errors import PredictorError
from predictor.prediction.live import (
    LIVE_ERROR_MODEL,
    NO_CORRECTION,
    OWN_RATE,
    LiveCorrection,
    LivePredictor,
    WindGain,
)
from predictor.prediction.uncertainty import GEOD
from predictor.tracks.cleaning import clean
from predictor.tracks.reading import Fix
from tests.predictor.predict_helpers import RELEASE, isothermal_cube
from tests.predictor.synthetic_flights import synthetic_flight

PAYLOAD = PROFILES["drs"]
BAND = (15000.0, 20000.0)
BAND_ERROR_MS = 8.0


def forecast() -> WeatherCube:
    return isothermal_cube(u=10.0, v=2.0)


def descent_of(effects: list[Term]) -> tuple[list[Fix], Fix]:
    """The logged descent (cleaned, without its landing fix) and the true landing.

    A fix every 40 s: at the DRS's ~6 m/s sea-level rate the 5 km wind band still holds several.
    """
    flown = synthetic_flight(
        forecast(), launch_time=RELEASE - timedelta(hours=2), lat=46.0, lon=6.0, payload=PAYLOAD,
        effects=effects, cadence_s=40.0, noise_m=0.0, ground_fixes=3, seed=1,
    )  # fmt: skip
    flight = clean(flown.track)
    return list(flight.descent[:-1]), flown.landing


def band_truth() -> tuple[list[Fix], Fix]:
    wrong = BinnedWind(edges_m=BAND, east_ms=(BAND_ERROR_MS,), north_ms=(0.0,))
    return descent_of([wrong])


def miss_km(live: LivePredictor, fix: Fix, truth: Fix, correction: LiveCorrection) -> float:
    p = live.predict_from(fix, correction).prediction
    return GEOD.inv(p.landing.lon, p.landing.lat, truth.lon, truth.lat)[2] / 1000.0


def fed(fixes: list[Fix], until_alt_m: float) -> tuple[LivePredictor, Fix]:
    live = LivePredictor(forecast(), PAYLOAD)
    last = fixes[0]
    for fix in fixes:
        if fix.alt_m < until_alt_m:
            break
        live.observe(fix)
        last = fix
    return live, last


def test_the_wind_error_is_measured_in_its_band_and_nowhere_else() -> None:
    fixes, _ = band_truth()
    live, _ = fed(fixes, -1e9)
    inside = [g for g in live.legs if g.bottom_m >= BAND[0] + 50 and g.top_m <= BAND[1] - 50]
    below = [g for g in live.legs if g.top_m <= BAND[0] - 50]
    above = [g for g in live.legs if g.bottom_m >= BAND[1] + 50]
    assert inside and below and above
    for g in inside:
        assert g.wind_error[0] == pytest.approx(BAND_ERROR_MS, abs=0.3)
        assert g.wind_error[1] == pytest.approx(0.0, abs=0.3)
    for g in below + above:
        assert abs(g.wind_error[0]) < 0.3 and abs(g.wind_error[1]) < 0.3
        assert g.rate_factor == pytest.approx(1.0, abs=0.02)


def test_below_the_band_a_decaying_correction_beats_carrying_the_error_to_the_ground() -> None:
    fixes, truth = band_truth()
    live, report = fed(fixes, BAND[0] - 1500.0)
    assert BAND[0] - 1500.0 <= report.alt_m < BAND[0]
    plain = miss_km(live, report, truth, NO_CORRECTION)
    decaying = miss_km(live, report, truth, LiveCorrection.everywhere(False, 1000.0))
    constant = miss_km(live, report, truth, LiveCorrection.everywhere(False, 1e12))
    # The air below the band is as forecast: restarting from the report is nearly exact, carrying the
    # band's error down to the ground is kilometres wrong, and a short decay stays close.
    assert plain < 0.1
    assert constant > 3.0
    assert decaying < 0.5 * constant


def test_inside_the_band_the_correction_moves_the_landing_toward_the_truth() -> None:
    fixes, truth = band_truth()
    live, report = fed(fixes, 0.5 * (BAND[0] + BAND[1]))
    assert BAND[0] + 1000.0 < report.alt_m < BAND[1]
    plain = miss_km(live, report, truth, NO_CORRECTION)
    corrected = miss_km(live, report, truth, LiveCorrection.everywhere(False, 2000.0))
    # The correction assumes a smooth decay, the truth stops sharply at the band's bottom: it recovers
    # a good part of the miss, not all of it.
    assert plain > 1.0
    assert corrected < 0.7 * plain


def test_the_wind_gain_carries_its_share_of_the_measured_error_and_none_carries_all_of_it() -> None:
    # A model file without ``wind_gain`` (written before it was learned) flies all of the error, as
    # it did; a gain g moves the landing g of the way from the restart's to that one's (the isothermal
    # forecast is horizontally uniform, so the added wind's drift is linear in it).
    fixes, truth = band_truth()
    live, report = fed(fixes, 0.5 * (BAND[0] + BAND[1]))
    whole = LiveCorrection.everywhere(False, 2000.0)

    def landing(correction: LiveCorrection) -> tuple[float, float]:
        p = live.predict_from(report, correction)
        return p.prediction.landing.lat, p.prediction.landing.lon

    def gain(g: float) -> LiveCorrection:
        return replace(whole, wind_gain=WindGain((5.0, 30.0), (g, g)))

    assert whole.wind_gain is None and live.predict_from(report, whole).wind_gain is None
    assert landing(gain(1.0)) == pytest.approx(landing(whole), abs=1e-9)
    assert landing(gain(0.0)) == pytest.approx(landing(NO_CORRECTION), abs=1e-9)
    half = live.predict_from(report, gain(0.5))
    assert half.wind_gain == 0.5 and half.wind_error_ms == live.predict_from(report, whole).wind_error_ms
    midpoint = GEOD.inv(*landing(NO_CORRECTION)[::-1], *landing(whole)[::-1])[2] / 2.0
    assert GEOD.inv(*landing(NO_CORRECTION)[::-1], *landing(gain(0.5))[::-1])[2] == pytest.approx(
        midpoint, rel=0.01
    )
    assert miss_km(live, report, truth, gain(0.5)) < miss_km(live, report, truth, NO_CORRECTION)
    assert WindGain((2.0, 10.0), (0.0, 0.8)).at(6.0) == pytest.approx(0.4), "linear in height between"


def test_a_faster_descent_is_measured_and_scales_the_rest_of_the_fall() -> None:
    fixes, truth = descent_of([DescentRateScale(scale=1.3)])
    live, report = fed(fixes, 12000.0)
    rate = live.rate(report).factor
    assert rate == pytest.approx(1.3, abs=0.03)
    plain = live.predict_from(report, NO_CORRECTION)
    corrected = live.predict_from(report, LiveCorrection.everywhere(True, None))
    assert corrected.rate_factor == pytest.approx(rate)
    late_plain = abs((plain.prediction.landing.time - truth.time).total_seconds())
    late_corrected = abs((corrected.prediction.landing.time - truth.time).total_seconds())
    assert late_plain > 120.0
    assert late_corrected < 0.15 * late_plain
    assert miss_km(live, report, truth, LiveCorrection.everywhere(True, None)) < 0.3 * miss_km(
        live, report, truth, NO_CORRECTION
    )


def test_the_live_ellipse_shrinks_as_the_capsule_comes_down() -> None:
    fixes, _ = band_truth()
    live = LivePredictor(forecast(), PAYLOAD, correction=OWN_RATE)
    sigmas = [live.update(f).prediction.ellipse.sigma_parallel_km for f in fixes]
    assert sigmas[0] == pytest.approx(max(LIVE_ERROR_MODEL.sigma_parallel_km[:2]), rel=0.2)
    assert sigmas[-1] < 0.5 * sigmas[0]
    assert sigmas[-1] == pytest.approx(LIVE_ERROR_MODEL.sigma_parallel_km[-1])


def test_a_report_not_after_the_previous_one_is_refused() -> None:
    fixes, _ = band_truth()
    live = LivePredictor(forecast(), PAYLOAD)
    live.update(fixes[3])
    with pytest.raises(PredictorError, match="is not after the previous one"):
        live.update(fixes[2])


def test_live_cli_needs_a_track_and_weather(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["live", "--ascent-winds"]) == 2
    assert capsys.readouterr().err.strip() == "drs: error: drs live needs --track FILE"
    assert main(["live", "--track", str(tmp_path / "t.csv")]) == 2
    assert "needs --weather FILE... or --ascent-winds" in capsys.readouterr().err
    assert main(["live", "evaluate"]) == 2
    assert "needs track files" in capsys.readouterr().err


def test_the_flights_own_evidence_favours_its_lambda_when_it_falls_off_the_law() -> None:
    # Asked 1.5 and 3 km higher up, the λ the record then allowed predicts the fall to the report far
    # better than the law as it stands; on a flight that falls as the law says, neither is worse.
    fast, _ = descent_of([DescentRateScale(scale=1.3)])
    live, report = fed(fast, 12000.0)
    evidence = live.self_check(report)
    assert evidence is not None
    assert evidence["λ"] < 0.05 * evidence["plain"]
    assert evidence["plain"] == pytest.approx(0.0688, rel=0.2), "ln(1.3)² ≈ 0.069: the law's miss"
    lawful, _ = descent_of([])
    live, report = fed(lawful, 12000.0)
    evidence = live.self_check(report)
    assert evidence is not None and max(evidence.values()) < 0.002


def test_no_evidence_before_the_record_reaches_the_first_check() -> None:
    fixes, _ = descent_of([])
    live, report = fed(fixes, fixes[0].alt_m - 1000.0)
    assert live.self_check(report) is None
