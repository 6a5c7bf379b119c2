"""How sure a landing prediction is: the paper's empirical error ellipse and the ensemble's own.

The parametric model (Sirks et al. 2020) grows the along-track error with the release→landing
distance d and the mean forecast lead time ⟨t_future⟩ of the weather used:
σ∥² = σ0² + h·d² + k·⟨t_future⟩², σ⊥ = σ∥/q, the ellipse's long axis along the release→landing bearing.

Contour labels are TRUE 2-D coverages. For a bivariate normal the n-σ ellipse holds
1 − exp(−n²/2) of the probability (39.3 %, 86.5 %, 98.9 % for n = 1, 2, 3), not the 1-D 68/95/99 %
pyBalloon printed; a contour for probability p is drawn at n = sqrt(−2·ln(1 − p)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pyproj import Geod, Proj

from predictor.errors import PredictorError

GEOD = Geod(ellps="WGS84")
STANDARD_N_SIGMA = (1.0, 2.0, 3.0)


@dataclass(frozen=True)
class ErrorModel:
    """Parameters of σ∥² = σ0² + h·d² + k·⟨t_future⟩², σ⊥ = σ∥/q (σ in km, d in km, t in h)."""

    sigma0_km: float
    h: float
    k_km2_per_h2: float
    q: float
    name: str = "user"

    def __post_init__(self) -> None:
        values = (self.sigma0_km, self.h, self.k_km2_per_h2, self.q)
        if not all(math.isfinite(v) for v in values) or min(values[:3]) < 0.0 or self.q <= 0.0:
            raise PredictorError(
                f"error model {self.name!r}: sigma0, h and k must be ≥ 0 and q > 0, got {values}"
            )

    def sigmas_km(self, distance_km: float, t_future_h: float) -> tuple[float, float]:
        """(σ∥, σ⊥) in km for a descent of this release→landing distance and mean lead time."""
        parallel = math.sqrt(self.sigma0_km**2 + self.h * distance_km**2 + self.k_km2_per_h2 * t_future_h**2)
        return parallel, parallel / self.q

    def to_dict(self) -> dict[str, float | str]:
        return {
            "name": self.name,
            "sigma0_km": self.sigma0_km,
            "h": self.h,
            "k_km2_per_h2": self.k_km2_per_h2,
            "q": self.q,
        }


LAUNCH = ErrorModel(sigma0_km=1.77, h=3.1e-4, k_km2_per_h2=3.6e-3, q=1.14, name="launch")
"""The paper's fit for predictions made at launch (live weather)."""
HINDSIGHT = ErrorModel(sigma0_km=1.63, h=6.4e-4, k_km2_per_h2=3.3e-3, q=1.20, name="hindsight")
"""The paper's fit with hindsight (freshest weather)."""
ERROR_MODELS = {model.name: model for model in (LAUNCH, HINDSIGHT)}


def coverage(n_sigma: float) -> float:
    """Probability inside the n-σ ellipse of a bivariate normal."""
    return 1.0 - math.exp(-0.5 * n_sigma**2)


def n_sigma_for(probability: float) -> float:
    """The n whose n-σ ellipse holds the given probability of a bivariate normal."""
    if not 0.0 < probability < 1.0:
        raise PredictorError(f"a contour probability must be strictly between 0 and 1, got {probability!r}")
    return math.sqrt(-2.0 * math.log(1.0 - probability))


@dataclass(frozen=True)
class Contour:
    n_sigma: float
    probability: float
    semi_major_km: float
    semi_minor_km: float
    observed_fraction: float | None = None
    """For an ensemble: the fraction of members that really fell inside (None for the parametric model)."""

    def to_dict(self) -> dict[str, float]:
        out = {
            "n_sigma": round(self.n_sigma, 6),
            "probability": round(self.probability, 6),
            "semi_major_km": self.semi_major_km,
            "semi_minor_km": self.semi_minor_km,
        }
        if self.observed_fraction is not None:
            out["observed_fraction"] = self.observed_fraction
        return out


