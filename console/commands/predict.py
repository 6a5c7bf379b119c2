"""``drs predict``: a landing prediction from GRIB weather, and ``drs predict bench``, its measured speed.

The human summary is what an operator reads on launch day, so it leads with the demo warning
when there is one and gives every number with its unit; ``--json`` prints the result document.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import UtcTime, input_file, latitude, longitude
from predictor.descent import PROFILES
from predictor.environment import weather_bbox
from predictor.errors import PredictorError, UsageError
from predictor.geofiles import piped

if TYPE_CHECKING:  # the descent engine (numba) and the exports load only when a prediction runs
    from predictor.prediction import EnsemblePrediction, Prediction

MAX_MEMBERS = 100_000
"""About 2.5 GB of trajectories at the default step: well inside an operations laptop, and 100× the
1000 members whose ellipse is already stable to a few percent."""


ERROR_MODEL_NAMES = ("hindsight", "launch")
"""``predictor.prediction.ERROR_MODELS``'s names (a test holds them equal): importing that module loads
numpy and pyproj, and ``drs predict --help`` must not wait for them."""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "predict",
        help="predict a capsule's landing (or `drs predict bench` to measure speed)",
        description="Predict where a capsule released from a balloon lands, with its error ellipse.",
    )
    parser.add_argument(
        "action", nargs="?", choices=("bench",), help="bench: measure and print the speed figures"
    )
    parser.add_argument(
        "--weather",
        nargs="+",
        metavar="FILE",
        type=input_file("--weather"),
        help="GFS GRIB2 files (forecast steps, cycles); - reads one from standard input",
    )
    parser.add_argument(
        "--demo-weather", action="store_true", help="use the generated DEMO atmosphere instead of --weather"
    )
    parser.add_argument(
        "--dem", metavar="DIR", help="terrain: directory of SRTM .hgt tiles and/or NetCDF DEMs"
    )
    parser.add_argument("--lat", type=latitude, help="release latitude, degrees north")
    parser.add_argument("--lon", type=longitude, help="release longitude, degrees east")
    parser.add_argument("--alt", type=float, help="release altitude, m above mean sea level")
    parser.add_argument(
        "--time",
        type=UtcTime("--time"),
        help="release (or drift start) time, ISO 8601 UTC, e.g. 2024-05-01T06:30Z, or now",
    )
    parser.add_argument(
        "--payload", choices=sorted(PROFILES), help="payload profile (default drs; not with --model)"
    )
    parser.add_argument(
        "--model", metavar="PATH", type=input_file("--model"),
        help="a calibrated model from drs calibrate --save-model (- reads standard input): its payload, terms "
        "and ellipse (not with --payload, --mass, --cda)",
    )  # fmt: skip
    parser.add_argument("--mass", type=float, metavar="KG", help="override the profile's mass")
    parser.add_argument("--cda", type=float, metavar="M2", help="override the profile's Cd·A")
    parser.add_argument(
        "--step", type=float, default=100.0, metavar="M", help="altitude step (default 100 m)"
    )
    parser.add_argument(
        "--drift-minutes", type=float, default=0.0, metavar="N", help="float drift before release"
    )
    parser.add_argument(
        "--members", type=int, metavar="N",
        help=f"run a perturbed ensemble of N members (at most {MAX_MEMBERS:,}: memory grows with N)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="ensemble random seed (default 0)")
    parser.add_argument(
        "--error-model",
        choices=ERROR_MODEL_NAMES,
        help="ellipse parameters (default: the model's fitted ellipse with --model, else launch)",
    )
    parser.add_argument(
        "--probability", type=float, nargs="+", default=[], metavar="P", help="extra contours, e.g. 0.5 0.95"
    )
    parser.add_argument(
        "--kml", metavar="OUT", help="write KML (path, release, landing, ellipses); - for stdout"
    )
    parser.add_argument("--geojson", metavar="OUT", help="write GeoJSON; - for stdout")
    parser.add_argument(
        "--gpx",
        metavar="OUT",
        help="write GPX for a handheld (predicted landing, release, path); - for stdout",
    )
    parser.add_argument("--json", action="store_true", help="print the JSON result document")
    parser.add_argument("--track", action="store_true", help="include the path in the JSON")
    parser.add_argument("--cache-dir", metavar="DIR", help="weather cache (default ~/.cache/drs/weather)")
    bench = parser.add_argument_group("bench options")
    bench.add_argument(
        "--repeats", type=int, default=200, help="bench: single predictions timed (default 200)"
    )
    bench.add_argument("--ensemble-repeats", type=int, default=10, help="bench: ensembles timed (default 10)")
    bench.add_argument(
        "--bench-members",
        type=int,
        default=1000,
        help=f"bench: ensemble size (default 1000, at most {MAX_MEMBERS:,})",
    )
    bench.add_argument(
        "--skip-compile", action="store_true", help="bench: do not time a fresh-process compile"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.action == "bench":
        return run_bench(args)
    required = {
        "--lat": args.lat,
        "--lon": args.lon,
        "--alt": args.alt,
        "--time": args.time,
    }
    missing = [flag for flag, value in required.items() if value is None]
    if args.weather is None and not args.demo_weather:
        missing.insert(0, "--weather (or --demo-weather)")
    if missing:
        raise UsageError(f"drs predict needs {', '.join(missing)}")
    if args.weather is not None and args.demo_weather:
        raise UsageError("give either --weather or --demo-weather, not both")
    if args.members is not None and not 1 <= args.members <= MAX_MEMBERS:
        raise UsageError(f"--members {args.members}: give 1 to {MAX_MEMBERS:,} (10 million needed 24 GB)")
    from predictor.prediction import emit, release_altitude_warning

    emit(release_altitude_warning(args.alt))
    summary_to = (
        sys.stderr if piped(kml=args.kml, geojson=args.geojson, gpx=args.gpx, json=args.json) else sys.stdout
    )
    from predictor.descent import COMPILE_NOTICE, Release, kernels_compiled
    from predictor.environment import Terrain, demo_weather_files, load_weather
    from predictor.prediction import (
        EnsemblePrediction,
        EnsembleSpread,
        flown_model,
        predict,
        predict_ensemble,
        to_json,
        write_geojson,
        write_gpx,
        write_kml,
    )

    when: datetime = args.time
    files = demo_weather_files(args.lat, args.lon, when) if args.demo_weather else args.weather
    flown = flown_model(args.model, args.payload, args.mass, args.cda)
    calibrated = flown if args.model is not None else None
    terrain = Terrain.from_dir(args.dem) if args.dem else Terrain.sea_level()
    wx = load_weather(
        files, bbox=weather_bbox(args.lat, args.lon, args.drift_minutes), cache_dir=args.cache_dir
    )
    release = Release(when, args.lat, args.lon, args.alt, drift_minutes=args.drift_minutes)
    setup = flown.flight_setup(terrain, args.step, args.error_model, args.probability)
    if not kernels_compiled():
        print(f"drs: {COMPILE_NOTICE}", file=sys.stderr, flush=True)
    result: Prediction | EnsemblePrediction
    if args.members is not None:
        result = predict_ensemble(wx, release, setup, EnsembleSpread(args.members, args.seed))
    else:
        result = predict(wx, release, setup)
    central = result.central if isinstance(result, EnsemblePrediction) else result
    spread = None
    if calibrated is not None:
        # Only a model file has a rate prior to spread; a plain prediction never enters calibration.
        from predictor.calibration import descent_spread

        spread = descent_spread(
            calibrated, central, lambda terms: predict(wx, release, replace(setup, effects=terms))
        )
    if args.kml:
        write_kml(result, args.kml)
    if args.geojson:
        write_geojson(result, args.geojson)
    if args.gpx:
        write_gpx(result, args.gpx)
    if args.json:
        document = json.loads(to_json(result, track=args.track))
        if calibrated is not None:
            document["model"] = calibrated.document(args.model)
        if spread is not None:
            document["rate_prior_spread"] = spread.to_dict()
        print(json.dumps(document, indent=2, ensure_ascii=False))
    else:
        text = summary(result)
        if calibrated is not None:
            text += f"\nmodel     {calibrated.label()}" + (f"\n{spread.line()}" if spread is not None else "")
        print(text, file=summary_to)
    return 0


def summary(result: Prediction | EnsemblePrediction) -> str:
    from predictor.prediction import GEOD, EnsemblePrediction, iso_z

    pred = result.central if isinstance(result, EnsemblePrediction) else result
    lines = []
    if pred.is_demo:
        lines.append("*** DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations. ***")
    r, land, e = pred.release, pred.landing, pred.ellipse
    if pred.decision is not None:
        d = pred.decision
        lines.append(f"decision  {iso_z(d.time)}  {d.lat:.5f}, {d.lon:.5f}  then drift at float")
    lines += [
        f"release   {iso_z(r.time)}  {r.lat:.5f}, {r.lon:.5f}  {r.alt_m:.0f} m",
        f"landing   {iso_z(land.time)}  {land.lat:.5f}, {land.lon:.5f}  {land.alt_m:.0f} m"
        f" ({pred.terrain_source})",
        f"descent   {pred.descent_s / 60:.1f} min; drift {pred.drift_km:.2f} km toward "
        f"{pred.bearing_deg:.0f}° (path {pred.path_km:.2f} km)",
        f"ellipse   {e.kind}: σ∥ {e.sigma_parallel_km:.2f} km, σ⊥ {e.sigma_perpendicular_km:.2f} km "
        f"(⟨t_future⟩ {pred.t_future_mean_h:.1f} h)",
    ]
    lines += [
        f"          {c.n_sigma:.2f}σ holds {100 * c.probability:.1f} %: "
        f"{c.semi_major_km:.2f} × {c.semi_minor_km:.2f} km"
        for c in e.contours
    ]
    if isinstance(result, EnsemblePrediction):
        m = result.empirical
        _, _, gap = GEOD.inv(land.lon, land.lat, m.center_lon, m.center_lat)
        inside = ", ".join(
            f"{100 * (c.observed_fraction or 0):.1f} % in {c.n_sigma:.0f}σ" for c in m.contours[:3]
        )
        lines.append(
            f"ensemble  {result.members} members: σ∥ {m.sigma_parallel_km:.2f} km, "
            f"σ⊥ {m.sigma_perpendicular_km:.2f} km, mean {gap / 1000:.2f} km from the central landing; "
            f"{inside}"
        )
    lines.append(f"payload   {pred.payload.name}: {pred.payload.mass_kg} kg, Cd·A {pred.payload.cda_m2} m²")
    lines.append(f"weather   {pred.weather_source}")
    lines += [f"warning   {w}" for w in pred.warnings]
    return "\n".join(lines)


# ---------------------------------------------------------------- bench

BENCH_CYCLE = datetime(2024, 5, 1, 0, tzinfo=UTC)


def _timed(fn: Callable[[], object], repeats: int, cpu: list[float] | None = None) -> list[float]:
    """Wall-clock seconds of each call; the process CPU seconds of each go into ``cpu`` when given.

    CPU time is reported beside wall time because this machine is shared: when other work holds
    the cores, wall time grows while the CPU the call itself needs does not.
    """
    out = []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        out.append(time.perf_counter() - start)
        if cpu is not None:
            cpu.append(time.process_time() - start_cpu)
    return out


def _figure(times: Sequence[float], unit: float, label: str) -> str:
    return (
        f"median {statistics.median(times) * unit:.3g}, min {min(times) * unit:.3g}, "
        f"max {max(times) * unit:.3g} {label} over {len(times)} runs"
    )


_COMPILE_PROBE = textwrap.dedent(
    """
    import time
    start = time.perf_counter()
    from datetime import datetime, timezone
    import numpy as np
    from predictor import predict, Release, WeatherCube
    levels = np.array([1000.0, 500.0, 100.0, 10.0])
    z = np.array([100.0, 5500.0, 16000.0, 31000.0])[None, :, None, None] * np.ones((2, 4, 3, 3))
    cube = WeatherCube(
        times=np.array(["2024-05-01T00", "2024-05-01T06"], dtype="datetime64[s]"),
        lead_h=np.array([0.0, 6.0]), levels_hpa=levels, lats=np.array([45.0, 46.0, 47.0]),
        lons=np.array([5.0, 6.0, 7.0]), z_m=z,
        u=np.zeros_like(z), v=np.zeros_like(z), temperature_k=np.full_like(z, 250.0),
        density=1.2 * np.exp(-z / 7300.0), source="compile probe")
    predict(cube, Release(datetime(2024, 5, 1, 3, tzinfo=timezone.utc), 46.0, 6.0, 30000.0))
    print(time.perf_counter() - start)
    """
)


def _fresh_process_seconds(cache_dir: str) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    done = subprocess.run(
        [sys.executable, "-c", _COMPILE_PROBE],
        env=env,
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    if done.returncode != 0:
        raise PredictorError(f"the compile probe failed: {done.stderr.strip().splitlines()[-1]}")
    return float(done.stdout.strip())


def _whole_process_seconds(argv: Sequence[str], repeats: int = 5) -> list[float]:
    """Wall time of `drs ARGV` in a fresh process, as a person at a terminal waits for it."""
    command = [sys.executable, "-m", "console.commands.main", *argv]
    return _timed(lambda: subprocess.run(command, capture_output=True, check=True, timeout=600), repeats)


def _print_whole_process(files: Sequence[Path], cache_dir: Path) -> None:
    """What a person feels: help, and one prediction from cached weather with the numba cache warm, each
    against the bare interpreter it cannot beat (issue #25: help ≤ 8× ``import argparse``, a first
    prediction ≤ 2.5× ``import numpy, scipy.optimize``), measured in the same run."""
    release = ["--lat", "46.0", "--lon", "6.0", "--alt", "30000", "--time", "2024-05-01T04:00Z"]
    predict_argv = ["predict", "--weather", *map(str, files), "--cache-dir", str(cache_dir), *release]
    _whole_process_seconds(predict_argv, repeats=1)  # the numba cache for this install, once

    def bare(code: str) -> list[float]:
        return _timed(lambda: subprocess.run([sys.executable, "-c", code], check=True, timeout=600), 5)

    argparse_s = statistics.median(bare("import argparse"))
    science_s = statistics.median(bare("import numpy, scipy.optimize"))
    for label, argv, reference, name in (
        ("drs --help", ["--help"], argparse_s, "import argparse"),
        ("drs predict --help", ["predict", "--help"], argparse_s, "import argparse"),
        (
            "drs predict (cached weather, warm numba cache)",
            predict_argv,
            science_s,
            "import numpy, scipy.optimize",
        ),
    ):
        times = _whole_process_seconds(argv)
        print(
            f"whole process: {label}: {_figure(times, 1, 's')}, "
            f"{statistics.median(times) / reference:.1f}× python -c '{name}'"
        )
    print(
        f"whole process, for reference: python -c 'import argparse' {argparse_s:.3f} s, "
        f"python -c 'import numpy, scipy.optimize' {science_s:.3f} s (medians of 5)"
    )


def run_bench(args: argparse.Namespace) -> int:
    if not 1 <= args.bench_members <= MAX_MEMBERS:
        raise UsageError(
            f"--bench-members {args.bench_members}: give 1 to {MAX_MEMBERS:,} (memory grows with it)"
        )
    import numba

    from predictor.descent import Release
    from predictor.environment import GFS_LEVELS_HPA, Terrain, demo_weather_files, load_weather
    from predictor.prediction import EnsembleSpread, FlightSetup, predict, predict_ensemble

    print(
        f"drs predict bench: {os.cpu_count()} CPUs, numba {numba.__version__} with "
        f"{numba.get_num_threads()} threads, load average {os.getloadavg()[0]:.2f} at start"
    )
    with tempfile.TemporaryDirectory(prefix="drs-bench-") as tmp:
        root = Path(tmp)
        start = time.perf_counter()
        files = demo_weather_files(46.0, 6.0, BENCH_CYCLE, root / "grib", hours=12, half_width_deg=5.0)
        written = time.perf_counter() - start
        size_mb = sum(f.stat().st_size for f in files) / 1e6
        print(
            f"weather: {len(files)} GRIB2 files of the demo atmosphere (gribwrite, {written:.2f} s to "
            f"write), 0.5°, 10°×10° (21×21), {len(GFS_LEVELS_HPA)} levels, {size_mb:.1f} MB"
        )
        start = time.perf_counter()
        load_weather(files, cache_dir=root / "cache")
        cold = time.perf_counter() - start
        cached_times = _timed(lambda: load_weather(files, cache_dir=root / "cache"), 5)
        print(f"  load cold (decode all, write cache):  {cold:.3f} s   [floor 2 s]")
        print(f"  load from cache:                      {_figure(cached_times, 1, 's')}   [floor 0.2 s]")
        wx = load_weather(files, cache_dir=root / "cache")
        if not args.skip_compile:
            compile_s = _fresh_process_seconds(str(root / "numba-cache"))
            cached_s = _fresh_process_seconds(str(root / "numba-cache"))
            print(
                f"compile: first prediction in a fresh process (import + JIT) {compile_s:.2f} s with an "
                f"empty numba cache, {cached_s:.2f} s with the on-disk cache"
            )
        _print_whole_process(files, root / "cache")
    when = BENCH_CYCLE + timedelta(hours=4)
    release = Release(when, 46.0, 6.0, 30000.0)
    setup = FlightSetup(PROFILES["drs"], terrain=Terrain.sea_level())
    first = predict(wx, release, setup)
    steps = math.ceil(30500.0 / 100.0)
    singles = _timed(lambda: predict(wx, release, setup), args.repeats)
    print(
        f"one prediction, drs payload, 30 km → sea level, Δz 100 m ({steps} steps, drift "
        f"{first.drift_km:.1f} km, {first.descent_s / 60:.1f} min), whole predict() call: "
        f"{_figure(singles, 1e3, 'ms')}   [floor 2 ms]"
    )
    n = args.bench_members
    predict_ensemble(wx, release, setup, EnsembleSpread(n))
    cpu: list[float] = []
    ensembles = _timed(
        lambda: predict_ensemble(wx, release, setup, EnsembleSpread(n)),
        args.ensemble_repeats,
        cpu,
    )
    print(
        f"{n}-member perturbed ensemble, same descent, whole predict_ensemble() call (central run, members, "
        f"terrain crossing, empirical ellipse): {_figure(ensembles, 1e3, 'ms')}   [floor 100 ms]; "
        f"CPU time used (all threads): median {statistics.median(cpu) * 1e3:.3g} ms"
    )
    return 0
