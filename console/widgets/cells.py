"""How one capsule's telemetry reads: a short form for a table cell and a long form in full words.

Both forms of a field live side by side here, so every screen words a value the same way and a
table cell and the detail pane can never disagree. Every form carries its age; a stale one starts
with ``STALE_GLYPH`` (the detail also says STALE), because colour alone is lost on colour-blind
operators and monochrome terminals. A form is plain text plus a level (ok, warn, bad, stale,
none); the colour of a level is the stylesheet's business (``level--*`` component classes).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Generic, Literal, TypeVar

from rich.cells import cell_len
from rich.text import Text
from textual.widget import Widget

from console.context import LOW_BANDWIDTH_AGE_STEP_S
from drs_link.feeds import FeedStatus
from drs_link.ops import (
    MISSING_TEXT,
    STALE_GLYPH,
    BalloonSample,
    CapsuleTelemetry,
    Freshness,
    GnssSample,
    LinkSample,
    PredictionSample,
    PredictionStatus,
    Reading,
    ReleaseSample,
    ReportSample,
    Sample,
    StorageSample,
    SyncSample,
    format_age,
)

Level = Literal["ok", "warn", "bad", "stale", "none"]
LEVEL_CLASSES = frozenset({"level--ok", "level--warn", "level--bad", "level--stale", "level--none"})
"""Component classes a widget declares to colour cells by level (styled in console.tcss)."""
AGE_WIDTH = 4
"""Widest short age ("59s", "23h", "999d", "-59m"); field widths budget for it."""
S = TypeVar("S", bound=Sample)


@dataclass(frozen=True)
class Cell:
    """Words that carry the whole meaning, and a level that only decides their colour."""

    text: str
    level: Level

    def styled(self, widget: Widget) -> Text:
        """The text coloured by the widget's ``level--*`` rule, so the theme decides the colour."""
        return Text(self.text, style=widget.get_component_rich_style(f"level--{self.level}", partial=True))


AGE_STEPS_S = ((600.0, 10.0), (3600.0, 60.0))
"""(from a minute up to this age, show it in steps of): an old age changes every 10 s, then each
minute; beyond an hour its format already counts minutes, below a minute the view time's own step
(``ConsoleContext.view_time``) sets the pace. Every change is a repainted row on an SSH link, and
one second more on an old reading tells nobody anything."""


def age_shown(seconds: float) -> float:
    """The age rounded down to its step (``AGE_STEPS_S``); under a minute, or negative (a wrong
    clock), as it is."""
    if seconds < 60.0:
        return seconds
    for below, step in AGE_STEPS_S:
        if seconds < below:
            return seconds - seconds % step
    return seconds


def reading_age(reading: Reading[Any], view_time: datetime) -> float:
    """The age shown at the view time, which trails the clock by up to one step (``ConsoleContext.view_time``,
    at most ``LOW_BANDWIDTH_AGE_STEP_S``). A reading taken since the last step is newer than the view, not
    from the future: it is 0 s old. Only a time further ahead than a whole step means a wrong clock (the fleet showed "-2s" and "timestamped in the future" on every fresh reading of a
    warm demo, issue #32)."""
    age = reading.age_s(view_time) or 0.0
    return max(age, 0.0) if age > -LOW_BANDWIDTH_AGE_STEP_S else age


def short_age(seconds: float) -> str:
    """The age in its largest whole unit, at most four characters where a cell has little room."""
    sign = "-" if seconds < 0 else ""
    whole = int(abs(age_shown(seconds)))
    for unit, size in (("d", 86400), ("h", 3600), ("m", 60)):
        if whole >= size:
            return f"{sign}{whole // size}{unit}"
    return f"{sign}{whole}s"


def long_age(seconds: float) -> str:
    """The age in words; a negative one means a clock is wrong, which the operator should hear about."""
    return (
        f"{format_age(age_shown(seconds))} ago" if seconds >= 0 else "timestamped in the future (clock skew?)"
    )


def _compact(x: float) -> str:
    """At most three characters for 0–999: one decimal below 10 (after rounding), whole above."""
    return f"{x:.1f}" if round(x, 1) < 10 else f"{x:.0f}"


def _gb(n: float) -> str:
    gb = n / 1e9
    return f"{_compact(gb)}G" if round(gb) < 1000 else f"{_compact(gb / 1000)}T"


