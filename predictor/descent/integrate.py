"""The altitude stepper: moves many trajectories down through a weather cube, knowing no physics.

Why altitude steps: the fall speed changes by a factor of ten between 30 km and the ground, so equal
altitude steps (Δz, default 100 m) give short steps where the air is thin and fast and long ones near
the ground, at a fixed and predictable cost (300 steps from 30 km). Every quantity of a step is
evaluated at its MIDPOINT: altitude z − Δz/2, and the time and horizontal position half-way through
the step, estimated from the previous step's duration and velocity (second-order accurate; the
first step estimates them from a sample at its start).

What happens in a step is the model's business (``predictor.descent.model``): the stepper samples the
weather, fills ``env``, calls the timing, vertical and horizontal chains, and moves the point on the
WGS84 ellipsoid at altitude (radii of curvature M(φ)+h and (N(φ)+h)·cos φ). It does not know the
ground: it runs every trajectory down to ``z_floor`` (below any ground on Earth) and records the
path; ``predictor.prediction.landings`` finds where the path meets the terrain afterwards.

Weather sampling: cubic in time (``_time_weights``), bilinear in latitude/longitude, and in each
grid column linear in geometric altitude for the wind and linear in altitude for log-density (exact for an
exponential atmosphere). Below a column's lowest level the wind is held at the lowest level's value
and log-density is extrapolated linearly; above the top level the same holds, but only up to
``TOP_TOLERANCE_M`` (beyond that the weather says nothing and the step fails).
"""

from __future__ import annotations

import math
import os
import weakref
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange
from numba.core.caching import (
    CompileResultCacheImpl,
    FunctionCache,
    InTreeCacheLocator,
    UserProvidedCacheLocator,
    UserWideCacheLocator,
)

from predictor.descent.model import (
    ENV_DT,
    ENV_DZ,
    ENV_G,
    ENV_LAT,
    ENV_RHO,
    ENV_SIZE,
    ENV_T_REL,
    ENV_T_START,
    ENV_TIME_SHIFT,
    ENV_U_WIND,
    ENV_V_WIND,
    ENV_Z,
    FAMILY_HORIZONTAL,
    FAMILY_TIMING,
    FAMILY_VERTICAL,
    VEL_DOWN,
    VEL_EAST,
    VEL_NORTH,
    Chain,
    apply_family,
)
from predictor.environment import WeatherCube

WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3
GRAVITY_MEAN_RADIUS_M = 6371009.0
G0 = 9.80665
TOP_TOLERANCE_M = 500.0
"""How far above a column's top level the weather may be extrapolated (wind held, density log-linear)."""
MEMO_MAX_COLUMNS = 250_000
"""Largest cube (times × lats × lons) whose columns the stepper memoises per step (40 bytes each per
thread block); larger cubes, e.g. whole global files, are interpolated column by column."""
MEMO_MIN_TRAJECTORIES = 16
"""Below this many trajectories in a block the memo's allocation costs more than it saves."""
DEFAULT_TIME_TOLERANCE_S = 5400.0
"""How far beyond the first/last valid time the weather is held constant (half a 3-hourly GFS step)."""

STATUS_OK = 0
STATUS_OUTSIDE_REGION = 1
STATUS_OUTSIDE_TIME = 2
STATUS_ABOVE_TOP = 3
STATUS_NOT_DESCENDING = 4

FIELD_Z = 0
FIELD_U = 1
FIELD_V = 2
FIELD_LOG_RHO = 3


class PackedWeather(NamedTuple):
    """A cube rearranged for the kernel: columns contiguous in level, times in epoch seconds."""

    t_s: np.ndarray
    lats: np.ndarray
    lons: np.ndarray
    columns: np.ndarray
    """Shape (T, Y, X, L, 4): geometric altitude, u, v, log density along each column."""
    lead_h: np.ndarray


_PACKED: weakref.WeakKeyDictionary[WeatherCube, PackedWeather] = weakref.WeakKeyDictionary()


