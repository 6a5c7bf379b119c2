"""Measured descents against predicted ones: where, when and by how much the model is wrong.

Every calibration question reduces to "run the model on a flight and compare with what was measured",
thousands of times (every candidate effect, every parameter value, every held-out fold). So this
module runs many parameter sets of one model on one flight in ONE call of the compiled stepper (the
parameters of a term may be arrays, one value per trajectory) and scores all of them in one compiled
pass. Comparison rules, the same for every use:

* The prediction starts at the flight's descent start (time, position, altitude) and ends where it
  meets the ground: the measured landing altitude (no DEM needed), or the terrain with ``--dem``.
* Positions are compared at the same time since the descent start, in a local east/north/up frame
  (km) around the descent start; a predicted path that has already landed stays at its landing.
  RMS scores over all the flight's descent fixes after the start: the 3-D error, the altitude error
  alone and the horizontal error alone (km), and the time error at each fix's altitude (s). The
  last two of the vertical record (altitude against time since descent start) are untouched by the
  wind.
* A replayed run (``replay=True``) flies the flight's own measured altitude–time profile instead of
  the drag law (``MeasuredDescentRate``), and drops every vertical effect: its horizontal error is
  the wind's alone, so a horizontal effect is fitted to it and a descent-rate error (which moves the
  capsule through the wind layers at the wrong times) cannot masquerade as wind.
* Landing error: distance between predicted and measured landing points (km, local frame);
  descent-time error: predicted minus measured, seconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from numba import get_num_threads, njit

from predictor.descent import (
    DEFAULT_TIME_TOLERANCE_S,
    LOWEST_GROUND_M,
    STATUS_OK,
    MeasuredDescentRate,
    Model,
    Payload,
    Starts,
    Stepping,
    Term,
    Wind,
    descend,
    packed,
)
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.numba_cache import ensure_cache_dir
from predictor.tracks import Fix, Flight

ensure_cache_dir(__file__)  # before the first @njit(cache=True): predictor/numba_cache.py

WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3
HIGHEST_GROUND_KM = 8.9
"""No terrain is higher (Everest 8849 m): the DEM is only read below this."""
MIN_REPLAY_RATE_MS = 0.1
RATE_FACTOR_BOUNDS = (0.5, 2.0)
"""A flight's own λ is fitted within these (the bounds of the ``descent_rate_scale`` candidate): a
flight outside them is not the payload family the law was fitted for."""


@dataclass(frozen=True)
class FlightCase:
    """One flight ready to be predicted and scored: its measured descent and the weather to fly it in."""

    name: str
    cube: WeatherCube
    start_time: datetime
    start_lat: float
    start_lon: float
    start_alt_m: float
    fix_t: np.ndarray
    """Seconds since descent start of every descent fix after the start (landing included)."""
    fix_x: np.ndarray
    """East of the descent start, km."""
    fix_y: np.ndarray
    """North of the descent start, km."""
    fix_z: np.ndarray
    """Altitude, km."""
    landing_alt_m: float
    descent_time_s: float
    """Descent start to the estimated touchdown (``touchdown_s``), not to the landing fix."""
    fix_pressure_z: np.ndarray
    """Altitude (km) at which the weather column at the descent start has each fix's logged pressure;
    NaN where none was logged. The vertical record read against pressure instead of GNSS altitude."""
    terrain: Terrain | None = None
    """Ground from a DEM; None means the ground is the measured landing altitude."""

    def local(self, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(east, north) km from the descent start; longitudes taken the short way round."""
        return local_km(self.start_lat, self.start_lon, lat, lon)

    def geographic(self, east_km: np.ndarray, north_km: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lat, lon) of local (east, north) km: the inverse of ``local``."""
        per_deg_north, per_deg_east = _km_per_degree(self.start_lat)
        lon = self.start_lon + np.asarray(east_km) / per_deg_east
        return self.start_lat + np.asarray(north_km) / per_deg_north, (lon + 180.0) % 360.0 - 180.0


def local_km(lat0: float, lon0: float, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equirectangular (east, north) km around (lat0, lon0) with WGS84 radii of curvature: within
    0.1 % over the ~100 km of a descent, far below the km-sized errors it measures."""
    per_deg_north, per_deg_east = _km_per_degree(lat0)
    d_lon = (np.asarray(lon) - lon0 + 180.0) % 360.0 - 180.0
    return d_lon * per_deg_east, (np.asarray(lat) - lat0) * per_deg_north


