"""The release-window sweep: for each candidate release time, where it lands, how sure, and go/no-go.

Why a sweep and not one prediction: the operator's question on the day is "when", not "where". The
balloon keeps drifting, so every candidate time releases from a different place; each candidate's
landing is a Gaussian (the paper's parametric ellipse widened by the balloon's own position
uncertainty, or the ensemble's fitted ellipse when members are asked for), and what matters is the
probability that this Gaussian lands in a town, lake or restricted area, and how far from a road or
recovery point it will on average be. Candidates that meet the thresholds are "go"; runs of
consecutive go candidates are the windows, ranked.

Ensemble members share their random draws across candidates (common random numbers): the
differences between two candidates are then differences of the weather, not of the dice, so the
go/no-go timeline does not flicker from sampling noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from shapely.geometry.base import BaseGeometry

from predictor.descent import (
    STATUS_ABOVE_TOP,
    STATUS_NOT_DESCENDING,
    STATUS_OUTSIDE_REGION,
    STATUS_OUTSIDE_TIME,
    DescentRateScale,
    Model,
    Release,
    Starts,
    WindOffset,
    degrees_per_metre,
    wrap_lon,
)
from predictor.environment import WeatherCube
from predictor.errors import PredictorError
from predictor.planning.balloon import BalloonPath, Sweep, balloon_path
from predictor.planning.batch import (
    STATUS_NO_GROUND,
    STATUS_RELEASE_UNDERGROUND,
    BatchLandings,
    descend_batch,
)
from predictor.planning.limits import MAX_MEMBER_DESCENTS
from predictor.prediction import (
    GEOD,
    Ellipse,
    EnsembleSpread,
    ErrorModel,
    Feature,
    FlightSetup,
    LocalPlane,
    distance_at_center_km,
    ellipse_covariance,
    expected_distance_km,
    inside_any,
    iso_z,
    parametric_ellipse,
    zone_probabilities,
)

STATUS_TEXT = {
    -1: "the balloon path left the weather before this time",
    STATUS_OUTSIDE_REGION: "the descent leaves the weather region",
    STATUS_OUTSIDE_TIME: "the descent needs weather beyond the forecast's time span",
    STATUS_ABOVE_TOP: "the release is above the weather's top level",
    STATUS_NOT_DESCENDING: "the model gives no positive descent rate",
    STATUS_RELEASE_UNDERGROUND: "the release altitude is under the ground",
    STATUS_NO_GROUND: "the path never met the ground",
}


@dataclass(frozen=True)
class Thresholds:
    """What makes a candidate "go". ``None`` switches a test off."""

    max_zone_probability: float = 0.05
    """Highest acceptable probability of landing inside any exclusion zone."""
    max_target_km: float | None = None
    """Highest acceptable expected distance from the nearest target (needs targets)."""
    max_sigma_km: float | None = None
    """Largest acceptable 1σ major axis of the landing ellipse."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_zone_probability) and 0.0 <= self.max_zone_probability <= 1.0):
            raise PredictorError(f"max zone probability must be in 0…1, got {self.max_zone_probability!r}")
        for name in ("max_target_km", "max_sigma_km"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0.0):
                raise PredictorError(f"{name.replace('_', ' ')} must be a positive number, got {value!r}")

    def to_dict(self) -> dict[str, float | None]:
        return {
            "max_zone_probability": self.max_zone_probability,
            "max_target_km": self.max_target_km,
            "max_sigma_km": self.max_sigma_km,
        }


@dataclass(frozen=True)
class Criteria:
    """What each candidate is judged against: the exclusion zones, the targets to land near, and the
    thresholds that make it go."""

    zones: Sequence[Feature] = ()
    targets: Sequence[Feature] = ()
    thresholds: Thresholds = field(default_factory=Thresholds)