def packed(cube: WeatherCube) -> PackedWeather:
    """The packed form of a cube, built once per cube object."""
    found = _PACKED.get(cube)
    if found is None:
        fields = np.stack(
            [cube.z_m, cube.u, cube.v, np.log(np.maximum(cube.density, 1e-30))], axis=-1
        ).astype(np.float64)
        columns = np.ascontiguousarray(fields.transpose(0, 2, 3, 1, 4))
        found = PackedWeather(
            t_s=cube.times.astype("datetime64[s]").astype(np.int64).astype(np.float64),
            lats=np.asarray(cube.lats, dtype=np.float64),
            lons=np.asarray(cube.lons, dtype=np.float64),
            columns=columns,
            lead_h=np.asarray(cube.lead_h, dtype=np.float64),
        )
        _PACKED[cube] = found
    return found


@njit(cache=True, inline="always")
def _bracket(axis: np.ndarray, x: float) -> tuple[int, float]:
    """Index i and fraction f with axis[i] + f·(axis[i+1] − axis[i]) = x; i = −1 when outside.

    Starts from the index an evenly spaced axis would give (exact for GFS grids) and walks from there.
    """
    n = axis.shape[0]
    if n == 1:
        return (0, 0.0) if x == axis[0] else (-1, 0.0)
    if x < axis[0] or x > axis[n - 1]:
        return -1, 0.0
    i = min(max(int((x - axis[0]) / (axis[n - 1] - axis[0]) * (n - 1)), 0), n - 2)
    while i > 0 and axis[i] > x:
        i -= 1
    while i < n - 2 and axis[i + 1] <= x:
        i += 1
    return i, (x - axis[i]) / (axis[i + 1] - axis[i])


@njit(cache=True, inline="always")
def _time_weights(t_s: np.ndarray, it: int, ft: float) -> tuple[float, float, float, float]:
    """Weights of the valid times it−1, it, it+1, it+2 for a time at fraction ``ft`` of [it, it+1].

    Cubic (Catmull-Rom) through four evenly spaced times, quadratic through three in the first and
    last interval, linear otherwise (two times, or uneven spacing). A moving weather system sampled
    every 3 h is undershot between the samples by linear interpolation: on a synthetic jet whose
    meander moves 36° of phase per step it alone missed the landing by 0.76 % of the drift, against
    0.04 % for the vertical interpolation and nothing measurable for the altitude step
    (docs/predictor.md, tests/predictor/descent/test_synthetic_truth.py).
    """
    nt = t_s.shape[0]
    if ft == 0.0 or nt < 3:
        return 0.0, 1.0 - ft, ft, 0.0
    h = t_s[it + 1] - t_s[it]
    even_before = it >= 1 and abs(t_s[it] - t_s[it - 1] - h) < 1.0
    even_after = it + 2 <= nt - 1 and abs(t_s[it + 2] - t_s[it + 1] - h) < 1.0
    f = ft
    if even_before and even_after:
        f2 = f * f
        f3 = f2 * f
        before, at = 0.5 * (-f3 + 2.0 * f2 - f), 0.5 * (3.0 * f3 - 5.0 * f2 + 2.0)
        return before, at, 0.5 * (-3.0 * f3 + 4.0 * f2 + f), 0.5 * (f3 - f2)
    if even_after:
        return 0.0, 0.5 * (f - 1.0) * (f - 2.0), -f * (f - 2.0), 0.5 * f * (f - 1.0)
    if even_before:
        return 0.5 * f * (f - 1.0), 1.0 - f * f, 0.5 * f * (f + 1.0), 0.0
    return 0.0, 1.0 - f, f, 0.0