def _km_per_degree(lat_deg: float) -> tuple[float, float]:
    meridional, normal = _radii_km(lat_deg)
    return meridional * math.pi / 180.0, normal * math.cos(math.radians(lat_deg)) * math.pi / 180.0


def _radii_km(lat_deg: float) -> tuple[float, float]:
    """Meridional and prime-vertical radii of curvature of WGS84 at this latitude, km."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    w = math.sqrt(1.0 - WGS84_E2 * s2)
    return WGS84_A * (1.0 - WGS84_E2) / w**3 / 1000.0, WGS84_A / w / 1000.0


def flight_case(flight: Flight, cube: WeatherCube, terrain: Terrain | None = None) -> FlightCase:
    if not flight.usable or flight.descent_start is None or flight.landing is None:
        raise PredictorError(f"flight {flight.name} cannot be calibrated on: {'; '.join(flight.exclusions)}")
    start, land = flight.descent_start, flight.landing
    fixes = [f for f in flight.descent if f.time > start.time]
    if not fixes:
        raise PredictorError(f"flight {flight.name} has no descent fix after its descent start")
    x, y = local_km(start.lat, start.lon, np.array([f.lat for f in fixes]), np.array([f.lon for f in fixes]))
    return FlightCase(
        name=flight.name,
        cube=cube,
        start_time=start.time,
        start_lat=start.lat,
        start_lon=start.lon,
        start_alt_m=start.alt_m,
        fix_t=np.array([(f.time - start.time).total_seconds() for f in fixes]),
        fix_x=x,
        fix_y=y,
        fix_z=np.array([f.alt_m for f in fixes]) / 1000.0,
        landing_alt_m=land.alt_m,
        descent_time_s=touchdown_s(start, fixes),
        fix_pressure_z=_pressure_altitude_km(cube, start, fixes),
        terrain=terrain,
    )


def _pressure_altitude_km(cube: WeatherCube, start: Fix, fixes: Sequence[Fix]) -> np.ndarray:
    """Each logged pressure as an altitude in the weather's column nearest the descent start (the
    column ``column_density`` uses): what the predicted path, which lives in altitude, is compared at."""
    pressure = np.array([np.nan if f.pressure_pa is None else f.pressure_pa for f in fixes])
    if np.isnan(pressure).all():
        return pressure
    ti = int(np.argmin(np.abs(cube.times.astype("datetime64[s]").astype(np.int64) - start.time.timestamp())))
    yi = int(np.argmin(np.abs(cube.lats - start.lat)))
    xi = int(np.argmin(np.abs(cube.lons - float(cube.lon_in_cube(start.lon)))))
    log_p = np.log(np.asarray(cube.levels_hpa, dtype=float) * 100.0)
    z = cube.z_m[ti, :, yi, xi]
    order = np.argsort(log_p)
    return np.interp(np.log(pressure), log_p[order], z[order], left=np.nan, right=np.nan) / 1000.0


def touchdown_s(start: Fix, fixes: Sequence[Fix]) -> float:
    """Seconds from the descent start to the touchdown, estimated: the landing fix is the first one on
    the ground, up to one fix interval after the touchdown (1–5 min late with 2–5 min telemetry, a bias
    every prediction would carry), so the last airborne fix is carried down to the landing altitude at
    the rate of the interval before it. The landing fix's own time when that cannot be done."""
    land = fixes[-1]
    late = (land.time - start.time).total_seconds()
    if len(fixes) < 3:
        return late
    a, b = fixes[-3], fixes[-2]
    rate = (a.alt_m - b.alt_m) / (b.time - a.time).total_seconds()
    height = b.alt_m - land.alt_m
    if rate <= 0.0 or height <= 0.0:
        return late
    return min(late, (b.time - start.time).total_seconds() + height / rate)


