"""An independent world: descents flown by physics, weather and an integrator the project never wrote.

Why: the calibration loop's own synthetic flights (``tests/predictor/synthetic_flights.py``) are flown by the
project's engine, with the library's own terms, in the very weather cube the calibration reads. A loop
that only ever meets its own engine can be right for the wrong reason. Here everything that makes the
truth is separate code:

* the atmosphere is an analytic field (piecewise-linear temperature in geopotential height, pressure
  in closed form per layer, latitude-dependent gravity falling off with height); the wind is an
  analytic jet whose direction turns with height and with time and whose speed varies with longitude;
* the truth is integrated with classical RK4 at fixed time steps (``STEP_S``), the field evaluated
  exactly at each stage's position and time (no grid, no interpolation);
* the calibration meets the weather only as GFS-like GRIB2 files SAMPLED from that field on the 0.5°
  grid and whole-hour steps (written with eccodes by ``predictor.environment.gribwrite``, the one
  project function used here, as a file writer), so it reads them with its own decoder and
  interpolation, and the sampling is an error it must live with, as with a real forecast;
* the physics of the fall is written here: v = λᵢ·sqrt(2·m·g/(ρ·Cd·A)) through the air, each flight
  with its own rate factor λᵢ (log-normal across flights, a payload family's rigging scatter), plus
  effects the project's library does not have in that form: a canopy that opens further below a
  height (two regimes), a wind bias that ramps with altitude, an updraft in a band of heights, or
  nothing but GNSS noise;
* what makes real flights hard (issue #30) can be switched on (``HARD``): a wider per-flight λ scatter
  (σ ln λ = 0.10, real payloads show 0.06–0.13); forecast winds that differ from the winds flown by a
  random field correlated in height, space and time (``ForecastError``: a few m/s, kilometres in the
  vertical, ~100 km and ~2 h), so the winds the ascent measured — tens of kilometres and one to two
  hours away from the descent at the same height — are not the winds the descent meets; and effects
  whose form no library term has: a rate that drifts with time since release, a drag coefficient
  that follows the Reynolds number (with the air's viscosity, so not a function of density alone);
* the tracks come out as canonical CSV files (``time,lat,lon,alt_m,pressure_pa,speed_mps``), written
  here, with ground fixes before launch and after landing, a random logging phase and Gaussian noise,
  and go through ``predictor.tracks``' reader and cleaning like a real file.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

from predictor.environment.gribwrite import GFS_LEVELS_HPA, gfs_file_name, write_gfs_grib2

G0 = 9.80665
R_AIR = 287.053
EARTH_RADIUS_M = 6_371_000.0
"""Of gravity's fall-off with height."""
WGS84_A = 6_378_137.0
WGS84_E2 = 0.00669437999013
STEP_S = 1.0
"""RK4 step of the descent (the ascent takes 5 s steps: nothing is scored on it but its winds)."""
GROUND_M = 350.0
"""The ground everywhere (the calibration takes the measured landing altitude as its ground)."""
CYCLE = datetime(2025, 3, 10, 0, 0, tzinfo=UTC)
"""The forecast cycle of the GRIB files; flights launch from 06 UTC."""
LAUNCH_LAT, LAUNCH_LON = 45.5, 5.0
LATS = np.arange(43.0, 49.01, 0.5)
LONS = np.arange(2.0, 12.01, 0.5)
WEATHER_HOURS = tuple(range(4, 19))
"""Forecast steps written (hours after the cycle): cover every flight of a world from launch to landing."""
MASS_KG = 2.0
CDA_M2 = 1.4
"""The payload's nominal drag law (what the calibration is told: ``Payload(MASS_KG, CDA_M2)``)."""

# Temperature layers of the analytic atmosphere: (base geopotential height m, base K, lapse K/m). Not the
# ISA: a warmer ground and a higher tropopause, so nothing can lean on a standard-atmosphere table.
_LAYERS = ((0.0, 291.0, -0.0068), (11_800.0, 0.0, 0.0), (20_500.0, 0.0, 0.0011), (32_000.0, 0.0, 0.0026))
_P0 = 101_800.0


