"""Live re-prediction with a calibrated model on unseen flights of worlds the project's engine did not make.

Each world (``tests/independent_world.py``: its own atmosphere, RK4 integrator and physics, effects
the library lacks) gives calibration flights and unseen ones. The model is what a flight team would
make of the calibration flights with the product itself (``drs calibrate --save-model``, then ``drs
live evaluate --save-model`` for its live settings); the unseen flights are then replayed fix by fix
with ``model.live_predictor`` against the plain restart from each report with the nominal payload
(``drs live --no-correction``). Issue #21's floor: from 20 km and from 10 km above the ground, the
model's mean |remaining-time error| over the unseen flights is never worse than the plain restart's
by more than 10 % + 10 s.

The two-regime canopy is a RECOGNITION CHECK only: its form is exactly the library's
``two_regime_rate``, so passing it shows the library recognises its own term, not that the loop
generalises. Issue #30's floors are asserted on the hard worlds of ``test_live_hard_worlds.py`` (λ
scatter, forecast wind errors, ascent winds from elsewhere, effects no library term has). It is the
hard case here: the calibration fits it as ``two_regime_rate`` 1.45× above
21 km where the truth is 1.3× above 20 km, so a 10 s record down to 20 km reads λ ~9 % slow. The
live evaluation measures that departure (``RateDiscrepancy``) on the 2-minute calibration flights at
the checkpoint's height, interpolated between the reports either side of it; taken at the first report
below 20 km (often 1–4 km lower, where the misfit averages out) it read +1.4 % and live lost there
(185 s against 159 s); at the height it reads −1.1 % ± 4.8 %, and the update leans on the prior.

Deterministic: every world is seeded (the flights' own λᵢ, bursts, launch points, logging phases and
GNSS noise), so a failure is a change of the estimator or of the generator, not a draw.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.calibration.live_evaluation import LevelGround
from predictor.descent.payload import Payload
from predictor.environment.weather import load_weather
from predictor.prediction import CalibratedModel, load_model
from predictor.tracks import clean, read_track
from tests.independent_world import (
    CDA_M2,
    GROUND_M,
    MASS_KG,
    NOISE_ONLY,
    TWO_REGIME,
    UPDRAFT,
    WIND_RAMP,
    Effects,
    make_world,
    write_weather,
)

WORLDS = {
    "noise only": NOISE_ONLY,
    "two-regime canopy": TWO_REGIME,
    "wind ramp": WIND_RAMP,
    "updraft": UPDRAFT,
}
CHECKPOINTS_M = (20_000.0, 10_000.0)
UNSEEN_CADENCE_S = 10.0
"""The unseen flights log every 10 s, so their measured touchdown (the first fix on the ground) is
within 10 s of the truth; the same for both predictors, which are compared flight by flight."""


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, ...]:
    return write_weather(tmp_path_factory.mktemp("independent-gfs"))


def calibrated(directory: Path, effects: Effects, weather: tuple[Path, ...]) -> CalibratedModel:
    """The model a team would make of eight calibration flights, with its own live settings."""
    world = make_world(directory / "calibration", effects, flights=8, seed=11, weather=weather)
    model = directory / "model.json"
    tracks, grib = [str(p) for p in world.tracks], [str(p) for p in weather]
    assert main(["calibrate", "--tracks", *tracks, "--weather", *grib, "--mass", str(MASS_KG), "--cda",
                 str(CDA_M2), "--save-model", str(model), "--cache-dir", str(directory / "cache")]) == 0  # fmt: skip
    assert main(["live", "evaluate", *tracks, "--model", str(model), "--weather", *grib, "--save-model", str(model),
                 "--out", str(directory / "live"), "--cache-dir", str(directory / "cache")]) == 0  # fmt: skip
    return load_model(model)


def remaining_errors(
    model: CalibratedModel,
    effects: Effects,
    directory: Path,
    weather: tuple[Path, ...],
    cadence_s: float = UNSEEN_CADENCE_S,
) -> dict[float, tuple[list[float], list[float]]]:
    """Per checkpoint: (model live, plain restart) remaining-time errors (s) on six unseen flights."""
    world = make_world(directory / f"unseen-{cadence_s:g}", effects, flights=6, seed=23, cadence_s=cadence_s,
                       weather=weather)  # fmt: skip
    cube = load_weather([str(p) for p in weather], cache_dir=directory / "cache")
    ground = LevelGround(GROUND_M)
    nominal = CalibratedModel(Payload(MASS_KG, CDA_M2, name="nominal"), (), None)
    out: dict[float, tuple[list[float], list[float]]] = {km: ([], []) for km in CHECKPOINTS_M}
    for truth in world.flights:
        flight = clean(read_track(truth.path))
        assert flight.landing is not None
        live = model.live_predictor(cube, ground)
        plain = nominal.live_predictor(cube, ground, corrected=False)
        pending = list(CHECKPOINTS_M)
        for fix in flight.descent[:-1]:
            live.observe(fix)
            plain.observe(fix)
            if pending and fix.alt_m - GROUND_M <= pending[0]:
                remaining = (flight.landing.time - fix.time).total_seconds()
                out[pending[0]][0].append(live.predict_from(fix).prediction.descent_s - remaining)
                out[pending[0]][1].append(plain.predict_from(fix).prediction.descent_s - remaining)
                pending.pop(0)
    return out


@pytest.mark.parametrize("name", list(WORLDS))
def test_on_unseen_flights_live_with_the_model_is_never_much_worse_than_the_plain_restart(
    name: str, weather: tuple[Path, ...], tmp_path: Path
) -> None:
    # Measured (model vs plain restart, mean |remaining-time error|, from 20 / 10 km): noise only 6/2 vs
    # 73/48 s; two-regime canopy 11/3 vs 159/104 s (the floor from 20 km is 185 s; 84/3 s with the
    # payload's law live instead of the model's); wind ramp 6/2 vs 73/48 s; updraft 16/16 vs 283/268 s.
    effects = WORLDS[name]
    model = calibrated(tmp_path, effects, weather)
    assert model.live is not None and model.live.prior is not None
    # The model's law flies live only where it beat the payload's with the same λ beyond its interval
    # on the calibration flights: the library's own two-regime form does; with nothing to find, no.
    assert model.live.restart == "payload"
    if name in ("noise only", "two-regime canopy"):
        assert model.live.law == ("model" if name == "two-regime canopy" else "payload")
    errors = remaining_errors(model, effects, tmp_path, weather)
    for km, (with_model, restart) in errors.items():
        assert len(with_model) == 6, (name, km)
        model_s, restart_s = float(np.mean(np.abs(with_model))), float(np.mean(np.abs(restart)))
        assert model_s <= 1.1 * restart_s + 10.0, (
            f"{name} from {km / 1000:g} km: {model_s:.0f} s vs {restart_s:.0f} s"
        )


def test_the_two_regime_canopy_floor_holds_on_1hz_records_too(
    weather: tuple[Path, ...], tmp_path: Path
) -> None:
    # The live λ must not depend on how densely the unseen flights are logged. Measured with the same
    # model on 1 Hz records (the touchdown exact to a second): 14 / 1 s against 124 / 81 s for the plain
    # restart from 20 / 10 km (floors 146 / 99 s; 78 / 2 s with the payload's law live instead). With the
    # record from its top and the whole-descent prior it was 94 s from 20 km.
    model = calibrated(tmp_path, TWO_REGIME, weather)
    errors = remaining_errors(model, TWO_REGIME, tmp_path, weather, cadence_s=1.0)
    for km, (with_model, restart) in errors.items():
        assert len(with_model) == 6, km
        model_s, restart_s = float(np.mean(np.abs(with_model))), float(np.mean(np.abs(restart)))
        assert model_s <= 1.1 * restart_s + 10.0, (
            f"from {km / 1000:g} km: {model_s:.0f} s vs {restart_s:.0f} s"
        )