def _bytes(n: float) -> str:
    for unit, size, digits in (("GB", 1e9, 1), ("MB", 1e6, 1), ("kB", 1e3, 0)):
        if n >= size:
            return f"{n / size:.{digits}f} {unit}"
    return f"{n:.0f} B"


def _km(metres: float) -> str:
    return f"{_compact(metres / 1000)}km"


# Link -------------------------------------------------------------------------------------------


def _link_short(v: LinkSample) -> str:
    return "UP" if v.up else "DOWN"


def _link_long(v: LinkSample) -> str:
    words = "up" if v.up else "down"
    return f"{words} ({v.note})" if v.note else words


def _link_level(v: LinkSample) -> Level:
    return "ok" if v.up else "bad"


# Release ----------------------------------------------------------------------------------------

_RELEASE_SHORT = {
    "idle": "IDLE",
    "power-on-unknown": "PWR ?",
    "go-sent-unverified": "GO SENT?",
    "released": "RELEASED",
}
_RELEASE_LONG = {
    "idle": "idle, not powered",
    "go-sent-unverified": "Go sent, release not yet confirmed",
    "released": "released",
}


def _release_short(v: ReleaseSample) -> str:
    if v.powered:
        return "PWR NMEA" if v.nmea_seen else "PWR noNMEA"
    return _RELEASE_SHORT.get(v.state, v.state.upper()[:10])


def _release_long(v: ReleaseSample) -> str:
    if v.powered:
        if v.nmea_seen:
            return "powered, NMEA arriving from the microcontroller"
        return "powered, no NMEA from the microcontroller yet"
    return v.note or _RELEASE_LONG.get(v.state, f"state {v.state!r}")


def _release_level(v: ReleaseSample) -> Level:
    return "ok" if v.state in ("idle", "released") else "warn"


# GNSS -------------------------------------------------------------------------------------------


def _hdop_short(hdop: float | None) -> str:
    return "" if hdop is None else f" H{_compact(min(hdop, 99))}"


def _gnss_short(v: GnssSample) -> str:
    sv = f"{v.sats}sv" if v.sats is not None else "?sv"
    if v.has_fix:
        return sv + _hdop_short(v.hdop)
    return f"NOFIX {sv}"


def _gnss_long(v: GnssSample) -> str:
    words = [v.quality or ("fix" if v.has_fix else "no fix")]
    words.append(f"{v.sats} satellites" if v.sats is not None else "satellites unknown")
    if v.hdop is not None:
        words.append(f"HDOP {v.hdop:.1f}")
    if v.has_fix and v.lat is not None and v.lon is not None:
        where = f"{v.lat:.4f} {v.lon:.4f}"
        if v.alt_m is not None:
            where += f" {v.alt_m / 1000:.1f} km"
        words.append(where)
    if v.fix_age_s is not None:
        words.append(f"fix {format_age(v.fix_age_s)} old")
    return ", ".join(words)


def _gnss_level(v: GnssSample) -> Level:
    return "ok" if v.has_fix else "bad"


# Storage ----------------------------------------------------------------------------------------


def _storage_short(v: StorageSample) -> str:
    free = v.free_bytes
    space = _gb(free) if free is not None else "?"
    if v.raid == "healthy":
        return f"{space} free"
    return f"RAID{'!' if v.raid in ('degraded', 'inactive') else '?'} {space}"


def _storage_long(v: StorageSample) -> str:
    free = v.free_bytes
    raid = f"RAID {v.raid or 'unknown'}"
    if free is None or v.used_bytes is None or v.total_bytes is None:
        return f"usage unknown, {raid}"
    return f"{v.used_bytes / 1e9:.1f} of {v.total_bytes / 1e9:.0f} GB used, {free / 1e9:.0f} GB free, {raid}"


def _storage_level(v: StorageSample) -> Level:
    return "ok" if v.raid == "healthy" else "bad"


# Sync -------------------------------------------------------------------------------------------


def _percent(fraction: float) -> str:
    """Whole percent, rounded down: 99.9% synced must not read as 100%."""
    return f"{int(min(max(fraction, 0.0), 1.0) * 100)}%"


def _sync_short(v: SyncSample) -> str:
    return "?%" if v.fraction is None else _percent(v.fraction)


