"""The balloon's future path: where the capsule will be released from at each candidate time.

The balloon is carried by the wind at its altitude: at float altitude, or along an altitude plan
(times and altitudes, linear between them, held beyond the ends) when it is still climbing or being
ballasted. Each leg between candidates is integrated by the same compiled midpoint stepper that
a prediction's ``Release.drift_minutes`` uses, in 60 s steps, so a candidate at whole minutes is exactly
where a single prediction with that drift would release.

Uncertainty: the wind at float altitude is wrong by an unknown amount that is, over an hour or two,
nearly constant (forecast errors are correlated in time). A constant error of σ_w per component moves
the balloon by σ_w·t, so the position's σ (per axis, km) is sqrt(σ_0² + (σ_w·t)²). σ_w = 2 m/s is an
assumption (a typical GFS wind error in the lower stratosphere), not a number fitted here: no flight
data with a float forecast exist in this project; set it per flight with ``float_wind_sigma_ms``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from predictor.descent import DEFAULT_TIME_TOLERANCE_S, STATUS_OK, Release, drift_at_float, packed
from predictor.environment import WeatherCube
from predictor.errors import OutOfCoverageError, PredictorError

FLOAT_STEP_S = 60.0
"""The stepper's longest step (the same as ``predictor.prediction.landings.DRIFT_STEP_S``)."""
DEFAULT_FLOAT_WIND_SIGMA_MS = 2.0
DEFAULT_POSITION_SIGMA_KM = 0.01
"""GNSS position of the balloon now."""


@dataclass(frozen=True)
class AltitudePlan:
    """Balloon altitude against time: linear between the points, held before the first and after the last."""

    times: tuple[datetime, ...]
    alts_m: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.times) != len(self.alts_m) or not self.times:
            raise PredictorError("an altitude plan needs one altitude per time, and at least one point")
        if any(t.tzinfo is None for t in self.times):
            raise PredictorError("altitude plan times must be timezone-aware (UTC)")
        if any(b <= a for a, b in zip(self.times[:-1], self.times[1:], strict=False)):
            raise PredictorError("altitude plan times must be strictly increasing")
        if not all(math.isfinite(z) and z > 0.0 for z in self.alts_m):
            raise PredictorError("altitude plan altitudes must be positive numbers of metres")

    @classmethod
    def parse(cls, text: str) -> AltitudePlan:
        """``ISO=metres,ISO=metres,...`` (e.g. ``2024-05-01T06:00Z=30000,2024-05-01T07:00Z=28000``)."""
        times: list[datetime] = []
        alts: list[float] = []
        for item in text.split(","):
            when, sep, alt = item.strip().partition("=")
            if not sep:
                raise PredictorError(f"altitude plan item {item.strip()!r} is not TIME=METRES")
            try:
                t = datetime.fromisoformat(when.strip().replace("Z", "+00:00"))
                z = float(alt)
            except ValueError:
                raise PredictorError(f"altitude plan item {item.strip()!r} is not TIME=METRES") from None
            if t.tzinfo is None:
                raise PredictorError(f"altitude plan time {when.strip()!r} needs a zone (Z)")
            times.append(t.astimezone(UTC))
            alts.append(z)
        return cls(tuple(times), tuple(alts))

    def altitude_at(self, epoch_s: np.ndarray | float) -> np.ndarray:
        knots = np.array([t.timestamp() for t in self.times])
        return np.interp(epoch_s, knots, np.asarray(self.alts_m, float))


@dataclass(frozen=True)
class Sweep:
    """The candidate release times (from the release's time to ``hours`` later, every ``every_minutes``),
    how the balloon is carried between them, and how finely the ensemble members are stepped."""

    hours: float
    every_minutes: float
    altitude_plan: AltitudePlan | None = None
    """None: the balloon stays at the release's altitude."""
    float_wind_sigma_ms: float = DEFAULT_FLOAT_WIND_SIGMA_MS
    member_step_m: float | None = None
    """Altitude step of the ensemble members; None: twice the central step. They only shape the
    ellipse, and the midpoint stepper at 200 m lands within ~1 m of 100 m (``drs plan bench`` measures
    it), at half the cost."""


@dataclass(frozen=True)
class BalloonPath:
    """Positions at the candidate times; rows after the balloon left the weather are NaN."""

    t_s: np.ndarray
    """Epoch seconds of each candidate."""
    lat: np.ndarray
    lon: np.ndarray
    """Continuous (unwrapped) longitudes, as the stepper produced them."""
    alt_m: np.ndarray
    sigma_km: np.ndarray
    """1σ of the position per axis (isotropic)."""
    status: np.ndarray
    """STATUS_* of the stepper per candidate (non-zero: the path left the weather before it)."""