@dataclass(frozen=True)
class Candidate:
    index: int
    release_time: datetime
    release_lat: float
    release_lon: float
    release_alt_m: float
    balloon_sigma_km: float
    status: str | None
    """Why there is no landing (None when there is one)."""
    landing_time: datetime | None = None
    landing_lat: float = math.nan
    landing_lon: float = math.nan
    landing_alt_m: float = math.nan
    drift_km: float = math.nan
    bearing_deg: float = math.nan
    t_future_mean_h: float = math.nan
    ellipse: Ellipse | None = None
    """The paper's parametric ellipse of this descent alone (as ``predict`` gives it)."""
    sigma_major_km: float = math.nan
    sigma_minor_km: float = math.nan
    """1σ axes of the Gaussian that the zone and target numbers integrate over."""
    uncertainty: str = "parametric"
    zone_probability: float = math.nan
    worst_zone: str | None = None
    worst_zone_probability: float = math.nan
    members_in_zones: float | None = None
    """Ensemble only: the fraction of members whose landing is inside a zone (a check on the Gaussian)."""
    expected_target_km: float | None = None
    target_km_at_center: float | None = None
    go: bool = False
    reasons: tuple[str, ...] = ()
    member_lat: np.ndarray | None = field(default=None, repr=False)
    member_lon: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "index": self.index,
            "release": {
                "time": iso_z(self.release_time),
                "lat": _num(self.release_lat),
                "lon": _num(self.release_lon),
                "alt_m": _num(self.release_alt_m),
                "sigma_km": self.balloon_sigma_km,
            },
            "go": self.go,
            "reasons": list(self.reasons),
        }
        if self.status is not None:
            out["status"] = self.status
            return out
        assert self.landing_time is not None and self.ellipse is not None
        out.update(
            {
                "landing": {
                    "time": iso_z(self.landing_time),
                    "lat": self.landing_lat,
                    "lon": self.landing_lon,
                    "alt_m": self.landing_alt_m,
                },
                "drift_km": self.drift_km,
                "bearing_deg": self.bearing_deg,
                "t_future_mean_h": self.t_future_mean_h,
                "ellipse": self.ellipse.to_dict(),
                "uncertainty": {
                    "kind": self.uncertainty,
                    "sigma_major_km": self.sigma_major_km,
                    "sigma_minor_km": self.sigma_minor_km,
                },
                "zone_probability": self.zone_probability,
                "worst_zone": self.worst_zone,
                "worst_zone_probability": _num(self.worst_zone_probability),
                "members_in_zones": self.members_in_zones,
                "expected_target_km": self.expected_target_km,
                "target_km_at_center": self.target_km_at_center,
            }
        )
        return out


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class Window:
    """A run of consecutive go candidates; ``recommended`` is the best candidate inside it."""

    rank: int
    first: int
    last: int
    recommended: int
    score: float

    def to_dict(self, candidates: Sequence[Candidate]) -> dict[str, Any]:
        return {
            "rank": self.rank,
            "opens": iso_z(candidates[self.first].release_time),
            "closes": iso_z(candidates[self.last].release_time),
            "candidates": self.last - self.first + 1,
            "recommended": iso_z(candidates[self.recommended].release_time),
            "recommended_index": self.recommended,
            "score": self.score,
        }


