"""Every effect term against what it must do to a descent with a known answer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from predictor import EFFECTS, Model, Payload, PredictorError, Term, predict
from predictor.descent import Release
from predictor.descent.model import (
    BASE_STAGE,
    ENV_SIZE,
    FAMILIES,
    FAMILY_VERTICAL,
    TERMS,
    BinnedDescentRate,
    BinnedWind,
    DeploymentDelay,
    DescentRateScale,
    DragDensityExponent,
    SeaLevelRate,
    TerminalVelocity,
    TwoRegimeRate,
    VerticalAirMotion,
    WeatherTimeOffset,
    Wind,
    WindBandScale,
    WindLag,
    WindOffset,
    WindRotation,
    WindScale,
    apply_family,
)
from predictor.prediction import FlightSetup
from tests.predictor.predict_helpers import (
    G0,
    H_ISO,
    R_GRAVITY,
    RELEASE,
    RHO0,
    closed_form_fall_time,
    isothermal_cube,
)

PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)
CALM = isothermal_cube()
WINDY = isothermal_cube(u=10.0)


def descent(cube=CALM, *effects, **kw):  # type: ignore[no-untyped-def]
    return predict(cube, Release(RELEASE, 46.0, 4.0, 30000.0), FlightSetup(PAYLOAD, effects, **kw))


def test_the_library_has_every_effect_the_calibration_needs() -> None:
    needed = {
        "descent_rate_scale",
        "drag_density_exponent",
        "deployment_delay",
        "wind_scale",
        "wind_rotation",
        "wind_band_scale",
        "wind_lag",
        "weather_time_offset",
        "binned_descent_rate",
        "binned_wind",
        "two_regime_rate",
    }
    assert needed <= set(EFFECTS)
    assert {EFFECTS[n].family for n in needed} == {"vertical", "horizontal", "timing"}


def test_descent_rate_scale_divides_the_fall_time() -> None:
    base = descent()
    faster = descent(CALM, DescentRateScale(scale=1.25))
    assert faster.descent_s == pytest.approx(base.descent_s / 1.25, rel=1e-9)


def test_drag_density_exponent_matches_its_closed_form() -> None:
    beta = 0.08
    res = descent(CALM, DragDensityExponent(exponent=beta))
    expected = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 30000.0, beta=beta)
    assert res.descent_s == pytest.approx(expected, rel=1e-4)
    assert res.descent_s != pytest.approx(descent().descent_s, rel=1e-3)


@pytest.mark.parametrize("w", [0.4, -0.4])
def test_vertical_air_motion_matches_the_fall_through_moving_air(w: float) -> None:
    """T = ∫ dz / (v(z) − w), with the drag law's v(z) in the isothermal test atmosphere."""
    from scipy.integrate import quad

    v0 = math.sqrt(2.0 * PAYLOAD.mass_kg * G0 / (RHO0 * PAYLOAD.cda_m2))

    def seconds_per_metre(z: float) -> float:
        return 1.0 / (v0 * math.exp(0.5 * z / H_ISO) / (1.0 + z / R_GRAVITY) - w)

    expected, _ = quad(seconds_per_metre, 0.0, 30000.0, limit=200)
    res = descent(CALM, VerticalAirMotion(speed_ms=w))
    assert res.descent_s == pytest.approx(expected, rel=1e-4)
    assert (res.descent_s > descent().descent_s) == (w > 0)


def test_an_updraft_faster_than_the_fall_stops_the_descent_with_an_error() -> None:
    with pytest.raises(PredictorError, match="no positive descent rate"):
        descent(CALM, VerticalAirMotion(speed_ms=50.0))


def test_deployment_delay_saves_the_fast_fall_time_whatever_the_step() -> None:
    delay, factor = 20.0, 3.0
    base = descent()
    coarse = descent(CALM, DeploymentDelay(delay_s=delay, speed_factor=factor), step_m=100.0)
    fine = descent(CALM, DeploymentDelay(delay_s=delay, speed_factor=factor), step_m=5.0)
    # Falling factor× faster for `delay` s covers the height that would have taken factor·delay s.
    saved = base.descent_s - coarse.descent_s
    assert saved == pytest.approx((factor - 1.0) * delay, rel=0.08)
    assert coarse.descent_s == pytest.approx(fine.descent_s, abs=0.5)


