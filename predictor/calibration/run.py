"""What ``drs calibrate`` runs: measured flights in, the missing effect and the error before/after out.

Everything that decides (which flights, which effects, how much they help) is printed or written
with its reason, so a calibration can be checked by someone who did not run it. The parser lives in
``calibrate_cli``, which imports this module only when a calibration runs (it loads numba, scipy and
matplotlib).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from predictor.calibration.effects import LIBRARY, library
from predictor.calibration.ellipse_fit import MIN_FLIGHTS, EllipseFit, fit_ellipse
from predictor.calibration.report import Exclusion, result_json, verdict, write_calibration_report
from predictor.calibration.residuals import FlightCase, flight_case, run, score
from predictor.calibration.selection import Calibration, calibrate
from predictor.descent import Payload, payload_profile
from predictor.environment import Terrain, WeatherCube, load_weather
from predictor.errors import PredictorError, WeatherError
from predictor.geofiles import is_stdout, write_text
from predictor.prediction import CalibratedModel, load_model, save_model
from predictor.tracks import ascent_weather_cube, clean, read_track


@dataclass(frozen=True)
class Inputs:
    cases: list[FlightCase]
    excluded: list[Exclusion]
    payload: Payload
    weather: str


def _payload(args: argparse.Namespace) -> Payload:
    if args.payload is None and (args.mass is None or args.cda is None):
        raise PredictorError("give the payload: --payload NAME, or both --mass KG and --cda M2")
    if args.payload is None:
        return Payload(mass_kg=args.mass, cda_m2=args.cda, name="custom", source="--mass and --cda")
    return payload_profile(args.payload).overridden(args.mass, args.cda)


def prepare(args: argparse.Namespace) -> Inputs:
    """Read, clean, give each flight its weather; every flight left out is left out by a stated rule."""
    if not args.tracks:
        raise PredictorError("give the flights: --tracks FILE...")
    if args.weather is None and args.winds is None:
        raise PredictorError("give the weather: --weather FILE... or --winds ascent")
    if not 10.0 <= args.step <= 1000.0:
        raise PredictorError(f"--step must be between 10 and 1000 m, got {args.step:g}")
    if args.max_effects < 0:
        raise PredictorError(f"--max-effects must be 0 or more, got {args.max_effects}")
    payload = _payload(args)
    library(args.effects)
    terrain = Terrain.from_dir(args.dem) if args.dem else None
    shared: WeatherCube | None = (
        load_weather(args.weather, cache_dir=args.cache_dir) if args.weather else None
    )
    cases: list[FlightCase] = []
    excluded: list[Exclusion] = []
    for name in args.tracks:
        flight = clean(read_track(name, day=args.date), terrain)
        if not flight.usable:
            excluded.append(Exclusion(flight.name, "cleaning: " + "; ".join(flight.exclusions)))
            continue
        try:
            cube = shared if shared is not None else ascent_weather_cube(flight)
        except WeatherError as exc:
            excluded.append(Exclusion(flight.name, f"no ascent winds: {exc}"))
            continue
        case = flight_case(flight, cube, terrain)
        runs = run(case, payload, (), 1, args.step)
        if not (runs.ok[0] and np.isfinite(score(case, runs).landing_t[0])):
            excluded.append(Exclusion(flight.name, "the weather does not cover its predicted descent"))
            continue
        cases.append(case)
    if len(cases) < 3:
        left_out = "; ".join(f"{e.name}: {e.reason}" for e in excluded) or "none"
        raise PredictorError(
            f"leave-one-flight-out needs at least 3 usable flights, got {len(cases)} (excluded: {left_out})"
        )
    weather = "each flight's own ascent winds (--winds ascent)" if shared is None else shared.source
    return Inputs(cases, excluded, payload, weather)


def analyse(inputs: Inputs, args: argparse.Namespace) -> tuple[Calibration, EllipseFit | None]:
    cal = calibrate(
        inputs.cases, inputs.payload, library(args.effects) if args.effects else LIBRARY,
        step_m=args.step, max_effects=args.max_effects, seed=args.seed,
        nested=getattr(args, "nested_stability", False), progress=getattr(args, "progress", None),
    )  # fmt: skip
    return cal, preflight_ellipse(cal, args.seed)


def preflight_ellipse(cal: Calibration, seed: int = 0) -> EllipseFit | None:
    """The landing ellipse a prediction before release states, fitted on the held-out landings of the law
    that flies then (``Calibration.preflight_residuals``: the plain law where the gate kept every term and
    λ out), so it describes the prediction it is drawn around. None with fewer than ``MIN_FLIGHTS``."""
    if len(cal.names) < MIN_FLIGHTS:
        return None
    along = np.array([r.landing_along_km for r in cal.preflight_residuals])
    cross = np.array([r.landing_cross_km for r in cal.preflight_residuals])
    return fit_ellipse(along, cross, cal.predicted_drift_km, cal.t_future_h, seed=seed)


def run_calibrate(args: argparse.Namespace) -> int:
    inputs = prepare(args)
    cal, ellipse = analyse(inputs, args)
    data = result_json(cal, ellipse, inputs.excluded, inputs.payload.to_dict(), inputs.weather)
    said = sys.stderr if is_stdout(args.json) else sys.stdout  # with --json -, stdout is the JSON alone
    if args.json:
        if not is_stdout(args.json):
            args.json.parent.mkdir(parents=True, exist_ok=True)
        write_text(args.json, json.dumps(data, indent=2) + "\n", "JSON")
    if args.report:
        write_calibration_report(
            args.report,
            cal,
            ellipse,
            inputs.excluded,
            args.title,
            _command(args),
            data,
            _preface(args.preface),
        )
    _print_summary(cal, inputs, data, said)
    if args.save_model:
        saved = save_model(
            calibrated_model(cal, ellipse, inputs, data, _command(args), args.dem, args.step), args.save_model
        )
        print(
            f"model saved: {saved} (use it with --model on drs predict, drs plan, or a capsule's model key)",
            file=said,
        )
    return 0


def calibrated_model(
    cal: Calibration,
    ellipse: EllipseFit | None,
    inputs: Inputs,
    data: dict[str, Any],
    command: str,
    dem: str | None = None,
    step_m: float = 200.0,
) -> CalibratedModel:
    """What this calibration learned, as the model predictions fly: the selected terms, then the binned
    correction's parts (rate factors, added wind) that beat them on held-out flights, each marked by the
    pre-flight gate as flown both ways or live-only (with the pre-flight λ when it differs), and the
    pre-flight uncertainty measured on that pre-flight law (``ellipse`` from ``preflight_ellipse``, the λ
    spread about it). The DEM and step are recorded so that ``drs live evaluate`` refits the law as it was
    fitted, whatever its own --dem."""
    terms = cal.terms()
    provenance = {
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "project_version": _version(),
        "command": command,
        "flights": [case.name for case in inputs.cases],
        "excluded": [{"flight": e.name, "reason": e.reason} for e in inputs.excluded],
        "weather": inputs.weather,
        "dem": dem,
        "step_m": step_m,
        "metric": (
            "per family: vertical shape_time_rms_s (time at altitude, each flight's own λ profiled out), "
            "horizontal horizontal_rms_km (replayed), timing both"
        ),
        "rate_prior": "descent_rate_scale in terms is the rate prior's median λ; the other terms are the shape",
        "selection_stability": data["selection_stability"],
        "selection_stability_method": cal.stability_method,
        "unstable_terms": data["unstable"],
        "held_out_rate_only": data["rate_only"],
        "held_out_before": data["baseline"],
        "held_out_after": data["after"],
        "binned_correction_used": cal.unexplained,
        "preflight_gate": data["preflight_gate"],
        "held_out_preflight": data["preflight"],
        "vertical_contest": data["vertical_contest"],
    }
    return CalibratedModel(
        inputs.payload, terms, ellipse.model() if ellipse else None, provenance, rate_prior=cal.rate_prior,
        preflight=cal.preflight_terms(), preflight_spread=cal.preflight_spread(),
    )  # fmt: skip


def _version() -> str:
    try:
        return metadata.version("drs-console")
    except metadata.PackageNotFoundError:
        return "unknown"


def _preface(path: Path | None) -> str:
    if path is None:
        return ""
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise PredictorError(f"cannot read the report preface {path}: {exc}") from None


def _command(args: argparse.Namespace) -> str:
    """The command line that reproduces this run, for the report."""
    parts = ["drs", "calibrate", "--tracks", *args.tracks]
    parts += ["--weather", *args.weather] if args.weather else ["--winds", args.winds]
    for flag, value in (
        ("--dem", args.dem),
        ("--payload", args.payload),
        ("--mass", args.mass),
        ("--cda", args.cda),
    ):
        if value is not None:
            parts += [flag, str(value)]
    if args.effects:
        parts += ["--effects", *args.effects]
    if args.report:
        parts += ["--report", str(args.report)]
        if args.title != "Calibration report":
            parts += ["--title", args.title]
        if args.preface is not None:
            parts += ["--preface", str(args.preface)]
    if args.json:
        parts += ["--json", str(args.json)]
    if getattr(args, "nested_stability", False):
        parts.append("--nested-stability")
    return shlex.join(parts)


def _print_summary(cal: Calibration, inputs: Inputs, data: dict[str, Any], out: TextIO) -> None:
    print(f"{len(inputs.cases)} flights used, {len(inputs.excluded)} excluded", file=out)
    for e in inputs.excluded:
        print(f"  excluded {e.name}: {e.reason}", file=out)
    b, a = data["baseline"], data["after"]
    for label, block in (("baseline", b), ("after   ", a)):
        print(
            f"{label} (held out): time-at-altitude RMS {block['time_rms_s']['mean']:.0f} s, |descent-time error| "
            f"{block['descent_time_error_s']['mean']:.0f} s, horizontal RMS (replayed) "
            f"{block['horizontal_rms_km']['mean']:.3f} km, landing {block['landing_error_km']['mean']:.3f} km mean / "
            f"{block['landing_error_km']['median']:.3f} km median",
            file=out,
        )
    selected = ", ".join(f"{f['effect']} ({f['family']})" for f in data["selected"])
    print(f"selected: {selected or 'none'}", file=out)
    for g in cal.gate:
        print(f"  {g.term}: {g.reason}", file=out)
    p, r = data["preflight"], data["rate_only"]
    print(
        f"pre-flight (held out, what ships): |descent-time error| {p['descent_time_error_s']['mean']:.0f} s, landing "
        f"{p['landing_error_km']['mean']:.3f} km; plain law × median λ {r['descent_time_error_s']['mean']:.0f} s, "
        f"{r['landing_error_km']['mean']:.3f} km",
        file=out,
    )
    print(verdict(cal), file=out)


def run_vertical(args: argparse.Namespace) -> int:
    """``drs calibrate vertical``: a saved model's descent law on flights it never saw, vertical record only."""
    from predictor.calibration import vertical_check

    if args.weather is None and args.winds is None:
        raise PredictorError("give the weather: --weather FILE... or --winds ascent")
    model = load_model(args.model)
    shared = load_weather(args.weather, cache_dir=args.cache_dir) if args.weather else None
    checks = []
    for name in args.tracks:
        flight = clean(read_track(name, day=args.date))
        cube = shared if shared is not None else ascent_weather_cube(flight)
        case = vertical_check.vertical_case(flight, cube)
        checks.append(vertical_check.check_flight(case, model, flight.usable, args.step))
    parts = ["drs", "calibrate", "vertical", "--model", str(args.model), "--tracks", *args.tracks]
    parts += ["--weather", *args.weather] if args.weather else ["--winds", args.winds]
    parts += ["--date", args.date.isoformat()] if args.date else []
    parts += ["--report", str(args.report)] if args.report else []
    parts += ["--json", str(args.json)] if args.json else []
    command = shlex.join(parts)
    if args.report:
        vertical_check.write_vertical_report(args.report, checks, model, command)
    if args.json:
        write_text(
            args.json, json.dumps(vertical_check.to_json(checks, model, command), indent=2) + "\n", "JSON"
        )
    said = sys.stderr if is_stdout(args.json) else sys.stdout
    for check in checks:
        for law in check.scores:
            print(
                f"{check.name}: {law.law}: time-at-altitude RMS {law.time_rms_s:.0f} s, altitude-at-time RMS "
                f"{law.altitude_rms_km:.3f} km, time-to-end error {law.descent_time_error_s:+.0f} s",
                file=said,
            )
    return 0


