"""`drs calibrate vertical`: a saved law on flights it never saw, scored on the vertical record alone."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from console.commands.main import main
from predictor.calibration.vertical_check import check_flight, vertical_case
from predictor.descent.model import DescentRateScale, DragDensityExponent
from predictor.descent.payload import PROFILES
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel
from predictor.tracks.cleaning import clean
from tests.approx import assert_text_close
from tests.conftest import REPO_ROOT
from tests.predictor.calibration.conftest import LAUNCH, jet_cube
from tests.predictor.synthetic_flights import synthetic_flight

PAYLOAD = PROFILES["superbit-test"]
REPORT = REPO_ROOT / "docs" / "calibration" / "v4-vertical.md"
V4 = Path("..") / "shared" / "data" / "tracks" / "astra_meridiaz_V4_spain" / "V4_flight_1hz_DERIVED.csv"


def cut_in_the_air(exponent: float, end_m: float = 2000.0):  # noqa: ANN201
    """A flight of another payload (falling 30 % slower) with a density exponent, whose log stops at
    ``end_m`` on the way down: no landing, as the V4 record."""
    cube = jet_cube(95.0)
    truth = (DescentRateScale(scale=0.7), DragDensityExponent(exponent=exponent))
    flight = synthetic_flight(
        cube, launch_time=LAUNCH, lat=46.0, lon=6.0, payload=PAYLOAD, effects=truth, burst_alt_m=25_000.0,
        ascent_rate_ms=8.0, cadence_s=30.0, noise_m=2.0, seed=3, name="cut",
    )  # fmt: skip
    fixes = flight.track.fixes
    peak = max(range(len(fixes)), key=lambda i: fixes[i].alt_m)
    end = next(i for i in range(peak, len(fixes)) if fixes[i].alt_m < end_m)
    return clean(dataclasses.replace(flight.track, fixes=fixes[:end])), cube


def test_a_record_that_ends_in_the_air_is_scored_to_its_last_fix() -> None:
    flight, cube = cut_in_the_air(0.15)
    assert not flight.usable and flight.landing is None
    case = vertical_case(flight, cube)
    assert case.landing_alt_m == flight.descent[-1].alt_m > 1500.0
    assert case.descent_time_s == pytest.approx(
        (flight.descent[-1].time - flight.descent_start.time).total_seconds(), abs=30.0
    )


def test_the_law_the_flight_carries_beats_rho_to_the_minus_half_whatever_its_payload() -> None:
    flight, cube = cut_in_the_air(0.15)
    model = CalibratedModel(PAYLOAD, (DragDensityExponent(exponent=0.15),), None, {"flights": ["others"]})
    plain, textbook, law, own = check_flight(vertical_case(flight, cube), model, landed=False).scores
    assert plain.time_rms_s > 2 * textbook.time_rms_s, "λ = 1 is the wrong payload"
    assert law.time_rms_s < 0.5 * textbook.time_rms_s
    assert law.parameters["descent_rate_scale"] == pytest.approx(0.7, abs=0.03)
    assert own.parameters["drag_density_exponent"] == pytest.approx(0.15, abs=0.03)


def test_a_law_the_flight_does_not_carry_loses_to_rho_to_the_minus_half() -> None:
    flight, cube = cut_in_the_air(0.0)
    model = CalibratedModel(PAYLOAD, (DragDensityExponent(exponent=0.15),), None, {"flights": ["others"]})
    _, textbook, law, own = check_flight(vertical_case(flight, cube), model, landed=False).scores
    assert law.time_rms_s > 2 * textbook.time_rms_s
    assert abs(own.parameters["drag_density_exponent"]) < 0.03


def test_a_flight_the_model_was_calibrated_on_is_refused() -> None:
    flight, cube = cut_in_the_air(0.15)
    model = CalibratedModel(PAYLOAD, (DragDensityExponent(exponent=0.15),), None, {"flights": ["cut"]})
    with pytest.raises(PredictorError, match="cut: the model was calibrated on this flight"):
        check_flight(vertical_case(flight, cube), model, landed=False)


def test_the_committed_v4_report_is_what_the_command_writes(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The committed command was run from the checkout, with paths relative to it; here it runs in a
    # scratch directory laid out the same way (../shared is the test data beside the checkout).
    (tmp_path / "docs" / "calibration").mkdir(parents=True)
    (tmp_path / "docs" / "planning").mkdir()
    (tmp_path / "docs" / "planning" / "superbit-2018-2019-model.json").write_bytes(
        (REPO_ROOT / "docs" / "planning" / "superbit-2018-2019-model.json").read_bytes()
    )
    monkeypatch.chdir(tmp_path)
    v4 = shared_data / "tracks" / "astra_meridiaz_V4_spain" / V4.name
    assert main(["calibrate", "vertical", "--model", "docs/planning/superbit-2018-2019-model.json", "--tracks", str(v4),
                 "--winds", "ascent", "--date", "2021-06-01", "--report", "docs/calibration/v4-vertical.md",
                 "--json", "docs/calibration/v4-vertical.json"]) == 0  # fmt: skip
    written = (tmp_path / "docs" / "calibration" / "v4-vertical.md").read_text(encoding="utf-8")
    # The words exactly, each number within one unit of its last printed digit (tests/approx.py).
    assert_text_close(written.replace(str(v4), str(V4)), REPORT.read_text(encoding="utf-8"))
    laws = json.loads((tmp_path / "docs" / "calibration" / "v4-vertical.json").read_text(encoding="utf-8"))
    assert [s["law"] for s in laws["flights"][0]["scores"]][:2] == ["ρ^-½, λ = 1", "ρ^-½, λ fitted here"]
    assert "V4_flight_1hz_DERIVED: ρ^-½, λ fitted here: time-at-altitude RMS" in capsys.readouterr().out
