"""``drs calibrate`` on real flights, and every input error as one line with exit status 1."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.calibration.model_file import load_model
from predictor.descent.model import DescentRateScale
from predictor.descent.payload import PROFILES
from predictor.environment.gribwrite import GFS_LEVELS_HPA, gfs_file_name, write_gfs_grib2
from predictor.environment.weather import load_weather
from predictor.tracks.reading import write_canonical_csv
from predictor.tracks.standard_atmosphere import pressure_temperature
from predictor.tracks.synthetic import synthetic_flight

PAYLOAD = PROFILES["superbit-test"]

FLIGHTS = ("18-5-19", "18-6-30", "19-2-2", "19-7-28")


def _tracks(shared_data: Path) -> list[str]:
    return [str(shared_data / "tracks" / "pyballoon_superbit" / f"{name}.csv") for name in FLIGHTS]


def test_calibrating_real_flights_writes_the_json_and_the_report(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ascent_only = tmp_path / "ascent-only.csv"
    lines = (shared_data / "tracks" / "pyballoon_superbit" / "18-5-19.csv").read_text().splitlines()
    ascent_only.write_text("\n".join(lines[:30]) + "\n")
    out_json, out_md = tmp_path / "cal.json", tmp_path / "docs" / "cal.md"
    status = main([
        "calibrate", "--tracks", *_tracks(shared_data), str(ascent_only), "--winds", "ascent",
        "--payload", "superbit-test", "--effects", "descent_rate_scale", "wind_scale",
        "--json", str(out_json), "--report", str(out_md), "--save-model", str(tmp_path / "superbit.model.json"),
    ])  # fmt: skip
    assert status == 0
    data = json.loads(out_json.read_text())
    model = load_model(tmp_path / "superbit.model.json")
    assert model.payload.cda_m2 == PAYLOAD.cda_m2 and model.provenance["flights"] == list(FLIGHTS)
    passed = [t["record"] for t in data["binned_correction"]["tests"] if t["passed"]]
    binned = [name for name, record in (("binned_descent_rate", "vertical"), ("binned_wind", "horizontal"))
              if record in passed]  # fmt: skip
    # λ first (the rate prior's median), then the shape, then the binned parts that passed.
    assert [t.name for t in model.terms] == [
        "descent_rate_scale",
        *(f["effect"] for f in data["selected"]),
        *binned,
    ]
    assert model.rate_prior is not None and model.rate_prior.to_dict() == {
        k: data["rate_prior"][k] for k in ("median", "log_sigma", "flights")
    }
    assert model.terms[0].parameters()["scale"] == model.rate_prior.median
    assert model.provenance["held_out_before"] == data["baseline"]
    assert model.ellipse is not None
    assert model.ellipse.sigma0_km == pytest.approx(
        data["uncertainty_model"]["sigma0_km"], abs=1e-3
    )  # rounded there
    assert data["flights"] == list(FLIGHTS)
    assert data["excluded"][0]["name"] == "ascent-only" and data["excluded"][0]["reason"].startswith(
        "cleaning:"
    )
    # λ is each flight's own (the rate prior), never a shared candidate.
    assert [c["effect"] for c in data["candidates"]] == ["wind_scale"]
    assert 0.5 < data["baseline"]["landing_error_km"]["median"] < 10.0
    assert data["uncertainty_model"]["k_identifiable"] is False  # ascent winds have no lead time
    assert out_md.is_file() and (tmp_path / "docs" / "cal-speed-ratio.png").is_file()
    printed = capsys.readouterr().out
    assert "4 flights used, 1 excluded" in printed and "excluded ascent-only: cleaning:" in printed


def test_the_bench_times_the_whole_calibration(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main([
        "calibrate", "bench", "--tracks", *_tracks(shared_data)[:3], "--winds", "ascent",
        "--payload", "superbit-test", "--effects", "wind_scale",
    ])  # fmt: skip
    assert status == 0
    out = capsys.readouterr().out
    assert out.startswith("3 flights, 1 candidate effects, step 200 m, best of 1:") and "total" in out


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--payload", "superbit-test"], "give the weather: --weather FILE... or --winds ascent"),
        (["--winds", "ascent"], "give the payload: --payload NAME, or both --mass KG and --cda M2"),
        (["--winds", "ascent", "--mass", "1.5"], "give the payload"),
        (["--winds", "ascent", "--payload", "balloon"], "unknown payload profile 'balloon'"),
        (["--winds", "ascent", "--payload", "drs", "--step", "5"], "--step must be between 10 and 1000 m"),
        (["--winds", "ascent", "--payload", "drs", "--effects", "gusts"], "unknown effect(s) gusts"),
        (
            ["--winds", "ascent", "--payload", "drs", "--dem", "/nonexistent"],
            "terrain directory /nonexistent",
        ),
        (
            ["--weather", "/nonexistent.grib2", "--payload", "drs"],
            "weather file /nonexistent.grib2 does not exist",
        ),
    ],
)
def test_bad_input_is_one_line_with_status_1(
    shared_data: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    status = main(["calibrate", "--tracks", *_tracks(shared_data)[:1], *extra])
    err = capsys.readouterr().err
    assert status == 1 and err.startswith("drs: error: ") and message in err and err.count("\n") == 1


def test_an_unreadable_track_names_its_file_and_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,lat,lon,alt_m\n2024-05-01T08:00:00Z,46.0,six,500\n")
    status = main(["calibrate", "--tracks", str(bad), "--winds", "ascent", "--payload", "drs"])
    err = capsys.readouterr().err
    assert status == 1 and err.startswith(f"drs: error: {bad}:2") and err.count("\n") == 1


def test_no_usable_flight_is_an_error_not_an_empty_report(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          shared_data: Path) -> None:  # fmt: skip
    short = tmp_path / "short.csv"
    lines = (shared_data / "tracks" / "pyballoon_superbit" / "18-5-19.csv").read_text().splitlines()
    short.write_text("\n".join(lines[:30]) + "\n")
    status = main(["calibrate", "--tracks", str(short), "--winds", "ascent", "--payload", "superbit-test"])
    err = capsys.readouterr().err
    assert status == 1 and "needs at least 3 usable flights, got 0 (excluded: short: cleaning:" in err


def test_flights_logged_in_forecast_weather_are_calibrated_from_grib_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """GFS-like GRIB2 written by eccodes, flights flown in it with λ = 0.8, exported as canonical CSV."""
    cycle = datetime(2024, 5, 1, 0, tzinfo=UTC)
    levels = np.array(GFS_LEVELS_HPA[:-3], dtype=float)  # 1000 … 5 hPa (to ~36 km)
    lats, lons = np.arange(43.0, 49.01, 0.5), np.arange(3.0, 11.01, 0.5)
    shape = (levels.size, lats.size, lons.size)
    z_std = np.linspace(-500.0, 40_000.0, 4000)
    p_std, t_std = pressure_temperature(z_std)
    gh = np.interp(np.log(levels * 100.0), np.log(p_std[::-1]), z_std[::-1])
    t = np.interp(gh, z_std, t_std)
    files = []
    for step in (0, 3, 6):
        u = np.full(shape, 9.0 + step) + 0.3 * (gh[:, None, None] / 1000.0)
        v = np.full(shape, 2.0) + 0.2 * (lats[None, :, None] - 46.0)
        t3d, gh3d = np.broadcast_to(t[:, None, None], shape), np.broadcast_to(gh[:, None, None], shape)
        path = tmp_path / gfs_file_name(cycle, step)
        files.append(write_gfs_grib2(path, cycle, step, levels, lats, lons, u, v, t3d, gh3d))
    cube = load_weather(files, cache_dir=tmp_path / "cache")
    tracks = []
    for k in range(4):
        flight = synthetic_flight(
            cube, launch_time=cycle + timedelta(minutes=40 + 15 * k), lat=45.5 + 0.2 * k, lon=5.0,
            payload=PAYLOAD,
            effects=(DescentRateScale(scale=0.8),), burst_alt_m=24_000.0, ascent_rate_ms=8.0, seed=k,
        )  # fmt: skip
        path = tmp_path / f"flight-{k}.csv"
        write_canonical_csv(flight.track.fixes, path)
        tracks.append(str(path))
    out = tmp_path / "cal.json"
    status = main([
        "calibrate", "--tracks", *tracks, "--weather", *map(str, files),
        "--cache-dir", str(tmp_path / "cache"),
        "--payload", "superbit-test", "--effects", "wind_scale", "descent_rate_scale", "--json", str(out),
    ])  # fmt: skip
    assert status == 0, capsys.readouterr().err
    data = json.loads(out.read_text())
    # A factor on every flight's rate is no shape: the shape record sees nothing, and λ = 0.8 is the
    # rate prior every flight shares (the same payload), which the pre-flight prediction flies.
    assert data["selected"] == []
    assert data["rate_prior"]["median"] == pytest.approx(0.8, abs=0.01)
    assert data["rate_prior"]["log_sigma"] < 0.01
    assert data["after"]["track_rms_km"]["mean"] < 0.1 * data["baseline"]["track_rms_km"]["mean"]
    assert data["library_explains_residual"] is True
