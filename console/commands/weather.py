"""`drs weather …`: fetch GFS for a flight, prune the caches, look at weather files, time their loading."""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import platformdirs

from console.commands.argparser import UtcTime, at_least_zero, input_file, latitude, longitude, positive
from predictor.environment import (
    AVAILABILITY_DELAY,
    DEFAULT_URL_TEMPLATE,
    GFS_LEVELS_HPA,
    RESOLUTIONS,
    SIZE_ONLY_KEEP,
    URL_TEMPLATE_ENV,
    Downloader,
    PruneResult,
    Region,
    free_space_warning,
    gfs_file_name,
    plan_forecast_files,
    prune,
)
from predictor.errors import UsageError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("weather", help="get, inspect and benchmark GFS weather files")
    commands = parser.add_subparsers(dest="weather_command", metavar="ACTION", required=True)

    fetch = commands.add_parser(
        "fetch",
        help="download the GFS forecast files a flight needs (regional subsets from NOMADS)",
        description=(
            "Choose the GFS cycle and steps that were published at --time (a cycle counts as published "
            f"{AVAILABILITY_DELAY.total_seconds() / 3600:g} h after its nominal time) or, with --hindsight, "
            "the freshest cycle for each valid time, and download them. Prints the local file paths."
        ),
    )
    fetch.add_argument(
        "--time",
        type=UtcTime("--time"),
        required=True,
        help="ISO 8601 release time, e.g. 2024-05-01T06:30Z, or 'now'",
    )
    fetch.add_argument("--lat", type=latitude, required=True, help="latitude of the release point, degrees")
    fetch.add_argument(
        "--lon", type=longitude, required=True, help="longitude of the release point, degrees east"
    )
    fetch.add_argument(
        "--radius-km", type=float, default=500.0, help="half-width of the region (default 500 km)"
    )
    fetch.add_argument(
        "--hours", type=float, default=12.0, help="hours of forecast after --time (default 12)"
    )
    fetch.add_argument("--dir", type=Path, default=None, help="download directory (default ~/.cache/drs/gfs)")
    fetch.add_argument("--hindsight", action="store_true", help="use the freshest cycle for each valid time")
    fetch.add_argument("--resolution", choices=RESOLUTIONS, default="0p50", help="GFS grid (default 0p50)")
    fetch.add_argument(
        "--url-template",
        default=None,
        help=f"grib-filter URL template (default ${URL_TEMPLATE_ENV} or the NOMADS filter_gfs URL)",
    )
    fetch.add_argument(
        "--retries", type=int, default=4, help="retries per file after the first try (default 4)"
    )
    fetch.set_defaults(func=run_fetch)

    size_only_days = SIZE_ONLY_KEEP.total_seconds() / 86400
    prune_parser = commands.add_parser(
        "prune",
        help="free disk: remove old GFS cycles and the cached cubes built from them",
        description=(
            "Remove downloaded GFS cycles older than --keep-days, then, with --max-gb, the oldest until the "
            "download cache and the cube cache together are under the limit. A cycle's age counts from its "
            "cycle time or its latest download, whichever is later. Cycles inside the keep window "
            f"(--keep-days, or {size_only_days:g} days with --max-gb alone) and cycles a fetch is working on "
            "are never removed. Cached cubes that no load can use any more are removed too."
        ),
    )
    prune_parser.add_argument(
        "--keep-days",
        type=at_least_zero("days", 36500),
        default=None,
        metavar="N",
        help="remove cycles older than N days",
    )
    prune_parser.add_argument(
        "--max-gb",
        type=positive("gigabytes"),
        default=None,
        metavar="X",
        help="then remove the oldest cycles until both caches hold under X GB (10^9 bytes)",
    )
    prune_parser.add_argument("--dry-run", action="store_true", help="only say what would be removed")
    prune_parser.add_argument(
        "--dir", type=Path, default=None, help="GFS download directory (default ~/.cache/drs/gfs)"
    )
    prune_parser.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="weather cube cache (default ~/.cache/drs/weather)",
    )
    prune_parser.set_defaults(func=run_prune)

    info = commands.add_parser("info", help="what a set of GRIB files holds once loaded as one cube")
    info.add_argument(
        "files",
        nargs="+",
        type=lambda text: Path(input_file("FILE")(text)),
        help="GRIB files; - reads standard input",
    )
    info.add_argument("--json", action="store_true", help="print JSON")
    info.set_defaults(func=run_info)

    bench = commands.add_parser(
        "bench",
        help="measure loading of generated GFS-like files: cold (no cube cache) and from the cube cache",
    )
    bench.add_argument("--files", type=int, default=5, help="forecast steps (files) to load (default 5)")
    bench.add_argument("--grid", type=float, default=0.5, help="grid spacing in degrees (default 0.5)")
    bench.add_argument("--size-deg", type=float, default=10.0, help="region side in degrees (default 10)")
    bench.add_argument("--repeat", type=int, default=5, help="measurements of each kind (default 5)")
    bench.set_defaults(func=run_bench)


