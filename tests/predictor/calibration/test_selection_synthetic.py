"""The whole loop on synthetic flights with a hidden effect: it names the effect, cuts the held-out error.

Each test flies a few flights with one effect switched on in the truth (the calibration is not told),
logs them like a tracker, cleans them like a real file, and runs the leave-one-flight-out selection.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from predictor.calibration.effects import LIBRARY, library
from predictor.calibration.report import verdict
from predictor.calibration.residuals import FlightCase
from predictor.calibration.selection import calibrate
from predictor.descent.model import (
    DeploymentDelay,
    DescentRateScale,
    DragDensityExponent,
    Term,
    WindBandScale,
    WindLag,
    WindOffset,
    WindRotation,
    WindScale,
)
from predictor.descent.payload import PROFILES

PAYLOAD = PROFILES["superbit-test"]
Cases = Callable[..., list[FlightCase]]

# (truth, fitted parameter, its true value, tolerance, two distractors, fix cadence s)
LIBRARY_CASES = [
    (DragDensityExponent(exponent=0.15), "exponent", 0.15, 0.01, ("descent_rate_scale", "wind_lag"), 120.0),
    (WindScale(scale=1.3), "scale", 1.3, 0.01, ("wind_band_scale", "descent_rate_scale"), 300.0),
    (WindRotation(angle_deg=20.0), "angle_deg", 20.0, 0.5, ("wind_scale", "weather_time_offset"), 180.0),
    (
        WindBandScale(bottom_m=9000.0, top_m=15000.0, scale=1.8),
        "scale",
        1.8,
        0.05,
        ("wind_scale", "drag_density_exponent"),
        180.0,
    ),  # fmt: skip
    (WindLag(time_constant_s=120.0), "time_constant_s", 120.0, 10.0, ("wind_scale", "wind_rotation"), 180.0),
]


@pytest.mark.parametrize(
    ("truth", "parameter", "value", "tolerance", "distractors", "cadence_s"),
    LIBRARY_CASES,
    ids=[case[0].name for case in LIBRARY_CASES],
)
def test_the_loop_names_the_hidden_library_effect_and_cuts_the_held_out_error(
    synthetic_cases: Cases,
    truth: Term,
    parameter: str,
    value: float,
    tolerance: float,
    distractors: tuple[str, ...],
    cadence_s: float,
) -> None:
    cases = synthetic_cases((truth,), n=4, cadence_s=cadence_s)
    cal = calibrate(cases, PAYLOAD, library([*distractors, truth.name]))
    assert [f.candidate.name for f in cal.selected] == [truth.name]
    assert cal.selected[0].describe()["parameters"][parameter] == pytest.approx(value, abs=tolerance)
    assert cal.after.track_rms_km.mean() < 0.1 * cal.baseline.track_rms_km.mean()
    assert cal.after.landing_error_km.mean() < cal.baseline.landing_error_km.mean()
    assert not cal.unexplained


def test_a_deployment_delay_is_found_in_a_1_hz_log(synthetic_cases: Cases) -> None:
    """1 Hz: the descent starts a second after burst, so the fast fall before the canopy opens is measured."""
    cases = synthetic_cases(
        (DeploymentDelay(delay_s=90.0, speed_factor=3.0),), n=4, cadence_s=1.0, noise_m=2.0
    )
    cal = calibrate(
        cases, PAYLOAD, library(["descent_rate_scale", "drag_density_exponent", "deployment_delay"])
    )
    assert [f.candidate.name for f in cal.selected] == ["deployment_delay"]
    assert cal.selected[0].value == pytest.approx(90.0, abs=3.0)
    assert cal.after.track_rms_km.mean() < 0.1 * cal.baseline.track_rms_km.mean()


@pytest.mark.parametrize("scale", [0.8, 1.2])
def test_a_factor_on_every_flights_rate_is_the_rate_prior_not_a_shape(
    synthetic_cases: Cases, scale: float
) -> None:
    """Among the whole library nothing is selected (the shape is the drag law's), and the pre-flight
    prediction flies the prior's median λ: the held-out track error falls to a tenth."""
    cal = calibrate(synthetic_cases((DescentRateScale(scale=scale),), n=4), PAYLOAD, LIBRARY)
    assert cal.selected == ()
    assert cal.rate_prior.median == pytest.approx(scale, abs=0.01)
    assert cal.rate_prior.log_sigma < 0.01
    assert cal.terms()[0].parameters()["scale"] == cal.rate_prior.median
    assert cal.after.track_rms_km.mean() < 0.1 * cal.baseline.track_rms_km.mean()
    assert cal.after.shape_time_rms_s.mean() < 10.0


def test_an_effect_outside_the_library_is_left_to_the_binned_correction_and_reported_as_unexplained(
    synthetic_cases: Cases,
) -> None:
    """A constant eastward wind bias: not a scale, rotation, band or lag of the forecast wind, since
    every flight's wind blows another way; only the altitude-binned added wind can take it up."""
    cal = calibrate(synthetic_cases((WindOffset(east_ms=4.0, north_ms=0.0),), n=4), PAYLOAD, LIBRARY)
    assert cal.selected == ()
    assert cal.unexplained
    assert cal.binned_heldout.track_rms_km.mean() < 0.2 * cal.baseline.track_rms_km.mean()
    assert all(
        abs(e - 4.0) < 0.5 for e, s in zip(cal.binned.east_ms, cal.binned.measured_s, strict=True) if s > 600
    )
    assert "No library effect explains it" in verdict(cal)


def test_with_no_hidden_effect_nothing_is_selected(plain_cases: list[FlightCase]) -> None:
    cal = calibrate(plain_cases, PAYLOAD, LIBRARY)
    assert cal.selected == ()
    assert not cal.unexplained
    assert cal.baseline.track_rms_km.mean() < 0.05
    assert "No library effect beat the plain model" in verdict(cal)


def test_forward_selection_finds_two_hidden_effects_of_different_families(synthetic_cases: Cases) -> None:
    """A rotation of the wind and λ = 0.85 on every flight: the rotation is selected, λ is the rate prior."""
    truth = (DescentRateScale(scale=0.85), WindRotation(angle_deg=15.0))
    cal = calibrate(
        synthetic_cases(truth, n=4), PAYLOAD, library(["descent_rate_scale", "wind_rotation", "wind_scale"])
    )
    found = {f.candidate.name: f.value for f in cal.selected}
    assert set(found) == {"wind_rotation"}
    assert cal.rate_prior.median == pytest.approx(0.85, abs=0.01)
    assert found["wind_rotation"] == pytest.approx(15.0, abs=0.5)
    assert len(cal.rounds) == 2  # the second round tries wind_scale and keeps nothing
    assert cal.after.track_rms_km.mean() < 0.1 * cal.baseline.track_rms_km.mean()


def test_the_nested_stability_repeats_the_whole_selection_without_each_flight(synthetic_cases: Cases) -> None:
    cases = synthetic_cases((DragDensityExponent(exponent=0.15),), n=4)
    candidates = library(["drag_density_exponent", "wind_scale"])
    nested = calibrate(cases, PAYLOAD, candidates, nested=True)
    assert nested.stability_method == "nested" and nested.stability == {"drag_density_exponent": 1.0}
    replayed = calibrate(cases, PAYLOAD, candidates)
    assert replayed.stability_method == "decision" and replayed.stability == {"drag_density_exponent": 1.0}
    assert nested.unstable == () and [f.candidate.name for f in nested.selected] == ["drag_density_exponent"]