def balloon_path(
    cube: WeatherCube, release: Release, sweep: Sweep, time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S
) -> BalloonPath:
    """The balloon at the release's time, + every, … up to + hours (inclusive)."""
    start, lat, lon, alt_m = release.time, release.lat, release.lon, release.alt_m
    hours, every_minutes = sweep.hours, sweep.every_minutes
    altitude_plan, float_wind_sigma_ms = sweep.altitude_plan, sweep.float_wind_sigma_ms
    if release.drift_minutes or release.since_release_s:
        raise PredictorError(
            "a sweep starts where the balloon is now: drift before release and a start mid-descent "
            "are a single prediction's"
        )
    if start.tzinfo is None:
        raise PredictorError("the sweep start must be a timezone-aware time (UTC), e.g. 2024-05-01T06:00Z")
    if not (math.isfinite(hours) and 0.0 <= hours <= 48.0):
        raise PredictorError(f"the sweep length must be between 0 and 48 hours, got {hours!r}")
    if not (math.isfinite(every_minutes) and 0.5 <= every_minutes <= 24 * 60):
        raise PredictorError(f"the sweep step must be between 0.5 and 1440 minutes, got {every_minutes!r}")
    if not (math.isfinite(float_wind_sigma_ms) and float_wind_sigma_ms >= 0.0):
        raise PredictorError(f"the float wind σ must be ≥ 0 m/s, got {float_wind_sigma_ms!r}")
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0 and math.isfinite(lon)):
        raise PredictorError(f"the balloon position {lat!r}, {lon!r} is not a latitude/longitude")
    if not (math.isfinite(alt_m) and alt_m > 0.0):
        raise PredictorError(f"the balloon altitude must be a positive number of metres, got {alt_m!r}")
    n = int(math.floor(hours * 60.0 / every_minutes + 1e-9)) + 1
    w = packed(cube)
    t0 = start.timestamp()
    if not cube.covers(lat, lon):
        raise OutOfCoverageError(
            f"the balloon position {lat:.4f}, {lon:.4f} is outside the weather region "
            f"(lat {cube.lats[0]:g}…{cube.lats[-1]:g}, lon {cube.lons[0]:g}…{cube.lons[-1]:g} °E)"
        )
    if not w.t_s[0] - time_tolerance_s <= t0 <= w.t_s[-1] + time_tolerance_s:
        raise OutOfCoverageError(
            f"the sweep starts at {start.astimezone(UTC).isoformat()} but the weather covers "
            f"{cube.times[0]}Z to {cube.times[-1]}Z; load forecast steps for that time"
        )
    leg_s = every_minutes * 60.0
    t_s = t0 + leg_s * np.arange(n)
    lats, lons, alts = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    status = np.zeros(n, dtype=np.int64)
    la, lo, tt = np.array([float(lat)]), np.array([float(lon)]), np.array([t0])
    code = np.zeros(1, dtype=np.int64)
    for i in range(n):
        if i > 0 and code[0] == STATUS_OK:
            if altitude_plan is None:
                drift_at_float(
                    w.t_s, w.lats, w.lons, w.columns, time_tolerance_s,
                    la, lo, np.array([alt_m]), tt, leg_s, FLOAT_STEP_S, code,
                )  # fmt: skip
            else:
                # Along a plan the altitude changes, so each ≤60 s step flies at its midpoint's altitude.
                steps = int(math.ceil(leg_s / FLOAT_STEP_S))
                for _ in range(steps):
                    mid = tt[0] + 0.5 * leg_s / steps
                    z = np.array([float(altitude_plan.altitude_at(mid))])
                    drift_at_float(
                        w.t_s, w.lats, w.lons, w.columns, time_tolerance_s,
                        la, lo, z, tt, leg_s / steps, FLOAT_STEP_S, code,
                    )  # fmt: skip
                    if code[0] != STATUS_OK:
                        break
        status[i] = code[0]
        if code[0] == STATUS_OK:
            lats[i], lons[i] = la[0], lo[0]
            alts[i] = alt_m if altitude_plan is None else float(altitude_plan.altitude_at(t_s[i]))
    elapsed = t_s - t0
    sigma = np.sqrt(DEFAULT_POSITION_SIGMA_KM**2 + (float_wind_sigma_ms * elapsed / 1000.0) ** 2)
    return BalloonPath(t_s=t_s, lat=lats, lon=lons, alt_m=alts, sigma_km=sigma, status=status)