@pytest.mark.parametrize("step_m", [5.0, 100.0, 350.0])
def test_two_regime_rate_is_the_fall_faster_above_its_height_whatever_the_step(step_m: float) -> None:
    """T = ∫₀ʰ dz / v(z) + ∫ₕ^top dz / (f·v(z)); the height falls inside a step at 100 and 350 m."""
    from scipy.integrate import quad

    v0 = math.sqrt(2.0 * PAYLOAD.mass_kg * G0 / (RHO0 * PAYLOAD.cda_m2))
    height, factor = 20_050.0, 1.3

    def seconds_per_metre(z: float) -> float:
        return 1.0 / (v0 * math.exp(0.5 * z / H_ISO) / (1.0 + z / R_GRAVITY))

    below, _ = quad(seconds_per_metre, 0.0, height, limit=200)
    above, _ = quad(seconds_per_metre, height, 30000.0, limit=200)
    res = descent(CALM, TwoRegimeRate(height_m=height, factor=factor), step_m=step_m)
    assert res.descent_s == pytest.approx(below + above / factor, rel=1e-4)
    assert descent(CALM, TwoRegimeRate(height_m=height, factor=1.0)).descent_s == pytest.approx(
        descent().descent_s
    )


def test_wind_scale_scales_the_drift() -> None:
    base = descent(WINDY)
    scaled = descent(WINDY, WindScale(scale=1.5))
    assert scaled.drift_km == pytest.approx(1.5 * base.drift_km, rel=1e-3)


def test_wind_rotation_is_clockwise_for_a_positive_angle() -> None:
    base = descent(WINDY)
    veered = descent(WINDY, WindRotation(angle_deg=90.0))
    assert veered.bearing_deg == pytest.approx(180.0, abs=0.2)
    assert veered.drift_km == pytest.approx(base.drift_km, rel=2e-3)


def test_wind_band_scale_changes_only_the_time_spent_in_the_band() -> None:
    bottom, top = 10000.0, 20000.0
    res = descent(WINDY, WindBandScale(bottom_m=bottom, top_m=top, scale=0.0))
    outside = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, bottom) + (
        closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 30000.0)
        - closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, top)
    )
    assert res.drift_km == pytest.approx(10.0 * outside / 1000.0, rel=5e-3)


def test_wind_lag_with_a_tiny_time_constant_follows_the_wind() -> None:
    shear = isothermal_cube(u=lambda t, z, y, x: 20.0 - z / 1000.0)
    base = descent(shear)
    lagged = descent(shear, WindLag(time_constant_s=1e-3))
    assert lagged.landing.lon == pytest.approx(base.landing.lon, abs=1e-6)


def test_wind_lag_with_a_huge_time_constant_keeps_the_release_velocity() -> None:
    shear = isothermal_cube(u=lambda t, z, y, x: 20.0 - z / 1000.0)
    res = descent(shear, WindLag(time_constant_s=1e9))
    u_release = 20.0 - 29950.0 / 1000.0
    assert res.drift_km == pytest.approx(abs(u_release) * res.descent_s / 1000.0, rel=5e-3)
    assert res.bearing_deg == pytest.approx(270.0, abs=0.2)


def test_wind_lag_runs_after_the_other_wind_terms_whatever_the_order_given() -> None:
    model = Model((WindLag(time_constant_s=5.0), TerminalVelocity.of(PAYLOAD), WindScale(scale=2.0), Wind()))
    assert [t.name for t in model.ordered()] == ["terminal_velocity", "wind", "wind_scale", "wind_lag"]


def test_weather_time_offset_samples_later_weather() -> None:
    # The wind grows by 2 m/s per hour; sampling 3 h later adds 6 m/s for the whole descent.
    growing = isothermal_cube(u=lambda t, z, y, x: 2.0 * t + 12.0 + 0.0 * z, hours=(-6.0, 12.0))
    base = descent(growing)
    later = descent(growing, WeatherTimeOffset(offset_s=3 * 3600.0))
    assert (later.drift_km - base.drift_km) == pytest.approx(6.0 * base.descent_s / 1000.0, rel=5e-3)


def test_binned_descent_rate_acts_only_inside_its_bins() -> None:
    base = descent()
    res = descent(CALM, BinnedDescentRate(edges_m=(0.0, 10000.0, 20000.0), factors=(2.0, 1.0)))
    lower_half = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 10000.0)
    assert base.descent_s - res.descent_s == pytest.approx(lower_half / 2.0, rel=1e-3)


def test_binned_wind_adds_its_wind_inside_its_bins() -> None:
    res = descent(
        CALM, BinnedWind(edges_m=(-1000.0, 10000.0, 40000.0), east_ms=(4.0, 0.0), north_ms=(0.0, 0.0))
    )
    in_bin = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 10000.0)
    assert res.drift_km == pytest.approx(4.0 * in_bin / 1000.0, rel=5e-3)


