"""The effects library as fit-able candidates, and the altitude-binned correction for what it lacks.

A candidate is one of ``predictor.descent.model``'s effect terms with ONE continuous parameter to fit (and,
for an effect that needs a place, a small set of discrete variants such as the altitude band of
``wind_band_scale``). Every other parameter is held at a stated value: with 10–30 flights, each
extra free parameter mostly fits noise, and a parameter the data cannot pin down (the fast-fall
speed of ``deployment_delay`` trades off exactly against its duration) is better fixed than fitted.

Why a grid first: all grid values of a candidate fly as one batch of the compiled stepper (one run
per value per flight), which is cheaper than the hundreds of sequential runs an optimiser would ask
for, and the fit for every held-out fold is then a sum over the other flights' rows. The optimum is
refined with ``scipy.optimize.minimize_scalar`` (bounded, to the neighbouring grid values) on a
cubic spline through the grid's objective; then the same again on a fine grid (9 values between the
coarse neighbours of the optimum), which takes the spline's error on a coarse grid (0.01 in λ) out.
A candidate whose place is a continuous height (``Candidate.refined``: the two-regime canopy's break)
has its height refined in the same fine pass, jointly with the parameter: height and factor trade off
along a narrow valley (a higher break with a larger factor makes nearly the same fall), so a height
held on the coarse 3 km grid drags the factor away from the truth (a 1.3× canopy above 20 km was fitted
as 1.45 above 21 km). The fine table (heights at a third of the coarse spacing × factors a coarse step
either side) is minimised on a bicubic spline through it (a mesh, then a bounded polish).

The binned correction is not a candidate: it is fitted in closed form from the residuals (time and
displacement in each altitude bin, measured against predicted) and answers "how much of the error
is systematic with altitude at all", whatever its cause.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import CubicSpline, RectBivariateSpline
from scipy.optimize import minimize, minimize_scalar

from predictor.calibration.residuals import BinBudget
from predictor.descent import EFFECTS, BinnedDescentRate, BinnedWind, Term
from predictor.errors import PredictorError

BIN_EDGES_M = tuple(float(z) for z in range(0, 39_000, 3000))
"""Altitude bins of the binned correction: 3 km, coarse enough for 2–5 min fixes (1–4 km apart)."""
MIN_BIN_SECONDS = 60.0
"""A bin measured for less than this over all training flights keeps factor 1 and no added wind."""
BINNED_FACTOR_BOUNDS = (0.5, 2.0)


REFINED_FACTORS = 5
"""Values of the fitted parameter per refined height in the fine pass (a coarse step either side, so
half the coarse spacing apart): the table is heights × these, every row a trajectory per flight and fold."""


@dataclass(frozen=True)
class Candidate:
    """One effect to try: the term, its fitted parameter (grid and bounds), what is held fixed."""

    name: str
    family: str
    parameter: str
    grid: tuple[float, ...]
    bounds: tuple[float, float]
    neutral: float
    """The value at which the effect does nothing (the baseline)."""
    fixed: Mapping[str, float] = field(default_factory=dict)
    variants: tuple[Mapping[str, float], ...] = ({},)
    """Discrete alternatives tried with every grid value (e.g. altitude bands)."""
    why: str = ""
    refined: str = ""
    """A variant key that is a continuous quantity (a height), refined by the fine pass jointly with
    ``parameter`` (``fine``, ``fit_refined``); "" for variants that are truly discrete."""

    def points(self) -> list[tuple[int, float]]:
        """(variant index, value) of every grid point, variant-major."""
        return [(v, x) for v in range(len(self.variants)) for x in self.grid]

    def term(
        self, variant: np.ndarray | int, value: np.ndarray | float, refined: np.ndarray | float | None = None
    ) -> Term:
        """The model term for one value or for arrays of (variant, value), one per trajectory;
        ``refined``: the value(s) of the ``refined`` key in place of the variants' own."""
        cls = EFFECTS[self.name]
        variant = np.asarray(variant)
        kwargs: dict[str, object] = dict(self.fixed)
        for key in self.variants[0]:
            column = np.array([self.variants[int(i)][key] for i in variant.ravel()])
            kwargs[key] = float(column[0]) if variant.ndim == 0 else column
        if refined is not None:
            kwargs[self.refined] = float(refined) if np.ndim(refined) == 0 else np.asarray(refined, float)
        kwargs[self.parameter] = float(value) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
        return cls(**kwargs)

    def parameters(self, variant: int, value: float, refined: float | None = None) -> dict[str, float]:
        place = dict(self.variants[variant])
        if refined is not None:
            place[self.refined] = float(refined)
        return {**self.fixed, **place, self.parameter: float(value)}

    def fine(self, variant: int, value: float, points: int = 9) -> Candidate:
        """The same effect on one variant, with a grid spanning the coarse neighbours of ``value``; for a
        ``refined`` candidate, on heights at a third of the coarse spacing between the neighbouring
        variants, with ``REFINED_FACTORS`` values a coarse step either side of ``value``."""
        grid = np.asarray(self.grid)
        gap = float(np.min(np.diff(grid)))
        if self.refined:
            places = np.array([v[self.refined] for v in self.variants])
            here = places[variant]
            spacing = float(np.min(np.diff(np.sort(places))))
            lower, upper = places[places < here], places[places > here]
            bottom = float(lower.max()) if lower.size else here
            top = float(upper.min()) if upper.size else here
            heights = np.linspace(bottom, top, round((top - bottom) / (spacing / 3.0)) + 1)
            lo, hi = max(self.bounds[0], value - gap), min(self.bounds[1], value + gap)
            return replace(
                self, grid=tuple(np.linspace(lo, hi, REFINED_FACTORS)),
                variants=tuple({**self.variants[variant], self.refined: float(h)} for h in heights),
            )  # fmt: skip
        below, above = grid[grid < value], grid[grid > value]
        lo = max(self.bounds[0], float(below.max()) if below.size else value - gap)
        hi = min(self.bounds[1], float(above.min()) if above.size else value + gap)
        return replace(self, grid=tuple(np.linspace(lo, hi, points)), variants=(self.variants[variant],))

    def fit_refined(self, objective: np.ndarray) -> tuple[float, float, float]:
        """(refined value, value, objective) minimising a fine table over (variants × grid): the minimum
        of a bicubic spline through the table (both axes in grid steps, so the optimiser sees them
        alike) where it is below the table's best point."""
        table = np.asarray(objective, dtype=float).reshape(len(self.variants), len(self.grid))
        places = np.array([v[self.refined] for v in self.variants])
        finite = np.isfinite(table)
        if not finite.any():
            return float(places[len(places) // 2]), self.neutral, float("inf")
        table = np.where(finite, table, 10.0 * np.nanmax(np.abs(table[finite])) + 1.0)
        row, col = np.unravel_index(int(np.argmin(table)), table.shape)
        best = (float(row), float(col), float(table[row, col]))
        if min(table.shape) >= 4:
            rows, cols = np.arange(table.shape[0]), np.arange(table.shape[1])
            spline = RectBivariateSpline(rows, cols, table)
            # The valley runs diagonally across the cells: a mesh of a tenth of a cell finds it, the
            # optimiser then polishes that point inside the table.
            mesh = (np.linspace(0.0, rows[-1], 10 * rows[-1] + 1),
                    np.linspace(0.0, cols[-1], 10 * cols[-1] + 1))  # fmt: skip
            values = spline(*mesh)
            i, j = np.unravel_index(int(np.argmin(values)), values.shape)
            found = minimize(lambda p: float(spline(p[0], p[1])[0, 0]), x0=(mesh[0][i], mesh[1][j]),
                             bounds=[(0.0, rows[-1]), (0.0, cols[-1])], method="L-BFGS-B")  # fmt: skip
            if found.success and float(found.fun) < best[2]:
                best = (float(found.x[0]), float(found.x[1]), float(found.fun))
        at = np.arange(table.shape[0]), np.arange(table.shape[1])
        return float(np.interp(best[0], at[0], places)), float(np.interp(best[1], at[1], self.grid)), best[2]

    def fit(self, objective: np.ndarray) -> tuple[int, float, float]:
        """(variant, value, objective) minimising a grid objective of shape (len(points),)."""
        table = np.asarray(objective, dtype=float).reshape(len(self.variants), len(self.grid))
        finite = np.isfinite(table)
        if not finite.any():
            return 0, self.neutral, float("inf")
        table = np.where(finite, table, 10.0 * np.nanmax(np.abs(table[finite])) + 1.0)
        if np.ptp(table) <= 1e-12 * max(1.0, float(np.min(table))):
            # The data cannot see this effect (e.g. a time offset in weather constant in time).
            return 0, self.neutral, float(table.min())
        variant, k = (int(i) for i in np.unravel_index(int(np.argmin(table)), table.shape))
        row = table[variant]
        grid = np.asarray(self.grid)
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        best_value, best = float(grid[k]), float(row[k])
        if len(grid) >= 4 and hi > lo:
            spline = CubicSpline(grid, row)
            found = minimize_scalar(lambda x: float(spline(x)), bounds=(lo, hi), method="bounded")
            if found.success and float(found.fun) < best:
                best_value, best = float(found.x), float(found.fun)
        return int(variant), best_value, best


def _heights() -> tuple[Mapping[str, float], ...]:
    return tuple({"height_m": float(h)} for h in range(6000, 27_001, 3000))


def _bands() -> tuple[Mapping[str, float], ...]:
    return tuple({"bottom_m": float(b), "top_m": float(b + 6000)} for b in range(0, 27_000, 3000))


LIBRARY: tuple[Candidate, ...] = (
    Candidate(
        "descent_rate_scale",
        "vertical",
        "scale",
        tuple(np.linspace(0.6, 1.6, 11)),
        (0.5, 2.0),
        1.0,
        why="λ, the paper's one number: Cd·A or mass wrong by a constant factor",
    ),
    Candidate(
        "drag_density_exponent",
        "vertical",
        "exponent",
        tuple(np.linspace(-0.4, 0.4, 9)),
        (-0.5, 0.5),
        0.0,
        fixed={"reference_density": 1.225},
        why="drag that changes with density (Reynolds number): fast or slow high up, not near the ground",
    ),
    Candidate(
        "deployment_delay",
        "vertical",
        "delay_s",
        tuple(np.linspace(0.0, 180.0, 10)),
        (0.0, 240.0),
        0.0,
        fixed={"speed_factor": 3.0},
        why="the canopy opens late: 3× faster fall until then (the factor trades off with the delay)",
    ),
    Candidate(
        "two_regime_rate",
        "vertical",
        "factor",
        tuple(np.linspace(0.7, 1.7, 6)),
        (0.5, 2.0),
        1.0,
        variants=_heights(),
        why="a canopy that opens further below a height: a factor on the rate above it (heights every 3 km)",
        refined="height_m",
    ),
    Candidate(
        "wind_scale",
        "horizontal",
        "scale",
        tuple(np.linspace(0.5, 1.5, 11)),
        (0.3, 2.0),
        1.0,
        why="the forecast wind speed wrong by a constant factor",
    ),
    Candidate(
        "wind_rotation",
        "horizontal",
        "angle_deg",
        tuple(np.linspace(-40.0, 40.0, 9)),
        (-60.0, 60.0),
        0.0,
        why="the forecast wind direction off by a constant angle",
    ),
    Candidate(
        "wind_band_scale",
        "horizontal",
        "scale",
        tuple(np.linspace(0.2, 2.0, 7)),
        (0.0, 2.5),
        1.0,
        variants=_bands(),
        why="the wind wrong by a factor only in a 6 km band (bands every 3 km from the ground to 30 km)",
    ),
    Candidate(
        "wind_lag",
        "horizontal",
        "time_constant_s",
        (0.0, 15.0, 30.0, 60.0, 120.0, 240.0, 480.0),
        (0.0, 600.0),
        0.0,
        why="the payload's horizontal inertia: its velocity relaxes to the air's with a time constant",
    ),
    Candidate(
        "weather_time_offset",
        "timing",
        "offset_s",
        tuple(np.linspace(-10800.0, 10800.0, 9)),
        (-14400.0, 14400.0),
        0.0,
        why="the weather happens earlier or later than forecast (invisible in time-constant weather)",
    ),
)
"""Every library candidate; ``selection`` tries them all unless given a subset."""


ALTITUDE_LIMITS_M = (-500.0, 50_000.0)
WIND_LIMITS_MS = (-60.0, 60.0)
FIXED_LIMITS: dict[tuple[str, str], tuple[float, float]] = {
    ("drag_density_exponent", "reference_density"): (0.5, 2.0),
    ("deployment_delay", "speed_factor"): (1.0, 10.0),
    ("two_regime_rate", "height_m"): ALTITUDE_LIMITS_M,
    ("wind_band_scale", "bottom_m"): ALTITUDE_LIMITS_M,
    ("wind_band_scale", "top_m"): ALTITUDE_LIMITS_M,
    ("vertical_air_motion", "speed_ms"): (-5.0, 5.0),
    ("wind_offset", "east_ms"): WIND_LIMITS_MS,
    ("wind_offset", "north_ms"): WIND_LIMITS_MS,
    ("binned_descent_rate", "edges_m"): ALTITUDE_LIMITS_M,
    ("binned_descent_rate", "factors"): BINNED_FACTOR_BOUNDS,
    ("binned_wind", "edges_m"): ALTITUDE_LIMITS_M,
    ("binned_wind", "east_ms"): WIND_LIMITS_MS,
    ("binned_wind", "north_ms"): WIND_LIMITS_MS,
}
"""What the calibration never fits but may hold fixed or get from the binned fit: the range a model file
may carry (a reference density of sea-level air give or take, a fast fall at most 10× the canopy's,
heights inside the weather, ±60 m/s of added wind, the binned fit's own factor bounds)."""


def parameter_limits() -> dict[tuple[str, str], tuple[float, float]]:
    """(effect, parameter) → the calibration's own (low, high): a fitted parameter's candidate bounds, the
    rest from ``FIXED_LIMITS``. A model file with a value outside them was not made by a calibration
    and is refused (an exponent of 5 is an 8-minute fall from 28 km, a wind scale of −1 blows backwards)."""
    limits = dict(FIXED_LIMITS)
    for c in LIBRARY:
        limits[(c.name, c.parameter)] = c.bounds
    return limits


def library(names: Sequence[str] | None = None) -> tuple[Candidate, ...]:
    if names is None:
        return LIBRARY
    known = {c.name: c for c in LIBRARY}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise PredictorError(f"unknown effect(s) {', '.join(unknown)}; the library has {', '.join(known)}")
    return tuple(known[n] for n in names)


@dataclass(frozen=True)
class BinnedCorrection:
    """Per altitude bin: a factor on the descent rate and an added wind (east, north)."""

    edges_m: tuple[float, ...]
    rate_factor: tuple[float, ...]
    east_ms: tuple[float, ...]
    north_ms: tuple[float, ...]
    measured_s: tuple[float, ...]
    """Time the training flights spent in each bin (what each value rests on)."""

    def terms(self) -> tuple[Term, ...]:
        return (
            BinnedDescentRate(edges_m=self.edges_m, factors=self.rate_factor),
            BinnedWind(edges_m=self.edges_m, east_ms=self.east_ms, north_ms=self.north_ms),
        )

    def to_dict(self) -> dict[str, list[float]]:
        return {
            "edges_m": list(self.edges_m),
            "rate_factor": [round(x, 4) for x in self.rate_factor],
            "east_ms": [round(x, 3) for x in self.east_ms],
            "north_ms": [round(x, 3) for x in self.north_ms],
            "measured_s": [round(x, 1) for x in self.measured_s],
        }


def fit_binned(budgets: Sequence[BinBudget], edges_m: Sequence[float] = BIN_EDGES_M) -> BinnedCorrection:
    """Closed form: the factor that makes predicted bin times equal measured ones over all flights,
    and the mean horizontal velocity the prediction missed in each bin (time-weighted)."""
    measured = np.sum([b.measured_s for b in budgets], axis=0)
    predicted = np.sum([b.predicted_s for b in budgets], axis=0)
    missed_east = np.sum([b.measured_east_m - b.predicted_east_ms * b.measured_s for b in budgets], axis=0)
    missed_north = np.sum([b.measured_north_m - b.predicted_north_ms * b.measured_s for b in budgets], axis=0)
    enough = measured >= MIN_BIN_SECONDS
    safe = np.where(enough, measured, 1.0)
    factor = np.where(enough, np.clip(predicted / safe, *BINNED_FACTOR_BOUNDS), 1.0)
    return BinnedCorrection(
        edges_m=tuple(float(e) for e in edges_m),
        rate_factor=tuple(float(x) for x in factor),
        east_ms=tuple(float(x) for x in np.where(enough, missed_east / safe, 0.0)),
        north_ms=tuple(float(x) for x in np.where(enough, missed_north / safe, 0.0)),
        measured_s=tuple(float(x) for x in measured),
    )