def run_bench(args: argparse.Namespace) -> int:
    """Wall time of the whole calibration (read, clean, weather, selection over the library, ellipse)."""
    if args.repeat < 1:
        raise PredictorError(f"--repeat must be at least 1, got {args.repeat}")
    best = {"prepare": float("inf"), "select": float("inf"), "ellipse": float("inf"), "total": float("inf")}
    inputs = None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        inputs = prepare(args)
        t1 = time.perf_counter()
        cal = calibrate(
            inputs.cases, inputs.payload, library(args.effects) if args.effects else LIBRARY,
            step_m=args.step, max_effects=args.max_effects, seed=args.seed,
        )  # fmt: skip
        t2 = time.perf_counter()
        preflight_ellipse(cal, args.seed)
        t3 = time.perf_counter()
        for key, value in (
            ("prepare", t1 - t0),
            ("select", t2 - t1),
            ("ellipse", t3 - t2),
            ("total", t3 - t0),
        ):
            best[key] = min(best[key], value)
    assert inputs is not None
    effects = args.effects or [c.name for c in LIBRARY]
    print(
        f"{len(inputs.cases)} flights, {len(effects)} candidate effects, step {args.step:g} m, "
        f"best of {args.repeat}:"
    )
    for key, value in best.items():
        print(f"  {key:<8} {value:8.2f} s")
    return 0