def _sync_long(v: SyncSample) -> str:
    if v.fraction is None:
        return "progress unknown"
    if v.fraction >= 1.0 and not v.bytes_pending:
        return "complete, nothing pending"
    files = v.files_pending
    in_files = f" in {files} file{'s' if files != 1 else ''}" if files else ""
    return f"{_percent(v.fraction)} synced, {_bytes(v.bytes_pending)}{in_files} pending"


def _sync_level(v: SyncSample) -> Level:
    return "ok" if v.fraction is not None and v.fraction >= 1.0 else "warn"


# Battery and last Iridium report ----------------------------------------------------------------


def _report_short(v: ReportSample) -> str:
    volts = f"{v.vbat:.1f}V" if v.vbat is not None else "?V"
    if v.landed:
        return f"{volts} landed"
    return f"{volts} {_km(v.alt_m) if v.alt_m is not None else 'nofix'}"


def _report_long(v: ReportSample) -> str:
    words = [f"{v.vbat:.2f} V" if v.vbat is not None else "battery unknown"]
    words.append(f"{v.alt_m / 1000:.1f} km" if v.alt_m is not None else "no GNSS fix")
    if v.landed:
        words.append("landed")
    if v.lat is not None and v.lon is not None:
        where = f"at {v.lat:.4f} {v.lon:.4f}"
        if v.uncertainty_m is not None:
            where += f" ±{v.uncertainty_m:.0f} m"
        if v.position_source:
            where += f" ({v.position_source})"
        words.append(where)
    if v.momsn is not None:
        words.append(f"MO #{v.momsn}")
    if v.interval_min:
        words.append(f"every {v.interval_min} min")
    return ", ".join(words)


def _report_level(v: ReportSample) -> Level:
    return "bad" if v.vbat is not None and v.vbat < 6.5 else "ok"


# Prediction -------------------------------------------------------------------------------------


def _prediction_short(v: PredictionSample) -> str:
    sigma = max(v.sigma_par_km, v.sigma_perp_km)
    return f"{min(v.distance_km, 999):.0f}km σ{_compact(min(sigma, 999))}"


def _prediction_long(v: PredictionSample) -> str:
    where = (
        f"landing {v.landing_lat:.3f}, {v.landing_lon:.3f}, {v.distance_km:.1f} km at {v.bearing_deg:.0f}°"
    )
    origin = f"; position from {v.origin_source}" if v.origin_source else ""
    model = f"; model {v.model}" if v.model else ""
    return f"{where} from release, σ∥ {v.sigma_par_km:.2f} σ⊥ {v.sigma_perp_km:.2f} km{origin}{model}"


def _always_ok(v: PredictionSample) -> Level:
    """A prediction has no good or bad value of its own: only its age matters here."""
    return "ok"