@dataclass(frozen=True)
class Runs:
    """n predicted descents of one flight (one per parameter set), recorded step by step."""

    t: np.ndarray
    """Seconds since descent start, shape (n, steps)."""
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    """km, local frame."""
    n_rec: np.ndarray
    ok: np.ndarray
    """False where the stepper failed (weather coverage, a term that stopped the descent)."""


@dataclass(frozen=True)
class Scores:
    """Per trajectory: the numbers every comparison uses (NaN where the run failed)."""

    track_rms_km: np.ndarray
    altitude_rms_km: np.ndarray
    """RMS of predicted − measured altitude at the fixes' times."""
    pressure_time_rms_s: np.ndarray
    """The same over the fixes that logged a pressure, each at its pressure's altitude (NaN without
    pressure): reported, not used for selection."""
    time_rms_s: np.ndarray
    """RMS of predicted − measured time since descent start at the fixes' altitudes: the vertical record
    read the other way, weighted by where the time is spent (the slow fall near the ground, which sets
    the landing time), where the altitude error is weighted by where the capsule falls fast. The
    landing fix's term is the descent-time error."""
    shape_time_rms_s: np.ndarray
    """The shape record: ``time_rms_s`` with the flight's own rate factor λ profiled out, i.e. the
    predicted times divided by the λ that fits them best (closed form, see ``_profiled``). It scores the
    law's shape alone, which every flight of a payload family shares, apart from each flight's rate."""
    rate_factor: np.ndarray
    """That best λ of the flight under this law (its times ∝ 1/λ), within ``RATE_FACTOR_BOUNDS``."""
    horizontal_rms_km: np.ndarray
    """RMS horizontal distance at the fixes' times (the wind's error when the run was replayed)."""
    landing_error_km: np.ndarray
    descent_time_error_s: np.ndarray
    landing_x: np.ndarray
    landing_y: np.ndarray
    landing_t: np.ndarray
    landing_z: np.ndarray


