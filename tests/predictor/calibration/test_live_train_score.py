"""`drs live evaluate --train … --score …`: a season, a payload or a team held out whole, and a
calibrate → live evaluate chain that refits the law as it was fitted, whatever --dem each was given."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.calibration.live_evaluation import (
    Evaluation,
    band_switch_correction,
    evaluate_live,
    fit_live_sigma,
    floors,
    rate_helps,
    wind_helps,
    write_live_report,
)
from predictor.errors import PredictorError
from predictor.prediction import load_model
from tests.approx import assert_text_close

TRAIN = ("18-6-30.csv", "18-8-3.csv", "18-5-6.csv")
SCORE = ("19-1-1.csv", "19-2-2.csv")
SWISS = ("18-6-30.csv", "19-1-1.csv", "19-2-2.csv")
"""Three flights launched and landed between 46° and 48° N, 6° and 8° E: one DEM of four tiles covers them."""


def tracks(shared_data: Path, names: tuple[str, ...]) -> list[Path]:
    return [shared_data / "tracks" / "pyballoon_superbit" / name for name in names]


@pytest.fixture(scope="module")
def scored(shared_data: Path) -> Evaluation:
    return evaluate_live(tracks(shared_data, SCORE), train=tracks(shared_data, TRAIN))


def test_the_scored_flights_fly_what_the_training_flights_alone_chose(scored: Evaluation) -> None:
    training = scored.training
    assert training is not None
    assert scored.flights == ["19-1-1", "19-2-2"]
    assert training.flights == ["18-6-30", "18-8-3", "18-5-6"]
    assert scored.rate_laws == training.rate_laws, "the λ prior and discrepancy are the training flights'"
    prior = scored.rate_laws["model"][0]
    assert prior is not None and prior.flights == 3
    for km, (rate, wind) in training.all_flights_choice.items():
        assert set(scored.rate_choice[km].values()) == {rate}
        assert set(scored.wind_choice[km].values()) == {wind}
        assert rate_helps(scored, km) == rate_helps(training, km)
        assert wind_helps(scored, km) == wind_helps(training, km)
    assert band_switch_correction(scored) == band_switch_correction(training)


def test_the_train_score_report_says_so_and_checks_the_floors(scored: Evaluation, tmp_path: Path) -> None:
    text = write_live_report(scored, tmp_path, "drs live evaluate --train … --score …", "cross").read_text(
        encoding="utf-8"
    )
    assert (
        tmp_path / "cross.png"
    ).exists() and "![landing and remaining-time error against height](cross.png)" in text
    assert "Train → score: held out whole" in text and "18-6-30, 18-8-3, 18-5-6" in text
    checks = floors(scored)
    assert {(km, label.split(" ")[0]) for km, label, *_ in checks} <= {
        (km, metric) for km in (25.0, 20.0, 15.0, 10.0, 5.0) for metric in ("time", "landing")
    }
    for km, label, ratio, low, high, met in checks:
        assert low <= ratio <= high and met == (
            ratio <= (0.85 if km in (15.0, 10.0) and "time" in label else 1.0)
        )


def test_a_flight_both_trained_and_scored_on_is_refused(shared_data: Path) -> None:
    with pytest.raises(PredictorError, match="flights both trained and scored on: 18-6-30"):
        evaluate_live(tracks(shared_data, ("18-6-30.csv",)), train=tracks(shared_data, TRAIN))


def test_a_model_calibrated_on_a_scored_flight_is_refused(shared_data: Path) -> None:
    committed = load_model(Path(__file__).parents[3] / "docs" / "planning" / "superbit-2018-2019-model.json")
    with pytest.raises(
        PredictorError, match=r"was calibrated on scored flights \(19-1-1, 19-2-2\): calibrate"
    ):
        evaluate_live(tracks(shared_data, SCORE), model=committed, train=tracks(shared_data, TRAIN))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--train", "a.csv"], "--train and --score go together"),
        (["--score", "a.csv"], "--train and --score go together"),
        (["x.csv", "--train", "a.csv", "--score", "b.csv"], "track files or --train/--score, not both"),
        (["x.csv", "--name", "a/b"], "--name must be a file name without '/'"),
    ],
)
def test_evaluate_refuses_a_half_given_split(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["live", "evaluate", *argv]) != 0
    assert message in capsys.readouterr().err


def test_leave_one_out_on_two_flights_is_one_line_naming_the_minimum_not_a_traceback(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before: numpy's "need at least one array to concatenate" from the live error model's fit.
    two = tracks(shared_data, ("19-7-28.csv", "18-8-3.csv"))
    assert main(["live", "evaluate", *map(str, two), "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.strip() == "drs: error: a live evaluation needs at least 3 usable flights, got 2"
    assert not any(tmp_path.iterdir())


def test_a_training_set_of_two_flights_is_refused_naming_train(shared_data: Path) -> None:
    with pytest.raises(PredictorError, match=r"^--train needs at least 3 usable flights, got 2$"):
        evaluate_live(tracks(shared_data, SCORE), train=tracks(shared_data, TRAIN[:2]))


def test_a_live_error_model_with_no_checkpoint_of_three_flights_says_so(scored: Evaluation) -> None:
    few = dataclasses.replace(
        scored, training=None, cases=[c for c in scored.cases if c.flight == scored.flights[0]]
    )
    with pytest.raises(PredictorError, match="needs 3 flights with a report at one checkpoint height"):
        fit_live_sigma(few)


@pytest.fixture(scope="module")
def flat_dem(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """SRTM3 tiles of level ground at 300 m over 46–48° N, 6–8° E."""
    directory = tmp_path_factory.mktemp("dem")
    for name in ("N46E006", "N46E007", "N47E006", "N47E007"):
        np.full((1201, 1201), 300, dtype=">i2").tofile(directory / f"{name}.hgt")
    return directory


def test_calibrate_then_live_evaluate_works_whatever_dem_each_was_given(
    shared_data: Path, flat_dem: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Calibrated on a DEM, evaluated on level ground at each landing: the law is refitted on the
    # calibration's own ground (recorded in the model), so each flight still flies its own fold's law.
    files = [str(p) for p in tracks(shared_data, SWISS)]
    model = tmp_path / "m.json"
    assert main(["calibrate", "--tracks", *files, "--winds", "ascent", "--payload", "superbit-test",
                 "--dem", str(flat_dem), "--save-model", str(model)]) == 0  # fmt: skip
    saved = json.loads(model.read_text(encoding="utf-8"))
    assert saved["provenance"]["dem"] == str(flat_dem) and saved["provenance"]["step_m"] == 200.0
    assert saved["terms"], "the chain is tested only if the model has a law to refit"
    out = tmp_path / "report"
    assert main(["live", "evaluate", *files, "--model", str(model), "--out", str(out)]) == 0
    capsys.readouterr()
    assert "Everything is held out: each of the 3 flights" in (out / "live-reprediction.md").read_text(
        encoding="utf-8"
    )


def test_a_refit_disagreement_names_the_weather_when_it_differs(shared_data: Path) -> None:
    from predictor.calibration.live_evaluation import refit_causes

    committed = load_model(Path(__file__).parents[3] / "docs" / "planning" / "superbit-2018-2019-model.json")
    unrecorded = {k: v for k, v in committed.provenance.items() if k not in ("dem", "step_m")}
    said = refit_causes(
        dataclasses.replace(committed, provenance=unrecorded), "GFS 0.25° 2019-07-28 (3 files)", 200.0
    )
    assert (
        "it was calibrated on each flight's own ascent winds (--winds ascent), this evaluation flies GFS"
        in said
    )
    # A model saved before the DEM and step were recorded (as this one, stripped of them) says so.
    assert "it does not record the DEM it was calibrated with" in said
    assert "it does not record its calibration step" in said
    recorded = dataclasses.replace(
        committed, provenance={**committed.provenance, "dem": None, "step_m": 200.0, "project_version": None}
    )
    assert refit_causes(recorded, "each flight's own ascent winds (`ascent_weather_cube`)", 200.0).startswith(
        "the weather, ground, step and flights are the calibration's own"
    )


PLANNING = Path(__file__).parents[3] / "docs" / "planning"


@pytest.fixture(scope="module")
def across_seasons(shared_data: Path) -> dict[str, Evaluation]:
    """SuperBIT 2018 → 2019 and 2019 → 2018, each season's model calibrated on it alone (the committed
    reports' commands, docs/planning.md)."""
    folder = shared_data / "tracks" / "pyballoon_superbit"
    seasons = {year: sorted(folder.glob(f"{year}-*.csv")) for year in ("18", "19")}
    return {
        f"20{a} → 20{b}": evaluate_live(
            seasons[b], model=load_model(PLANNING / f"superbit-20{a}-model.json"), train=seasons[a]
        )
        for a, b in (("18", "19"), ("19", "18"))
    }


