"""``drs calibrate``: the command line. The work is in ``calibrate_run``, imported when a calibration runs,
so that ``drs calibrate --help`` answers without loading numba, scipy or matplotlib.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from console.commands.argparser import UtcDate, input_file

DEFAULT_STEP_M = 200.0
"""Altitude step of every calibration run: 150 steps from 30 km. The step's truncation error is the
same for every candidate, so it cannot favour one; halving it doubles the run time."""
DEFAULT_MAX_EFFECTS = 3
"""Forward selection keeps at most this many effects per family (``selection.calibrate`` has the same default)."""


def run_calibrate(args: argparse.Namespace) -> int:
    from console.commands.progress import progress
    from predictor.calibration import run_calibrate as run

    with progress(quiet=bool(getattr(args, "json", None))) as tell:
        args.progress = tell
        return run(args)


def run_bench(args: argparse.Namespace) -> int:
    from predictor.calibration import run_bench as run

    return run(args)


def run_vertical(args: argparse.Namespace) -> int:
    from predictor.calibration import run_vertical as run

    return run(args)


def register(subparsers: argparse._SubParsersAction) -> None:
    cal = subparsers.add_parser(
        "calibrate",
        help="find the effect the model lacks from measured descents (leave-one-flight-out) and report "
        "the error before and after",
    )
    _inputs(cal, required=False)
    cal.add_argument("--json", type=Path, metavar="OUT", help="write the results as JSON; - for stdout")
    cal.add_argument("--report", type=Path, metavar="OUT.md", help="write a Markdown report with PNG plots")
    cal.add_argument("--title", default="Calibration report", help="the report's title")
    cal.add_argument(
        "--save-model", type=Path, metavar="PATH",
        help="write the calibrated model (payload, selected terms, ellipse, provenance) for --model",
    )  # fmt: skip
    cal.add_argument(
        "--preface",
        type=Path,
        metavar="FILE.md",
        help="Markdown placed under the report's title (a hand-written reading of the results)",
    )
    cal.add_argument(
        "--nested-stability", action="store_true",
        help="measure the selection's stability by repeating the whole selection without each flight "
        "(n times the cost; default: its decisions replayed without each flight)",
    )  # fmt: skip
    cal.set_defaults(func=run_calibrate)
    actions = cal.add_subparsers(dest="calibrate_command", metavar="ACTION")
    bench = actions.add_parser(
        "bench", help="time the full calibration of the given flights (best of N runs)"
    )
    _inputs(bench, required=True)
    bench.add_argument("--repeat", type=int, default=1, metavar="N", help="runs; the best is reported")
    bench.set_defaults(func=run_bench)
    vertical = actions.add_parser(
        "vertical",
        help="a saved model's descent law on flights it never saw, scored on the vertical record alone "
        "(no landing needed: a record that ends in the air is scored to its last fix)",
    )
    _inputs(vertical, required=True)
    vertical.add_argument("--model", type=lambda text: Path(input_file("--model")(text)), required=True,
                          metavar="PATH", help="the calibrated model; - reads standard input")  # fmt: skip
    vertical.add_argument("--json", type=Path, metavar="OUT", help="write the results as JSON; - for stdout")
    vertical.add_argument("--report", type=Path, metavar="OUT.md", help="write a Markdown report")
    vertical.set_defaults(func=run_vertical)


def _inputs(parser: argparse.ArgumentParser, required: bool) -> None:
    parser.add_argument(
        "--tracks",
        nargs="+",
        metavar="FILE",
        type=input_file("--tracks"),
        required=required,
        help="flight track files; - reads one from standard input",
    )
    parser.add_argument(
        "--date",
        type=UtcDate("--date"),
        metavar="YYYY-MM-DD",
        help="UTC date of the first fix, for logs with times of day only (V4)",
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--weather", nargs="+", metavar="FILE", type=input_file("--weather"),
                        help="GFS GRIB2 files covering every descent; - reads one from standard input")  # fmt: skip
    source.add_argument(
        "--winds", choices=("ascent",), help="'ascent': each flight's own ascent as its weather"
    )
    parser.add_argument(
        "--cache-dir", metavar="DIR", help="cache of decoded weather (default ~/.cache/drs/weather)"
    )
    parser.add_argument(
        "--dem", metavar="DIR", help="terrain (SRTM .hgt / NetCDF) for the predicted landings"
    )
    parser.add_argument("--payload", metavar="NAME", help="payload profile (e.g. superbit-test, drs)")
    parser.add_argument("--mass", type=float, metavar="KG")
    parser.add_argument("--cda", type=float, metavar="M2", help="drag coefficient × canopy area")
    parser.add_argument("--effects", nargs="+", metavar="NAME", help="library subset to try (default: all)")
    parser.add_argument(
        "--max-effects",
        type=int,
        default=DEFAULT_MAX_EFFECTS,
        metavar="N",
        help="effects kept per family at most",
    )
    parser.add_argument("--step", type=float, default=DEFAULT_STEP_M, metavar="M", help="altitude step, m")
    parser.add_argument("--seed", type=int, default=0, help="seed of the bootstrap resampling")
