"""``drs plan`` (release window), ``drs plan bench`` (its speed) and ``drs live`` (re-prediction in descent).

The summary leads with the verdict (GO with the recommended time, or NO-GO), because that is the
decision the operator is making; ``--json`` prints the whole plan document.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from console.commands.argparser import UtcDate, UtcTime, input_file, latitude, longitude, positive
from console.commands.progress import progress, while_saying
from predictor.descent import PROFILES
from predictor.errors import PredictorError, UsageError
from predictor.planning import MAX_MEMBER_DESCENTS

BENCH_START = datetime(2024, 5, 1, 6, 0, tzinfo=UTC)


def register(subparsers: argparse._SubParsersAction) -> None:
    plan = subparsers.add_parser(
        "plan",
        help="sweep release times: landing strip, zone risk, go/no-go (or `drs plan bench`)",
        description="For every candidate release time: landing, ellipse, P(exclusion zone), target distance.",
    )
    plan.add_argument("action", nargs="?", choices=("bench",), help="bench: measure the sweep's speed")
    plan.add_argument("--weather", nargs="+", metavar="FILE", type=input_file("--weather"),
                      help="GFS GRIB2 files; - reads one from standard input")  # fmt: skip
    plan.add_argument("--dem", metavar="DIR", help="terrain: directory of SRTM .hgt tiles and/or NetCDF DEMs")
    plan.add_argument("--lat", type=latitude, help="balloon latitude now, degrees north")
    plan.add_argument("--lon", type=longitude, help="balloon longitude now, degrees east")
    plan.add_argument("--alt", type=float, help="balloon (float) altitude, m above mean sea level")
    plan.add_argument(
        "--from",
        dest="start",
        metavar="ISO",
        type=UtcTime("--from"),
        help="first candidate release time, ISO 8601 UTC, or now",
    )
    plan.add_argument("--hours", type=float, default=2.0, help="length of the sweep (default 2 h)")
    plan.add_argument(
        "--every-minutes", type=positive("minutes"), default=5.0, help="candidate spacing (default 5 min)"
    )
    plan.add_argument("--altitude-plan", metavar="T=M,...", help="balloon altitude plan: ISO=metres,...")
    plan.add_argument(
        "--zones",
        metavar="FILE",
        type=input_file("--zones"),
        help="GeoJSON exclusion zones (Polygon/MultiPolygon); - reads standard input",
    )
    plan.add_argument(
        "--targets",
        metavar="FILE",
        type=input_file("--targets"),
        help="GeoJSON targets (points/lines: roads, recovery points); - reads standard input",
    )
    plan.add_argument(
        "--max-zone-probability", type=float, default=0.05, help="go needs P(zone) ≤ this (0.05)"
    )
    plan.add_argument("--max-target-km", type=float, help="go needs expected target distance ≤ this")
    plan.add_argument("--max-sigma-km", type=float, help="go needs the 1σ major axis ≤ this")
    plan.add_argument(
        "--members", type=int, default=0,
        help=f"ensemble members per candidate (default 0: none; candidates × members at most {MAX_MEMBER_DESCENTS:,})",
    )  # fmt: skip
    plan.add_argument("--seed", type=int, default=0, help="ensemble seed (default 0)")
    plan.add_argument("--float-wind-sigma", type=float, default=2.0, metavar="MS",
                      help="σ of the float-altitude wind error, m/s (default 2)")  # fmt: skip
    plan.add_argument(
        "--payload", choices=sorted(PROFILES), help="payload profile (default drs; not with --model)"
    )
    plan.add_argument(
        "--mass", type=float, metavar="KG", help="override the profile's mass (not with --model)"
    )
    plan.add_argument(
        "--cda", type=float, metavar="M2", help="override the profile's Cd·A (not with --model)"
    )
    plan.add_argument(
        "--model", metavar="PATH", type=input_file("--model"),
        help="a calibrated model (drs calibrate --save-model; - reads standard input): its payload, terms and "
        "ellipse replace --payload",
    )  # fmt: skip
    plan.add_argument("--json", action="store_true", help="print the plan document")
    plan.add_argument("--kml", metavar="OUT", help="write the landing strip as KML; - for stdout")
    plan.add_argument("--geojson", metavar="OUT", help="write the landing strip as GeoJSON; - for stdout")
    plan.add_argument("--cache-dir", metavar="DIR", help="weather cache (default ~/.cache/drs/weather)")
    plan.add_argument("--repeats", type=int, default=5, help="bench: sweeps timed (default 5)")
    plan.set_defaults(func=run_plan)

    live = subparsers.add_parser(
        "live",
        help="re-predict the landing from each fix of a descent track (or `drs live evaluate`)",
        description="Live re-prediction: each report restarts the prediction and corrects it by what "
        "the descent so far measured.",
    )
    live.add_argument("action", nargs="?", choices=("evaluate", "bench"),
                      help="evaluate: the leave-one-flight-out report on real tracks; bench: time evaluate "
                      "on the tracks re-sampled to 1 Hz")  # fmt: skip
    live.add_argument("tracks", nargs="*", metavar="TRACK", type=input_file("TRACK"),
                      help="evaluate/bench: track files; - reads one from standard input")  # fmt: skip
    live.add_argument(
        "--train", nargs="+", metavar="TRACK", type=input_file("--train"),
        help="evaluate: the flights every choice is learned on (with --score; instead of leave-one-out)",
    )  # fmt: skip
    live.add_argument(
        "--score", nargs="+", metavar="TRACK", type=input_file("--score"),
        help="evaluate: the flights scored, held out whole (a season, a payload, a team)",
    )  # fmt: skip
    live.add_argument(
        "--name", default="live-reprediction", metavar="NAME",
        help="evaluate: the report's file name, NAME.md and NAME.png in --out (default live-reprediction)",
    )  # fmt: skip
    live.add_argument("--weather", nargs="+", metavar="FILE", type=input_file("--weather"),
                      help="GFS GRIB2 files (evaluate: for every flight, instead of each one's ascent winds)")  # fmt: skip
    live.add_argument("--ascent-winds", action="store_true", help="use the track's own ascent as the weather")
    live.add_argument(
        "--track",
        metavar="FILE",
        type=input_file("--track"),
        help="the descent's track (any format `drs tracks` reads); - reads standard input",
    )
    live.add_argument(
        "--date",
        type=UtcDate("--date"),
        help="UTC date of the first fix, for logs with times of day only (V4)",
    )
    live.add_argument("--dem", metavar="DIR",
                      help="terrain directory (evaluate: instead of level ground at each measured landing)")  # fmt: skip
    live.add_argument(
        "--payload", choices=sorted(PROFILES), help="payload profile (default drs; evaluate: superbit-test)"
    )
    live.add_argument("--mass", type=float, metavar="KG", help="override the profile's mass")
    live.add_argument("--cda", type=float, metavar="M2", help="override the profile's Cd·A")
    live.add_argument("--model", metavar="PATH", type=input_file("--model"),
                      help="a calibrated model (drs calibrate --save-model); - reads standard input")  # fmt: skip
    live.add_argument("--no-correction", action="store_true", help="plain re-prediction from each report")
    live.add_argument("--json", action="store_true", help="print one JSON document per report")
    live.add_argument("--out", metavar="DIR", default="docs/planning", help="evaluate: report directory")
    live.add_argument(
        "--save-model", metavar="PATH",
        help="evaluate: write the --model file with the live settings measured for its law (correction "
        "bands, λ discrepancy, live ellipse; its λ prior when it has none), which drs live and the console fly",
    )  # fmt: skip
    live.add_argument("--cache-dir", metavar="DIR", help="weather cache (default ~/.cache/drs/weather)")
    live.set_defaults(func=run_live)


def run_plan(args: argparse.Namespace) -> int:
    if args.action == "bench":
        return run_bench(args)
    required = {"--weather": args.weather, "--lat": args.lat, "--lon": args.lon, "--alt": args.alt,
                "--from": args.start}  # fmt: skip
    missing = [flag for flag, value in required.items() if value is None]
    if missing:
        raise UsageError(f"drs plan needs {', '.join(missing)}")
    from predictor.descent import Release
    from predictor.environment import Terrain, load_weather, weather_bbox
    from predictor.geofiles import piped
    from predictor.planning import (
        AltitudePlan,
        Criteria,
        Sweep,
        Thresholds,
        plan_release,
        write_geojson,
        write_kml,
    )
    from predictor.prediction import (
        EnsembleSpread,
        emit,
        far_features_warning,
        flown_model,
        load_targets,
        load_zones,
        release_altitude_warning,
    )

    summary_to = sys.stderr if piped(kml=args.kml, geojson=args.geojson, json=args.json) else sys.stdout
    start: datetime = args.start
    model = flown_model(args.model, args.payload, args.mass, args.cda)
    if args.model is not None:
        print(f"model     {model.label()}", file=sys.stderr)
    thresholds = Thresholds(args.max_zone_probability, args.max_target_km, args.max_sigma_km)
    zones = load_zones(args.zones) if args.zones else ()
    targets = load_targets(args.targets) if args.targets else ()
    emit(
        release_altitude_warning(args.alt),
        far_features_warning("exclusion zone", [z.geometry for z in zones], [(args.lat, args.lon)]),
        far_features_warning("target", [t.geometry for t in targets], [(args.lat, args.lon)]),
    )
    altitude_plan = AltitudePlan.parse(args.altitude_plan) if args.altitude_plan else None
    terrain = Terrain.from_dir(args.dem) if args.dem else Terrain.sea_level()
    hours = args.hours if math.isfinite(args.hours) else 0.0
    with progress(quiet=bool(args.json)) as tell:
        wx = while_saying(tell, f"loading weather ({len(args.weather)} files)", lambda: load_weather(
            args.weather, bbox=weather_bbox(args.lat, args.lon, max(hours, 0.0) * 60.0), cache_dir=args.cache_dir
        ))  # fmt: skip
        plan = while_saying(tell, "sweeping the release times", lambda: plan_release(
            wx,
            Release(start, args.lat, args.lon, args.alt),
            Sweep(args.hours, args.every_minutes, altitude_plan, args.float_wind_sigma),
            model.flight_setup(terrain),
            EnsembleSpread(args.members, args.seed),
            Criteria(zones, targets, thresholds),
        ))  # fmt: skip
    if args.kml:
        write_kml(plan, args.kml)
    if args.geojson:
        write_geojson(plan, args.geojson)
    if args.json:
        print(json.dumps(plan.to_dict(), indent=1, ensure_ascii=False))
    else:
        print(plan_summary(plan), file=summary_to)
    return 0


def plan_summary(plan: object) -> str:
    from predictor.planning import ReleasePlan
    from predictor.prediction import iso_z

    assert isinstance(plan, ReleasePlan)
    lines = []
    if plan.is_demo:
        lines.append("*** DEMO WEATHER: generated atmosphere, not a forecast. Do not use for operations. ***")
    lines.append(plan.verdict)
    for w in plan.windows:
        c = plan.candidates[w.recommended]
        lines.append(
            f"window {w.rank}: {iso_z(plan.candidates[w.first].release_time)} – "
            f"{iso_z(plan.candidates[w.last].release_time)}, best {iso_z(c.release_time)} "
            f"→ {c.landing_lat:.4f}, {c.landing_lon:.4f}  P(zone) {c.zone_probability:.3f}"
            + (f", E[target] {c.expected_target_km:.1f} km" if c.expected_target_km is not None else "")
            + f", 1σ {c.sigma_major_km:.1f} km"
        )
    if plan.windows:
        first = (
            "the nearest expected target distance (to 0.1 km)"
            if any(c.expected_target_km is not None for c in plan.candidates)
            else "the lowest zone probability (to 0.1 %)"
        )
        lines.append(f"best = {first}, then the smallest 1σ ellipse, then the window's middle")
    lines.append("timeline (+ go, - no-go, x no landing):")
    marks = "".join("+" if c.go else ("x" if c.status else "-") for c in plan.candidates)
    lines += [f"  {marks[i : i + 60]}" for i in range(0, len(marks), 60)]
    for c in plan.candidates:
        when = iso_z(c.release_time)[11:16]
        if c.status is not None:
            lines.append(f"  {when}  no landing: {c.status}")
            continue
        target = f"  E[target] {c.expected_target_km:6.1f} km" if c.expected_target_km is not None else ""
        verdict = "GO   " if c.go else "NO-GO " + "; ".join(c.reasons)
        lines.append(
            f"  {when}  land {c.landing_lat:8.4f} {c.landing_lon:9.4f}  1σ {c.sigma_major_km:4.1f} km  "
            f"P(zone) {c.zone_probability:.3f}{target}  {verdict}"
        )
    lines.append(f"weather   {plan.weather_source}")
    lines += [f"warning   {w}" for w in plan.warnings]
    return "\n".join(lines)


def run_bench(args: argparse.Namespace) -> int:
    import numba
    import numpy as np
    import shapely

    from predictor.descent import Release
    from predictor.environment import demo_weather_files, load_weather
    from predictor.planning import Criteria, Sweep, plan_release
    from predictor.prediction import EnsembleSpread, Feature, FlightSetup

    members, hours, every = 200, 2.0, 1.0
    print(
        f"drs plan bench: {os.cpu_count()} CPUs, numba {numba.__version__} with {numba.get_num_threads()} "
        f"threads, load average {os.getloadavg()[0]:.2f} at start"
    )
    files = demo_weather_files(46.0, 6.0, BENCH_START, cache_dir=args.cache_dir)
    wx = load_weather(files, bbox=(38.0, 54.0, -6.0, 18.0), cache_dir=args.cache_dir)
    zones = (
        Feature("lake", shapely.Polygon([(6.6, 46.1), (7.2, 46.1), (7.2, 46.4), (6.6, 46.4), (6.6, 46.1)])),
        Feature("town", shapely.Point(7.5, 46.25).buffer(0.1)),
    )
    targets = (Feature("road", shapely.LineString([(6.0, 45.9), (8.0, 46.5)])),)
    release, sweep = Release(BENCH_START, 46.0, 6.0, 30000.0), Sweep(hours, every)
    setup, criteria = FlightSetup(PROFILES["drs"]), Criteria(zones, targets)
    spread = EnsembleSpread(members)
    plan_release(wx, release, sweep, setup, spread, criteria)
    times, cpu = [], []
    for _ in range(max(args.repeats, 1)):
        t0, c0 = time.perf_counter(), time.process_time()
        plan = plan_release(wx, release, sweep, setup, spread, criteria)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    n_c = len(plan.candidates)
    print(
        f"sweep {hours:g} h every {every:g} min ({n_c} candidates) × {members} members = "
        f"{n_c * members} member "
        f"descents + {n_c} central (Δz 100 m central, 200 m members), 30 km → sea level, demo weather, "
        f"2 zones + 1 target: median {statistics.median(times):.3f} s, min {min(times):.3f} s, "
        f"max {max(times):.3f} s over {len(times)} runs   [goal < 1 s]"
    )
    print(
        f"  CPU time of those sweeps (all threads together): median {statistics.median(cpu):.3f} s; "
        f"wall ≈ CPU / {numba.get_num_threads()} threads when the cores are free"
    )
    t0 = time.perf_counter()
    parametric = plan_release(wx, release, sweep, setup, criteria=criteria)
    print(f"same sweep without members (parametric ellipses only): {time.perf_counter() - t0:.3f} s")
    fine = plan_release(wx, release, Sweep(0.0, every, member_step_m=100.0), setup, spread, criteria)
    coarse = plan_release(wx, release, Sweep(0.0, every), setup, spread, criteria)
    from predictor.prediction import GEOD

    a, b = fine.candidates[0], coarse.candidates[0]
    assert a.member_lat is not None and b.member_lat is not None
    assert a.member_lon is not None and b.member_lon is not None
    _, _, gap = GEOD.inv(a.member_lon, a.member_lat, b.member_lon, b.member_lat)
    print(
        f"member landings at Δz 200 m vs 100 m ({members} members): RMS {np.sqrt(np.mean(gap**2)):.2f} m, "
        f"max {gap.max():.2f} m (the ensemble's own 1σ is {a.sigma_major_km:.2f} km)"
    )
    print(f"go candidates: {parametric.go_count} parametric, {plan.go_count} ensemble; load average now "
          f"{os.getloadavg()[0]:.2f}")  # fmt: skip
    return 0


def run_live(args: argparse.Namespace) -> int:
    from predictor.environment import Terrain
    from predictor.prediction import flown_model, iso_z
    from predictor.tracks import ascent_weather_cube, clean, read_track

    if args.action == "evaluate":
        return run_evaluate(args)
    if args.action == "bench":
        return run_live_bench(args)
    if not args.track:
        raise UsageError("drs live needs --track FILE")
    if not args.weather and not args.ascent_winds:
        raise UsageError("drs live needs --weather FILE... or --ascent-winds")
    flight = clean(read_track(args.track, day=args.date))
    if flight.descent_start is None or not flight.descent:
        reason = "; ".join(flight.exclusions) or "no descent found"
        raise PredictorError(f"{args.track}: no descent to re-predict ({reason})")
    if args.ascent_winds:
        wx = ascent_weather_cube(flight)
    else:
        from predictor.environment import load_weather, weather_bbox

        start = flight.descent_start
        wx = load_weather(
            args.weather, bbox=weather_bbox(start.lat, start.lon, 0.0), cache_dir=args.cache_dir
        )
    terrain = Terrain.from_dir(args.dem) if args.dem else Terrain.sea_level()
    model = flown_model(args.model, args.payload, args.mass, args.cda)
    live = model.live_predictor(wx, terrain, corrected=not args.no_correction)
    if not args.json:
        flown = "plain restart from each report (--no-correction)" if args.no_correction else model.label()
        print(f"drs live: {flown}" + "".join(f"\n  note: {n}" for n in live.notes))
    descent = list(flight.descent)
    if flight.landing is not None:
        descent = descent[:-1]
    for fix in descent:
        if fix.alt_m <= float(terrain.elevation(fix.lat, fix.lon)):
            continue
        result = live.update(fix)
        if args.json:
            print(json.dumps(result.to_dict(), ensure_ascii=False))
            continue
        p = result.prediction
        minutes, seconds = divmod(round(p.descent_s), 60)
        spread = result.remaining_sigma_s
        print(
            f"{iso_z(fix.time)}  {fix.alt_m:7.0f} m  → {p.landing.lat:.5f}, {p.landing.lon:.5f} at "
            f"{iso_z(p.landing.time)[11:19]} (in {minutes}m{seconds:02d}s"
            + (f", ± {spread:.0f} s 1σ" if spread is not None else "")
            + f")  1σ {p.ellipse.sigma_parallel_km:.2f}×{p.ellipse.sigma_perpendicular_km:.2f} km  "
            + (result.rate.describe() if result.rate is not None else "λ off")
            + (
                f"  wind Δ {result.wind_error_ms[0]:+.1f},{result.wind_error_ms[1]:+.1f} m/s "
                f"L {result.decay_m / 1000:g} km"
                + (f" × gain {result.wind_gain:.2f}" if result.wind_gain is not None else "")
                if result.decay_m is not None
                else ""
            )  # fmt: skip
        )
    if flight.landing is not None and not args.json:
        print(
            f"measured landing {iso_z(flight.landing.time)}  "
            f"{flight.landing.lat:.5f}, {flight.landing.lon:.5f}"
        )
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    from predictor.calibration import evaluate_live, live_settings, write_live_report
    from predictor.environment import Terrain, load_weather
    from predictor.prediction import flown_model, save_model

    if (args.train is None) != (args.score is None):
        raise UsageError("drs live evaluate --train and --score go together")
    if args.train is not None and args.tracks:
        raise UsageError("drs live evaluate takes track files or --train/--score, not both")
    if not args.tracks and args.score is None:
        raise UsageError("drs live evaluate needs track files (or --train FILE... --score FILE...)")
    if not args.name or "/" in args.name:
        raise UsageError(f"drs live evaluate --name must be a file name without '/', got {args.name!r}")
    if args.save_model and args.model is None:
        raise UsageError(
            "drs live evaluate --save-model needs --model: live settings belong to a model's law"
        )
    started = time.perf_counter()
    # Two laws are compared: the model's, and the textbook law of the same payload (its profile
    # without calibrated terms), so the difference is the law and not the mass or Cd·A.
    profile = args.payload if args.model is not None or args.payload is not None else "superbit-test"
    model = flown_model(args.model, profile, args.mass, args.cda)
    with progress() as tell:
        weather = (
            while_saying(
                tell, "loading weather", lambda: load_weather(args.weather, cache_dir=args.cache_dir)
            )
            if args.weather
            else None
        )
        result = evaluate_live(
            args.score or args.tracks, model=model if args.model is not None else None, profile=model.payload,
            day=args.date, weather=weather, terrain=Terrain.from_dir(args.dem) if args.dem else None,
            train=args.train, progress=tell,
        )  # fmt: skip
    flown = f" --model {args.model}" if args.model is not None else ""
    flown += f" --weather <{len(args.weather)} GRIB files>" if args.weather else ""
    flown += f" --dem {args.dem}" if args.dem else ""
    flown += f" --name {args.name}" if args.name != "live-reprediction" else ""
    if args.train is not None:
        tracks = f"--train {_tracks_said(args.train)} --score {_tracks_said(args.score)}"
    else:
        tracks = _tracks_said(args.tracks)
    command = f"drs live evaluate {tracks}{flown} --out {args.out}"
    md = write_live_report(result, args.out, command, args.name)
    if args.save_model:
        # Train → score: the model flies what its training flights measured, never the scored ones.
        saved = save_model(live_settings(model, result.training or result, command), args.save_model)
        print(f"{saved}: the model with its live settings", file=sys.stderr)
    print(
        f"{md}: {len(result.flights)} flights, {result.fixes_used} descent fixes (all used), "
        f"{time.perf_counter() - started:.1f} s",
        file=sys.stderr,
    )
    print(md.read_text(encoding="utf-8"))
    return 0


def _tracks_said(tracks: list[str]) -> str:
    """Track files as a report's command line names them: how many, in which folders, and which names
    when they are a subset (a season) rather than the whole folder."""
    folders = sorted({Path(t).parent.name for t in tracks})
    stems = sorted(Path(t).stem for t in tracks)
    prefixes = sorted({stem.split("-")[0] for stem in stems})
    which = f" {prefixes[0]}-*" if len(prefixes) == 1 and len(stems) > 1 else ""
    return f"<{len(tracks)} track files{which} in {', '.join(folders)}>"


def run_live_bench(args: argparse.Namespace) -> int:
    from predictor.calibration import bench
    from predictor.prediction import load_model

    if not args.tracks:
        raise UsageError("drs live bench needs track files")
    print(bench(args.tracks, load_model(args.model) if args.model is not None else None))
    return 0
