"""Which report interval a capsule runs at each cycle, from the INTERVAL commands and the firmware's switch-over.

Health (is this spacing a missed cycle?), staleness (is the last report overdue?) and the PARACHUTE
planner (when is the next cycle?) all need this, and all take it from this one rule: a guess of their
own (the firmware default, the last *confirmed* command, the spacing seen) would, after ``[INTERVAL=5]``,
let one screen say "1 cycle missed" while another calls a 5-minute-old report stale.

The switch-over (drs_protocol.md 3.8, the ``[INTERVAL=n]`` row: "The alarm already armed keeps the
old spacing, so the new interval takes effect from the following cycle"; 3.5 "Reporting interval":
the alarm handler re-arms at alarm time + INTERVAL): the alarm is re-armed when it fires, at the start
of a cycle, before that cycle's SBD session downloads any MT. So an INTERVAL downloaded with report k
leaves the spacing k → k+1 at the old value; the new value spaces k+1 → k+2 and later. A failed
session downloads nothing, so the value holds across missed cycles.

What the console cannot know it does not guess: before any INTERVAL from this console the unit runs
whatever its flash holds (drs_protocol.md 7 item 2), read from the spacing seen (else the firmware
default, 2 min); a command whose effect is still pending leaves both the old and the new value
possible; one the reports did not show (rejected or not downloaded) changed nothing.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from drs_link.iridium import lifecycle as lc
from drs_link.iridium.commands import INTERVAL, PENDING, SEEN
from drs_link.iridium.reports import StoredReport

DEFAULT_INTERVAL_MIN = 2
"""The firmware's INTERVAL when its flash is initialised (drs_protocol.md 3.2)."""


def infer_interval_min(fix_times: Sequence[datetime]) -> int | None:
    """The reporting interval in whole minutes, from fix spacing on one interval grid.

    The median spacing is a first guess (missed slots are rarer than kept ones); dividing the whole
    span by the number of grid slots it holds then averages the fix-acquisition jitter away.
    """
    spacings = [(b - a).total_seconds() / 60 for a, b in zip(fix_times, fix_times[1:], strict=False)]
    spacings = [s for s in spacings if s > 0.5]
    if not spacings:
        return None
    guess = max(1, round(statistics.median(spacings)))
    span = (fix_times[-1] - fix_times[0]).total_seconds() / 60
    slots = max(1, round(span / guess))
    return max(1, round(span / slots))


@dataclass(frozen=True)
class IntervalTrack:
    """For each report (time order), the INTERVAL(s) that may space it from the next cycle."""

    spacing_after: dict[int, frozenset[int]]
    """By report id, minutes from its cycle to the next: what the flash held when its alarm fired."""
    last_report_id: int | None
    flash_now: frozenset[int]
    """What the flash may hold now, after the MT of the last report: the spacing from the next cycle on."""
    basis: str
    """``commanded`` (an INTERVAL from this console went down), ``spacing`` (read from the fixes) or
    ``default`` (fewer than two fixes and no command: the firmware default, a guess)."""

    def after(self, stored: StoredReport) -> frozenset[int]:
        """The INTERVAL(s) that may space ``stored`` from the cycle after it."""
        return self.spacing_after[stored.id]

    @property
    def next_spacing(self) -> frozenset[int]:
        """Minutes from the last report's cycle to the next one (the old value if it just downloaded one)."""
        return self.flash_now if self.last_report_id is None else self.spacing_after[self.last_report_id]

    def overdue_after(self, stored: StoredReport) -> int:
        """The longest spacing the report after ``stored`` may come at: staleness must not fire before it."""
        return max(self.after(stored))


def _interval_of(command: lc.Command) -> tuple[str, int] | None:
    for text in command.effects:
        minutes = INTERVAL.decode(text)
        if minutes is not None:
            return text, minutes
    return None


def _base(reports: Sequence[StoredReport], first_change: int) -> int | None:
    """The unit's own INTERVAL before this console changed it, from the spacing seen (None: too few fixes)."""
    fixes = [
        r.report.fix.time
        for r in reports[: first_change + 1]
        if r.report is not None and r.report.fix is not None
    ]
    return infer_interval_min(fixes)


def interval_track(reports: Sequence[StoredReport], commands: Sequence[lc.Command]) -> IntervalTrack:
    """Apply each delivered INTERVAL at its report with the switch-over rule (module docstring)."""
    index = {r.id: i for i, r in enumerate(reports)}
    changes: dict[int, list[tuple[lc.Command, str, int]]] = {}
    for command in sorted(commands, key=lambda c: (c.queued_utc or c.requested_utc, c.id)):
        interval = _interval_of(command)
        at = index.get(command.delivered_report_id) if command.delivered_report_id is not None else None
        if interval is not None and at is not None:
            changes.setdefault(at, []).append((command, *interval))
    first_change = min(changes, default=len(reports) - 1)
    base = _base(reports, first_change)
    flash = frozenset({base or DEFAULT_INTERVAL_MIN})
    spacing_after = {}
    for i, stored in enumerate(reports):
        spacing_after[stored.id] = flash
        for command, text, minutes in changes.get(i, []):
            effect = command.effects.get(text)
            if effect == SEEN:
                flash = frozenset({minutes})
            elif effect == PENDING:
                flash = flash | {minutes}
    basis = "commanded" if changes else "spacing" if base is not None else "default"
    return IntervalTrack(spacing_after, reports[-1].id if reports else None, flash, basis)


def minutes_text(minutes: frozenset[int]) -> str:
    """``5 min`` or, while a change is unconfirmed, ``2 or 5 min``."""
    return " or ".join(str(m) for m in sorted(minutes)) + " min"