@dataclass(frozen=True)
class Ellipse:
    """A Gaussian landing ellipse: σ along and across a reference bearing, plus its principal axes."""

    center_lat: float
    center_lon: float
    sigma_parallel_km: float
    sigma_perpendicular_km: float
    bearing_deg: float
    """Reference bearing (release→landing), degrees clockwise from north."""
    sigma_major_km: float
    sigma_minor_km: float
    major_axis_bearing_deg: float
    contours: tuple[Contour, ...]
    kind: str

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": self.kind,
            "center": {"lat": self.center_lat, "lon": self.center_lon},
            "sigma_parallel_km": self.sigma_parallel_km,
            "sigma_perpendicular_km": self.sigma_perpendicular_km,
            "bearing_deg": self.bearing_deg,
            "major_axis_bearing_deg": self.major_axis_bearing_deg,
            "contours": [c.to_dict() for c in self.contours],
        }

    def outline(self, contour: Contour, points: int = 72) -> list[tuple[float, float]]:
        """Closed ring of (lon, lat) on the WGS84 ellipsoid, longitudes in [-180, 180)."""
        theta = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
        major = contour.semi_major_km * np.cos(theta)
        minor = contour.semi_minor_km * np.sin(theta)
        distance_m = np.hypot(major, minor) * 1000.0
        azimuth = self.major_axis_bearing_deg + np.degrees(np.arctan2(minor, major))
        lons, lats, _ = GEOD.fwd(
            np.full(points, self.center_lon), np.full(points, self.center_lat), azimuth, distance_m
        )
        ring = [(float((lo + 180.0) % 360.0 - 180.0), float(la)) for lo, la in zip(lons, lats, strict=True)]
        return [*ring, ring[0]]


def _contours(
    sigma_major: float, sigma_minor: float, probabilities: Sequence[float]
) -> list[tuple[float, float, float, float]]:
    levels = [(n, coverage(n)) for n in STANDARD_N_SIGMA]
    levels += [(n_sigma_for(p), float(p)) for p in probabilities]
    return [(n, p, n * sigma_major, n * sigma_minor) for n, p in levels]


def parametric_ellipse(
    model: ErrorModel,
    distance_km: float,
    t_future_h: float,
    bearing_deg: float,
    center_lat: float,
    center_lon: float,
    probabilities: Sequence[float] = (),
) -> Ellipse:
    parallel, perpendicular = model.sigmas_km(distance_km, t_future_h)
    major, minor = max(parallel, perpendicular), min(parallel, perpendicular)
    major_bearing = bearing_deg if parallel >= perpendicular else (bearing_deg + 90.0) % 360.0
    return Ellipse(
        center_lat=center_lat,
        center_lon=center_lon,
        sigma_parallel_km=parallel,
        sigma_perpendicular_km=perpendicular,
        bearing_deg=bearing_deg,
        sigma_major_km=major,
        sigma_minor_km=minor,
        major_axis_bearing_deg=major_bearing,
        contours=tuple(Contour(*c) for c in _contours(major, minor, probabilities)),
        kind=f"parametric ({model.name})",
    )


def empirical_ellipse(
    lats: np.ndarray, lons: np.ndarray, bearing_deg: float, probabilities: Sequence[float] = ()
) -> Ellipse:
    """The Gaussian fitted to member landings (mean and covariance), σ along/across the given bearing."""
    lats = np.asarray(lats, dtype=np.float64)
    lons = np.asarray(lons, dtype=np.float64)
    if lats.size < 3:
        raise PredictorError(f"an empirical ellipse needs at least 3 members, got {lats.size}")
    first = Proj(proj="aeqd", lat_0=float(lats[0]), lon_0=float(lons[0]), ellps="WGS84")
    x0, y0 = first(lons, lats)
    center_lon, center_lat = first(float(np.mean(x0)), float(np.mean(y0)), inverse=True)
    local = Proj(proj="aeqd", lat_0=center_lat, lon_0=center_lon, ellps="WGS84")
    x, y = local(lons, lats)
    xy = np.stack([x, y]) / 1000.0
    xy -= xy.mean(axis=1, keepdims=True)
    cov = np.cov(xy)
    b = math.radians(bearing_deg)
    along = np.array([math.sin(b), math.cos(b)])
    across = np.array([math.cos(b), -math.sin(b)])
    eigval, eigvec = np.linalg.eigh(cov)
    eigval = np.maximum(eigval, 0.0)
    major_vec = eigvec[:, 1]
    sigma_major, sigma_minor = math.sqrt(eigval[1]), math.sqrt(eigval[0])
    # Squared Mahalanobis distance of each member, to count how many really fall inside each contour.
    inv = np.linalg.pinv(cov)
    d2 = np.einsum("in,ij,jn->n", xy, inv, xy)
    contours = tuple(
        Contour(n, p, a, c, observed_fraction=float(np.mean(d2 <= n * n)))
        for n, p, a, c in _contours(sigma_major, sigma_minor, probabilities)
    )
    return Ellipse(
        center_lat=float(center_lat),
        center_lon=float((center_lon + 180.0) % 360.0 - 180.0),
        sigma_parallel_km=float(math.sqrt(max(along @ cov @ along, 0.0))),
        sigma_perpendicular_km=float(math.sqrt(max(across @ cov @ across, 0.0))),
        bearing_deg=bearing_deg,
        sigma_major_km=sigma_major,
        sigma_minor_km=sigma_minor,
        major_axis_bearing_deg=float(math.degrees(math.atan2(major_vec[0], major_vec[1])) % 180.0),
        contours=contours,
        kind="empirical (ensemble)",
    )