def default_gfs_dir() -> Path:
    return platformdirs.user_cache_path("drs") / "gfs"


def run_fetch(args: argparse.Namespace) -> int:
    if not -90.0 <= args.lat <= 90.0:
        raise UsageError(f"--lat {args.lat:g} is not a latitude")
    start: datetime = args.time
    grid = 0.5 if args.resolution == "0p50" else 0.25
    region = Region.around(args.lat, args.lon, args.radius_km, grid)
    plan = plan_forecast_files(start, args.hours, hindsight=args.hindsight)
    template = args.url_template or os.environ.get(URL_TEMPLATE_ENV) or DEFAULT_URL_TEMPLATE
    directory = args.dir or default_gfs_dir()
    low_space = free_space_warning(directory)
    if low_space:
        print(f"warning: {low_space}", file=sys.stderr)
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        DownloadColumn,
        Progress,
        TaskID,
        TextColumn,
        TransferSpeedColumn,
    )

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        DownloadColumn(),
        TransferSpeedColumn(),
        console=Console(stderr=True),  # stdout carries only the file paths
    ) as bar:
        tasks: dict[str, TaskID] = {}

        def show(name: str, done: int, total: int | None) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=total)
            bar.update(tasks[name], completed=done, total=total)

        downloader = Downloader(
            directory,
            url_template=template,
            resolution=args.resolution,
            retries=args.retries,
            progress=show,
        )
        files = downloader.fetch_all(plan, region)
    cycles = sorted({item.cycle for item in plan})
    mode = "hindsight" if args.hindsight else f"as available at {start:%Y-%m-%d %H:%M}Z"
    cycle_text = ", ".join(f"{c:%Y-%m-%d %H}Z" for c in cycles)
    print(
        f"GFS {args.resolution} {mode}: cycles {cycle_text}, {len(files)} files, "
        f"region lat {region.lat_min:g}…{region.lat_max:g} lon {region.lon_min:g}…{region.lon_max:g}",
        file=sys.stderr,
    )
    for path in files:
        print(path)
    return 0


def run_prune(args: argparse.Namespace) -> int:
    from predictor.environment import default_cache_dir

    if args.keep_days is None and args.max_gb is None:
        raise UsageError("say what to prune: --keep-days N, --max-gb X, or both")
    max_bytes = None
    if args.max_gb is not None:
        if not (math.isfinite(args.max_gb) and args.max_gb > 0):
            raise UsageError(f"--max-gb must be a positive number of gigabytes, not {args.max_gb:g}")
        max_bytes = round(args.max_gb * 1e9)
    result = prune(
        args.dir or default_gfs_dir(),
        args.cache_dir or default_cache_dir(),
        keep_days=args.keep_days,
        max_bytes=max_bytes,
        dry_run=args.dry_run,
    )
    for line in _prune_report(result, max_bytes):
        print(line)
    return 0


def _prune_report(result: PruneResult, max_bytes: int | None) -> list[str]:
    """One line per removed cycle, one for the cube cache, one per cycle that had to stay, then totals."""
    verb = "would remove" if result.dry_run else "removed"
    lines = []
    for cycle in result.removed:
        written = f"{cycle.last_write:%Y-%m-%d %H:%M}Z" if cycle.last_write else "never"
        lines.append(
            f"{verb} {cycle.name} (cycle {cycle.cycle:%Y-%m-%d %H}Z, last written {written}): "
            f"{_count(cycle.files, 'file')}, {_size_text(cycle.size_bytes)}"
        )
    if result.removed_entries:
        lines.append(
            f"{verb} {_count(len(result.removed_entries), 'cached cube')} "
            f"({_size_text(sum(e.size_bytes for e in result.removed_entries))}) that no load can use any more"
        )
    for cycle, reason in result.skipped:
        lines.append(f"kept {cycle.name} although it is older than the keep window: {reason}")
    for entry, reason in result.failed_entries:
        lines.append(f"could not remove cached cube {entry.path}: {reason}")
    freed, left = ("would free", "would be left") if result.dry_run else ("freed", "left")
    cycles_left = len(result.kept) + len(result.skipped)
    lines.append(
        f"{freed} {_size_text(result.freed_bytes)}; {left}: {_count(cycles_left, 'cycle')}, "
        f"{_size_text(result.bytes_after)} in both caches (keep window from {result.keep_from:%Y-%m-%d %H:%M}Z)"
    )
    if max_bytes is not None and result.bytes_after > max_bytes:
        lines.append(
            f"note: the caches stay over the {_size_text(max_bytes)} limit: what is left is inside the keep "
            "window, being fetched, or cubes of weather files still in use"
        )
    return lines


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}{'' if number == 1 else 's'}"


