"""The release-window sweep (when to drop, as a go/no-go timeline) as a typed value the screens show,
built by the prediction service from its plan (``PredictionService.release_window``)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime


@dataclass(frozen=True)
class ReleaseCandidate:
    """One candidate release time and its verdict."""

    time: datetime
    go: bool
    landed: bool
    """False when the descent left the weather: no landing to judge."""
    reasons: tuple[str, ...]
    """Why it is no-go, in words."""
    landing_time: datetime | None = None
    """When it would land (None when it left the weather)."""


@dataclass(frozen=True)
class ReleaseWindow:
    computed_at: datetime
    every_minutes: float
    recommended: int | None
    """Index of the recommended candidate; None when no time is go."""
    candidates: tuple[ReleaseCandidate, ...]
    model: str = ""
    """The law the sweep flew (the capsule's model, else the default profile): the verdicts depend on it."""