def _layers() -> list[tuple[float, float, float, float]]:
    """(base H, base T, lapse, base p) of every layer, each base continuous with the layer below."""
    out: list[tuple[float, float, float, float]] = []
    h0, t0, lapse0 = _LAYERS[0]
    p0 = _P0
    out.append((h0, t0, lapse0, p0))
    for h1, _, lapse1 in _LAYERS[1:]:
        t1 = t0 + lapse0 * (h1 - h0)
        p1 = _pressure_in_layer(h1, h0, t0, lapse0, p0)
        out.append((h1, t1, lapse1, p1))
        h0, t0, lapse0, p0 = h1, t1, lapse1, p1
    return out


def _pressure_in_layer(h: float, h0: float, t0: float, lapse: float, p0: float) -> float:
    if lapse == 0.0:
        return p0 * math.exp(-G0 * (h - h0) / (R_AIR * t0))
    return p0 * (1.0 + lapse * (h - h0) / t0) ** (-G0 / (R_AIR * lapse))


LAYERS = _layers()


def surface_gravity(lat_deg: float) -> float:
    """Somigliana's normal gravity on the ellipsoid (m/s²)."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2)


def geopotential_height(z_m: float, lat_deg: float) -> float:
    """Geopotential metres of a geometric altitude: ∫ g dz / g0 with g = g_s·(R/(R+z))²."""
    return surface_gravity(lat_deg) / G0 * EARTH_RADIUS_M * z_m / (EARTH_RADIUS_M + z_m)


def geometric_altitude(h_gpm: float, lat_deg: float) -> float:
    k = h_gpm * G0 / surface_gravity(lat_deg)
    return EARTH_RADIUS_M * k / (EARTH_RADIUS_M - k)


def temperature_pressure(h_gpm: float) -> tuple[float, float]:
    """(K, Pa) at a geopotential height."""
    base = LAYERS[0]
    for layer in LAYERS:
        if h_gpm >= layer[0]:
            base = layer
    h0, t0, lapse, p0 = base
    return t0 + lapse * (h_gpm - h0), _pressure_in_layer(h_gpm, h0, t0, lapse, p0)


def height_of_pressure(p_pa: float) -> float:
    """The geopotential height of a pressure (the inverse of ``temperature_pressure``)."""
    base = LAYERS[0]
    for layer in LAYERS:
        if p_pa <= layer[3]:
            base = layer
    h0, t0, lapse, p0 = base
    if lapse == 0.0:
        return h0 - R_AIR * t0 / G0 * math.log(p_pa / p0)
    return h0 + t0 / lapse * ((p_pa / p0) ** (-R_AIR * lapse / G0) - 1.0)


def density(z_m: float, lat_deg: float) -> float:
    t, p = temperature_pressure(geopotential_height(z_m, lat_deg))
    return p / (R_AIR * t)


def gravity(z_m: float, lat_deg: float) -> float:
    return surface_gravity(lat_deg) * (EARTH_RADIUS_M / (EARTH_RADIUS_M + z_m)) ** 2


def wind(z_m: float, hours: float, lat_deg: float, lon_deg: float) -> tuple[float, float]:
    """The forecast's (east, north) wind, m/s: a jet at 11.5 km over a 7 m/s flow, blowing toward the
    east-north-east, turning 40° over 20 km of height and 4° an hour, 3 % stronger per degree east.
    Smooth on the scale of the GRIB grid (0.5°, 1 h, the GFS levels), so that with no effect the files
    carry the field up to sampling errors of a few metres per second·hour, not a wind-speed bias."""
    speed = (7.0 + 24.0 * math.exp(-(((z_m - 11_500.0) / 4500.0) ** 2)) + 5.0 * math.exp(-z_m / 2500.0)) * (
        1.0 + 0.03 * (lon_deg - LAUNCH_LON)
    )
    heading = math.radians(60.0 + 40.0 * min(max(z_m, 0.0), 20_000.0) / 20_000.0 + 4.0 * (hours - 6.0)
                           + 2.0 * (lat_deg - LAUNCH_LAT))  # fmt: skip
    return speed * math.sin(heading), speed * math.cos(heading)


# ---------------------------------------------------------------- the effects the library lacks


@dataclass(frozen=True)
class Effects:
    """What the true world has beyond the forecast's wind and each flight's drag law × λᵢ."""

    faster_above_m: float | None = None
    """Two-regime canopy: above this altitude it is less open and the fall is ``faster_factor`` faster."""
    faster_factor: float = 1.0
    wind_ramp_ms_per_km: tuple[float, float] = (0.0, 0.0)
    """An (east, north) wind the forecast lacks, growing linearly with altitude from 0 at the ground."""
    updraft_band_m: tuple[float, float] = (0.0, 0.0)
    updraft_ms: float = 0.0
    """Rising air (m/s) between the band's altitudes: the fall over the ground is slower by that much."""

    rate_drift_per_hour: float = 0.0
    """The rate through the air grows by this fraction per hour since release (a canopy whose fabric
    stretches and vents, a payload icing then shedding: the law's factor is 1 + drift·t, t in hours)."""
    reynolds_exponent: float = 0.0
    """Cd ∝ (Re/Re_ref)^(−k): a drag coefficient that rises as the Reynolds number falls. Re = ρ·v·D/μ
    with Sutherland's viscosity μ(T), so the change depends on temperature as well as density."""

    def rate_factor(self, z_m: float, since_release_s: float = 0.0) -> float:
        regime = self.faster_factor if self.faster_above_m is not None and z_m > self.faster_above_m else 1.0
        return regime * (1.0 + self.rate_drift_per_hour * since_release_s / 3600.0)

    def air_rising(self, z_m: float) -> float:
        bottom, top = self.updraft_band_m
        return self.updraft_ms if bottom <= z_m < top else 0.0

    def extra_wind(self, z_m: float) -> tuple[float, float]:
        k = max(z_m - GROUND_M, 0.0) / 1000.0
        return self.wind_ramp_ms_per_km[0] * k, self.wind_ramp_ms_per_km[1] * k

    def through_air(self, v_law_ms: float, z_m: float, lat_deg: float) -> float:
        """The fall through the air when the law alone gives ``v_law_ms`` (Cd at the reference Re):
        solving v = v_law·(Re(v)/Re_ref)^(k/2) for v in closed form."""
        k = self.reynolds_exponent
        if k == 0.0:
            return v_law_ms
        t, _ = temperature_pressure(geopotential_height(z_m, lat_deg))
        per_speed = density(z_m, lat_deg) * CANOPY_DIAMETER_M / viscosity(t) / REYNOLDS_REF
        return (v_law_ms * per_speed ** (k / 2.0)) ** (1.0 / (1.0 - k / 2.0))