@njit(cache=True, inline="always")
def _column_at(col: np.ndarray, z: float, dest: np.ndarray, a: int, b: int, c: int, hint: int) -> int:
    """(u, v, log ρ, level) at altitude z of one column into dest[a, b, c, 0:4]; returns the level.

    The level k has z[k] ≤ z < z[k+1] (found by walking from ``hint``: along a descent the bracket
    moves by at most one level per step); −1 means z is too far above the top level.
    """
    n = col.shape[0]
    k = min(max(hint, 0), n - 2)
    while k > 0 and col[k, FIELD_Z] > z:
        k -= 1
    while k < n - 2 and col[k + 1, FIELD_Z] <= z:
        k += 1
    f_rho = (z - col[k, FIELD_Z]) / (col[k + 1, FIELD_Z] - col[k, FIELD_Z])
    f_wind = min(max(f_rho, 0.0), 1.0)
    dest[a, b, c, 0] = col[k, FIELD_U] + f_wind * (col[k + 1, FIELD_U] - col[k, FIELD_U])
    dest[a, b, c, 1] = col[k, FIELD_V] + f_wind * (col[k + 1, FIELD_V] - col[k, FIELD_V])
    dest[a, b, c, 2] = col[k, FIELD_LOG_RHO] + f_rho * (col[k + 1, FIELD_LOG_RHO] - col[k, FIELD_LOG_RHO])
    if z > col[n - 1, FIELD_Z] + TOP_TOLERANCE_M:
        k = -1
    dest[a, b, c, 3] = k
    return k


@njit(cache=True)
def sample_weather(
    t_s: np.ndarray,
    lats: np.ndarray,
    lons: np.ndarray,
    columns: np.ndarray,
    time_tolerance_s: float,
    t: float,
    lat: float,
    lon: float,
    z: float,
    out: np.ndarray,
    hint: np.ndarray,
    memo_z: np.ndarray,
    memo: np.ndarray,
) -> int:
    """u, v, ρ at one point into out[0:3]; returns a STATUS_* code (out is valid only for STATUS_OK).

    ``memo`` (T, Y, X, 4) remembers each column's (u, v, log ρ, level) at the altitude in ``memo_z``
    (T, Y, X): trajectories that step through the same altitudes (ensemble members, a release sweep)
    then interpolate each grid column vertically once per step instead of once per trajectory.
    A zero-sized ``memo_z`` switches it off; ``memo`` then needs shape (1, 1, 1, 4) as scratch.

    ``hint[0]`` is the level index found last time for this trajectory; it is updated.
    """
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    iy, fy = _bracket(lats, lat)
    lon_c = lon if lons[0] <= lon <= lons[lons.shape[0] - 1] else (lon - lons[0]) % 360.0 + lons[0]
    ix, fx = _bracket(lons, lon_c)
    if iy < 0 or ix < 0:
        return STATUS_OUTSIDE_REGION
    nt = t_s.shape[0]
    t_c = min(max(t, t_s[0]), t_s[nt - 1])
    if abs(t - t_c) > time_tolerance_s:
        return STATUS_OUTSIDE_TIME
    it, ft = _bracket(t_s, t_c)
    w_before, w_at, w_after, w_next = _time_weights(t_s, it, ft)
    ny = lats.shape[0]
    nx = lons.shape[0]
    use_memo = memo_z.size > 0
    for a in range(4):
        ti = it - 1 + a
        wt = w_before if a == 0 else w_at if a == 1 else w_after if a == 2 else w_next
        if wt == 0.0:
            continue
        for b in range(2):
            yi = min(iy + b, ny - 1)
            wy = fy if b == 1 else 1.0 - fy
            if wy == 0.0:
                continue
            for c in range(2):
                xi = min(ix + c, nx - 1)
                wx = fx if c == 1 else 1.0 - fx
                if wx == 0.0:
                    continue
                if use_memo:
                    a_, b_, c_ = ti, yi, xi
                    if memo_z[ti, yi, xi] != z:
                        _column_at(columns[ti, yi, xi], z, memo, ti, yi, xi, hint[0])
                        memo_z[ti, yi, xi] = z
                else:
                    a_, b_, c_ = 0, 0, 0
                    _column_at(columns[ti, yi, xi], z, memo, 0, 0, 0, hint[0])
                k = int(memo[a_, b_, c_, 3])
                if k < 0:
                    return STATUS_ABOVE_TOP
                hint[0] = k
                w = wt * wy * wx
                out[0] += w * memo[a_, b_, c_, 0]
                out[1] += w * memo[a_, b_, c_, 1]
                out[2] += w * memo[a_, b_, c_, 2]
    out[2] = math.exp(out[2])
    return STATUS_OK


@njit(cache=True, inline="always")
def gravity(z: float) -> float:
    """g on a spherical Earth of mean radius (the latitude term is below the model's accuracy)."""
    r = GRAVITY_MEAN_RADIUS_M / (GRAVITY_MEAN_RADIUS_M + z)
    return G0 * r * r


