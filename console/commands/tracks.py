"""``drs tracks summary``: what the cleaning rules made of each flight file, for a person to check."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import TYPE_CHECKING, Any

from console.commands.argparser import UtcDate, input_file
from predictor.tracks import Fix, TrackError, read_track

if TYPE_CHECKING:  # cleaning loads numpy and pyproj: `drs tracks --help` does not wait for them
    from predictor.tracks import Flight


def register(subparsers: argparse._SubParsersAction) -> None:
    tracks = subparsers.add_parser("tracks", help="measured flight tracks: read, clean, summarise")
    actions = tracks.add_subparsers(dest="tracks_command", metavar="ACTION", required=True)
    summary = actions.add_parser(
        "summary",
        help="per flight: fixes kept and dropped (with reasons), launch, peak, descent start, landing, drift",
    )
    summary.add_argument(
        "files",
        nargs="+",
        metavar="FILE",
        type=input_file("FILE"),
        help="track files (canonical CSV, GPX, SuperBIT log, V4); - reads standard input",
    )
    summary.add_argument("--json", action="store_true", help="print JSON instead of text")
    summary.add_argument(
        "--date",
        type=UtcDate("--date"),
        default=None,
        metavar="YYYY-MM-DD",
        help="UTC date of the first fix, for logs that record only times of day (the V4 logger)",
    )
    summary.add_argument(
        "--dem",
        metavar="DIR",
        help="terrain: a track ending at the ground height has landed (docs/tracks.md)",
    )
    summary.set_defaults(func=run_summary)
    bench = actions.add_parser(
        "bench", help="time reading, cleaning and ascent-wind cubes for the given files (best of N runs)"
    )
    bench.add_argument("files", nargs="+", metavar="FILE", type=input_file("FILE"),
                       help="track files; - reads one from standard input")  # fmt: skip
    bench.add_argument(
        "--repeat", type=int, default=5, metavar="N", help="runs; the best is reported (default 5)"
    )
    bench.add_argument("--date", type=UtcDate("--date"), default=None, metavar="YYYY-MM-DD")
    bench.set_defaults(func=run_bench)


def run_summary(args: argparse.Namespace) -> int:
    from predictor.environment import Terrain
    from predictor.tracks import clean

    flights: list[Flight] = []
    failed = False
    terrain = Terrain.from_dir(args.dem) if args.dem else None
    for name in args.files:
        try:
            flights.append(clean(read_track(name, day=args.date), terrain))
        except TrackError as exc:
            print(f"drs: error: {exc}", file=sys.stderr)
            failed = True
    if args.json:
        print(json.dumps([flight_summary(f) for f in flights], indent=2))
    elif flights:
        print("\n\n".join(_text(f) for f in flights))
    return 1 if failed else 0


def run_bench(args: argparse.Namespace) -> int:
    """Best-of-N wall time per stage, so the numbers in the docs can be re-measured on any machine."""
    from predictor.tracks import MIN_ASCENT_FIXES, ascent_weather_cube, clean

    if args.repeat < 1:
        raise TrackError(f"--repeat must be at least 1, got {args.repeat}")
    best = {"read": math.inf, "clean": math.inf, "ascent cube": math.inf}
    fixes = 0
    for _ in range(args.repeat):
        start = time.perf_counter()
        tracks = [read_track(name, day=args.date) for name in args.files]
        read_done = time.perf_counter()
        flights = [clean(track) for track in tracks]
        clean_done = time.perf_counter()
        for flight in flights:
            if len(flight.ascent) >= MIN_ASCENT_FIXES:
                ascent_weather_cube(flight)
        cube_done = time.perf_counter()
        fixes = sum(len(t.fixes) for t in tracks)
        for stage, seconds in (
            ("read", read_done - start),
            ("clean", clean_done - read_done),
            ("ascent cube", cube_done - clean_done),
        ):
            best[stage] = min(best[stage], seconds)
    files = "1 file" if len(args.files) == 1 else f"{len(args.files)} files"
    print(f"{files}, {fixes} fixes, best of {args.repeat}:")
    for stage, seconds in best.items():
        print(f"  {stage:<12} {seconds * 1000:8.1f} ms")
    return 0


def flight_summary(flight: Flight) -> dict[str, Any]:
    """The flight as plain JSON types (times as ISO 8601 UTC)."""
    return {
        "name": flight.name,
        "source": flight.source,
        "fixes_read": flight.n_read,
        "fixes_kept": len(flight.fixes),
        "fixes_dropped": flight.n_dropped,
        "dropped": [
            {"rule": r.rule, "count": r.count, "reason": r.reason, "lines": list(r.lines)}
            for r in flight.removals
        ],
        "notes": list(flight.notes),
        "launch": _fix(flight.launch),
        "peak": _fix(flight.peak),
        "descent_start": _fix(flight.descent_start),
        "landing": _fix(flight.landing),
        "ascent_fixes": len(flight.ascent),
        "descent_fixes": len(flight.descent),
        "descent_time_s": flight.descent_time_s,
        "drift_km": None if flight.drift_km is None else round(flight.drift_km, 3),
        "flags": [{"code": f.code, "message": f.message} for f in flight.flags],
        "exclusions": list(flight.exclusions),
        "usable": flight.usable,
    }


def _fix(fix: Fix | None) -> dict[str, Any] | None:
    if fix is None:
        return None
    return {
        "time": fix.time.strftime("%Y-%m-%dT%H:%M:%SZ"),
        "lat": fix.lat,
        "lon": fix.lon,
        "alt_m": fix.alt_m,
        "line": fix.line,
    }


def _text(flight: Flight) -> str:
    lines = [
        f"{flight.name}  ({flight.source})",
        f"  fixes: {flight.n_read} read, {len(flight.fixes)} kept, {flight.n_dropped} dropped",
    ]
    for removal in flight.removals:
        lines.append(
            f"    - {removal.count} {removal.rule}: {removal.reason} (lines {_line_list(removal.lines)})"
        )
    lines.extend(f"    note: {note}" for note in flight.notes)
    for label, fix in (
        ("launch", flight.launch),
        ("peak", flight.peak),
        ("descent start", flight.descent_start),
        ("landing", flight.landing),
    ):
        lines.append(f"  {label:<14}{_fix_text(fix)}")
    if flight.descent_time_s is not None and flight.drift_km is not None:
        lines.append(
            f"  descent       {flight.descent_time_s / 60:.1f} min, {len(flight.descent)} fixes, "
            f"drift {flight.drift_km:.2f} km"
        )
    lines.extend(f"  flag: {flag.code}: {flag.message}" for flag in flight.flags)
    if flight.usable:
        lines.append("  usable for calibration")
    lines.extend(f"  EXCLUDED: {reason}" for reason in flight.exclusions)
    return "\n".join(lines)


def _fix_text(fix: Fix | None) -> str:
    if fix is None:
        return "-"
    where = f"{fix.lat:9.5f} {fix.lon:10.5f}  {fix.alt_m:7.0f} m"
    return f"{fix.time:%Y-%m-%d %H:%M:%S}Z  {where}  (line {fix.line})"


def _line_list(lines: tuple[int, ...]) -> str:
    """Runs of consecutive lines as ranges, so a 98-row drive home reads as one range."""
    runs: list[str] = []
    start = prev = lines[0]
    for line in (*lines[1:], None):
        if line is not None and line == prev + 1:
            prev = line
            continue
        runs.append(str(start) if start == prev else f"{start}-{prev}")
        if line is not None:
            start = prev = line
    return ", ".join(runs)
