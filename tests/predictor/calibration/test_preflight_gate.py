"""The pre-flight gate: a term flies before release only if, held out, it makes neither the descent time
nor the landing of the pre-flight law (shape × the other flights' median λ) worse and one of them
better beyond its interval; otherwise it ships live-only and no pre-flight prediction flies it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.calibration.effects import LIBRARY
from predictor.calibration.preflight_gate import GateCheck, compare, verdict
from predictor.calibration.residuals import FlightCase, flight_case, run, score
from predictor.calibration.run import prepare
from predictor.calibration.selection import calibrate
from predictor.descent.payload import Payload
from predictor.environment import Terrain, load_weather
from predictor.prediction import load_model
from predictor.tracks import clean, read_track
from tests.conftest import REPO_ROOT
from tests.independent_world import CDA_M2, MASS_KG, TWO_REGIME, make_world, write_weather

EOSS = sorted(str(p) for p in (REPO_ROOT / "tests/data/eoss").glob("*_descent.csv"))


def _checks(
    time_before: list[float], time_after: list[float], land_before: list[float], land_after: list[float]
) -> tuple[GateCheck, ...]:
    return compare(
        {"descent_time_error_s": np.array(time_before), "landing_error_km": np.array(land_before)},
        {"descent_time_error_s": np.array(time_after), "landing_error_km": np.array(land_after)},
        seed=0,
    )


def test_a_term_that_makes_the_landing_worse_ships_live_only_whatever_it_does_to_the_time() -> None:
    gate = verdict(
        "x", _checks([300, 250, 200, 280], [100, 90, 80, 70], [2.0, 3.0, 4.0, 5.0], [2.1, 3.1, 4.0, 5.0])
    )
    assert not gate.preflight and gate.reason.startswith("live-only: pre-flight it makes the landing")
    assert [c.worse for c in gate.checks] == [False, True]


def test_the_descent_time_is_judged_by_its_size_whatever_its_sign() -> None:
    """-300 s and +300 s are the same error: a term that turns one into the other changes nothing."""
    (time, _) = _checks([-300, 200, -250, 100], [300, -200, 250, -100], [1, 1, 1, 1], [1, 1, 1, 1])
    assert time.change == 0.0 and not time.worse


def test_a_term_within_the_noise_ships_live_only() -> None:
    rng = np.random.default_rng(3)
    before = rng.uniform(100.0, 400.0, 12)
    after = before + rng.normal(-1.0, 30.0, 12)
    land = list(rng.uniform(1.0, 6.0, 12))
    gate = verdict("x", _checks(list(before), list(after), land, land))
    assert not gate.checks[0].better, "the interval of the time change straddles zero"
    assert not gate.preflight and "improves neither beyond its interval" in gate.reason


def test_a_term_better_beyond_its_interval_on_one_and_no_worse_on_the_other_flies_pre_flight() -> None:
    gate = verdict(
        "x", _checks([300, 250, 200, 280, 260], [200, 160, 120, 190, 170], [2, 3, 4, 5, 6], [2, 3, 4, 5, 6])
    )
    assert gate.preflight and gate.checks[0].better and gate.checks[0].high < 0.0


def test_a_failed_run_makes_a_term_live_only() -> None:
    assert not verdict("x", _checks([300, 250, 200], [100, float("nan"), 80], [2, 3, 4], [1, 2, 3])).preflight


def test_on_real_eoss_flights_a_shape_that_worsens_the_pre_flight_landing_ships_live_only(
    tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Eleven EOSS flights land with the ETOPO DEM. Measured (drs calibrate, the command below): the
    two-regime rate (18.1 km, ×1.24) improves the shape record 36.5 → 14.8 s and the pre-flight descent
    time 361 → 354 s, but the landing 34.75 → 35.26 km: live-only. Then λ: the median makes the descent
    time 321 → 361 s against λ = 1 (the landing 35.54 → 34.75 km): live-only too, so the pre-flight law
    is the plain law, whose held-out numbers it then equals. About 7 s."""
    model = tmp_path / "eoss.json"
    out = tmp_path / "eoss-result.json"
    argv = ["calibrate", "--tracks", *EOSS, "--winds", "ascent", "--payload", "superbit-test",
            "--dem", str(shared_data / "dem/ferret_etopo"), "--json", str(out), "--save-model", str(model)]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    result = json.loads(out.read_text())
    assert [s["effect"] for s in result["selected"]] == ["two_regime_rate"]
    gate, rate = result["preflight_gate"]
    assert gate["term"] == "two_regime_rate" and not gate["preflight"]
    assert rate["term"] == "descent_rate_scale" and not rate["preflight"]
    landing = next(c for c in gate["checks"] if c["metric"] == "landing_error_km")
    assert landing["worse"] and landing["with"] > landing["without"]
    assert result["live_only"] == ["two_regime_rate", "descent_rate_scale"]
    for metric in ("descent_time_error_s", "landing_error_km"):
        assert result["preflight"][metric]["mean"] == pytest.approx(result["baseline"][metric]["mean"])
    flown = load_model(model)
    assert [t.name for t in flown.terms] == ["descent_rate_scale", "two_regime_rate"], "live flies it"
    (before,) = flown.flight_setup(Terrain.sea_level()).effects
    assert before.name == "descent_rate_scale" and before.parameters() == {"scale": 1.0}
    assert main(["model", "show", str(model)]) == 0
    assert "two_regime_rate (vertical)" in (shown := capsys.readouterr().out) and "LIVE-ONLY" in shown
    assert (
        "scale 1.0; pre-flight only (λ = 1, the plain law's rate: pre-flight it makes the descent time"
        in shown
    )