@njit(cache=True, inline="always")
def degrees_per_metre(lat: float, h: float) -> tuple[float, float]:
    """(°lat per metre north, °lon per metre east) on the WGS84 ellipsoid at height h."""
    s = math.sin(math.radians(lat))
    w = 1.0 - WGS84_E2 * s * s
    meridian = WGS84_A * (1.0 - WGS84_E2) / (w * math.sqrt(w))
    normal = WGS84_A / math.sqrt(w)
    cos_lat = max(math.cos(math.radians(lat)), 1e-9)
    return math.degrees(1.0 / (meridian + h)), math.degrees(1.0 / ((normal + h) * cos_lat))


@njit(cache=True)
def drift_at_float(
    t_s: np.ndarray,
    lats: np.ndarray,
    lons: np.ndarray,
    columns: np.ndarray,
    time_tolerance_s: float,
    lat: np.ndarray,
    lon: np.ndarray,
    z: np.ndarray,
    t: np.ndarray,
    duration_s: float,
    max_step_s: float,
    status: np.ndarray,
) -> None:
    """The balloon carries the capsule with the wind at constant altitude; updates lat, lon, t in place.

    Midpoint steps of at most max_step_s; the step count is computed, so any duration ends.
    """
    sample = np.zeros(3)
    hint = np.zeros(1, dtype=np.int64)
    no_z = np.empty((0, 0, 0))
    scratch = np.empty((1, 1, 1, 4))
    n_steps = int(math.ceil(duration_s / max_step_s)) if duration_s > 0.0 else 0
    for i in range(lat.shape[0]):
        for _ in range(n_steps):
            h = duration_s / n_steps
            code = sample_weather(
                t_s,
                lats,
                lons,
                columns,
                time_tolerance_s,
                t[i],
                lat[i],
                lon[i],
                z[i],
                sample,
                hint,
                no_z,
                scratch,
            )
            if code != STATUS_OK:
                status[i] = code
                break
            dlat, dlon = degrees_per_metre(lat[i], z[i])
            lat_m = lat[i] + 0.5 * h * sample[1] * dlat
            lon_m = lon[i] + 0.5 * h * sample[0] * dlon
            code = sample_weather(
                t_s,
                lats,
                lons,
                columns,
                time_tolerance_s,
                t[i] + 0.5 * h,
                lat_m,
                lon_m,
                z[i],
                sample,
                hint,
                no_z,
                scratch,
            )
            if code != STATUS_OK:
                status[i] = code
                break
            dlat, dlon = degrees_per_metre(lat_m, z[i])
            lat[i] += h * sample[1] * dlat
            lon[i] += h * sample[0] * dlon
            t[i] += h


_KERNEL_SOURCES = (Path(__file__), Path(__file__).with_name("model.py"))


class _StampOfIntegratorAndModel:
    """Cache stamp of both source files: the stepper compiles the model's terms into itself.

    numba checks only the stamp of the file that defines a cached function, so an edited term in
    ``predictor/descent/model.py`` would otherwise keep running its old compiled code inside the stepper.
    """

    def get_source_stamp(self) -> tuple[tuple[float, int], ...]:
        return tuple((os.stat(f).st_mtime, os.stat(f).st_size) for f in _KERNEL_SOURCES)


class _UserProvidedLocator(_StampOfIntegratorAndModel, UserProvidedCacheLocator):
    pass


class _InTreeLocator(_StampOfIntegratorAndModel, InTreeCacheLocator):
    pass


class _UserWideLocator(_StampOfIntegratorAndModel, UserWideCacheLocator):
    pass


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [_UserProvidedLocator, _InTreeLocator, _UserWideLocator]


class _KernelCache(FunctionCache):
    _impl_class = _KernelCacheImpl


def _cached_with_model(dispatcher: Any) -> Any:
    """Give a compiled function the on-disk cache that is invalidated by edits to either file."""
    dispatcher._cache = _KernelCache(dispatcher.py_func)
    return dispatcher


