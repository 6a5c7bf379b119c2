"""The go/no-go poll before ARM, computed from telemetry rather than from an operator's memory.

Each item states its value, its age and its verdict. Stale counts as NO-GO: a fix seen four
minutes ago says nothing about now. Only two items may be waived, and only with a logged reason
and operator (dropping without a fix, or with part of the data unsynced, are legitimate choices
the flown procedure allows, drs_protocol.md 5.2); the link, the microcontroller, the prediction
and the gateway cannot be waived.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from enum import StrEnum

from shapely.geometry import Polygon

from drs_link.errors import RefusedError
from drs_link.ops.staleness import Freshness, Reading, format_age
from drs_link.ops.typed_text import typed_text
from drs_link.store import Store, utc_now

WAIVABLE = ("gnss", "sync")


class Verdict(StrEnum):
    GO = "GO"
    NO_GO = "NO-GO"
    WAIVED = "WAIVED"
    RELEASED = "RELEASED"
    """The capsule has dropped: nothing can be armed again until it is recovered and reset."""
    NOT_APPLICABLE = "n/a"
    """A pre-release check that no longer applies (the link is down as expected, NMEA is history)."""


@dataclass(frozen=True)
class ExclusionZone:
    """Where a capsule must not land (a town, a lake, a border): a ring of (lon, lat) degrees."""

    name: str
    ring: tuple[tuple[float, float], ...]
    holes: tuple[tuple[tuple[float, float], ...], ...] = ()
    """Islands inside the ring that are not excluded (a GeoJSON polygon's inner rings)."""

    def polygon(self) -> Polygon:
        return Polygon(self.ring, self.holes)


@dataclass(frozen=True)
class PredictionCheck:
    """What go/no-go needs of a landing prediction: where, and the 2σ outline as (lon, lat)."""

    landing_lat: float
    landing_lon: float
    outline_2sigma: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class GoNoGoInputs:
    """Everything the poll looks at, each with its age."""

    link_up: Reading[bool]
    microcontroller_waiting: Reading[bool]
    gnss_fix: Reading[bool]
    sync_fraction: Reading[float]
    prediction: Reading[PredictionCheck]
    gateway_credentials: Reading[bool]
    powered: bool
    exclusion_zones: tuple[ExclusionZone, ...] = ()
    released: str | None = None
    """After Go: what the release record says ("released 12:03Z, Pi shut down"); None before."""
    prediction_pending: str | None = None
    """Why there is no prediction yet, when the console said ("no weather loaded: …"), for "no data"."""
    sync_pending: str | None = None
    """Why there is no sync fraction (no ``sync_source`` configured), for "no data"."""


@dataclass(frozen=True)
class Waiver:
    item: str
    operator: str
    reason: str
    at: datetime


@dataclass(frozen=True)
class GoNoGoItem:
    key: str
    title: str
    verdict: Verdict
    detail: str

    @property
    def blocking(self) -> bool:
        return self.verdict in (Verdict.NO_GO, Verdict.RELEASED)


@dataclass(frozen=True)
class GoNoGoReport:
    capsule: str
    items: tuple[GoNoGoItem, ...]
    fingerprint: str
    evaluated_at: datetime

    @property
    def go(self) -> bool:
        return all(not item.blocking for item in self.items)

    def blockers(self) -> list[GoNoGoItem]:
        return [item for item in self.items if item.blocking]

    def summary(self) -> str:
        if self.go:
            return "GO"
        return "NO-GO: " + "; ".join(f"{i.title}: {i.detail}" for i in self.blockers())


def _age(reading: Reading[object], now: datetime) -> str:
    age = reading.age_s(now)
    return "never received" if age is None else f"{format_age(age)} old (limit {format_age(reading.limit_s)})"


def _fresh_true(
    key: str, title: str, reading: Reading[bool], now: datetime, good: str, bad: str
) -> GoNoGoItem:
    state = reading.freshness(now)
    if state is Freshness.MISSING:
        return GoNoGoItem(key, title, Verdict.NO_GO, "no data")
    if state is Freshness.STALE:
        return GoNoGoItem(key, title, Verdict.NO_GO, f"STALE: {_age(reading, now)}")
    if reading.value:
        return GoNoGoItem(key, title, Verdict.GO, f"{good}, {_age(reading, now)}")
    return GoNoGoItem(key, title, Verdict.NO_GO, bad)


def _prediction_item(inputs: GoNoGoInputs, now: datetime) -> GoNoGoItem:
    reading = inputs.prediction
    base = _fresh_true("prediction", "Prediction fresh", Reading(
        reading.value is not None, reading.received_at, reading.expected_period_s, reading.tolerance
    ), now, "fresh", "none")  # fmt: skip
    if reading.value is None and inputs.prediction_pending:
        return GoNoGoItem("prediction", "Prediction fresh", Verdict.NO_GO, inputs.prediction_pending)
    if base.verdict is not Verdict.GO or reading.value is None:
        return base
    outline = reading.value.outline_2sigma
    if len(outline) < 4:
        return GoNoGoItem("prediction", "Prediction fresh", Verdict.NO_GO, "no 2σ ellipse in the prediction")
    ellipse = Polygon(outline)
    hits = [zone.name for zone in inputs.exclusion_zones if zone.polygon().intersects(ellipse)]
    if hits:
        return GoNoGoItem(
            "prediction",
            "Prediction fresh",
            Verdict.NO_GO,
            f"2σ ellipse touches exclusion zone {', '.join(hits)}",
        )
    zones = len(inputs.exclusion_zones)
    return GoNoGoItem(
        "prediction", "Prediction fresh", Verdict.GO, f"{base.detail}; 2σ ellipse clear of {zones} zone(s)"
    )


def _sync_item(reading: Reading[float], now: datetime, pending: str | None = None) -> GoNoGoItem:
    state = reading.freshness(now)
    if state is Freshness.MISSING or reading.value is None:
        return GoNoGoItem("sync", "Storage sync complete", Verdict.NO_GO, pending or "no data")
    if state is Freshness.STALE:
        return GoNoGoItem("sync", "Storage sync complete", Verdict.NO_GO, f"STALE: {_age(reading, now)}")
    if reading.value >= 1.0:
        return GoNoGoItem("sync", "Storage sync complete", Verdict.GO, f"100%, {_age(reading, now)}")
    return GoNoGoItem("sync", "Storage sync complete", Verdict.NO_GO, f"{reading.value * 100:.1f}% synced")


def evaluate(
    capsule: str, inputs: GoNoGoInputs, now: datetime, waivers: Sequence[Waiver] = ()
) -> GoNoGoReport:
    """The poll; a waived item is shown as WAIVED with who and why, never silently GO."""
    if inputs.released is not None:
        return _after_release(capsule, inputs.released, now)
    items = [
        _fresh_true("link", "SSH link up", inputs.link_up, now, "up", "link down"),
        GoNoGoItem(
            "power",
            "Power-on done",
            Verdict.GO if inputs.powered else Verdict.NO_GO,
            "relay latched in this session" if inputs.powered else "power-on has not succeeded",
        ),
        _fresh_true(
            "microcontroller",
            "Microcontroller talking",
            inputs.microcontroller_waiting,
            now,
            "NMEA arriving",
            "no NMEA since power-on",
        ),
        _fresh_true("gnss", "GNSS fix fresh", inputs.gnss_fix, now, "fix", "no fix"),
        _sync_item(inputs.sync_fraction, now, inputs.sync_pending),
        _prediction_item(inputs, now),
        _fresh_true(
            "gateway",
            "Gateway configured",
            inputs.gateway_credentials,
            now,
            "not verified",
            "invalid or missing",
        ),
    ]
    by_item = {waiver.item: waiver for waiver in waivers}
    for index, item in enumerate(items):
        waiver = by_item.get(item.key)
        if waiver is not None and item.blocking:
            items[index] = GoNoGoItem(
                item.key,
                item.title,
                Verdict.WAIVED,
                f"{item.detail}; waived by {waiver.operator}: {waiver.reason}",
            )
    return GoNoGoReport(capsule, tuple(items), _fingerprint(items), now)


PRE_RELEASE_CHECKS = (
    ("link", "SSH link up"), ("power", "Power-on done"), ("microcontroller", "Microcontroller talking"),
    ("gnss", "GNSS fix fresh"), ("sync", "Storage sync complete"), ("prediction", "Prediction fresh"),
    ("gateway", "Gateway configured"),
)  # fmt: skip


def _after_release(capsule: str, released: str, now: datetime) -> GoNoGoReport:
    """After Go the link is down as expected and the last NMEA is history: one line says so, and every
    pre-release check reads n/a instead of contradicting it ("Microcontroller talking ✔" with the Pi off)."""
    items = [GoNoGoItem("release", "Released", Verdict.RELEASED, released)]
    items += [GoNoGoItem(key, title, Verdict.NOT_APPLICABLE, "no longer applies after release")
              for key, title in PRE_RELEASE_CHECKS]  # fmt: skip
    return GoNoGoReport(capsule, tuple(items), _fingerprint(items), now)


def _fingerprint(items: Sequence[GoNoGoItem]) -> str:
    """Identity of the poll's verdicts: ARM remembers it, and any verdict changing disarms.

    Verdicts, not raw values: a landing that moves 200 m as the balloon drifts while its ellipse
    stays clear is not a change to the decision, but a waiver, a lost fix or a zone hit is.
    """
    verdicts = [(item.key, item.verdict.value) for item in items]
    return hashlib.sha256(json.dumps(verdicts).encode()).hexdigest()[:16]


WAIVER_REASON_MAX = 200
"""Characters of a waiver reason: a sentence fits, and the go/no-go and checklist stay on an 80×24 screen
(a 3,000-character reason pushed them off it). Longer accounts belong in the flight log."""


@dataclass
class WaiverBook:
    """The waivers of one capsule's current release attempt, each audited when granted."""

    store: Store
    capsule: str
    clock: Callable[[], datetime] = utc_now
    waivers: list[Waiver] = field(default_factory=list)

    def grant(self, item: str, operator: str, reason: str) -> Waiver:
        if item not in WAIVABLE:
            self.store.append_audit(
                operator or "unknown", self.capsule, "waiver", "refused", {"item": item}, when=self.clock()
            )
            raise RefusedError(f"{self.capsule}: {item!r} cannot be waived (only {', '.join(WAIVABLE)})")
        typed_text("the waiver reason", reason)
        if not operator.strip() or not reason.strip():
            raise RefusedError(f"{self.capsule}: a waiver needs the operator's name and a reason")
        if len(reason.strip()) > WAIVER_REASON_MAX:
            raise RefusedError(
                f"{self.capsule}: a waiver reason is at most {WAIVER_REASON_MAX} characters "
                f"({len(reason.strip())} given): one sentence; the rest belongs in the flight log"
            )
        waiver = Waiver(item, operator.strip(), reason.strip(), self.clock())
        self.store.append_audit(
            waiver.operator, self.capsule, "waiver", "granted", {"item": item, "reason": waiver.reason},
            when=waiver.at,
        )  # fmt: skip
        self.waivers = [w for w in self.waivers if w.item != item] + [waiver]
        return waiver

    def withdraw(self, item: str, operator: str) -> bool:
        """Drop the waiver of ``item`` (audited, with who withdrew it); False when none was held."""
        held = [w for w in self.waivers if w.item == item]
        if not held:
            return False
        self.waivers = [w for w in self.waivers if w.item != item]
        self.store.append_audit(operator or "unknown", self.capsule, "waiver", "withdrawn", {"item": item},
                                when=self.clock())  # fmt: skip
        return True

    def clear(self) -> None:
        self.waivers = []
