"""The release-window sweep (when to drop, as a go/no-go timeline) as a typed value the screens show.

The prediction service answers with plain data (ISO times, a JSON-able dict, as ``drs plan`` writes
it); this reads it once, so the timeline widget never parses times back out of strings.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any


@dataclass(frozen=True)
class ReleaseCandidate:
    """One candidate release time and its verdict."""

    time: datetime
    go: bool
    landed: bool
    """False when the descent left the weather: no landing to judge."""
    reasons: tuple[str, ...]
    """Why it is no-go, in words."""


@dataclass(frozen=True)
class ReleaseWindow:
    computed_at: datetime
    every_minutes: float
    recommended: int | None
    """Index of the recommended candidate; None when no time is go."""
    candidates: tuple[ReleaseCandidate, ...]

    @classmethod
    def from_sweep(cls, sweep: Mapping[str, Any]) -> ReleaseWindow:
        """From ``PredictionService.release_window``'s answer."""
        return cls(
            computed_at=datetime.fromisoformat(sweep["computed_at"]),
            every_minutes=float(sweep["every_minutes"]),
            recommended=sweep["recommended"],
            candidates=tuple(
                ReleaseCandidate(datetime.fromisoformat(c["time"]), bool(c["go"]), bool(c["landed"]),
                                 tuple(c["reasons"]))
                for c in sweep["candidates"]
            ),
        )  # fmt: skip