class Starts(NamedTuple):
    """Where and when each trajectory starts, one value per trajectory: the compiled engine's side of a
    ``Release`` (which may first drift, or be many members or candidates)."""

    time: np.ndarray
    """Epoch seconds."""
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray
    since_release_s: np.ndarray | None = None
    """Seconds already fallen at this start (a live report mid-descent), which time-since-release terms
    count from; None: 0, a start at the release itself."""


StartArrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""``Starts`` as the kernels receive it: a plain tuple, with ``since_release_s`` filled in."""


class Stepping(NamedTuple):
    """How every trajectory of one call is stepped."""

    step_m: float
    """Δz of every step."""
    floor_m: float
    """Each trajectory is stepped down to here."""
    time_tolerance_s: float
    """How far beyond the weather's first/last time it is held constant."""


class Record(NamedTuple):
    """What the stepper writes: the recorded paths, (n, columns), and per trajectory how it went."""

    lat: np.ndarray
    lon: np.ndarray
    z: np.ndarray
    t: np.ndarray
    """Epoch seconds."""
    path: np.ndarray
    """Path length projected to the ground, m."""
    skip: np.ndarray
    """Points are recorded from step ``skip[i]`` on (point 0 is the release); set before the run."""
    n_rec: np.ndarray
    """How many points were recorded; the rest of a row is left unwritten."""
    status: np.ndarray
    """A STATUS_* code."""
    time_held_s: np.ndarray
    """How far beyond the weather's time span the trajectory was held, s."""
    failed_at: np.ndarray
    """(n, 5): lat, lon, altitude, time and step index where a trajectory failed."""

    @classmethod
    def empty(cls, skip: np.ndarray, columns: int, fill: float | None = None) -> Record:
        n = skip.shape[0]
        lat, lon, z, t, path = (
            np.empty((n, columns)) if fill is None else np.full((n, columns), fill) for _ in range(5)
        )
        status = np.zeros(n, np.int64)
        return cls(lat, lon, z, t, path, skip, np.zeros(n, np.int64), status, np.zeros(n), np.zeros((n, 5)))

    def recorded(self) -> np.ndarray:
        """(n, columns): True where a point was recorded."""
        return np.arange(self.z.shape[1])[None, :] < self.n_rec[:, None]


@njit(cache=True)
def _note_failure(failed_at: np.ndarray, i: int, lat: float, lon: float, z: float, t: float, k: int) -> None:
    failed_at[i, 0] = lat
    failed_at[i, 1] = lon
    failed_at[i, 2] = z
    failed_at[i, 3] = t
    failed_at[i, 4] = k