CANOPY_DIAMETER_M = 1.3
"""The length in the payload's Reynolds number (a ~1.3 m canopy: Cd·A 1.4 m² at Cd 1.05)."""
REYNOLDS_REF = 4.0e5
"""Where Cd is the law's own: the Reynolds number near the ground (ρ 1.2, v 5 m/s, D 1.3 m)."""


def viscosity(t_k: float) -> float:
    """Sutherland's law for air, Pa·s."""
    return 1.458e-6 * t_k**1.5 / (t_k + 110.4)


NOISE_ONLY = Effects()
TWO_REGIME = Effects(faster_above_m=20_000.0, faster_factor=1.3)
"""Issue #21's canopy: 1.3× faster above 20 km, normal below. A RECOGNITION CHECK ONLY: its form is
exactly the library's ``two_regime_rate``, so a model that fits it shows the library can recognise its
own term, not that the loop generalises; issue #30's floors are not asserted on it."""
RATE_DRIFT = Effects(rate_drift_per_hour=0.25)
"""The fall speeds up 25 % per hour since release (≈ +12 % by the end of a 30 min descent): a
function of time since release, which no library term is (``deployment_delay`` is a step)."""
REYNOLDS_DRAG = Effects(reynolds_exponent=0.25)
"""Cd ∝ Re^−0.25: at 28 km (Re ~8·10⁴, cold air) the fall is ~20 % slower than ρ^−½ says."""
WIND_RAMP = Effects(wind_ramp_ms_per_km=(0.35, -0.2))
"""0.35 m/s east and −0.2 m/s north per km of height: 10 m/s east at 30 km."""
UPDRAFT = Effects(updraft_band_m=(1500.0, 5000.0), updraft_ms=1.5)
"""1.5 m/s rising air from 1.5 to 5 km (a convective boundary layer and lee wave, say)."""