@dataclass(frozen=True)
class ReleasePlan:
    balloon: BalloonPath
    candidates: tuple[Candidate, ...]
    windows: tuple[Window, ...]
    thresholds: Thresholds
    score_kind: str
    members: int
    weather_source: str
    is_demo: bool
    warnings: tuple[str, ...]
    zone_names: tuple[str, ...]
    target_names: tuple[str, ...]

    @property
    def go_count(self) -> int:
        return sum(c.go for c in self.candidates)

    @property
    def verdict(self) -> str:
        if not self.windows:
            return f"NO-GO: none of the {len(self.candidates)} candidate release times meets the thresholds"
        best = self.windows[0]
        return (
            f"GO: {self.go_count} of {len(self.candidates)} candidates meet the thresholds; "
            f"recommended release {iso_z(self.candidates[best.recommended].release_time)}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict,
            "go_candidates": self.go_count,
            "candidates_total": len(self.candidates),
            "windows": [w.to_dict(self.candidates) for w in self.windows],
            "thresholds": self.thresholds.to_dict(),
            "score": self.score_kind,
            "members": self.members,
            "weather": {"source": self.weather_source, "is_demo": self.is_demo},
            "is_demo": self.is_demo,
            "warnings": list(self.warnings),
            "zones": list(self.zone_names),
            "targets": list(self.target_names),
            "balloon": [
                {
                    "time": iso_z(_from_epoch(t)),
                    "lat": _num(la),
                    "lon": _num(lo),
                    "alt_m": _num(z),
                    "sigma_km": s,
                }
                for t, la, lo, z, s in zip(
                    self.balloon.t_s,
                    self.balloon.lat,
                    wrap_lon(self.balloon.lon),
                    self.balloon.alt_m,
                    self.balloon.sigma_km.tolist(),
                    strict=True,
                )
            ],
            "candidates": [c.to_dict() for c in self.candidates],
        }


def plan_release(
    cube: WeatherCube,
    release: Release,
    sweep: Sweep,
    setup: FlightSetup | None = None,
    spread: EnsembleSpread | None = None,
    criteria: Criteria | None = None,
) -> ReleasePlan:
    """Every candidate release of ``sweep`` from ``release``, judged by ``criteria``.

    With ``spread`` (and at least 3 members) each candidate also flies that many members, stepped at the
    sweep's member step. The central descents use the setup's step, so they are exactly what ``predict``
    gives.
    """
    setup = setup or FlightSetup()
    criteria = criteria or Criteria()
    zones, targets, thresholds = criteria.zones, criteria.targets, criteria.thresholds
    members = spread.members if spread is not None else 0
    step_m = setup.step_m
    if members != 0 and not (isinstance(members, int) and members >= 3):
        raise PredictorError(f"an ensemble needs at least 3 members (or 0 for none), got {members!r}")
    if thresholds.max_target_km is not None and not targets:
        raise PredictorError("a maximum target distance needs a targets file")
    member_step_m = 2.0 * step_m if sweep.member_step_m is None else sweep.member_step_m
    for name, value in (("altitude step", step_m), ("member altitude step", member_step_m)):
        if not (math.isfinite(value) and 0.1 <= value <= 2000.0):
            raise PredictorError(f"{name} must be between 0.1 and 2000 m, got {value!r}")
    balloon = balloon_path(cube, release, sweep, setup.time_tolerance_s)
    if members * balloon.t_s.size > MAX_MEMBER_DESCENTS:
        raise PredictorError(
            f"{balloon.t_s.size} candidates × {members} members is {members * balloon.t_s.size:,} member descents, "
            f"over the {MAX_MEMBER_DESCENTS:,} one sweep may run (memory grows with them): fewer members, "
            "a shorter sweep or a wider step"
        )
    base = setup.chain()
    starts = Starts(balloon.t_s.astype(float), balloon.lat, balloon.lon, balloon.alt_m)
    central = descend_batch(cube, base, starts, setup, with_lead=True)
    member_lat = member_lon = member_ok = None
    if spread is not None and members:
        member_lat, member_lon, member_ok = _ensemble(
            cube, base, balloon, spread, replace(setup, step_m=member_step_m), sweep.float_wind_sigma_ms
        )
    plane = LocalPlane(float(release.lat), float(release.lon))
    zone_xy = [plane.project(z.geometry) for z in zones]
    target_xy = [plane.project(t.geometry) for t in targets]
    candidates = _candidates(
        balloon, central, setup.error_model, plane, zone_xy, [z.name for z in zones], target_xy, thresholds,
        member_lat, member_lon, member_ok,
    )  # fmt: skip
    score_kind = (
        "expected distance to the nearest target, km" if targets else "probability of landing in a zone"
    )
    warnings = list(cube.warnings)
    if cube.is_demo:
        warnings.insert(
            0, "DEMO WEATHER: generated analytic atmosphere, not a forecast; do not use for operations"
        )
    if not zones:
        warnings.append("no exclusion zones given: every zone probability is 0")
    return ReleasePlan(
        balloon=balloon,
        candidates=tuple(candidates),
        windows=tuple(rank_windows(candidates, bool(targets))),
        thresholds=thresholds,
        score_kind=score_kind,
        members=members,
        weather_source=cube.source,
        is_demo=cube.is_demo,
        warnings=tuple(warnings),
        zone_names=tuple(z.name for z in zones),
        target_names=tuple(t.name for t in targets),
    )