@_cached_with_model
@njit(cache=True)
def _descend_range(
    lo: int,
    hi: int,
    weather: PackedWeather,
    stepping: Stepping,
    chain: Chain,
    release: StartArrays,
    record: Record,
) -> None:
    """Trajectories lo…hi−1 stepped together: each phase of a step runs for all of them before the next.

    Phases rather than one trajectory at a time, so that each term's kind is dispatched once per
    step for the whole range instead of once per trajectory and step. The value objects arrive as
    plain tuples (see ``descend``), so they are unpacked by position.
    """
    t_s, lats, lons, columns, _ = weather
    dz, z_floor, time_tolerance_s = stepping
    table, params, state = chain
    t0, lat0, lon0, z0, since0 = release
    out_lat, out_lon, out_z, out_t, out_path, skip, n_rec, status, time_held_s, failed_at = record
    n = t0.shape[0]
    nt = t_s.shape[0]
    env = np.zeros((n, ENV_SIZE))
    vel = np.zeros((n, 3))
    sample = np.zeros(3)
    hint = np.full(n, columns.shape[3] - 2, dtype=np.int64)
    grid_columns = columns.shape[0] * columns.shape[1] * columns.shape[2]
    if grid_columns <= MEMO_MAX_COLUMNS and hi - lo >= MEMO_MIN_TRAJECTORIES:
        memo_z = np.full(columns.shape[:3], np.nan)
        memo = np.empty((columns.shape[0], columns.shape[1], columns.shape[2], 4))
    else:
        memo_z = np.empty((0, 0, 0))
        memo = np.empty((1, 1, 1, 4))
    active = np.zeros(n, dtype=np.bool_)
    lat = lat0.copy()
    lon = lon0.copy()
    z = z0.copy()
    t = t0.copy()
    path = np.zeros(n)
    dt = np.zeros(n)
    dt_est = np.zeros(n)
    u_est = np.zeros(n)
    v_est = np.zeros(n)
    dlat = np.zeros(n)
    dlon = np.zeros(n)
    lat_m = np.zeros(n)
    for i in range(lo, hi):
        n_rec[i] = 0
        if skip[i] == 0:
            out_lat[i, 0] = lat[i]
            out_lon[i, 0] = lon[i]
            out_z[i, 0] = z[i]
            out_t[i, 0] = t[i]
            out_path[i, 0] = 0.0
            n_rec[i] = 1
        active[i] = z[i] > z_floor
        dlat[i], dlon[i] = degrees_per_metre(lat[i], z[i])
    k = 0
    n_active = hi - lo
    while n_active > 0:
        # The first step has no previous step: a first pass estimates its midpoint from its start
        # (vertical terms therefore run twice there; none of them keeps state).
        for pass_index in range(2 if k == 0 else 1):
            first_pass = k == 0 and pass_index == 0
            for i in range(lo, hi):
                if not active[i]:
                    continue
                zm = z[i] - 0.5 * dz
                t_rel = t[i] - t0[i] + since0[i]
                # The metres→degrees factors of the previous step are close enough for this estimate.
                lat_m[i] = lat[i] + 0.5 * dt_est[i] * v_est[i] * dlat[i]
                e = env[i]
                e[:] = 0.0
                e[ENV_Z] = zm
                e[ENV_T_START] = t_rel
                e[ENV_T_REL] = t_rel + 0.5 * dt_est[i]
                e[ENV_DZ] = dz
                e[ENV_LAT] = lat_m[i]
                e[ENV_G] = gravity(zm)
                vel[i, 0] = 0.0
                vel[i, 1] = 0.0
                vel[i, 2] = 0.0
            apply_family(table, FAMILY_TIMING, params, env, vel, state, active, lo, hi)
            for i in range(lo, hi):
                if not active[i]:
                    continue
                e = env[i]
                t_wx = t[i] + 0.5 * dt_est[i] + e[ENV_TIME_SHIFT]
                lon_m = lon[i] + 0.5 * dt_est[i] * u_est[i] * dlon[i]
                code = sample_weather(
                    t_s,
                    lats,
                    lons,
                    columns,
                    time_tolerance_s,
                    t_wx,
                    lat_m[i],
                    lon_m,
                    e[ENV_Z],
                    sample,
                    hint[i : i + 1],
                    memo_z,
                    memo,
                )
                if code != STATUS_OK:
                    status[i] = code
                    active[i] = False
                    _note_failure(failed_at, i, lat_m[i], lon_m, e[ENV_Z], t_wx, k)
                    continue
                held = max(t_s[0] - t_wx, t_wx - t_s[nt - 1], 0.0)
                if held > time_held_s[i]:
                    time_held_s[i] = held
                e[ENV_U_WIND] = sample[0]
                e[ENV_V_WIND] = sample[1]
                e[ENV_RHO] = sample[2]
            apply_family(table, FAMILY_VERTICAL, params, env, vel, state, active, lo, hi)
            for i in range(lo, hi):
                if not active[i]:
                    continue
                if not vel[i, VEL_DOWN] > 0.0:
                    status[i] = STATUS_NOT_DESCENDING
                    active[i] = False
                    _note_failure(failed_at, i, lat_m[i], lon[i], env[i, ENV_Z], t[i], k)
                    continue
                dt[i] = dz / vel[i, VEL_DOWN]
                env[i, ENV_DT] = dt[i]
                if first_pass:
                    dt_est[i] = dt[i]
                    u_est[i] = env[i, ENV_U_WIND]
                    v_est[i] = env[i, ENV_V_WIND]
        apply_family(table, FAMILY_HORIZONTAL, params, env, vel, state, active, lo, hi)
        n_active = 0
        for i in range(lo, hi):
            if not active[i]:
                continue
            zm = env[i, ENV_Z]
            dlat[i], dlon[i] = degrees_per_metre(lat_m[i], zm)
            east = vel[i, VEL_EAST] * dt[i]
            north = vel[i, VEL_NORTH] * dt[i]
            lat[i] += north * dlat[i]
            lon[i] += east * dlon[i]
            z[i] -= dz
            t[i] += dt[i]
            path[i] += math.sqrt(east * east + north * north) * WGS84_A / (WGS84_A + zm)
            dt_est[i] = dt[i]
            u_est[i] = vel[i, VEL_EAST]
            v_est[i] = vel[i, VEL_NORTH]
            c = k + 1 - skip[i]
            if c >= 0:
                out_lat[i, c] = lat[i]
                out_lon[i, c] = lon[i]
                out_z[i, c] = z[i]
                out_t[i, c] = t[i]
                out_path[i, c] = path[i]
                n_rec[i] = c + 1
            if z[i] > z_floor:
                n_active += 1
            else:
                active[i] = False
        k += 1