def test_a_shape_that_helps_before_release_ships_in_the_pre_flight_law(tmp_path: Path) -> None:
    """The independent world's canopy 1.3× faster above 20 km, ten flights with little λ scatter (sd of
    ln λ 0.02), seed 11. Measured: held out, pre-flight descent time 44 → 41 s and landing 1.02 → 0.68 km
    (95 % −0.58…−0.03): pre-flight. (With six flights the landing's interval reached +0.00 and the term was
    live-only: the gate asks for evidence, not a coin toss.) It flies with λ = 1. About 6 s."""
    files = list(write_weather(tmp_path / "gfs"))
    cube = load_weather(files, cache_dir=tmp_path / "cache")
    world = make_world(tmp_path / "w", TWO_REGIME, flights=10, seed=11, weather=files, rate_log_sigma=0.02)
    cases = [flight_case(clean(read_track(p)), cube) for p in world.tracks]
    cal = calibrate(cases, Payload(MASS_KG, CDA_M2, name="independent", source="world"), LIBRARY)
    assert [f.candidate.name for f in cal.selected] == ["two_regime_rate"]
    # The world's λ is 1 give or take 2 %: its median earns no place before release (judged last).
    assert cal.live_only == ("descent_rate_scale",) and [g.preflight for g in cal.gate] == [True, False]
    assert [t.name for t in cal.preflight_terms()] == ["descent_rate_scale", "two_regime_rate"]
    assert cal.preflight is not None
    assert cal.preflight.landing_error_km.mean() < cal.rate_only.landing_error_km.mean()


def _superbit(shared_data: Path, season: str) -> tuple[list[FlightCase], Payload]:
    """The season's flights as ``drs calibrate --winds ascent --payload superbit-test`` uses them."""
    tracks = sorted(str(p) for p in (shared_data / "tracks/pyballoon_superbit").glob(f"{season}-*.csv"))
    args = argparse.Namespace(
        tracks=tracks, weather=None, winds="ascent", step=200.0, max_effects=3, payload="superbit-test",
        mass=None, cda=None, effects=None, dem=None, cache_dir=None, date=None,
    )  # fmt: skip
    inputs = prepare(args)
    return inputs.cases, inputs.payload


def test_a_median_lambda_that_does_not_beat_lambda_one_held_out_stays_out_of_the_pre_flight_law(
    shared_data: Path,
) -> None:
    """Calibrated on the 15 SuperBIT 2019 flights, the median λ (1.088) makes the held-out pre-flight
    descent time 300 → 233 s and the landing 5.03 → 4.31 km, beyond its interval on neither: the
    pre-flight law flies λ = 1, and on the 2018 flights, which no part of it saw, it is then no worse
    than the plain law (with 2019's λ it was 1.35× in time and 1.16× in landing). Deterministic on
    committed data (fixed seeds); about 10 s. Live keeps the rate prior: ``terms()`` still leads with it."""
    c19, payload = _superbit(shared_data, "19")
    c18, _ = _superbit(shared_data, "18")
    cal = calibrate(c19, payload, LIBRARY, seed=0)
    errors: dict[str, tuple[list[float], list[float]]] = {"ships": ([], []), "plain": ([], [])}
    for case in c18:
        for name, terms in (("ships", cal.preflight_terms()), ("plain", ())):
            s = score(case, run(case, payload, terms, 1, 200.0))
            errors[name][0].append(abs(float(s.descent_time_error_s[0])))
            errors[name][1].append(float(s.landing_error_km[0]))
    for k in (0, 1):
        assert np.mean(errors["ships"][k]) <= np.mean(errors["plain"][k])
    rate = next((g for g in cal.gate if g.term == "descent_rate_scale"), None)
    assert rate is not None and not rate.preflight and rate.reason.endswith("the pre-flight law flies λ = 1")
    assert cal.preflight_terms()[0].parameters() == {"scale": 1.0}
    assert cal.terms()[0].parameters()["scale"] == pytest.approx(cal.rate_prior.median)