def _size_text(size_bytes: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size_bytes >= scale:
            return f"{size_bytes / scale:.1f} {unit}"
    return f"{size_bytes} B"


def run_info(args: argparse.Namespace) -> int:
    import numpy as np

    from predictor.environment import load_weather

    cube = load_weather(args.files)
    if args.json:
        document = {
            "source": cube.source,
            "valid_times_utc": [np.datetime_as_string(t, unit="s") + "Z" for t in cube.times],
            "lead_h": [float(h) for h in cube.lead_h],
            "levels_hpa": [float(p) for p in cube.levels_hpa],
            "top_altitude_m": float(cube.z_m[:, -1].min()),
            "region": {"lat_min": float(cube.lats[0]), "lat_max": float(cube.lats[-1]),
                       "lon_min": float(cube.lons[0]), "lon_max": float(cube.lons[-1])},
            "global": bool(cube.is_global),
            "warnings": list(cube.warnings),
        }  # fmt: skip
        print(json.dumps(document, indent=2, ensure_ascii=False))
        return 0
    print(f"source: {cube.source}")
    print(f"valid times: {', '.join(np.datetime_as_string(t, unit='m') + 'Z' for t in cube.times)}")
    print(f"lead times (h): {', '.join(f'{h:g}' for h in cube.lead_h)}")
    print(
        f"levels: {cube.levels_hpa[0]:g} … {cube.levels_hpa[-1]:g} hPa ({cube.levels_hpa.size}), "
        f"top altitude ≥ {cube.z_m[:, -1].min() / 1000:.1f} km"
    )
    print(
        f"region: lat {cube.lats[0]:g} … {cube.lats[-1]:g}, lon {cube.lons[0]:g} … {cube.lons[-1]:g}"
        f"{' (global)' if cube.is_global else ''}"
    )
    for warning in cube.warnings:
        print(f"warning: {warning}")
    return 0


def run_bench(args: argparse.Namespace) -> int:
    import numpy as np

    from predictor.environment import load_weather, write_gfs_grib2

    """Cold = no cube cache (the files themselves are in the OS page cache, just written)."""
    if args.files < 1 or args.repeat < 1 or args.grid <= 0 or args.size_deg < args.grid:
        raise UsageError("bench needs --files ≥ 1, --repeat ≥ 1 and a region at least one grid cell wide")
    load_average = os.getloadavg()[0]  # the machine may be shared: say how busy it was
    levels = np.array(GFS_LEVELS_HPA, dtype=float)
    lats = np.arange(40.0, 40.0 + args.size_deg + 1e-9, args.grid)
    lons = np.arange(-5.0, -5.0 + args.size_deg + 1e-9, args.grid)
    shape = (levels.size, lats.size, lons.size)
    rng = np.random.default_rng(0)
    cycle = datetime(2024, 5, 1, 6, tzinfo=UTC)
    with tempfile.TemporaryDirectory(prefix="drs-weather-bench-") as scratch:
        folder = Path(scratch)
        files = []
        for index in range(args.files):
            step = 3 * index
            gh = np.linspace(100.0, 48000.0, levels.size)[:, None, None] + rng.normal(0, 20, shape)
            files.append(
                write_gfs_grib2(
                    folder / gfs_file_name(cycle, step),
                    cycle,
                    step,
                    levels,
                    lats,
                    lons,
                    rng.normal(10, 8, shape),
                    rng.normal(0, 8, shape),
                    rng.normal(240, 15, shape),
                    gh,
                )
            )
        box = (float(lats[0]), float(lats[-1]), float(lons[0]), float(lons[-1]))
        cold, cached = [], []
        for attempt in range(args.repeat):
            cache = folder / f"cache{attempt}"
            began = time.perf_counter()
            load_weather(files, bbox=box, cache_dir=cache)
            cold.append(time.perf_counter() - began)
            began = time.perf_counter()
            load_weather(files, bbox=box, cache_dir=cache)
            cached.append(time.perf_counter() - began)
    side = f"{args.size_deg:g}°×{args.size_deg:g}°"
    size = f"{args.files} files, {args.grid:g}° grid, {side}, {levels.size} levels"
    print(f"weather load ({size}), {args.repeat} runs each, load average {load_average:.2f} at start")
    for label, values in (("cold (decode + crop + cache write)", cold), ("cached (cube cache hit)", cached)):
        print(
            f"  {label}: median {statistics.median(values) * 1000:.1f} ms, best {min(values) * 1000:.1f} ms"
        )
    return 0
