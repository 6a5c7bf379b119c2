"""Landing predictions: one descent (``predict``) or many (``predict_ensemble``), and their results.

This module joins the parts: it checks the question, runs the compiled stepper
(``predictor.descent.integrate``) with the model chain (``predictor.descent.model``), finds where each path meets the
terrain, and attaches the uncertainty (``predictor.prediction.uncertainty``). The stepper knows nothing of the
ground, so the crossing is found here: ground heights are looked up (vectorised) along every path
below the highest ground on Earth, the first point under the ground and the one before it bracket the
crossing, and position, time and path length are interpolated linearly between them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from numba import get_num_threads

from predictor.descent import (
    DEFAULT_TIME_TOLERANCE_S,
    HIGHEST_GROUND_M,
    LOWEST_GROUND_M,
    STATUS_ABOVE_TOP,
    STATUS_NOT_DESCENDING,
    STATUS_OK,
    STATUS_OUTSIDE_REGION,
    STATUS_OUTSIDE_TIME,
    TOP_TOLERANCE_M,
    DescentRateScale,
    Model,
    Payload,
    Record,
    Release,
    Starts,
    Stepping,
    WindOffset,
    descend,
    drift_at_float,
    ground_crossings,
    packed,
    wrap_lon,
)
from predictor.environment import Terrain, WeatherCube
from predictor.errors import OutOfCoverageError, PredictorError
from predictor.prediction.setup import EnsembleSpread, FlightSetup
from predictor.prediction.uncertainty import (
    GEOD,
    Ellipse,
    ErrorModel,
    empirical_ellipse,
    parametric_ellipse,
)

DRIFT_STEP_S = 60.0
CHUNKS_PER_THREAD = 4
"""Trajectory blocks per numba thread: smaller blocks even out a thread that other work slows down."""


def iso_z(t: datetime) -> str:
    """ISO 8601 UTC with a Z, whole seconds (the JSON's time format)."""
    return t.astimezone(UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def _epoch(t: datetime) -> float:
    return t.timestamp()


def _from_epoch(s: float) -> datetime:
    return datetime(1970, 1, 1, tzinfo=UTC) + timedelta(seconds=float(s))


@dataclass(frozen=True)
class Point:
    time: datetime
    lat: float
    lon: float
    alt_m: float

    def to_dict(self) -> dict[str, Any]:
        return {"time": iso_z(self.time), "lat": self.lat, "lon": self.lon, "alt_m": self.alt_m}


@dataclass(frozen=True)
class Track:
    """The descent path from release to landing (the landing point last)."""

    t_s: np.ndarray
    """Seconds since release."""
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray

    def to_list(self) -> list[dict[str, float]]:
        return [
            {"t_s": round(float(t), 3), "lat": float(la), "lon": float(lo), "alt_m": round(float(z), 2)}
            for t, la, lo, z in zip(self.t_s, self.lat, self.lon, self.alt_m, strict=True)
        ]


@dataclass(frozen=True)
class Prediction:
    release: Point
    landing: Point
    descent_s: float
    drift_km: float
    """Geodesic release→landing distance (the d of the error model)."""
    path_km: float
    """Length of the path projected to the ground."""
    t_future_mean_h: float
    bearing_deg: float
    ellipse: Ellipse
    warnings: tuple[str, ...]
    track: Track
    weather_source: str
    is_demo: bool
    terrain_source: str
    payload: Payload
    model: list[dict[str, Any]]
    step_m: float
    error_model: ErrorModel
    decision: Point | None = None
    """Where the balloon was when the drift before release began (None without drift)."""

    def to_dict(self, track: bool = False) -> dict[str, Any]:
        ellipse = self.ellipse.to_dict()
        out: dict[str, Any] = {
            "release": self.release.to_dict(),
            "landing": self.landing.to_dict(),
            "descent_s": round(self.descent_s, 3),
            "drift_km": self.drift_km,
            "path_km": self.path_km,
            "t_future_mean_h": self.t_future_mean_h,
            "bearing_deg": self.bearing_deg,
            "ellipse": {**ellipse, "error_model": self.error_model.to_dict()},
            "warnings": list(self.warnings),
            "weather": {"source": self.weather_source, "is_demo": self.is_demo},
            "is_demo": self.is_demo,
            "terrain_source": self.terrain_source,
            "payload": self.payload.to_dict(),
            "model": self.model,
            "step_m": self.step_m,
        }
        if self.decision is not None:
            out["decision"] = self.decision.to_dict()
        if track:
            out["track"] = self.track.to_list()
        return out


@dataclass(frozen=True)
class EnsemblePrediction:
    central: Prediction
    """The unperturbed descent (its parametric ellipse is the paper's model)."""
    member_lat: np.ndarray
    member_lon: np.ndarray
    member_alt_m: np.ndarray
    member_descent_s: np.ndarray
    empirical: Ellipse
    perturbations: dict[str, Any] = field(default_factory=dict)

    @property
    def members(self) -> int:
        return int(self.member_lat.size)

    def to_dict(self, track: bool = False) -> dict[str, Any]:
        out = self.central.to_dict(track=track)
        out["ensemble"] = {
            "members": self.members,
            "perturbations": self.perturbations,
            "empirical_ellipse": self.empirical.to_dict(),
            "landings": [
                {
                    "lat": float(a),
                    "lon": float(o),
                    "alt_m": round(float(z), 2),
                    "descent_s": round(float(s), 2),
                }
                for a, o, z, s in zip(
                    self.member_lat, self.member_lon, self.member_alt_m, self.member_descent_s, strict=True
                )
            ],
        }
        return out


@dataclass(frozen=True)
class _Landings:
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray
    t_s: np.ndarray
    path_m: np.ndarray
    index: np.ndarray
    """Index of the first recorded point below the ground, per trajectory."""


def _check_question(release: Release, step_m: float) -> None:
    time, lat, lon, alt_m = release.time, release.lat, release.lon, release.alt_m
    drift_minutes = release.drift_minutes
    if not isinstance(time, datetime) or time.tzinfo is None:
        raise PredictorError(
            "the release time must be a timezone-aware datetime (UTC), e.g. 2024-05-01T06:00Z"
        )
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise PredictorError(f"latitude must be between -90 and 90 degrees, got {lat!r}")
    if not math.isfinite(lon):
        raise PredictorError(f"longitude must be a finite number of degrees, got {lon!r}")
    if not (math.isfinite(alt_m) and alt_m > 0.0):
        raise PredictorError(f"release altitude must be a positive number of metres, got {alt_m!r}")
    if not (math.isfinite(step_m) and 0.1 <= step_m <= 2000.0):
        raise PredictorError(f"altitude step must be between 0.1 and 2000 m, got {step_m!r}")
    if not (math.isfinite(drift_minutes) and 0.0 <= drift_minutes <= 24 * 60):
        raise PredictorError(f"drift time must be between 0 and 1440 minutes, got {drift_minutes!r}")


def _describe_span(cube: WeatherCube) -> str:
    first = iso_z(_from_epoch(packed(cube).t_s[0]))
    last = iso_z(_from_epoch(packed(cube).t_s[-1]))
    return f"{first} to {last}" if first != last else f"only {first}"


def _region(cube: WeatherCube) -> str:
    return f"lat {cube.lats[0]:g}…{cube.lats[-1]:g}, lon {cube.lons[0]:g}…{cube.lons[-1]:g} °E"


def coverage_error(
    cube: WeatherCube, code: int, phase: str, t: float, lat: float, lon: float, z: float
) -> PredictorError:
    """The one wording of a flight that left the weather or terrain, shared with Tawhiri's ascent so both
    stages tell an operator alike what to load."""
    where = f"{lat:.4f}, {float(wrap_lon(lon)):.4f} at {z:.0f} m, {iso_z(_from_epoch(t))}"
    if code == STATUS_OUTSIDE_REGION and phase == "release point":
        return OutOfCoverageError(
            f"the release point {where} is outside the weather region ({_region(cube)}); "
            "load weather that covers it"
        )
    if code == STATUS_OUTSIDE_REGION:
        return OutOfCoverageError(
            f"the {phase} leaves the weather region ({_region(cube)}) at {where}; "
            "load weather for a larger region"
        )
    if code == STATUS_OUTSIDE_TIME:
        return OutOfCoverageError(
            f"the {phase} needs weather at {iso_z(_from_epoch(t))} but the weather covers "
            f"{_describe_span(cube)} (held at most {DEFAULT_TIME_TOLERANCE_S / 60:.0f} min beyond); "
            "load forecast steps for that time"
        )
    if code == STATUS_ABOVE_TOP:
        return OutOfCoverageError(
            f"the {phase} at {where} is more than {TOP_TOLERANCE_M:.0f} m above the weather's top level "
            f"({cube.levels_hpa[-1]:g} hPa); use weather with higher levels or release lower"
        )
    if code == STATUS_NOT_DESCENDING:
        return PredictorError(f"the model gives no positive descent rate at {where}; check the model's terms")
    return PredictorError(f"the {phase} failed with status {code} at {where}")


def _integrate(
    cube: WeatherCube,
    model: Model,
    starts: Starts,
    step_m: float,
    time_tolerance_s: float,
    whole_track: bool = True,
) -> Record:
    """Run the stepper; without ``whole_track`` only the part near and below the highest ground is kept."""
    n = starts.time.size
    paths = descend(
        packed(cube),
        model.chain(n),
        starts,
        Stepping(step_m, LOWEST_GROUND_M, time_tolerance_s),
        record_below_m=math.inf if whole_track else HIGHEST_GROUND_M,
        blocks=min(n, CHUNKS_PER_THREAD * get_num_threads()),
    )
    bad = np.flatnonzero(paths.status != STATUS_OK)
    if bad.size:
        lat, lon, z, t, k = paths.failed_at[int(bad[0])]
        phase = "release point" if k == 0 else "descent"
        raise coverage_error(cube, int(paths.status[bad[0]]), phase, t, lat, lon, z)
    return paths


def _find_landings(paths: Record, terrain: Terrain) -> _Landings:
    """First crossing of each path with the ground; every path must land, or the question is wrong.

    Only the part of the paths below the highest ground on Earth is looked at (from the step before
    the first point under that ceiling), which is most of the cost saved for a 30 km release.
    """
    valid = paths.recorded()
    under_ceiling = valid & (paths.z <= HIGHEST_GROUND_M)
    if not under_ceiling.any():
        raise PredictorError(f"no path came below {HIGHEST_GROUND_M:.0f} m; nothing can have landed")
    start = max(int(under_ceiling.any(axis=0).argmax()) - 1, 0)
    lat, lon, z = paths.lat[:, start:], paths.lon[:, start:], paths.z[:, start:]
    crossing = ground_crossings(lat, lon, z, valid[:, start:], terrain)
    underground = np.flatnonzero(crossing.found & (crossing.index == 0))
    if underground.size:
        i = int(underground[0])
        raise PredictorError(
            f"the release altitude {z[i, 0]:.0f} m is at or below the ground "
            f"({crossing.ground_m[i]:.0f} m) at {lat[i, 0]:.4f}, {float(wrap_lon(lon[i, 0])):.4f}"
        )
    if not crossing.found.all():
        raise PredictorError(f"a path ended at {LOWEST_GROUND_M:.0f} m without meeting the ground")
    return _Landings(
        lat=crossing.at(lat),
        lon=crossing.at(lon),
        alt_m=crossing.at(z),
        t_s=crossing.at(paths.t[:, start:]),
        path_m=crossing.at(paths.path[:, start:]),
        index=crossing.index + start,
    )


def _release_state(
    cube: WeatherCube, release: Release, time_tolerance_s: float
) -> tuple[float, float, float, Point | None]:
    """(lat, lon, epoch seconds) of the release, after the balloon's drift at float altitude."""
    time, lat, lon, alt_m, drift_minutes = (
        release.time,
        release.lat,
        release.lon,
        release.alt_m,
        release.drift_minutes,
    )
    t0 = _epoch(time)
    if drift_minutes <= 0.0:
        return lat, lon, t0, None
    w = packed(cube)
    la, lo, tt = np.array([lat]), np.array([lon]), np.array([t0])
    status = np.zeros(1, dtype=np.int64)
    drift_at_float(
        w.t_s, w.lats, w.lons, w.columns, time_tolerance_s,
        la, lo, np.array([alt_m]), tt, drift_minutes * 60.0, DRIFT_STEP_S, status,
    )  # fmt: skip
    if status[0] != STATUS_OK:
        raise coverage_error(cube, int(status[0]), "drift before release", tt[0], la[0], lo[0], alt_m)
    decision = Point(time=time.astimezone(UTC), lat=lat, lon=float(wrap_lon(lon)), alt_m=alt_m)
    return float(la[0]), float(lo[0]), float(tt[0]), decision


def _t_future_mean(cube: WeatherCube, t_epoch: np.ndarray) -> float:
    """Time-weighted mean lead time of the weather along the path (the paper's ⟨t_future⟩)."""
    w = packed(cube)
    lead = np.interp(t_epoch, w.t_s, w.lead_h)
    if t_epoch.size < 2 or t_epoch[-1] <= t_epoch[0]:
        return float(lead[0])
    return float(np.trapezoid(lead, t_epoch) / (t_epoch[-1] - t_epoch[0]))


def _cube_of(wx: WeatherCube | Sequence[WeatherCube]) -> WeatherCube:
    if isinstance(wx, WeatherCube):
        return wx
    raise PredictorError("predict needs one WeatherCube (use predict_ensemble for one member per cube)")


def predict(wx: WeatherCube, release: Release, setup: FlightSetup | None = None) -> Prediction:
    """One descent from ``release`` to the ground, with the paper's parametric error ellipse.

    The chain is the setup's (``FlightSetup.chain``: the payload's drag law, the wind and ``effects``, or
    a whole ``model``); a release with ``drift_minutes`` first drifts at float, and one with
    ``since_release_s`` (a live report mid-descent) keeps counting time-since-release terms from the real
    release.
    """
    cube = _cube_of(wx)
    setup = setup or FlightSetup()
    _check_question(release, setup.step_m)
    chain = setup.chain()
    rel_lat, rel_lon, rel_t, decision = _release_state(cube, release, setup.time_tolerance_s)
    starts = Starts(
        np.array([rel_t]),
        np.array([rel_lat]),
        np.array([rel_lon]),
        np.array([release.alt_m]),
        np.array([release.since_release_s]),
    )
    paths = _integrate(cube, chain, starts, setup.step_m, setup.time_tolerance_s)
    land = _find_landings(paths, setup.terrain)
    return _build_prediction(cube, paths, land, 0, setup, chain, decision)


def _build_prediction(
    cube: WeatherCube,
    paths: Record,
    land: _Landings,
    row: int,
    setup: FlightSetup,
    model: Model,
    decision: Point | None,
) -> Prediction:
    terrain, error_model = setup.terrain, setup.error_model
    k = int(land.index[row])
    t_path = np.append(paths.t[row, :k], land.t_s[row])
    lat_path = np.append(paths.lat[row, :k], land.lat[row])
    lon_path = wrap_lon(np.append(paths.lon[row, :k], land.lon[row]))
    z_path = np.append(paths.z[row, :k], land.alt_m[row])
    rel_lat, rel_lon = float(lat_path[0]), float(lon_path[0])
    end_lat, end_lon = float(lat_path[-1]), float(lon_path[-1])
    azimuth, _, distance_m = GEOD.inv(rel_lon, rel_lat, end_lon, end_lat)
    bearing = float(azimuth % 360.0)
    drift_km = float(distance_m / 1000.0)
    t_future = _t_future_mean(cube, t_path)
    ellipse = parametric_ellipse(
        error_model, drift_km, t_future, bearing, end_lat, end_lon, setup.probabilities
    )
    terrain_source = terrain.source_at(end_lat, end_lon)
    warnings = list(cube.warnings)
    if cube.is_demo:
        warnings.insert(
            0, "DEMO WEATHER: generated analytic atmosphere, not a forecast; do not use for operations"
        )
    warnings.append(f"landing altitude from {terrain_source}")
    time_held_s = float(paths.time_held_s[row])
    if time_held_s > 0.0:
        warnings.append(
            f"weather held at its nearest valid time for up to {time_held_s / 60:.0f} min "
            f"(the weather covers {_describe_span(cube)})"
        )
    return Prediction(
        release=Point(_from_epoch(t_path[0]), rel_lat, rel_lon, float(z_path[0])),
        landing=Point(_from_epoch(t_path[-1]), end_lat, end_lon, float(z_path[-1])),
        descent_s=float(t_path[-1] - t_path[0]),
        drift_km=drift_km,
        path_km=float(land.path_m[row] / 1000.0),
        t_future_mean_h=t_future,
        bearing_deg=bearing,
        ellipse=ellipse,
        warnings=tuple(warnings),
        track=Track(t_s=t_path - t_path[0], lat=lat_path, lon=lon_path, alt_m=z_path),
        weather_source=cube.source,
        is_demo=cube.is_demo,
        terrain_source=terrain_source,
        payload=setup.payload,
        model=model.describe(),
        step_m=setup.step_m,
        error_model=error_model,
        decision=decision,
    )


@dataclass(frozen=True)
class LandingSet:
    """Where many descents land: one entry per trajectory of ``predict_landings``."""

    lat: np.ndarray
    lon: np.ndarray
    """Degrees east in [-180, 180)."""
    alt_m: np.ndarray
    time: np.ndarray
    """Landing times, ``datetime64[ms]`` UTC."""
    descent_s: np.ndarray
    path_km: np.ndarray
    drift_km: np.ndarray
    """Geodesic release→landing distance."""
    bearing_deg: np.ndarray


def predict_landings(
    wx: WeatherCube,
    times: Sequence[datetime] | np.ndarray,
    lat: float | np.ndarray,
    lon: float | np.ndarray,
    alt_m: float | np.ndarray,
    model: Model,
    terrain: Terrain | None = None,
    step_m: float = 100.0,
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
) -> LandingSet:
    """Many descents in one vectorised call: release sweeps, members, flights fitted together.

    ``times`` (aware datetimes or ``datetime64`` UTC), ``lat``, ``lon`` and ``alt_m`` broadcast to one
    value per trajectory; the model's parameters may be per-trajectory arrays of the same length. No
    drift before release and no ellipses: this is the engine under release planning and calibration.
    """
    terrain = terrain or Terrain.sea_level()
    if isinstance(times, np.ndarray) and np.issubdtype(times.dtype, np.datetime64):
        t_epoch = times.astype("datetime64[ms]").astype(np.int64) / 1000.0
    else:
        for when in times:
            if not isinstance(when, datetime) or when.tzinfo is None:
                raise PredictorError("release times must be timezone-aware datetimes (UTC)")
        t_epoch = np.array([_epoch(when) for when in times], dtype=np.float64)
    t0, la, lo, z0 = (np.ravel(a).astype(np.float64) for a in np.broadcast_arrays(t_epoch, lat, lon, alt_m))
    if t0.size == 0:
        raise PredictorError("predict_landings needs at least one trajectory")
    if not np.all(np.isfinite(la) & (np.abs(la) <= 90.0)):
        raise PredictorError("every latitude must be between -90 and 90 degrees")
    if not np.all(np.isfinite(lo)):
        raise PredictorError("every longitude must be a finite number of degrees")
    if not np.all(np.isfinite(z0) & (z0 > 0.0)):
        raise PredictorError("every release altitude must be a positive number of metres")
    _check_question(Release(_from_epoch(t0[0]), float(la[0]), float(lo[0]), float(z0[0])), step_m)
    paths = _integrate(wx, model, Starts(t0, la, lo, z0), step_m, time_tolerance_s, whole_track=False)
    land = _find_landings(paths, terrain)
    azimuth, _, distance_m = GEOD.inv(wrap_lon(lo), la, wrap_lon(land.lon), land.lat)
    return LandingSet(
        lat=land.lat,
        lon=wrap_lon(land.lon),
        alt_m=land.alt_m,
        time=(land.t_s * 1000.0).round().astype("datetime64[ms]"),
        descent_s=land.t_s - t0,
        path_km=land.path_m / 1000.0,
        drift_km=np.asarray(distance_m) / 1000.0,
        bearing_deg=np.asarray(azimuth) % 360.0,
    )


def predict_ensemble(
    wx: WeatherCube | Sequence[WeatherCube],
    release: Release,
    setup: FlightSetup | None = None,
    spread: EnsembleSpread | None = None,
) -> EnsemblePrediction:
    """Many descents at once: perturbed members of one cube, or one member per cube (GEFS).

    With one cube each member draws its errors as ``spread`` says; both are held for the whole descent,
    which is how forecast errors behave over the ~40 min of a descent (correlated, not white noise). With
    several cubes (an ensemble forecast) each cube is one member and nothing is perturbed.
    """
    setup = setup or FlightSetup()
    spread = spread or EnsembleSpread()
    members, seed = spread.members, spread.seed
    rate_sigma, wind_sigma_ms = spread.rate_sigma, spread.wind_sigma_ms
    _check_question(release, setup.step_m)
    cubes = [wx] if isinstance(wx, WeatherCube) else list(wx)
    if not cubes or not all(isinstance(c, WeatherCube) for c in cubes):
        raise PredictorError("predict_ensemble needs a WeatherCube or a non-empty list of them")
    if len(cubes) == 1 and not (isinstance(members, int) and members >= 3):
        raise PredictorError(f"an ensemble needs at least 3 members, got {members!r}")
    if len(cubes) == 2:
        raise PredictorError("an ensemble of weather files needs at least 3 of them (one member per file)")
    if not (
        math.isfinite(rate_sigma)
        and rate_sigma >= 0.0
        and math.isfinite(wind_sigma_ms)
        and wind_sigma_ms >= 0.0
    ):
        raise PredictorError("ensemble spreads must be finite and ≥ 0")
    central = predict(cubes[0], release, setup)
    base = setup.chain()
    if len(cubes) == 1:
        rng = np.random.default_rng(seed)
        rate = np.exp(rng.normal(0.0, rate_sigma, members))
        d_east = rng.normal(0.0, wind_sigma_ms, members)
        d_north = rng.normal(0.0, wind_sigma_ms, members)
        model = base.with_terms(DescentRateScale(scale=rate), WindOffset(east_ms=d_east, north_ms=d_north))
        rel_lat, rel_lon, rel_t, _ = _release_state(cubes[0], release, setup.time_tolerance_s)
        ones = np.ones(members)
        starts = Starts(
            ones * rel_t, ones * rel_lat, ones * rel_lon, ones * release.alt_m, ones * release.since_release_s
        )
        paths = _integrate(cubes[0], model, starts, setup.step_m, setup.time_tolerance_s)
        land = _find_landings(paths, setup.terrain)
        landings = (land.lat, land.lon, land.alt_m, land.t_s - rel_t)
        perturbations: dict[str, Any] = {
            "kind": "perturbed",
            "seed": seed,
            "descent_rate_factor": {"distribution": "lognormal", "median": 1.0, "sigma_log": rate_sigma},
            "wind_offset_ms": {
                "distribution": "normal per component, constant per member",
                "sigma": wind_sigma_ms,
            },
        }
    else:
        rows: list[tuple[float, float, float, float]] = []
        for cube in cubes:
            member = predict(cube, release, setup)
            rows.append((member.landing.lat, member.landing.lon, member.landing.alt_m, member.descent_s))
        arr = np.array(rows)
        landings = (arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3])
        perturbations = {"kind": "one member per weather cube", "sources": [c.source for c in cubes]}
    empirical = empirical_ellipse(
        landings[0], wrap_lon(landings[1]), central.bearing_deg, setup.probabilities
    )
    return EnsemblePrediction(
        central=central,
        member_lat=np.asarray(landings[0]),
        member_lon=wrap_lon(landings[1]),
        member_alt_m=np.asarray(landings[2]),
        member_descent_s=np.asarray(landings[3]),
        empirical=empirical,
        perturbations=perturbations,
    )