# The table of fields ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Field(Generic[S]):
    """One kind of telemetry as a column title, a detail label, and its short and long wording."""

    sample: type[S]
    title: str
    label: str
    short_width: int
    """Widest short text without glyph or age (cells are fixed-width so a growing age never crops)."""
    short: Callable[[S], str]
    long: Callable[[S], str]
    level: Callable[[S], Level]
    pending_status: bool = False
    """Whether a ``PredictionStatus`` says what the console is doing about a value it has never had."""
    after_release: Literal["live", "history", "final"] = "live"
    """What Go makes of the value: ``history`` for what the Pi sent (it shuts down at Go, so a link
    down and old NMEA are what Go leaves: shown plainly, no alarm colour, no STALE); ``final`` for
    the release record (nothing polls or changes it until a reset: it never goes stale)."""

    @property
    def kind(self) -> str:
        """The kind's name in recordings, also the column's key."""
        return self.sample.KIND

    @property
    def width(self) -> int:
        """Cells a column needs: the widest stale short form, or the title if that is wider."""
        return max(cell_len(self.title), cell_len(STALE_GLYPH) + self.short_width + 1 + AGE_WIDTH)

    def _described(self, value: S, form: Callable[[S], str]) -> tuple[str, str, Level]:
        """(text, error, level): telemetry of the wrong shape is named, never a crash of the view."""
        try:
            return form(value), "", self.level(value)
        except (TypeError, ValueError, KeyError, AttributeError) as exc:
            return "", f"unreadable {self.kind} data ({type(exc).__name__}: {exc})", "bad"

    def pending(self, t: CapsuleTelemetry, form: Literal["text", "short"] = "text") -> str | None:
        """What the console is doing about a value it has never had, if it said; ``form`` is ``text``
        (words) or ``short`` (a table cell)."""
        status = t.reading(PredictionStatus).value if self.pending_status else None
        if status is None:
            return None
        return (status.short if form == "short" else status.text) or None

    def cell(self, t: CapsuleTelemetry, now: datetime) -> Cell:
        """The short form for a table cell: value and age, glyph first when stale, "—" when missing."""
        reading = t.reading(self.sample)
        state = reading.freshness(now)
        if state is Freshness.MISSING or reading.value is None:
            return Cell(self.pending(t, "short") or MISSING_TEXT, "none")
        text, error, level = self._described(reading.value, self.short)
        text = f"{text or 'BAD DATA'} {short_age(reading_age(reading, now))}"
        if t.released and self.after_release != "live":
            return Cell(text, "bad" if error else "none" if self.after_release == "history" else level)
        if state is Freshness.STALE:
            return Cell(f"{STALE_GLYPH}{text}", "bad" if error else "stale")
        return Cell(text, "bad" if error else level)

    def line(self, t: CapsuleTelemetry, now: datetime) -> Cell:
        """The long form for the detail pane: every part in words, its age, and STALE in words."""
        reading = t.reading(self.sample)
        state = reading.freshness(now)
        if state is Freshness.MISSING or reading.value is None:
            return Cell(f"{MISSING_TEXT} {self.pending(t) or 'nothing received yet'}", "none")
        text, error, level = self._described(reading.value, self.long)
        age = long_age(reading_age(reading, now))
        if t.released and self.after_release == "history":
            return Cell(
                f"{error or text} — {age}; history: the Pi shut down at Go", "bad" if error else "none"
            )
        if t.released and self.after_release == "final":
            return Cell(f"{error or text} — {age}", "bad" if error else level)
        if state is Freshness.STALE:
            return Cell(f"{error or text} — {STALE_GLYPH}STALE {age}", "bad" if error else "stale")
        return Cell(f"{error or text} — {age}", "bad" if error else level)


FIELDS: tuple[Field[Any], ...] = (
    Field(LinkSample, "Link", "Link", 4, _link_short, _link_long, _link_level, after_release="history"),
    Field(
        ReleaseSample,
        "Release",
        "Release",
        10,
        _release_short,
        _release_long,
        _release_level,
        after_release="final",
    ),  # fmt: skip
    Field(GnssSample, "GNSS", "GNSS", 10, _gnss_short, _gnss_long, _gnss_level, after_release="history"),
    Field(
        StorageSample,
        "Storage",
        "Storage",
        10,
        _storage_short,
        _storage_long,
        _storage_level,
        after_release="history",
    ),
    Field(SyncSample, "Sync", "Sync", 4, _sync_short, _sync_long, _sync_level, after_release="history"),
    Field(ReportSample, "Battery/last MO", "Battery/MO", 12, _report_short, _report_long, _report_level),
    Field(
        PredictionSample,
        "Prediction",
        "Prediction",
        10,
        _prediction_short,
        _prediction_long,
        _always_ok,
        pending_status=True,
    ),  # fmt: skip
)
"""Every field of a capsule, in the fleet table's priority order (the first ones stay at 80 columns)."""


def balloon_lines(reading: Reading[BalloonSample], feed: FeedStatus | None, now: datetime) -> list[str]:
    """The balloon's position with its age and source, then the feed's health when one is configured.

    A feed that rejects lines or cannot connect says so here, in words, so nobody trusts a silent gap.
    """

    def position(v: BalloonSample) -> str:
        via = f" ({v.format} via {v.source})" if v.source else ""
        return f"{v.lat:.4f}, {v.lon:.4f} at {v.alt_m / 1000:.1f} km{via}"

    lines = ["Balloon: " + reading.label(now, position)]
    if feed is None:
        if reading.value is None:
            lines[0] += " (no [balloon_feed] configured: predictions wait for a capsule's own GNSS)"
        return lines
    health = f"Feed {feed.source} {feed.state}: {feed.accepted} fixes"
    if feed.rejected:
        health += f", {feed.rejected} rejected (last: {feed.last_rejection})"
    if feed.out_of_order:
        health += f", {feed.out_of_order} out of order"
    if feed.last_error:
        health += f"; {feed.last_error}"
    return [*lines, health]