def ensemble_draws(
    members: int, seed: int, rate_sigma: float, wind_sigma_ms: float, float_wind_sigma_ms: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(rate factor, descent wind east, north, float wind east, north) per member.

    The first three are drawn exactly as ``predict_ensemble`` draws them, so a candidate with no
    balloon drift gives the same members as a single ensemble prediction with the same seed.
    """
    rng = np.random.default_rng(seed)
    rate = np.exp(rng.normal(0.0, rate_sigma, members))
    d_east = rng.normal(0.0, wind_sigma_ms, members)
    d_north = rng.normal(0.0, wind_sigma_ms, members)
    f_east = rng.normal(0.0, float_wind_sigma_ms, members)
    f_north = rng.normal(0.0, float_wind_sigma_ms, members)
    return rate, d_east, d_north, f_east, f_north


def _ensemble(
    cube: WeatherCube,
    base: Model,
    balloon: BalloonPath,
    spread: EnsembleSpread,
    setup: FlightSetup,
    float_wind_sigma_ms: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Member landings, shape (candidates, members): each member releases from the balloon moved by its
    own float-wind error × time since the start, and descends with its own rate and wind errors."""
    n_c = balloon.t_s.size
    members = spread.members
    rate, d_east, d_north, f_east, f_north = ensemble_draws(
        members, spread.seed, spread.rate_sigma, spread.wind_sigma_ms, float_wind_sigma_ms
    )
    elapsed = balloon.t_s - balloon.t_s[0]
    lat0 = np.repeat(balloon.lat, members)
    lon0 = np.repeat(balloon.lon, members)
    dlat = np.empty(n_c)
    dlon = np.empty(n_c)
    for i in range(n_c):
        la = balloon.lat[i] if math.isfinite(balloon.lat[i]) else 0.0
        alt = balloon.alt_m[i] if math.isfinite(balloon.alt_m[i]) else 0.0
        dlat[i], dlon[i] = degrees_per_metre(la, alt)
    shift = np.repeat(elapsed, members)
    lat0 = lat0 + np.tile(f_north, n_c) * shift * np.repeat(dlat, members)
    lon0 = lon0 + np.tile(f_east, n_c) * shift * np.repeat(dlon, members)
    model = base.with_terms(
        DescentRateScale(scale=np.tile(rate, n_c)),
        WindOffset(east_ms=np.tile(d_east, n_c), north_ms=np.tile(d_north, n_c)),
    )
    starts = Starts(
        np.repeat(balloon.t_s, members).astype(float), lat0, lon0, np.repeat(balloon.alt_m, members)
    )
    land = descend_batch(cube, model, starts, setup)
    shape = (n_c, members)
    return land.lat.reshape(shape), land.lon.reshape(shape), (land.status == 0).reshape(shape)


def _from_epoch(s: float) -> datetime:
    return datetime(1970, 1, 1, tzinfo=UTC) + timedelta(seconds=float(s))


def _candidates(
    balloon: BalloonPath,
    central: BatchLandings,
    error_model: ErrorModel,
    plane: LocalPlane,
    zone_xy: list[BaseGeometry],
    zone_names: list[str],
    target_xy: list[BaseGeometry],
    thresholds: Thresholds,
    member_lat: np.ndarray | None,
    member_lon: np.ndarray | None,
    member_ok: np.ndarray | None,
) -> list[Candidate]:
    n_c = balloon.t_s.size
    ok = central.status == 0
    rows = np.flatnonzero(ok)
    rel_lon = wrap_lon(balloon.lon)
    stats: dict[int, dict[str, Any]] = {}
    centers = np.zeros((rows.size, 2))
    covs = np.zeros((rows.size, 2, 2))
    for j, row in enumerate(rows):
        i = int(row)
        azimuth, _, distance_m = GEOD.inv(rel_lon[i], balloon.lat[i], central.lon[i], central.lat[i])
        bearing = float(azimuth % 360.0)
        drift_km = float(distance_m / 1000.0)
        ellipse = parametric_ellipse(
            error_model, drift_km, float(central.t_future_mean_h[i]), bearing,
            float(central.lat[i]), float(central.lon[i]),
        )  # fmt: skip
        cov_en = ellipse_covariance(ellipse.sigma_parallel_km, ellipse.sigma_perpendicular_km, bearing)
        cov_en = cov_en + np.eye(2) * balloon.sigma_km[i] ** 2
        cx, cy = plane.to_xy(np.array([central.lon[i]]), np.array([central.lat[i]]))
        centers[j] = (cx[0], cy[0])
        cov = plane.covariance_in_plane(central.lon[i], central.lat[i], cov_en)[0]
        kind = "parametric + balloon drift"
        in_zone = None
        if member_lat is not None and member_lon is not None and member_ok is not None:
            good = member_ok[i]
            if good.sum() >= 3:
                mx, my = plane.to_xy(member_lon[i, good], member_lat[i, good])
                centers[j] = (mx.mean(), my.mean())
                cov = np.cov(np.stack([mx, my]))
                kind = f"ensemble ({int(good.sum())} members)"
                if zone_xy:
                    in_zone = float(np.mean(inside_any(zone_xy, mx, my)))
        covs[j] = cov
        eig = np.linalg.eigvalsh(cov)
        stats[i] = {
            "bearing": bearing,
            "drift": drift_km,
            "ellipse": ellipse,
            "kind": kind,
            "major": math.sqrt(max(eig[1], 0.0)),
            "minor": math.sqrt(max(eig[0], 0.0)),
            "in_zone": in_zone,
        }
    if zone_xy and rows.size:
        hits = zone_probabilities(zone_xy, centers, covs)
        any_zone, per_zone = hits.any_zone, hits.per_zone
    else:
        any_zone, per_zone = np.zeros(rows.size), np.zeros((rows.size, 0))
    expected: np.ndarray | None
    at_center: np.ndarray | None
    if target_xy and rows.size:
        expected = expected_distance_km(target_xy, centers, covs)
        at_center = distance_at_center_km(target_xy, centers)
    else:
        expected = at_center = None
    out = []
    for i in range(n_c):
        text = None
        if not ok[i]:
            text = STATUS_TEXT.get(int(central.status[i]), f"descent failed (status {central.status[i]})")
        release = Candidate(
            index=i,
            release_time=_from_epoch(balloon.t_s[i]),
            release_lat=float(balloon.lat[i]),
            release_lon=float(rel_lon[i]),
            release_alt_m=float(balloon.alt_m[i]),
            balloon_sigma_km=float(balloon.sigma_km[i]),
            status=text,
        )
        if text is not None:
            out.append(replace(release, go=False, reasons=(text,)))
            continue
        j = int(np.searchsorted(rows, i))
        s = stats[i]
        worst = int(np.argmax(per_zone[j])) if per_zone.shape[1] and per_zone[j].max() > 0.0 else -1
        reasons = []
        if any_zone[j] > thresholds.max_zone_probability:
            reasons.append(
                f"P(zone) {any_zone[j]:.3f} > {thresholds.max_zone_probability:g} "
                f"(mostly {zone_names[worst]})"
            )
        if (
            thresholds.max_target_km is not None
            and expected is not None
            and expected[j] > thresholds.max_target_km
        ):
            reasons.append(f"expected target distance {expected[j]:.1f} km > {thresholds.max_target_km:g} km")
        if thresholds.max_sigma_km is not None and s["major"] > thresholds.max_sigma_km:
            reasons.append(f"1σ {s['major']:.2f} km > {thresholds.max_sigma_km:g} km")
        out.append(
            replace(
                release,
                landing_time=_from_epoch(central.t_s[i]),
                landing_lat=float(central.lat[i]),
                landing_lon=float(central.lon[i]),
                landing_alt_m=float(central.alt_m[i]),
                drift_km=s["drift"],
                bearing_deg=s["bearing"],
                t_future_mean_h=float(central.t_future_mean_h[i]),
                ellipse=s["ellipse"],
                sigma_major_km=s["major"],
                sigma_minor_km=s["minor"],
                uncertainty=s["kind"],
                zone_probability=float(any_zone[j]),
                worst_zone=zone_names[worst] if worst >= 0 else None,
                worst_zone_probability=float(per_zone[j, worst]) if worst >= 0 else math.nan,
                members_in_zones=s["in_zone"],
                expected_target_km=None if expected is None else float(expected[j]),
                target_km_at_center=None if at_center is None else float(at_center[j]),
                go=not reasons,
                reasons=tuple(reasons),
                member_lat=None if member_lat is None else member_lat[i],
                member_lon=None if member_lon is None else member_lon[i],
            )
        )
    return out


SCORE_RESOLUTION = {"target": 0.1, "zone": 0.001}
"""Differences in the score below these (0.1 km of expected target distance, 0.1 % of zone probability)
are below what the Gaussian integration and the ensemble can resolve; within them the smaller ellipse wins."""


def rank_windows(candidates: Sequence[Candidate], by_target: bool) -> list[Window]:
    """Runs of consecutive go candidates, best first.

    A candidate's score is its expected target distance (with targets) or its zone probability;
    lower is better. A window's recommended time is its best-scoring candidate; among candidates whose
    scores agree to ``SCORE_RESOLUTION``, the one with the smallest 1σ ellipse (the landing is least
    uncertain there: without zones every score is 0, and the middle of a window was recommended even
    where its ellipse was 3× the start's), then the one nearest the window's middle, which leaves the
    most slack either side. Windows rank by that score, then by length (a longer window forgives a
    late decision).
    """
    resolution = SCORE_RESOLUTION["target" if by_target else "zone"]

    def score(c: Candidate) -> float:
        if by_target and c.expected_target_km is not None:
            return c.expected_target_km
        return c.zone_probability

    def preference(i: int, middle: float) -> tuple[float, float, float]:
        c = candidates[i]
        sigma = c.sigma_major_km if math.isfinite(c.sigma_major_km) else math.inf
        return (round(score(c) / resolution), round(sigma, 2), abs(i - middle))

    runs: list[tuple[int, int]] = []
    start = None
    for c in candidates:
        if c.go and start is None:
            start = c.index
        if not c.go and start is not None:
            runs.append((start, c.index - 1))
            start = None
    if start is not None:
        runs.append((start, candidates[-1].index))
    found = []
    for first, last in runs:
        middle = 0.5 * (first + last)
        best = min(range(first, last + 1), key=lambda i: preference(i, middle))
        found.append((score(candidates[best]), -(last - first), first, last, best))
    found.sort()
    return [
        Window(rank=r + 1, first=first, last=last, recommended=best, score=s)
        for r, (s, _, first, last, best) in enumerate(found)
    ]
