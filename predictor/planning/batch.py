"""Many descents that start at different times, places and altitudes, in one compiled call per chunk.

``predict_ensemble`` starts every member at one release; a release-window sweep needs 120 releases
× 200 members, each from its own time and position. The descent engine (``integrate.descend``) takes
per-trajectory releases, so this module drives it directly and finds each path's ground crossing the
same way ``predict`` does (first recorded point at or under the terrain, linear interpolation inside
that step), so a trajectory here lands exactly where ``predict`` puts the same release.

Unlike ``predict``, a trajectory that leaves the weather does not abort the batch: it comes back with
its status code, because one candidate outside the forecast must not hide the others.
Trajectories are run in chunks so that the recorded paths (5 arrays × steps × trajectories) stay
within ~50 MB whatever the batch size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import get_num_threads

from predictor.descent import (
    HIGHEST_GROUND_M,
    LOWEST_GROUND_M,
    STATUS_OK,
    Model,
    Record,
    Starts,
    Stepping,
    descend,
    ground_crossings,
    packed,
    wrap_lon,
)
from predictor.environment import Terrain, WeatherCube
from predictor.prediction import FlightSetup

CHUNK = 4096
STATUS_RELEASE_UNDERGROUND = 101
STATUS_NO_GROUND = 102


@dataclass(frozen=True)
class BatchLandings:
    lat: np.ndarray
    lon: np.ndarray
    """Wrapped to [-180, 180)."""
    alt_m: np.ndarray
    t_s: np.ndarray
    """Epoch seconds of touchdown."""
    path_m: np.ndarray
    t_future_mean_h: np.ndarray
    """Time-weighted mean forecast lead along each path (NaN unless asked for)."""
    status: np.ndarray
    """0 for a landing; a STATUS_* code of the stepper, or STATUS_RELEASE_UNDERGROUND / STATUS_NO_GROUND."""


def descend_batch(
    cube: WeatherCube, model: Model, starts: Starts, setup: FlightSetup, with_lead: bool = False
) -> BatchLandings:
    """Land every trajectory over the setup's terrain, in its steps; the model's per-trajectory parameters
    have one value per start. A start with a NaN position or altitude is a candidate the balloon never
    reached: it gets status -1 and no landing."""
    t0, lat0, lon0, z0 = starts.time, starts.lat, starts.lon, starts.alt_m
    terrain = setup.terrain
    n = lat0.size
    w = packed(cube)
    chain = model.chain(n)
    stepping = Stepping(setup.step_m, LOWEST_GROUND_M, setup.time_tolerance_s)
    out = {name: np.full(n, np.nan) for name in ("lat", "lon", "alt_m", "t_s", "path_m", "lead")}
    status = np.zeros(n, dtype=np.int64)
    threads = get_num_threads()
    for lo in range(0, n, CHUNK):
        hi = min(lo + CHUNK, n)
        finite = np.isfinite(lat0[lo:hi]) & np.isfinite(lon0[lo:hi]) & np.isfinite(z0[lo:hi])
        # Rows without a start (the balloon left the weather before them) get a harmless start and are
        # marked afterwards; the kernel needs finite numbers.
        starts = Starts(
            np.ascontiguousarray(t0[lo:hi]),
            np.where(finite, lat0[lo:hi], 0.0),
            np.where(finite, lon0[lo:hi], 0.0),
            np.where(finite, z0[lo:hi], LOWEST_GROUND_M - 1.0),
        )
        # Unless the lead is wanted, only the part near and below the highest ground is recorded (as
        # predict does for members).
        record = descend(
            w, chain.rows(lo, hi), starts, stepping,
            record_below_m=math.inf if with_lead else HIGHEST_GROUND_M, blocks=min(hi - lo, threads),
        )  # fmt: skip
        code = record.status
        code[~finite] = -1
        part = _landings(record, code, terrain, w.t_s, w.lead_h, with_lead)
        for name, values in part.items():
            out[name][lo:hi] = values
        status[lo:hi] = code
    status[np.isnan(lat0) | np.isnan(lon0)] = -1
    return BatchLandings(
        lat=out["lat"],
        lon=wrap_lon(out["lon"]),
        alt_m=out["alt_m"],
        t_s=out["t_s"],
        path_m=out["path_m"],
        t_future_mean_h=out["lead"],
        status=status,
    )


def _landings(
    record: Record,
    code: np.ndarray,
    terrain: Terrain,
    t_axis: np.ndarray,
    lead_axis: np.ndarray,
    with_lead: bool,
) -> dict[str, np.ndarray]:
    """First ground crossing per row (rows with a bad code are left NaN; ``code`` is updated in place)."""
    lat, lon, z, t, path = record[:5]
    m = z.shape[0]
    valid = record.recorded() & (code == STATUS_OK)[:, None]
    crossing = ground_crossings(lat, lon, z, valid, terrain)
    # A crossing at the first recorded point is the release itself under the ground (with nothing
    # skipped), or a path whose skipped part already went under (impossible above 8900 m).
    code[crossing.found & (crossing.index == 0)] = STATUS_RELEASE_UNDERGROUND
    code[(code == STATUS_OK) & ~crossing.found] = STATUS_NO_GROUND
    result = {name: np.full(m, np.nan) for name in ("lat", "lon", "alt_m", "t_s", "path_m", "lead")}
    good = np.flatnonzero(code == STATUS_OK)
    if good.size == 0:
        return result
    for name, a in (("lat", lat), ("lon", lon), ("alt_m", z), ("t_s", t), ("path_m", path)):
        result[name][good] = crossing.at(a)[good]
    if with_lead:
        for row in good:
            kk = int(crossing.index[row])
            times = np.append(t[row, :kk], result["t_s"][row])
            lead = np.interp(times, t_axis, lead_axis)
            span = times[-1] - times[0]
            result["lead"][row] = float(np.trapezoid(lead, times) / span) if span > 0 else float(lead[0])
    return result