@_cached_with_model
@njit(cache=True, parallel=True)
def _descend_parallel(
    weather: PackedWeather,
    stepping: Stepping,
    chain: Chain,
    release: StartArrays,
    record: Record,
    blocks: int,
) -> None:
    """One contiguous range of trajectories per thread."""
    n = release[0].shape[0]
    for c in prange(blocks):
        _descend_range(c * n // blocks, (c + 1) * n // blocks, weather, stepping, chain, release, record)


COMPILE_NOTICE = "compiling the predictor (once)…"
"""What a front end shows while the first descent compiles the kernels (tens of seconds, once)."""


def kernels_compiled() -> bool:
    """Whether numba's on-disk cache holds the descent kernel for the current sources.

    Why ask: the first descent after an install or an edit of the physics compiles for 10–40 s, and an
    operator watching a silent terminal cannot tell that from a hang. The index is read as numba reads it
    (stamped with both source files), so the answer is False exactly when the next descent compiles.
    """
    return bool(_descend_range._cache._cache_file._load_index())


def descend(
    weather: PackedWeather,
    chain: Chain,
    release: Starts,
    stepping: Stepping,
    record_below_m: float = math.inf,
    fill: float | None = None,
    blocks: int = 1,
) -> Record:
    """Step every trajectory from its release down to the floor, recording each step: the one engine
    under predict, ensembles, planning, calibration and live.

    ``chain`` is ``Model.chain(n)`` (or its rows). Recording starts one step above ``record_below_m``
    (everything when infinite): when only the landing matters, the high part of each path is not kept,
    which saves memory. Past each path's end the record holds ``fill``, or is left unwritten (None),
    which is cheaper for callers that read only what ``Record.recorded`` marks. A trajectory that fails
    stops with its status; what to do about it is the caller's choice.

    Trajectories are split into ``blocks`` contiguous ranges run in parallel; with one block the
    range runs on the calling thread, because a parallel launch costs milliseconds when the
    machine's cores are busy and a single descent takes a fraction of that.
    """
    n = release.alt_m.shape[0]
    step_m, floor_m = stepping.step_m, stepping.floor_m
    if math.isinf(record_below_m):
        skip = np.zeros(n, dtype=np.int64)
        # The highest release needs the most steps: one scalar instead of an array per call.
        columns = math.ceil(max(float(release.alt_m.max()) - floor_m, 0.0) / step_m) + 2
    else:
        steps = np.ceil(np.maximum(release.alt_m - floor_m, 0.0) / step_m).astype(np.int64) + 1
        skip = np.maximum(np.floor((release.alt_m - record_below_m) / step_m).astype(np.int64) - 1, 0)
        columns = int((steps - skip).max()) + 1
    record = Record.empty(skip, columns, fill)
    if release.since_release_s is None:
        release = release._replace(since_release_s=np.zeros(n))
    # Plain tuples across the boundary, unpacked by position inside: numba types a NamedTuple argument
    # in Python on every call and a plain tuple in C, which saves a few µs of every single descent.
    args = (tuple(weather), tuple(stepping), tuple(chain), tuple(release), tuple(record))
    if blocks <= 1:
        _descend_range(0, n, *args)
    else:
        _descend_parallel(*args, blocks)
    return record