def test_per_trajectory_parameters_broadcast_and_scalars_repeat() -> None:
    model = Model.for_payload(
        PAYLOAD, DescentRateScale(scale=np.array([1.0, 2.0, 3.0])), WindOffset(1.0, 2.0)
    )
    params = model.parameter_matrix(3)
    assert params.shape == (3, 2 + 1 + 2)
    assert params[:, 2].tolist() == [1.0, 2.0, 3.0]
    assert params[:, 3].tolist() == [1.0, 1.0, 1.0]


def test_a_model_without_a_vertical_term_is_refused() -> None:
    with pytest.raises(PredictorError, match="no vertical term"):
        Model((Wind(),))


def test_binned_terms_refuse_bad_bins() -> None:
    with pytest.raises(PredictorError, match="strictly increasing"):
        BinnedDescentRate(edges_m=(0.0, 0.0), factors=(1.0,))
    with pytest.raises(PredictorError, match="one value per bin"):
        BinnedWind(edges_m=(0.0, 1.0, 2.0), east_ms=(1.0,), north_ms=(1.0, 2.0))


def test_a_model_that_stops_the_descent_is_an_error_not_a_hang() -> None:
    with pytest.raises(PredictorError, match="no positive descent rate"):
        descent(CALM, DescentRateScale(scale=0.0))


def test_describe_names_family_and_parameters_of_every_term() -> None:
    described = Model.for_payload(PAYLOAD, WindRotation(angle_deg=5.0)).describe()
    assert described[-1] == {
        "effect": "wind_rotation",
        "family": "horizontal",
        "parameters": {"angle_deg": 5.0},
    }
    assert described[0]["parameters"] == {"mass_kg": PAYLOAD.mass_kg, "cda_m2": PAYLOAD.cda_m2}


def test_isothermal_helper_is_self_consistent() -> None:
    # Guards the helper the closed forms rely on: density at one scale height is ρ0/e.
    cube = isothermal_cube()
    k = int(np.argmin(np.abs(cube.z_m[0, :, 0, 0] - H_ISO)))
    z = cube.z_m[0, k, 0, 0]
    assert cube.density[0, k, 0, 0] == pytest.approx(RHO0 * math.exp(-z / H_ISO))


def test_sea_level_rate_matches_its_closed_form() -> None:
    # v = r·sqrt(ρ_ref/ρ) with ρ = ρ0·e^(−z/H): t = 2H·(1 − e^(−Z/2H)) / (r·sqrt(ρ_ref/ρ0)).
    rate, z_top = 5.0, 30000.0
    res = predict(
        CALM,
        Release(RELEASE, 46.0, 4.0, z_top),
        FlightSetup(model=Model((SeaLevelRate(rate_ms=rate), Wind()))),
    )
    expected = 2 * H_ISO * (1 - math.exp(-z_top / (2 * H_ISO))) / (rate * math.sqrt(1.1045**2 / RHO0))
    assert res.descent_s == pytest.approx(expected, rel=1e-5)


def test_every_registered_term_has_its_own_kind_kernel_and_name() -> None:
    table = Model.for_payload(PAYLOAD, DescentRateScale()).table()
    assert table[:, 1].tolist() == [
        TERMS.index(TerminalVelocity),
        TERMS.index(Wind),
        TERMS.index(DescentRateScale),
    ]
    assert len({cls.name for cls in TERMS}) == len(TERMS)
    assert all(callable(cls.kernel) and cls.family in FAMILIES for cls in TERMS)
    assert set(EFFECTS.values()) == {cls for cls in TERMS if cls.stage != BASE_STAGE}


def test_a_term_missing_from_the_registry_is_refused_not_skipped() -> None:
    @dataclass(frozen=True)
    class Unregistered(Term):
        name: ClassVar[str] = "unregistered"
        family: ClassVar[str] = "vertical"

    with pytest.raises(PredictorError, match="not registered"):
        Model.for_payload(PAYLOAD, Unregistered())


def test_the_compiled_dispatch_refuses_an_unknown_kind() -> None:
    table = np.array([[FAMILY_VERTICAL, len(TERMS), 0, 0]], dtype=np.int64)
    rows = np.zeros((1, 4))
    with pytest.raises(PredictorError, match="not in predictor.descent.model.TERMS"):
        apply_family(
            table,
            FAMILY_VERTICAL,
            rows,
            np.zeros((1, ENV_SIZE)),
            np.zeros((1, 3)),
            rows,
            np.ones(1, bool),
            0,
            1,
        )