# ---------------------------------------------------------------- the forecast's error


@dataclass(frozen=True)
class ForecastError:
    """The winds flown minus the forecast's: for each component an independent Gaussian random field
    with a Gaussian covariance of the given scales in height, horizontal distance and time, drawn as
    ``modes`` random Fourier features (Rahimi & Recht): √(2/M)·Σ cos(k·x + φ) with k ~ N(0, 1/L²), so
    its variance is ``rms_ms``² and its correlation exp(−Δ²/2L²) in each coordinate."""

    rms_ms: float = 3.0
    vertical_m: float = 2500.0
    horizontal_m: float = 100_000.0
    hours: float = 2.0
    modes: int = 48
    seed: int = 0

    def field(self) -> WindError:
        rng = np.random.default_rng(self.seed + 7919)
        scales = np.array([self.vertical_m, self.horizontal_m, self.horizontal_m, self.hours * 3600.0])
        k = rng.normal(0.0, 1.0, (2, self.modes, 4)) / scales
        phase = rng.uniform(0.0, 2.0 * math.pi, (2, self.modes))
        return WindError(k, phase, self.rms_ms * math.sqrt(2.0 / self.modes))


@dataclass(frozen=True)
class WindError:
    """A drawn ``ForecastError``: evaluated exactly at any (altitude, place, time), no grid."""

    k: np.ndarray
    """(component, mode, [z, east, north, t]) wavenumbers, rad per m or per s."""
    phase: np.ndarray
    amplitude: float

    def at(self, z_m: float, lat_deg: float, lon_deg: float, t_s: float) -> tuple[float, float]:
        d_north, d_east = _from_degrees(lat_deg - LAUNCH_LAT, lon_deg - LAUNCH_LON)
        x = np.array([z_m, d_east, d_north, t_s])
        waves = np.cos(self.k @ x + self.phase)
        return float(self.amplitude * waves[0].sum()), float(self.amplitude * waves[1].sum())


HARD = {"rate_log_sigma": 0.10, "forecast_error": ForecastError()}
"""``make_world`` keywords for what makes real flights hard: the λ scatter of real payloads and
forecast winds that are not the winds flown (3 m/s rms per component)."""


# ---------------------------------------------------------------- flying


@dataclass(frozen=True)
class TrueFlight:
    name: str
    path: Path
    """The logged track (canonical CSV)."""
    rate_factor: float
    """This flight's own λᵢ on the nominal drag law."""
    burst_alt_m: float
    descent_s: float
    """True burst → touchdown seconds."""
    landing_lat: float
    landing_lon: float


@dataclass(frozen=True)
class World:
    weather: tuple[Path, ...]
    """The GRIB2 files (one per forecast hour)."""
    flights: tuple[TrueFlight, ...]
    effects: Effects
    mass_kg: float = MASS_KG
    cda_m2: float = CDA_M2
    notes: dict[str, float] = field(default_factory=dict)

    @property
    def tracks(self) -> list[Path]:
        return [f.path for f in self.flights]


def _to_degrees(lat0: float, d_north_m: float, d_east_m: float, z_m: float = 0.0) -> tuple[float, float]:
    """Degrees of a small (north, east) move at a height on the WGS84 ellipsoid (its radii of curvature)."""
    s2 = math.sin(math.radians(lat0)) ** 2
    w = math.sqrt(1.0 - WGS84_E2 * s2)
    meridional, normal = WGS84_A * (1.0 - WGS84_E2) / w**3 + z_m, WGS84_A / w + z_m
    return math.degrees(d_north_m / meridional), math.degrees(
        d_east_m / (normal * math.cos(math.radians(lat0)))
    )


def _from_degrees(d_lat: float, d_lon: float) -> tuple[float, float]:
    """(north, east) metres of a small move in degrees near the launch (a local flat frame)."""
    return math.radians(d_lat) * WGS84_A, math.radians(d_lon) * WGS84_A * math.cos(math.radians(LAUNCH_LAT))


@dataclass(frozen=True)
class _Sky:
    """Everything the truth of one flight is flown in."""

    rate_factor: float
    effects: Effects
    ascent_ms: float
    release_s: float = math.inf
    error: WindError | None = None


