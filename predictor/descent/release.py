"""Where and when a flight starts, as an operator or a caller states it: one value for every entry.

``predict``, ``predict_ensemble``, ``plan_release``, ``balloon_path`` and the console's release origin all
start from the same four numbers (and predictions from two more), so they take one ``Release`` rather
than each its own list of arguments. The compiled engine's side is ``integrate.Starts``: one array per
field, one entry per trajectory, made from a ``Release`` after any drift before it.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime


@dataclass(frozen=True)
class Release:
    """A start: a time (timezone-aware), a position and an altitude above mean sea level."""

    time: datetime
    lat: float
    lon: float
    alt_m: float
    drift_minutes: float = 0.0
    """The balloon drifts at float this long before letting go (a prediction for a later release, from
    where the balloon is now)."""
    since_release_s: float = 0.0
    """A start mid-descent (a live report) this long after the real release, from which
    time-since-release terms keep counting."""
