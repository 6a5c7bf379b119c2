"""What the console knows of a capsule's sounder, report interval and parachute release, in operator words.

The unit reports none of these (drs_protocol.md 3.8: "Nothing in the MO reports servo or sounder
state, or the stored settings"), so a recovery team can only be told what was *commanded* last from
this console and how far that command got (the MT lifecycle), plus the one indirect sign the reports
carry: the spacing of fixes for INTERVAL. Everything else is said to be unconfirmable rather than
guessed. A command that never left (requested, refused, failed, not sent, flushed) changed nothing
on the unit and is passed over, so the latest one that may have gone down is what the unit runs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from drs_link.iridium import lifecycle as lc
from drs_link.iridium.commands import (
    INTERVAL,
    NOT_SEEN,
    PARACHUTE,
    PARACHUTE_REACH_MIN,
    SEEN,
    SOUNDER,
    MtCommand,
    is_command,
    parachute_accepted,
)
from drs_link.iridium.mo import Fix
from drs_link.iridium.reports import StoredReport

NEVER_LEFT = frozenset({lc.REQUESTED, lc.FAILED, lc.NOT_SENT, lc.FLUSHED})
"""States in which the MT never reached (or was deleted from) the gateway queue: no effect on the unit."""
DESCENT_CHANGE_MS = 3.0
"""A change of descent rate below this (or below half the rate before) is fix noise, not a hint."""


@dataclass(frozen=True)
class SettingStatus:
    """One setting: ``value`` short (ON, 5 min, PARACHUTE=14:05), ``detail`` how it is known and how well."""

    name: str
    value: str
    detail: str
    command_id: int | None = None

    @property
    def heading(self) -> str:
        return f"{self.name}: {self.value}"

    @property
    def line(self) -> str:
        return f"{self.heading} — {self.detail}"


@dataclass(frozen=True)
class CommandedSettings:
    sounder: SettingStatus
    interval: SettingStatus
    parachute: SettingStatus

    def statuses(self) -> tuple[SettingStatus, SettingStatus, SettingStatus]:
        return self.sounder, self.interval, self.parachute


def _hhmm(moment: datetime) -> str:
    return f"{moment:%H:%M}Z"


def _sent_at(command: lc.Command) -> datetime:
    return command.queued_utc or command.requested_utc


def _queue_key(command: lc.Command) -> tuple[datetime, int]:
    return _sent_at(command), command.id


def _live(commands: Sequence[lc.Command], kind: MtCommand) -> list[lc.Command]:
    """Commands carrying ``kind`` that may have reached the unit, in gateway queue order."""
    found = [c for c in commands if c.state not in NEVER_LEFT and any(is_command(t, kind) for t in c.effects)]
    return sorted(found, key=_queue_key)


def _part(command: lc.Command, kind: MtCommand) -> str:
    """The sub-command of this MT that sets one thing (an MT may carry several)."""
    return next(t for t in command.effects if is_command(t, kind))


def _progress(command: lc.Command, commands: Sequence[lc.Command], by_id: dict[int, StoredReport]) -> str:
    """How far the MT got, in the lifecycle's own terms and never further than it knows."""
    sent = _hhmm(_sent_at(command))
    if command.state == lc.CONFIRMED:
        return f"confirmed {sent}, the gateway's answer was never recorded: check the RockBLOCK portal"
    if command.state == lc.DELIVERY_UNKNOWN:
        return (
            f"sent {sent}, delivery unknown (no gateway answer): "
            "check the portal, resolve on the Iridium screen"
        )
    if command.delivered_report_id is None:
        if command.state == lc.TIMED_OUT:
            hours = lc.QUEUE_TIMEOUT.total_seconds() / 3600
            return f"queued {sent}, no report for {hours:g} h since: probably still queued at the gateway"
        return f"queued {sent}, not yet fetched"
    report = by_id.get(command.delivered_report_id)
    at = f"the {_hhmm(report.time)} report" if report is not None else f"report {command.delivered_report_id}"
    older_unknown = [
        str(c.id) for c in commands if c.state == lc.DELIVERY_UNKNOWN and _queue_key(c) < _queue_key(command)
    ]
    if older_unknown:
        ids = ", ".join(older_unknown)
        return f"probably delivered at {at} or later (MT {ids}, delivery unknown, may have gone first)"
    return f"probably delivered at {at}"


def _companion_evidence(command: lc.Command, kind: MtCommand) -> str:
    """What the other commands of the same MT showed: a change that showed proves the whole MT went down."""
    others = [effect for text, effect in command.effects.items() if not is_command(text, kind)]
    if SEEN in others:
        return "; the change sent with it showed, so it did go down"
    if NOT_SEEN in others:
        return "; the change sent with it never showed, so it may not have gone down"
    return ""


def _measured(reports: Sequence[StoredReport]) -> str:
    """The spacing of the last two adjacent reports with a fix (a no-fix report breaks a pair)."""
    for earlier, later in zip(reversed(reports[:-1]), reversed(reports[1:]), strict=True):
        a, b = earlier.report, later.report
        if a is not None and b is not None and a.fix is not None and b.fix is not None:
            return f"measured spacing {(b.fix.time - a.fix.time).total_seconds() / 60:.1f} min"
    return "spacing not measured yet (needs two adjacent reports with a fix)"