def _velocity(
    state: tuple[float, float, float], t_s: float, descending: bool, sky: _Sky
) -> tuple[float, float, float]:
    """(dz/dt, dlat/dt, dlon/dt) in m/s and degrees/s at a state (z, lat, lon)."""
    z, lat, lon = state
    u, v = wind(z, t_s / 3600.0, lat, lon)
    if sky.error is not None:
        eu, ev = sky.error.at(z, lat, lon, t_s)
        u, v = u + eu, v + ev
    effects = sky.effects
    if descending:
        eu, ev = effects.extra_wind(z)
        u, v = u + eu, v + ev
        law = (
            sky.rate_factor
            * effects.rate_factor(z, t_s - sky.release_s)
            * math.sqrt(2.0 * MASS_KG * gravity(z, lat) / (density(z, lat) * CDA_M2))
        )
        dz = -(effects.through_air(law, z, lat) - effects.air_rising(z))
    else:
        dz = sky.ascent_ms
    d_lat, d_lon = _to_degrees(lat, v, u, z)
    return dz, d_lat, d_lon


def _rk4(
    state: tuple[float, float, float], t_s: float, dt: float, descending: bool, sky: _Sky
) -> tuple[float, float, float]:
    def f(s: tuple[float, float, float], t: float) -> tuple[float, float, float]:
        return _velocity(s, t, descending, sky)

    def ahead(
        s: tuple[float, float, float], k: tuple[float, float, float], h: float
    ) -> tuple[float, float, float]:
        return s[0] + h * k[0], s[1] + h * k[1], s[2] + h * k[2]

    k1 = f(state, t_s)
    k2 = f(ahead(state, k1, dt / 2), t_s + dt / 2)
    k3 = f(ahead(state, k2, dt / 2), t_s + dt / 2)
    k4 = f(ahead(state, k3, dt), t_s + dt)
    return tuple(state[i] + dt / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in range(3))  # type: ignore[return-value]


def fly(
    launch_s: float, lat: float, lon: float, burst_alt_m: float, rate_factor: float, effects: Effects,
    ascent_ms: float = 5.0, error: WindError | None = None,
) -> tuple[np.ndarray, float, float]:  # fmt: skip
    """The true path from launch to touchdown: rows (seconds since the cycle, lat, lon, alt m), and the
    burst and touchdown times. The last step is cut at the ground by linear interpolation. ``error``:
    the forecast's wind error, flown on the way up and down alike (the forecast files never carry it)."""
    rows = [(launch_s, lat, lon, GROUND_M)]
    state = (GROUND_M, lat, lon)
    t = launch_s
    sky = _Sky(rate_factor, effects, ascent_ms, error=error)
    while state[0] < burst_alt_m:
        dt = min(5.0, (burst_alt_m - state[0]) / ascent_ms)
        state = _rk4(state, t, dt, False, sky)
        t += dt
        rows.append((t, *state[1:], state[0]))
    burst_s = t
    sky = _Sky(rate_factor, effects, ascent_ms, release_s=burst_s, error=error)
    while state[0] > GROUND_M:
        new = _rk4(state, t, STEP_S, True, sky)
        if new[0] <= GROUND_M:
            w = (state[0] - GROUND_M) / (state[0] - new[0])
            state = tuple(a + w * (b - a) for a, b in zip(state, new, strict=True))  # type: ignore[assignment]
            t += w * STEP_S
            rows.append((t, state[1], state[2], GROUND_M))
            break
        state = new
        t += STEP_S
        rows.append((t, *state[1:], state[0]))
    return np.array(rows), burst_s, t


