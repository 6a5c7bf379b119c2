"""Every value an operator sees carries its age, and says so in words when it is too old to trust.

A number without an age is how a stale GNSS fix or a frozen sync counter gets trusted on launch
day. So a value is kept with the time it was received and the period at which a fresh one is
expected; past ``period × tolerance`` (Yamcs' expiration tolerance) it is stale, and the text
shown for it says STALE, never only a colour (colour-blind operators, monochrome terminals).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from enum import StrEnum
from typing import Generic, TypeVar

T = TypeVar("T", covariant=True)
U = TypeVar("U")

DEFAULT_TOLERANCE = 2.0
STALE_GLYPH = "⌛"
MISSING_TEXT = "—"


class Freshness(StrEnum):
    FRESH = "fresh"
    STALE = "stale"
    MISSING = "missing"


def format_age(seconds: float) -> str:
    """A short, unambiguous age: 12s, 3m05s, 2h14m, 3d."""
    if seconds < 0:
        return "future"
    whole = int(seconds)
    if whole < 60:
        return f"{whole}s"
    if whole < 3600:
        return f"{whole // 60}m{whole % 60:02d}s"
    if whole < 86400:
        return f"{whole // 3600}h{whole % 3600 // 60:02d}m"
    return f"{whole // 86400}d"


@dataclass(frozen=True)
class Reading(Generic[T]):
    """One value, when it was received, and how often a fresh one should come."""

    value: T | None
    received_at: datetime | None
    expected_period_s: float
    tolerance: float = DEFAULT_TOLERANCE

    def __post_init__(self) -> None:
        if self.expected_period_s <= 0 or self.tolerance < 1.0:
            raise ValueError("a reading needs a positive expected period and a tolerance of at least 1")
        if self.received_at is not None and self.received_at.tzinfo is None:
            raise ValueError("naive datetime: reading times are UTC and must say so")

    @classmethod
    def missing(cls, expected_period_s: float, tolerance: float = DEFAULT_TOLERANCE) -> Reading[T]:
        return cls(None, None, expected_period_s, tolerance)

    def map(self, part: Callable[[T], U | None]) -> Reading[U]:
        """One part of the value, as old as the whole: go/no-go judges each part with its own age.

        A part that is None (a sample that has no such value) reads as missing, like a missing whole."""
        value = None if self.value is None else part(self.value)
        return Reading(value, self.received_at, self.expected_period_s, self.tolerance)

    @property
    def limit_s(self) -> float:
        return self.expected_period_s * self.tolerance

    def age_s(self, now: datetime) -> float | None:
        if self.received_at is None:
            return None
        return (now - self.received_at).total_seconds()

    def freshness(self, now: datetime) -> Freshness:
        age = self.age_s(now)
        if age is None or self.value is None:
            return Freshness.MISSING
        return Freshness.FRESH if age <= self.limit_s else Freshness.STALE

    def is_fresh(self, now: datetime) -> bool:
        return self.freshness(now) is Freshness.FRESH

    def label(self, now: datetime, render: Callable[[T], str] = str) -> str:
        """The value with its age; a stale one is marked with a glyph and the word STALE."""
        state = self.freshness(now)
        if state is Freshness.MISSING or self.value is None:
            return MISSING_TEXT
        age = self.age_s(now)
        text = f"{render(self.value)} ({format_age(age or 0.0)})"
        if state is Freshness.STALE:
            return f"{STALE_GLYPH}STALE {text}"
        return text
