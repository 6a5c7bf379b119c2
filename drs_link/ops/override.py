"""A PARACHUTE queued WITHOUT landed evidence stays loud until another PARACHUTE replaces it.

Why: an override of the landed gate (``authorize``) was audited once and then every screen called the
flight normal: the checklist ticked "Landing confirmed", Recovery said "probably delivered" at 18.9 km
and live re-prediction kept predicting a canopy landing after the parachute would go. What the
screens need is read here from the audit and the MT lifecycle, the same for every console on the
store: who overrode and who approved, and when the firmware will act.

The firmware (drs_protocol.md 3.8) downloads the MT at the first SBD session after it is queued and
accepts ``[PARACHUTE=hh:mm]`` only if that cycle's own fix minute is within ±14 min of hh:mm; then
release B opens at the end of that cycle (``zzz``) and the capsule falls the rest of the way without
its parachute. A cycle with no fix, or with a fix outside the window, drops the command for good.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

from drs_link.iridium import (
    DEFAULT_SESSION_DELAY,
    PARACHUTE,
    StoredReport,
    commanded as mt_commanded,
    commands as mt_commands,
    is_command,
    lifecycle as lc,
)
from drs_link.ops.typed_text import shown
from drs_link.store import AuditRecord

GONE_MODE_SPACING = timedelta(minutes=2)
"""The report spacing in Gone mode when the reports do not show it yet (drs_protocol.md 5.3)."""


@dataclass(frozen=True)
class ParachuteOverride:
    """The latest PARACHUTE of a capsule, authorised without landed evidence and possibly on its way."""

    capsule: str
    text: str
    overridden_by: str
    approved_by: str
    reason: str
    command: lc.Command

    def banner(self) -> str:
        return (
            f"{self.capsule}: PARACHUTE queued WITHOUT landed evidence "
            f"(override by {self.overridden_by}, approved by {self.approved_by})"
        )


def _approver(detail: dict[str, object]) -> str:
    """Who stood for the second operator, saying how much that is worth."""
    if detail.get("approved_by"):
        return str(detail["approved_by"])
    if detail.get("second_operator"):
        return f"{detail['second_operator']} (typed name)"
    if detail.get("single_operator_waiver"):
        return f"nobody: single-operator waiver “{detail['single_operator_waiver']}”"
    return "nobody"


def parachute_override(
    capsule: str, records: Sequence[AuditRecord], commands: Sequence[lc.Command]
) -> ParachuteOverride | None:
    """The override in force for ``capsule``: its latest authorised PARACHUTE overrode the landed gate and
    the MT that carried it may have reached the gateway (the newest command with that text)."""
    authorised = [
        r for r in records if r.capsule == capsule and r.action == "mt.parachute" and r.result == "authorised"
    ]
    if not authorised:
        return None
    latest = authorised[-1]
    detail = latest.detail or {}
    text = str(detail.get("text", ""))
    if not detail.get("override_landed") or not text:
        return None
    carried = [c for c in commands if c.text == text]
    command = max(carried, key=lambda c: c.id) if carried else None
    if command is None or command.state in mt_commanded.NEVER_LEFT:  # it never left: it cannot drop anything
        return None
    reason = shown(detail["override_landed"])
    return ParachuteOverride(
        capsule, shown(text), shown(latest.operator), shown(_approver(detail)), reason, command
    )


def _spacing(reports: Sequence[StoredReport]) -> timedelta:
    if len(reports) >= 2 and reports[-1].time > reports[-2].time:
        return reports[-1].time - reports[-2].time
    return GONE_MODE_SPACING


def drop_schedule(
    override: ParachuteOverride, reports: Sequence[StoredReport]
) -> tuple[datetime | None, str]:
    """When release B opens as the firmware does it, and the sentence that says so: the end of the cycle
    that downloads the MT, if that cycle's fix is inside the window; None when it will never open."""
    part = next((t for t in override.command.effects if is_command(t, PARACHUTE)), override.text)
    hour, minute = PARACHUTE.decode(part)
    reach = mt_commands.PARACHUTE_REACH_MIN
    by_id = {r.id: r for r in reports}
    delivered = by_id.get(override.command.delivered_report_id or -1)
    if delivered is not None:
        fix = delivered.report.fix if delivered.report is not None else None
        if fix is None:
            return None, "downloaded in a no-fix cycle, which ignores PARACHUTE: release B stays closed"
        if not mt_commands.parachute_accepted(hour * 60 + minute, fix.time.hour * 60 + fix.time.minute):
            outside = f"downloaded with the {fix.time:%H:%M}Z fix, outside ±{reach} min"
            return None, f"{outside}: rejected, release B closed"
        return fix.time, f"release B opened at the end of the {fix.time:%H:%M:%S}Z cycle (after its report)"
    if not reports:
        return None, f"no report yet: release B opens at the end of the first cycle within ±{reach} min"
    spacing = _spacing(reports)
    expected = reports[-1].time + spacing
    queued = override.command.queued_utc
    # The cycle that downloads it is the first whose session comes after it was queued, as the Iridium
    # helper plans it: a cycle that passed (or whose session failed) before the queue cannot take it.
    while queued is not None and expected + DEFAULT_SESSION_DELAY <= queued:
        expected += spacing
    latest = hour * 60 + minute + reach
    last_minute = f"{latest // 60 % 24:02d}:{latest % 60:02d}"
    if not mt_commands.parachute_accepted(hour * 60 + minute, expected.hour * 60 + expected.minute):
        return None, (
            f"the next cycle (expected {expected:%H:%M}Z) is outside ±{reach} min of "
            f"{hour:02d}:{minute:02d}: it will be rejected"
        )
    return expected, (
        f"scheduled drop at the end of the next cycle, expected {expected:%H:%M:%S}Z "
        f"(accepted until {last_minute}Z)"
    )


def after_drop(drop: datetime | None, landing_time: datetime | None) -> str:
    """What the descent becomes after the drop, against a canopy prediction that lands at ``landing_time``."""
    if drop is None:
        return "the canopy descent continues"
    if landing_time is not None and landing_time <= drop:
        return f"the canopy landing ({landing_time:%H:%M:%S}Z) comes before the drop"
    return (
        f"from {drop:%H:%M:%S}Z it falls WITHOUT its parachute: faster and nearer below the drop point "
        "than any canopy prediction shown; a canopy landing after that time will not happen"
    )