def _log(path: Path, truth: np.ndarray, cadence_s: float, noise_m: float, rng: np.random.Generator) -> None:
    """Sample the truth every ``cadence_s`` from a random phase, 10 min on the ground either side, with
    GNSS noise (altitude 1.5× the horizontal), the pressure of the true altitude with 0.3 % noise."""
    t0, t1 = truth[0, 0] - 600.0, truth[-1, 0] + 600.0
    times = np.arange(t0 + rng.uniform(0.0, cadence_s), t1, cadence_s)
    lat = np.interp(times, truth[:, 0], truth[:, 1])
    lon = np.interp(times, truth[:, 0], truth[:, 2])
    alt = np.interp(times, truth[:, 0], truth[:, 3])
    n = times.size
    east, north = rng.normal(0.0, noise_m, (2, n))
    alt_noisy = alt + rng.normal(0.0, 1.5 * noise_m, n)
    with path.open("w", newline="", encoding="utf-8") as handle:
        out = csv.writer(handle, lineterminator="\n")
        out.writerow(("time", "lat", "lon", "alt_m", "pressure_pa", "speed_mps"))
        for k in range(n):
            d_lat, d_lon = _to_degrees(lat[k], north[k], east[k])
            _, p = temperature_pressure(geopotential_height(float(alt[k]), float(lat[k])))
            when = CYCLE + timedelta(seconds=float(times[k]))
            out.writerow((
                when.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z", f"{lat[k] + d_lat:.7f}", f"{lon[k] + d_lon:.7f}",
                f"{alt_noisy[k]:.2f}", f"{p * (1.0 + rng.normal(0.0, 0.003)):.1f}", "",
            ))  # fmt: skip


def write_weather(directory: Path) -> tuple[Path, ...]:
    """The forecast as GFS-like GRIB2 files: the analytic field sampled at the grid points, levels and
    whole hours (it is the field WITHOUT the world's effects: those are what the forecast lacks)."""
    levels = np.array([p for p in GFS_LEVELS_HPA if p >= 5], dtype=float)
    shape = (levels.size, LATS.size, LONS.size)
    files = []
    for hour in WEATHER_HOURS:
        u, v, t, gh = (np.zeros(shape) for _ in range(4))
        for li, level in enumerate(levels):
            h = height_of_pressure(level * 100.0)
            temp, _ = temperature_pressure(h)
            for yi, lat in enumerate(LATS):
                z = geometric_altitude(h, float(lat))
                for xi, lon in enumerate(LONS):
                    u[li, yi, xi], v[li, yi, xi] = wind(z, float(hour), float(lat), float(lon))
                    t[li, yi, xi] = temp
                    gh[li, yi, xi] = h
        files.append(write_gfs_grib2(directory / gfs_file_name(CYCLE, hour), CYCLE, hour, levels, LATS, LONS,
                                     u, v, t, gh))  # fmt: skip
    return tuple(files)


def make_world(
    directory: Path, effects: Effects, *, flights: int = 6, seed: int = 0, cadence_s: float = 120.0,
    noise_m: float = 4.0, rate_log_sigma: float = 0.06, rate_median: float = 1.0,
    weather: Sequence[Path] | None = None, forecast_error: ForecastError | None = None,
) -> World:  # fmt: skip
    """``flights`` flights launched 40 min apart from 06 UTC, bursting at 26–30 km, each with its own
    λᵢ = rate_median·exp(N(0, rate_log_sigma)), logged every ``cadence_s`` s with ``noise_m`` of noise.
    ``weather``: GRIB files already written by ``write_weather`` (they do not depend on the effects).
    ``forecast_error``: the winds flown differ from the files' by this field, drawn from the world's
    own seed (calibration and unseen worlds of different seeds meet different forecast errors)."""
    directory.mkdir(parents=True, exist_ok=True)
    files = tuple(weather) if weather is not None else write_weather(directory / "gfs")
    error = (
        None if forecast_error is None else replace(forecast_error, seed=forecast_error.seed + seed).field()
    )
    rng = np.random.default_rng(seed)
    out = []
    for k in range(flights):
        rate_factor = float(rate_median * math.exp(rng.normal(0.0, rate_log_sigma)))
        burst = float(rng.uniform(26_000.0, 30_000.0))
        launch_s = 6 * 3600.0 + 2400.0 * k
        lat = LAUNCH_LAT + float(rng.uniform(-0.3, 0.3))
        lon = LAUNCH_LON + float(rng.uniform(-0.3, 0.3))
        truth, burst_s, land_s = fly(launch_s, lat, lon, burst, rate_factor, effects, error=error)
        path = directory / f"world-{seed}-{k}.csv"
        _log(path, truth, cadence_s, noise_m, rng)
        out.append(TrueFlight(path.stem, path, rate_factor, burst, land_s - burst_s,
                              float(truth[-1, 1]), float(truth[-1, 2])))  # fmt: skip
    return World(files, tuple(out), effects)
