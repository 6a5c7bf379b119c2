"""Where a recorded descent path meets the ground.

The integrator knows nothing of terrain: it steps every path down to below the lowest ground on
Earth, and the landing is found afterwards as the first recorded point at or under the terrain,
with the crossing interpolated linearly inside that step. ``predict`` and the release-window sweep
both land their paths here, so the same release lands in the same place whichever computed it;
what to do with a path that does not land (raise, or record a status) is the caller's choice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from predictor.environment import Terrain

HIGHEST_GROUND_M = 8900.0
"""No terrain is higher: points above it need no terrain lookup (most of a 30 km descent)."""
LOWEST_GROUND_M = -500.0
"""No terrain is lower (Dead Sea shore −430 m): paths are stepped down to here before the crossing is found."""


def wrap_lon(lon: np.ndarray | float) -> np.ndarray:
    return (np.asarray(lon, dtype=np.float64) + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class GroundCrossings:
    index: np.ndarray
    """Per path, the first recorded point at or under the ground (0 where there is none)."""
    found: np.ndarray
    """Per path, whether it reached the ground at all."""
    ground_m: np.ndarray
    """Terrain elevation under the point ``index`` (NaN where not found)."""
    fraction: np.ndarray
    """Where in the step from ``index - 1`` to ``index`` the path meets the ground (NaN unless
    found with ``index > 0``; a crossing at point 0 means the path started under the ground)."""

    @property
    def landed(self) -> np.ndarray:
        return self.found & (self.index > 0)

    def at(self, values: np.ndarray) -> np.ndarray:
        """A recorded quantity (lat, lon, z, t, path) interpolated at each crossing; NaN if none."""
        rows = np.flatnonzero(self.landed)
        k = self.index[rows]
        out = np.full(values.shape[0], np.nan)
        before, after = values[rows, k - 1], values[rows, k]
        out[rows] = before + self.fraction[rows] * (after - before)
        return out


def ground_crossings(
    lat: np.ndarray, lon: np.ndarray, z: np.ndarray, valid: np.ndarray, terrain: Terrain
) -> GroundCrossings:
    """First crossing of each path (rows of the (n, k) arrays; ``valid`` marks recorded points)."""
    low = valid & (z <= HIGHEST_GROUND_M)
    # The point before the first one under the ceiling brackets a crossing too.
    low[:, :-1] |= low[:, 1:]
    low &= valid
    ground = np.full(z.shape, -np.inf)
    if low.any():
        ground[low] = terrain.elevation(lat[low], wrap_lon(lon[low]))
    below = valid & (z <= ground)
    index = below.argmax(axis=1)
    found = np.asarray(below.any(axis=1))  # one flag per path; numpy's stubs allow a lone bool here
    rows = np.arange(z.shape[0])
    ground_m = np.where(found, ground[rows, index], np.nan)
    fraction = np.full(z.shape[0], np.nan)
    landed = np.flatnonzero(found & (index > 0))
    k = index[landed]
    above = z[landed, k - 1] - ground[landed, k - 1]
    under = z[landed, k] - ground[landed, k]
    fraction[landed] = above / (above - under)
    return GroundCrossings(index=index, found=found, ground_m=ground_m, fraction=fraction)