def sounder_status(commands: Sequence[lc.Command], by_id: dict[int, StoredReport]) -> SettingStatus:
    live = _live(commands, SOUNDER)
    if not live:
        return SettingStatus(
            "Sounder",
            "unknown",
            "never commanded from this console (the unit keeps its last setting in flash)",
        )

    def value(command: lc.Command) -> str:
        return "ON" if SOUNDER.decode(_part(command, SOUNDER)) else "OFF"

    latest = live[-1]
    detail = _progress(latest, commands, by_id)
    if latest.delivered_report_id is not None:
        detail += _companion_evidence(latest, SOUNDER) + "; cannot be confirmed by telemetry"
    else:
        delivered = [c for c in live[:-1] if c.delivered_report_id is not None]
        if delivered:
            detail += f"; until then {value(delivered[-1])}, {_progress(delivered[-1], commands, by_id)}"
    return SettingStatus("Sounder", value(latest), detail, latest.id)


def interval_status(
    commands: Sequence[lc.Command], reports: Sequence[StoredReport], by_id: dict[int, StoredReport]
) -> SettingStatus:
    measured = _measured(reports)
    live = _live(commands, INTERVAL)
    if not live:
        return SettingStatus("Interval", "unknown", f"never commanded from this console; {measured}")
    latest = live[-1]
    text = _part(latest, INTERVAL)
    value = f"{INTERVAL.decode(text)} min"
    effect = latest.effects[text]
    progress = _progress(latest, commands, by_id)
    if effect == SEEN:
        detail = f"commanded {_hhmm(_sent_at(latest))}, confirmed by the spacing of later reports; {measured}"
    elif effect == NOT_SEEN:
        detail = f"{progress}, but NOT seen in the spacing since: rejected, or not downloaded; {measured}"
    elif latest.delivered_report_id is not None:
        detail = f"{progress}; pending (takes effect from the cycle after next): {measured}"
    else:
        detail = f"{progress}; pending: {measured}"
    return SettingStatus("Interval", value, detail, latest.id)


def _descent_rate(a: Fix, b: Fix) -> float:
    seconds = (b.time - a.time).total_seconds()
    return (a.alt_m - b.alt_m) / seconds if seconds > 0 else 0.0


def _sea_level_rate(a: Fix, b: Fix) -> float:
    """The descent rate as it would be in sea-level air: a canopy falls at a speed ∝ 1/√ρ, so this stays
    the same all the way down, and only a change of what falls (a release, a landing) changes it. The
    raw rate halved from 18 km to 5 km under an intact canopy and was taken for a release."""
    from predictor.tracks import pressure_temperature

    pressure, temperature = pressure_temperature((a.alt_m + b.alt_m) / 2.0)
    p0, t0 = pressure_temperature(0.0)
    return _descent_rate(a, b) * math.sqrt(float((pressure / temperature) / (p0 / t0)))


def _descent_hint(reports: Sequence[StoredReport], delivered_report_id: int) -> str:
    """A large change of descent rate after the cycle that downloaded the MT: a release's only trace."""
    index = next((i for i, r in enumerate(reports) if r.id == delivered_report_id), None)
    if index is None:
        return ""
    fixes = [
        (i, r.report.fix) for i, r in enumerate(reports) if r.report is not None and r.report.fix is not None
    ]
    before = [fix for i, fix in fixes if i <= index][-2:]
    after = [fix for i, fix in fixes if i > index]
    if len(before) < 2 or not after:
        return ""
    old, old_at_sea_level = _descent_rate(*before), _sea_level_rate(*before)
    for a, b in zip([before[-1], *after], after, strict=False):
        new, at_sea_level = _descent_rate(a, b), _sea_level_rate(a, b)
        if abs(at_sea_level - old_at_sea_level) >= max(DESCENT_CHANGE_MS, 0.5 * abs(old_at_sea_level)):
            return (
                f"; hint only: the descent rate went from {old:.1f} to {new:.1f} m/s by the "
                f"{_hhmm(b.time)} fix (a release or a landing both do that)"
            )
    return ""


def _window_verdict(text: str, report: StoredReport | None) -> str:
    """When the report it went down with makes the firmware reject it for certain, say so: it was lost."""
    if report is None:
        return ""
    hour, minute = PARACHUTE.decode(text)
    fix = report.report.fix if report.report is not None else None
    if fix is None:
        return "; that report had no fix and a no-fix cycle ignores PARACHUTE: lost if it went down then"
    if not parachute_accepted(hour * 60 + minute, fix.time.hour * 60 + fix.time.minute):
        return (
            f"; the {_hhmm(fix.time)} fix is outside its ±{PARACHUTE_REACH_MIN} min window: "
            "rejected and lost if it went down then"
        )
    return ""


def parachute_status(
    commands: Sequence[lc.Command], reports: Sequence[StoredReport], by_id: dict[int, StoredReport]
) -> SettingStatus:
    live = _live(commands, PARACHUTE)
    if not live:
        return SettingStatus("Parachute", "none", "no release commanded from this console")
    latest = live[-1]
    text = _part(latest, PARACHUTE)
    detail = _progress(latest, commands, by_id)
    hint = ""
    if latest.delivered_report_id is not None:
        detail += _companion_evidence(latest, PARACHUTE)
        detail += _window_verdict(text, by_id.get(latest.delivered_report_id))
        hint = _descent_hint(reports, latest.delivered_report_id)
    detail += "; the release cannot be confirmed by telemetry" + hint
    return SettingStatus("Parachute", text.strip("[]"), detail, latest.id)


def commanded_settings(commands: Sequence[lc.Command], reports: Sequence[StoredReport]) -> CommandedSettings:
    """One capsule's commands (any order) and reports (time order) → what can be said of each setting."""
    by_id = {r.id: r for r in reports}
    return CommandedSettings(
        sounder=sounder_status(commands, by_id),
        interval=interval_status(commands, reports, by_id),
        parachute=parachute_status(commands, reports, by_id),
    )