def replay_term(case: FlightCase, bin_m: float) -> MeasuredDescentRate:
    """The flight's measured descent rate in bins of ``bin_m`` down from its start to its landing.

    With the run's altitude step as ``bin_m`` every step of the stepper spans exactly one bin, so
    it takes the measured time to cross it (and a 1 Hz log of 10,000 fixes becomes ~150 numbers per
    trajectory). Crossing times of each level are read off the fixes (linear between them; the
    altitude is made monotonic first, as GNSS noise can make a fix rise; the ground is reached at the
    estimated touchdown), so the replayed capsule is at each level when the real one was.
    """
    top = case.start_alt_m
    n_bins = max(1, int(math.ceil((top - case.landing_alt_m) / bin_m)))
    edges = top - bin_m * np.arange(n_bins, -1, -1)
    t = np.concatenate(([0.0], case.fix_t[:-1], [case.descent_time_s]))
    z = np.minimum.accumulate(np.concatenate(([case.start_alt_m], case.fix_z * 1000.0)))
    crossing = np.interp(edges, z[::-1], t[::-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        # The lowest bin reaches below the landing altitude: only its part above it was measured.
        rates = np.diff(np.maximum(edges, z[-1])) / np.maximum(-np.diff(crossing), 1e-3)
    rates = np.clip(np.nan_to_num(rates, nan=MIN_REPLAY_RATE_MS), MIN_REPLAY_RATE_MS, None)
    return MeasuredDescentRate(
        bottom_m=float(edges[0]), bin_m=float(bin_m), rates_ms=tuple(map(float, rates))
    )


def run(
    case: FlightCase, payload: Payload, effects: tuple[Term, ...], n: int, step_m: float, replay: bool = False
) -> Runs:
    """Fly ``n`` descents of the chain payload + wind + effects (array parameters: one value per run);
    with ``replay`` the flight's measured descent profile replaces the payload and the vertical effects."""
    if replay:
        kept = tuple(e for e in effects if e.family != "vertical")
        model = Model((replay_term(case, step_m), Wind(), *kept))
    else:
        model = Model.for_payload(payload, *effects)
    floor = LOWEST_GROUND_M if case.terrain is not None else case.landing_alt_m - 2.0 * step_m
    t0 = case.start_time.timestamp()
    ones = np.ones(n)
    release = Starts(ones * t0, ones * case.start_lat, ones * case.start_lon, ones * case.start_alt_m)
    record = descend(
        packed(case.cube),
        model.chain(n),
        release,
        Stepping(step_m, floor, DEFAULT_TIME_TOLERANCE_S),
        # NaN past each path's end, so that what reads whole rows (the ground under every point) finds
        # nothing there.
        fill=np.nan,
        blocks=min(n, get_num_threads()),
    )
    lat, lon, z, t = record[:4]
    x, y = case.local(lat, lon)
    return Runs(t=t - t0, x=x, y=y, z=z / 1000.0, n_rec=record.n_rec, ok=record.status == STATUS_OK)


def ground_km(case: FlightCase, runs: Runs) -> np.ndarray:
    """Ground altitude (km) under every recorded point: the measured landing altitude, or the DEM."""
    if case.terrain is None:
        return np.full(runs.z.shape, case.landing_alt_m / 1000.0)
    ground = np.full(runs.z.shape, -np.inf)
    low = runs.z <= HIGHEST_GROUND_KM
    lat, lon = case.geographic(runs.x[low], runs.y[low])
    ground[low] = case.terrain.elevation(lat, lon) / 1000.0
    return ground


def score(case: FlightCase, runs: Runs) -> Scores:
    n = runs.t.shape[0]
    out = np.full((n, 11), np.nan)
    _score_kernel(
        runs.t, runs.x, runs.y, runs.z, ground_km(case, runs), runs.n_rec, runs.ok,
        case.fix_t, case.fix_x, case.fix_y, case.fix_z, case.fix_pressure_z, case.descent_time_s, out,
    )  # fmt: skip
    land_x, land_y = case.fix_x[-1], case.fix_y[-1]
    return Scores(
        track_rms_km=np.sqrt(out[:, 0]),
        altitude_rms_km=np.sqrt(out[:, 5]),
        horizontal_rms_km=np.sqrt(out[:, 6]),
        time_rms_s=np.sqrt(out[:, 7]),
        shape_time_rms_s=np.sqrt(out[:, 9]),
        rate_factor=out[:, 10],
        pressure_time_rms_s=np.sqrt(out[:, 8]),
        landing_error_km=np.hypot(out[:, 1] - land_x, out[:, 2] - land_y),
        descent_time_error_s=out[:, 3] - case.descent_time_s,
        landing_x=out[:, 1],
        landing_y=out[:, 2],
        landing_t=out[:, 3],
        landing_z=out[:, 4],
    )


@njit(cache=True)
def _score_kernel(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    ground: np.ndarray,
    n_rec: np.ndarray,
    ok: np.ndarray,
    fix_t: np.ndarray,
    fix_x: np.ndarray,
    fix_y: np.ndarray,
    fix_z: np.ndarray,
    fix_pressure_z: np.ndarray,
    touchdown: float,
    out: np.ndarray,
) -> None:
    """out[i] = (mean squared 3-D error over the fixes, landing x, y, t, z, mean squared altitude
    error, mean squared horizontal error, mean squared time error at the fixes' altitudes, the same at
    their pressures' altitudes)."""
    for i in range(t.shape[0]):
        if not ok[i]:
            continue
        k_land = -1
        for k in range(1, n_rec[i]):
            if z[i, k] <= ground[i, k]:
                k_land = k
                break
        if k_land < 0:
            continue
        above = z[i, k_land - 1] - ground[i, k_land - 1]
        under = z[i, k_land] - ground[i, k_land]
        f = above / (above - under)
        tl = t[i, k_land - 1] + f * (t[i, k_land] - t[i, k_land - 1])
        xl = x[i, k_land - 1] + f * (x[i, k_land] - x[i, k_land - 1])
        yl = y[i, k_land - 1] + f * (y[i, k_land] - y[i, k_land - 1])
        zl = z[i, k_land - 1] + f * (z[i, k_land] - z[i, k_land - 1])
        total_h = 0.0
        total_z = 0.0
        k = 0
        for j in range(fix_t.shape[0]):
            tj = fix_t[j]
            if tj >= tl:
                px, py, pz = xl, yl, zl
            else:
                while t[i, k + 1] < tj:
                    k += 1
                g = (tj - t[i, k]) / (t[i, k + 1] - t[i, k])
                px = x[i, k] + g * (x[i, k + 1] - x[i, k])
                py = y[i, k] + g * (y[i, k + 1] - y[i, k])
                pz = z[i, k] + g * (z[i, k + 1] - z[i, k])
            total_h += (px - fix_x[j]) ** 2 + (py - fix_y[j]) ** 2
            total_z += (pz - fix_z[j]) ** 2
        out[i, 0] = (total_h + total_z) / fix_t.shape[0]
        out[i, 1] = xl
        out[i, 2] = yl
        out[i, 3] = tl
        out[i, 4] = zl
        out[i, 5] = total_z / fix_t.shape[0]
        out[i, 6] = total_h / fix_t.shape[0]
        out[i, 7] = _mean_squared_time_error(t[i], z[i], tl, zl, fix_z, fix_t, touchdown)
        out[i, 8] = _mean_squared_time_error(t[i], z[i], tl, zl, fix_pressure_z, fix_t, touchdown)
        out[i, 9], out[i, 10] = _profiled(t[i], z[i], tl, zl, fix_z, fix_t, touchdown)


@njit(cache=True)
def _times_at_fixes(
    t: np.ndarray,
    z: np.ndarray,
    tl: float,
    zl: float,
    fix_z: np.ndarray,
    fix_t: np.ndarray,
    touchdown: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(predicted, measured) seconds at each fix that has an altitude, the predicted ones read off the
    falling track at the fix's altitude; the landing fix is measured at the estimated touchdown."""
    n = fix_t.shape[0]
    predicted = np.empty(n)
    measured = np.empty(n)
    count = 0
    k = 0
    for j in range(n):
        zj = fix_z[j]
        if not np.isfinite(zj):
            continue
        if zj <= zl:
            tj = tl
        elif zj >= z[0]:
            tj = 0.0
        else:
            while k > 0 and z[k] < zj:
                k -= 1
            while z[k + 1] >= zj:
                k += 1
            tj = t[k] + (zj - z[k]) / (z[k + 1] - z[k]) * (t[k + 1] - t[k])
        predicted[count] = tj
        measured[count] = touchdown if j == n - 1 else fix_t[j]
        count += 1
    return predicted[:count], measured[:count]


@njit(cache=True)
def _mean_squared_time_error(
    t: np.ndarray,
    z: np.ndarray,
    tl: float,
    zl: float,
    fix_z: np.ndarray,
    fix_t: np.ndarray,
    touchdown: float,
) -> float:
    """Mean of (predicted − measured time at each fix's altitude)² over the fixes with an altitude
    (NaN: none)."""
    predicted, measured = _times_at_fixes(t, z, tl, zl, fix_z, fix_t, touchdown)
    if predicted.shape[0] == 0:
        return np.nan
    return float(np.mean((predicted - measured) ** 2))


@njit(cache=True)
def _profiled(
    t: np.ndarray,
    z: np.ndarray,
    tl: float,
    zl: float,
    fix_z: np.ndarray,
    fix_t: np.ndarray,
    touchdown: float,
) -> tuple[float, float]:
    """(mean squared time error at the fixes' altitudes with λ profiled out, that λ).

    A factor λ on the whole descent rate divides every predicted time by λ, so the best λ of the
    record is closed form: with p the predicted and m the measured times at the fixes' altitudes,
    1/λ = Σ p·m / Σ p² (least squares), held within ``RATE_FACTOR_BOUNDS``. Exact for a law whose every
    term scales with the rate (the drag law, a density exponent, two regimes); for a term counted in
    seconds since release (a deployment delay) it is λ on the predicted time profile, the first-order
    answer, which is what a flight's λ means to its time at each altitude.
    """
    lo, hi = RATE_FACTOR_BOUNDS
    predicted, measured = _times_at_fixes(t, z, tl, zl, fix_z, fix_t, touchdown)
    pp = float(np.sum(predicted * predicted))
    pm = float(np.sum(predicted * measured))
    if predicted.shape[0] == 0 or pp <= 0.0 or pm <= 0.0:
        return np.nan, np.nan
    inverse = min(max(pm / pp, 1.0 / hi), 1.0 / lo)
    return float(np.mean((inverse * predicted - measured) ** 2)), 1.0 / inverse


# ---------------------------------------------------------------- residuals of one prediction


@dataclass(frozen=True)
class FlightResiduals:
    """One flight's residuals against one predicted descent (the plots; the ellipse fit's landing errors)."""

    name: str
    interval_alt_m: np.ndarray
    """Mid altitude of each interval between consecutive measured descent fixes."""
    interval_t_s: np.ndarray
    """Mid time since release of each interval."""
    interval_density: np.ndarray
    interval_wind_ms: np.ndarray
    speed_ratio: np.ndarray
    """Measured / predicted mean descent speed over the interval's altitude span (NaN for the last
    interval, which contains the touchdown)."""
    fix_alt_m: np.ndarray
    fix_t_s: np.ndarray
    fix_wind_ms: np.ndarray
    along_km: np.ndarray
    """Measured minus predicted position at the same time, along the predicted drift direction."""
    cross_km: np.ndarray
    """The same, across it (positive to the right of the drift direction)."""
    landing_error_km: float
    landing_along_km: float
    landing_cross_km: float
    descent_time_error_s: float
    descent_time_s: float
    """Measured, from descent start to touchdown: what ``descent_time_error_s`` is relative to."""
    predicted_drift_km: float

    @property
    def descent_time_log_ratio(self) -> float:
        """ln(predicted / measured descent time): for a law whose terms all scale the rate, the ln λ this
        flight needed to land on time, about the λ flown (what the pre-flight interval is stated in)."""
        return math.log1p(self.descent_time_error_s / self.descent_time_s)


def residuals(case: FlightCase, runs: Runs, row: int = 0) -> FlightResiduals:
    """The residuals of one predicted descent (row ``row`` of ``runs``) at every measured fix."""
    s = score(case, Runs(*(a[row : row + 1] for a in (runs.t, runs.x, runs.y, runs.z, runs.n_rec, runs.ok))))
    if not np.isfinite(s.landing_t[0]):
        raise PredictorError(f"flight {case.name}: the predicted descent did not reach the ground")
    m = int(runs.n_rec[row])
    t, x, y, z = runs.t[row, :m], runs.x[row, :m], runs.y[row, :m], runs.z[row, :m]
    keep = t < s.landing_t[0]
    t = np.append(t[keep], s.landing_t[0])
    x = np.append(x[keep], s.landing_x[0])
    y = np.append(y[keep], s.landing_y[0])
    z = np.append(z[keep], s.landing_z[0])
    px = np.interp(case.fix_t, t, x)
    py = np.interp(case.fix_t, t, y)
    drift = math.hypot(float(x[-1]), float(y[-1]))
    ux, uy = (x[-1] / drift, y[-1] / drift) if drift > 0 else (0.0, 1.0)
    ex, ey = case.fix_x - px, case.fix_y - py
    along = ex * ux + ey * uy
    cross = ex * uy - ey * ux
    fix_alt = case.fix_z * 1000.0
    all_t = np.concatenate(([0.0], case.fix_t))
    all_z = np.concatenate(([case.start_alt_m], fix_alt))
    dz = -np.diff(all_z)
    measured_rate = dz / np.diff(all_t)
    t_of_z = np.interp(all_z[::-1] / 1000.0, z[::-1], t[::-1])[::-1]
    predicted_span = np.diff(t_of_z)
    with np.errstate(divide="ignore", invalid="ignore"):
        predicted_rate = np.where(predicted_span > 0, dz / predicted_span, np.nan)
        ratio = np.where(dz > 0, measured_rate / predicted_rate, np.nan)
    # The landing fix is the first one on the ground: touchdown fell somewhere in the last interval,
    # so its measured rate is too slow by an unknown amount. It says nothing about the descent speed.
    ratio[-1] = np.nan
    mid_z = 0.5 * (all_z[1:] + all_z[:-1])
    lex, ley = s.landing_x[0] - case.fix_x[-1], s.landing_y[0] - case.fix_y[-1]
    return FlightResiduals(
        name=case.name,
        interval_alt_m=mid_z,
        interval_t_s=0.5 * (all_t[1:] + all_t[:-1]),
        interval_density=column_density(case, mid_z),
        interval_wind_ms=column_wind_speed(case, mid_z),
        speed_ratio=ratio,
        fix_alt_m=fix_alt,
        fix_t_s=case.fix_t,
        fix_wind_ms=column_wind_speed(case, fix_alt),
        along_km=along,
        cross_km=cross,
        landing_error_km=float(s.landing_error_km[0]),
        landing_along_km=-float(lex * ux + ley * uy),
        landing_cross_km=-float(lex * uy - ley * ux),
        descent_time_error_s=float(s.descent_time_error_s[0]),
        descent_time_s=case.descent_time_s,
        predicted_drift_km=drift,
    )


def _column(case: FlightCase) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The weather column nearest the descent start at the start time: z, log ρ, u, v."""
    cube = case.cube
    ti = int(
        np.argmin(np.abs(cube.times.astype("datetime64[s]").astype(np.int64) - case.start_time.timestamp()))
    )
    yi = int(np.argmin(np.abs(cube.lats - case.start_lat)))
    xi = int(np.argmin(np.abs(cube.lons - float(cube.lon_in_cube(case.start_lon)))))
    return (
        cube.z_m[ti, :, yi, xi],
        np.log(cube.density[ti, :, yi, xi]),
        cube.u[ti, :, yi, xi],
        cube.v[ti, :, yi, xi],
    )


def column_density(case: FlightCase, alt_m: np.ndarray) -> np.ndarray:
    z, log_rho, _, _ = _column(case)
    return np.exp(np.interp(alt_m, z, log_rho))


def column_wind_speed(case: FlightCase, alt_m: np.ndarray) -> np.ndarray:
    z, _, u, v = _column(case)
    return np.hypot(np.interp(alt_m, z, u), np.interp(alt_m, z, v))


# ---------------------------------------------------------------- altitude-bin budgets


@dataclass(frozen=True)
class BinBudget:
    """Per altitude bin: time spent and displacement, measured and predicted (the binned fit's input)."""

    measured_s: np.ndarray
    predicted_s: np.ndarray
    measured_east_m: np.ndarray
    measured_north_m: np.ndarray
    predicted_east_ms: np.ndarray
    predicted_north_ms: np.ndarray
    """Mean predicted horizontal velocity in the bin (0 where the prediction spent no time)."""


def bin_budget(case: FlightCase, runs: Runs, row: int, edges_m: np.ndarray) -> BinBudget:
    """Crossing times of every bin edge, measured (fixes, linear between them) and predicted."""
    m = int(runs.n_rec[row])
    pt, px, py, pz = (a[row, :m] for a in (runs.t, runs.x, runs.y, runs.z))
    mt = np.concatenate(([0.0], case.fix_t))
    mx = np.concatenate(([0.0], case.fix_x))
    my = np.concatenate(([0.0], case.fix_y))
    mz = np.concatenate(([case.start_alt_m / 1000.0], case.fix_z))
    # Stop at the last fix still in the air: touchdown fell somewhere in the last interval, so the
    # time measured below that fix includes time on the ground.
    top, bottom = mz[0], mz[-2] if len(mz) > 2 else mz[-1]
    levels = np.clip(np.asarray(edges_m) / 1000.0, bottom, top)

    def down(a: np.ndarray, zz: np.ndarray) -> np.ndarray:
        """Change of ``a`` across each bin, top edge to bottom edge, at the first crossings."""
        z_mono = np.minimum.accumulate(zz)[::-1]  # GNSS noise can make a fix rise: keep it monotonic
        return -np.diff(np.interp(levels, z_mono, a[::-1]))

    measured_s = down(mt, mz)
    predicted_s = down(pt, pz)
    with np.errstate(divide="ignore", invalid="ignore"):
        pe = np.where(predicted_s > 0, down(px, pz) * 1000.0 / predicted_s, 0.0)
        pn = np.where(predicted_s > 0, down(py, pz) * 1000.0 / predicted_s, 0.0)
    return BinBudget(
        measured_s=measured_s,
        predicted_s=predicted_s,
        measured_east_m=down(mx, mz) * 1000.0,
        measured_north_m=down(my, mz) * 1000.0,
        predicted_east_ms=pe,
        predicted_north_ms=pn,
    )
