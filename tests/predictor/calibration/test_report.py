"""The report: the JSON with the issue's keys, and a Markdown page with its verdict and real PNG plots."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from predictor.calibration.effects import BIN_EDGES_M, library
from predictor.calibration.ellipse_fit import EllipseFit
from predictor.calibration.report import (
    Exclusion,
    landing_change,
    result_json,
    speed_finding,
    speed_ratio_by_altitude,
    write_calibration_report,
)
from predictor.calibration.residuals import FlightCase
from predictor.calibration.run import preflight_ellipse
from predictor.calibration.selection import Calibration, calibrate
from predictor.descent.model import DragDensityExponent
from predictor.descent.payload import PROFILES

PAYLOAD = PROFILES["superbit-test"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def calibrated(plain_cases: list[FlightCase]) -> Calibration:
    return calibrate(plain_cases, PAYLOAD, library(["drag_density_exponent", "wind_rotation"]))


def _ellipse(cal: Calibration) -> EllipseFit:
    fit = preflight_ellipse(cal)
    assert fit is not None
    return fit


def test_the_json_has_the_keys_the_issue_names(calibrated: Calibration) -> None:
    data = result_json(calibrated, _ellipse(calibrated), [Exclusion("x", "cleaning: no landing observed")],
                       PAYLOAD.to_dict(), "synthetic")  # fmt: skip
    for key in ("flights", "excluded", "baseline", "candidates", "selected", "after", "uncertainty_model"):
        assert key in data
    assert data["excluded"] == [{"name": "x", "reason": "cleaning: no landing observed"}]
    assert data["flights"] == [f"synthetic-{k}" for k in range(5)]
    for block in (data["baseline"], data["after"], *(c["heldout"] for c in data["candidates"])):
        for metric in ("landing_error_km", "descent_time_error_s"):
            assert set(block[metric]) >= {"mean", "median"}
    assert [c["effect"] for c in data["candidates"]] == ["drag_density_exponent", "wind_rotation"]
    assert set(data["rate_prior"]) == {"median", "log_sigma", "flights", "per_flight"}
    assert data["rate_prior"]["flights"] == 5 and set(data["rate_prior"]["per_flight"]) == set(
        data["flights"]
    )
    assert data["unstable"] == [] and set(data["rate_only"]) == set(data["baseline"])
    assert {c["family"] for c in data["candidates"]} == {"vertical", "horizontal"}
    assert all(isinstance(c["parameters"], dict) for c in data["candidates"])
    model = data["uncertainty_model"]
    assert set(model) >= {"sigma0_km", "h", "k_km2_per_h2", "q", "coverage_1sigma", "coverage_2sigma"}
    assert data["selected"] == [] and data["library_explains_residual"] is True
    assert [f["family"] for f in data["families"]] == ["vertical", "horizontal"]
    assert [t["record"] for t in data["binned_correction"]["tests"]] == ["vertical", "horizontal"]


def test_the_markdown_report_states_its_verdict_and_links_real_plots(
    calibrated: Calibration, tmp_path: Path
) -> None:
    ellipse = _ellipse(calibrated)
    data = result_json(calibrated, ellipse, [], PAYLOAD.to_dict(), "synthetic")
    out = tmp_path / "cal" / "report.md"
    pngs = write_calibration_report(out, calibrated, ellipse, [], "Synthetic", "drs calibrate ...", data)
    text = out.read_text(encoding="utf-8")
    assert text.startswith("# Synthetic\n\n## What the data showed\n\nVertical: nothing beat the model")
    assert "No library effect beat the plain model" in text
    assert "Excluded: none" in text
    for png in pngs:
        assert png.parent == out.parent and png.read_bytes()[:8] == PNG_SIGNATURE
        assert f"]({png.name})" in text
    assert "## Vertical family (scored on the vertical record)" in text
    assert "## Horizontal family (scored on the horizontal record)" in text
    assert "| drag_density_exponent | reference_density = 1.225, exponent = " in text
    assert "paper (launch), same errors" in text
    assert (
        "| plain law × median λ of the other flights (λ alone) |" in text
        and "the rate prior is median λ" in text
    )


def test_a_preface_stands_under_the_title_and_survives_regeneration(
    calibrated: Calibration, tmp_path: Path
) -> None:
    ellipse = _ellipse(calibrated)
    data = result_json(calibrated, ellipse, [], PAYLOAD.to_dict(), "synthetic")
    out = tmp_path / "report.md"
    preface = "## Summary in plain words\n\nThe capsule fell slower near the ground.\n"
    for _ in range(2):
        write_calibration_report(
            out, calibrated, ellipse, [], "Synthetic", "drs calibrate ...", data, preface
        )
    text = out.read_text(encoding="utf-8")
    assert text.startswith(
        "# Synthetic\n\n## Summary in plain words\n\nThe capsule fell slower near the ground.\n\n"
    )
    assert text.count("Summary in plain words") == 1
    assert text.index("Summary in plain words") < text.index("## What the data showed")


def test_the_landing_change_is_paired_flight_by_flight_and_split_by_what_the_descent_time_did(
    synthetic_cases: Callable[..., list[FlightCase]], tmp_path: Path
) -> None:
    cal = calibrate(
        synthetic_cases((DragDensityExponent(exponent=0.15),), n=4),
        PAYLOAD,
        library(["drag_density_exponent"]),
    )
    change = landing_change(cal)
    d = cal.after.landing_error_km - cal.baseline.landing_error_km
    assert change["mean_change_km"]["value"] == pytest.approx(d.mean(), abs=1e-4)
    assert change["median_of_changes_km"]["value"] == pytest.approx(np.median(d), abs=1e-4)
    for key in ("mean_change_km", "median_of_changes_km", "median_shift_km"):
        c = change[key]
        assert c["low"] <= c["value"] <= c["high"], key
    closer, further = change["descent_time_closer"], change["descent_time_further"]
    assert closer["flights"] + further["flights"] == 4 and change["landing_closer"] == int((d < 0).sum())
    # The exponent the flights carry fixes every descent time, and with it the landings.
    assert closer == {
        "flights": 4,
        "landing_closer": 4,
        "median_change_km": pytest.approx(np.median(d), abs=1e-4),
    }
    assert change["median_of_changes_km"]["high"] < 0.0
    data = result_json(cal, None, [], PAYLOAD.to_dict(), "synthetic")
    write_calibration_report(tmp_path / "r.md", cal, None, [], "Synthetic", "drs calibrate ...", data)
    text = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert "## Landing error: before and after, flight by flight (held out)" in text
    assert "Flights whose descent time came closer to the measured one: 4 of 4 land closer" in text


@pytest.mark.parametrize("noise_m", [3.0, 8.0])
def test_a_noise_only_1_hz_flight_reads_no_systematic_difference(
    synthetic_cases: Callable[..., list[FlightCase]], noise_m: float
) -> None:
    """At 1 Hz the height between two fixes is the GNSS noise; per-interval ratios that dropped the rising
    ones read a noise-only flight as "160 % faster". Crossing times of 3 km bins do not."""
    cal = calibrate(
        synthetic_cases((), n=3, cadence_s=1.0, noise_m=noise_m, seed=7), PAYLOAD, library(["wind_scale"])
    )
    assert "shows no systematic difference" in speed_finding(cal)
    assert all(abs(r["ratio"] - 1.0) < 0.01 for r in speed_ratio_by_altitude(cal, BIN_EDGES_M))


def test_a_shape_the_law_lacks_is_read_as_a_systematic_difference_at_1_hz(
    synthetic_cases: Callable[..., list[FlightCase]],
) -> None:
    """The same text can fail: a density exponent of 0.15 makes the fall faster high up and slower low down."""
    cases = synthetic_cases((DragDensityExponent(exponent=0.15),), n=3, cadence_s=1.0, noise_m=3.0, seed=7)
    text = speed_finding(calibrate(cases, PAYLOAD, library(["wind_scale"])))
    assert "slower than predicted at 0–3 km" in text and "faster than predicted" in text