def test_across_seasons_what_ships_is_never_worse_than_the_plain_restart(
    across_seasons: dict[str, Evaluation],
) -> None:
    # Issue #30's floors, held out a whole season: what ships ÷ the plain restart from the nominal payload
    # ≤ 1.0 in remaining time and landing from 25, 20, 15, 10 and 5 km, and the time ≤ 0.85 from 15 and
    # 10 km. The training flights' band switch it replaced missed from 25 km in both directions (time /
    # landing 1.02 / 1.06 and 1.31 / 1.13: the training season's choice of the model's pooled λ) and the
    # landing from 20 km in 2018 → 2019 (1.11: its wind choice). Measured with the rule (the committed
    # reports, docs/planning/live-2018-to-2019.md and live-2019-to-2018.md): 2018 → 2019 1.00 / 1.00,
    # 0.80 / 0.91, 0.72 / 0.88, 0.65 / 0.90, 0.72 / 0.96; 2019 → 2018 1.00 / 1.00, 0.91 / 0.94,
    # 0.66 / 0.89, 0.60 / 0.94, 0.34 / 0.76 (25 → 5 km). The data are the committed tracks and models and
    # the evaluation draws nothing (the bootstrap interval has a fixed seed and is not asserted), so this
    # fails only if the rule, the λ estimator or the data change; from 25 km the plain restart flies (1.00
    # by the rule), and below it the closest margin is 0.04 (the landing from 5 km in 2018 → 2019).
    for split, result in across_seasons.items():
        checks = floors(result)
        assert len(checks) == 10, split
        missed = [(km, label, round(ratio, 3)) for km, label, ratio, _, _, met in checks if not met]
        assert not missed, split


def test_the_committed_cross_season_report_is_what_the_evaluation_writes(
    across_seasons: dict[str, Evaluation], tmp_path: Path
) -> None:
    # docs/planning/live-2018-to-2019.md, regenerated with the command it names (docs/planning.md).
    planning = PLANNING
    result = across_seasons["2018 → 2019"]
    command = (
        "drs live evaluate --train <15 track files 18-* in pyballoon_superbit> --score <15 track files 19-* "
        "in pyballoon_superbit> --model docs/planning/superbit-2018-model.json --name live-2018-to-2019 "
        "--out docs/planning"
    )
    written = write_live_report(result, tmp_path, command, "live-2018-to-2019")
    committed = planning / "live-2018-to-2019.md"
    # The words exactly, each number within one unit of its last printed digit (tests/approx.py): the
    # last digit of a regenerated float may differ on another machine.
    assert_text_close(written.read_text(encoding="utf-8"), committed.read_text(encoding="utf-8"))
