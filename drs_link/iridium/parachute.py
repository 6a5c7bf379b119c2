"""When to open the parachute release: the HH:MM the capsule will accept at the cycle that downloads it.

The firmware compares ``[PARACHUTE=HH:MM]`` with the GNSS fix minute of the cycle whose SBD
session downloads the MT (±14 min, drs_protocol.md 3.8) — not with the time the operator sends
it — and a rejected command is consumed and lost. So the capsule's next cycles are predicted from
its report history (the alarm grid of INTERVAL minutes as ``drs_link.iridium.interval`` says the
unit runs it, switch-over included, the fix-time jitter seen so far, the session delay), and the HH:MM is chosen, by checking every candidate against the firmware's own
test, to be accepted at every fix minute those cycles can have, for as many cycles as possible in
case a session fails and the MT comes down one cycle later.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

from drs_link.errors import RefusedError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.commands import (
    MINUTES_PER_DAY,
    PARACHUTE,
    PARACHUTE_REACH_MIN,
    PARACHUTE_WINDOW_MIN,
    parachute_accepted,
)
from drs_link.iridium.interval import IntervalTrack, interval_track, minutes_text
from drs_link.iridium.reports import StoredReport

EARLY_MARGIN = timedelta(seconds=30)
"""Slack before the earliest fix seen on the grid (the RTC alarm and GNSS warm-up are not exact)."""
LATE_MARGIN = timedelta(seconds=90)
"""Slack after the latest fix seen: one slow fix acquisition (the firmware tries for up to 2 min)."""
QUEUE_MARGIN = timedelta(seconds=60)
"""The MT must be at the gateway this long before the earliest predicted session."""
OPERATOR_MARGIN = timedelta(seconds=45)
"""Time an operator needs to read the plan and type the name and a reason: a cycle whose queue-before
falls sooner is left for the next one (the helper once offered "queue before … 5 s left", which the
check at submit then refused)."""
DEFAULT_SESSION_DELAY = timedelta(seconds=30)
WANTED_SLACK_MIN = 2
"""Minutes kept between the chosen HH:MM and the edge of the next cycle's window before more cycles
are covered: a fix earlier than any seen so far must not push the command out of the window."""
LONG_INTERVAL_MIN = 10
HISTORY = 12
MIDNIGHT_GUARD_MIN = PARACHUTE_WINDOW_MIN


class ParachuteRefused(RefusedError):
    """No PARACHUTE time can be chosen that the capsule would accept."""


@dataclass(frozen=True)
class CycleForecast:
    """One future cycle: ``offset`` cycles after the last report; its fix falls between the two times."""

    offset: int
    fix_earliest: datetime
    fix_latest: datetime

    def minutes_of_day(self) -> list[int]:
        """Every fix minute (hh·60+mm, what the firmware compares) the fix can fall in."""
        minutes, moment = [], self.fix_earliest.replace(second=0, microsecond=0)
        while moment <= self.fix_latest:
            minutes.append(moment.hour * 60 + moment.minute)
            moment += timedelta(minutes=1)
        return minutes


@dataclass(frozen=True)
class ParachutePlan:
    hour: int
    minute: int
    intervals: frozenset[int]
    """The INTERVAL(s) the capsule may run from the next cycle on (two while a change is unconfirmed)."""
    queue_by: datetime
    cycles: tuple[CycleForecast, ...]
    """The consecutive cycles, from the first that can download the MT, at which it is accepted."""
    accepted_window: str
    """The HH:MM range the first of those cycles accepts at every fix minute it can have."""
    warnings: tuple[str, ...]

    @property
    def interval_min(self) -> int:
        return max(self.intervals)

    @property
    def hhmm(self) -> str:
        return f"{self.hour:02d}:{self.minute:02d}"

    def window_text(self) -> str:
        first, last = self.cycles[0], self.cycles[-1]
        return (
            f"{PARACHUTE.encode((self.hour, self.minute))} queue before {self.queue_by:%H:%M:%S}Z; the next cycle's fix falls "
            f"{first.fix_earliest:%H:%M:%S}-{first.fix_latest:%H:%M:%S}Z and accepts {self.accepted_window}; "
            "still accepted if downloaded up to the cycle with its fix by "
            f"{last.fix_latest:%H:%M:%S}Z ({len(self.cycles)} cycle(s) of {minutes_text(self.intervals)})"
        )


def _residuals(reports: list[StoredReport], track: IntervalTrack) -> list[timedelta]:
    """How far each recent fix fell from the alarm grid through the last one, walking back while the
    spacing is known (a pending INTERVAL leaves it open); missed cycles keep the INTERVAL."""
    timed = [(r, r.report.fix.time) for r in reports if r.report is not None and r.report.fix is not None]
    fixed = timed[-HISTORY:]
    anchor = fixed[-1][1]
    residuals, grid = [timedelta(0)], timedelta(0)
    steps_back = zip(reversed(fixed[:-1]), reversed(fixed[1:]), strict=True)
    for (earlier, earlier_time), (_, later_time) in steps_back:
        spacing = track.after(earlier)
        if len(spacing) != 1:
            break
        step = timedelta(minutes=next(iter(spacing)))
        gap = later_time - earlier_time
        grid -= max(1, round(gap / step)) * step
        residuals.append(earlier_time - anchor - grid)
    return residuals


@functools.cache
def _accepted_at(g_minute: int) -> frozenset[int]:
    """Every PARACHUTE minute the firmware accepts when its fix minute is ``g_minute``."""
    return frozenset(p for p in range(MINUTES_PER_DAY) if parachute_accepted(p, g_minute))


def _accepted_in(cycle: CycleForecast) -> frozenset[int]:
    return frozenset.intersection(*(_accepted_at(g) for g in cycle.minutes_of_day()))


def _covered(p_minute: int, accepted_sets: list[frozenset[int]]) -> int:
    count = 0
    for accepted in accepted_sets:
        if p_minute not in accepted:
            break
        count += 1
    return count


def _slack(p_minute: int, cycle: CycleForecast) -> int:
    """Minutes to spare before the fix minute that is furthest from ``p_minute`` leaves its window."""
    return min(
        PARACHUTE_REACH_MIN - min(abs(p_minute - g), MINUTES_PER_DAY - abs(p_minute - g))
        for g in cycle.minutes_of_day()
    )


def plan_parachute(
    reports: list[StoredReport],
    now: datetime,
    commands: Sequence[lc.Command],
    requested: tuple[int, int] | None = None,
    accept_midnight: bool = False,
) -> ParachutePlan:
    """Choose (or check the operator's ``requested``) HH:MM for the next cycles; refuses when it cannot.

    ``commands`` are the capsule's MTs: the INTERVAL it runs comes from them and the reports, by the one
    rule of ``drs_link.iridium.interval``, whether the CLI or the console asks.
    """
    if not reports:
        raise ParachuteRefused("no reports from this capsule: its cycle times cannot be predicted")
    last = reports[-1]
    if last.report is None or last.report.fix is None:
        raise ParachuteRefused(
            "the last report had no GNSS fix (or was not a DRS report): a no-fix cycle ignores PARACHUTE "
            "(and the command is lost); "
            "wait for a report with a fix"
        )
    track = interval_track(reports, commands)
    if track.basis == "default":
        raise ParachuteRefused(
            "only one fix so far and no INTERVAL sent from this console: the next cycle cannot be predicted; "
            "wait for a second report"
        )
    first, then = track.next_spacing, track.flash_now
    anchor = last.report.fix.time
    residuals = _residuals(reports, track)
    early = min(min(residuals), timedelta(0)) - EARLY_MARGIN
    late = max(max(residuals), timedelta(0)) + LATE_MARGIN

    def alarm(k: int, latest: bool = False) -> datetime:
        """The k-th next alarm, earliest (or latest) over the INTERVALs the unit may run."""
        pick = max if latest else min
        return anchor + timedelta(minutes=pick(first) + (k - 1) * pick(then))

    delays = [
        r.delivery.transmit_utc - r.report.fix.time
        for r in reports[-HISTORY:]
        if r.delivery.transmit_utc is not None and r.report is not None and r.report.fix is not None
    ]
    session_delay = max(min(delays), timedelta(0)) if delays else DEFAULT_SESSION_DELAY
    first_offset = 1
    while alarm(first_offset) + early + session_delay - QUEUE_MARGIN < now + OPERATOR_MARGIN:
        first_offset += 1
    horizon = max(1, (2 * PARACHUTE_REACH_MIN + min(then)) // min(then) + 1)
    cycles = [
        CycleForecast(k, alarm(k) + early, alarm(k, latest=True) + late)
        for k in range(first_offset, first_offset + horizon)
    ]
    if len(cycles[0].minutes_of_day()) > 2 * PARACHUTE_REACH_MIN:
        raise ParachuteRefused(
            f"the next fix time cannot be predicted within {2 * PARACHUTE_REACH_MIN} min: no HH:MM is safe"
        )
    accepted_sets = [_accepted_in(cycle) for cycle in cycles]
    accepted = sorted(accepted_sets[0])
    candidates = [requested[0] * 60 + requested[1]] if requested is not None else accepted or [0]
    best = max(
        candidates,
        key=lambda p: (
            min(_slack(p, cycles[0]), WANTED_SLACK_MIN),
            _covered(p, accepted_sets),
            _slack(p, cycles[0]),
        ),
    )
    covered = _covered(best, accepted_sets)
    queue_by = cycles[0].fix_earliest + session_delay - QUEUE_MARGIN
    if covered == 0 or not accepted:
        window = _range_text(accepted) if accepted else "none"
        raise ParachuteRefused(
            f"{requested[0]:02d}:{requested[1]:02d} would be rejected at the next cycle (fix "
            f"{cycles[0].fix_earliest:%H:%M}-{cycles[0].fix_latest:%H:%M}Z accepts {window}) "
            "and the command lost"
            if requested is not None
            else "no HH:MM is accepted at every possible fix minute of the next cycle"
        )
    chosen = cycles[:covered]
    minutes = [best, *(g for cycle in chosen for g in cycle.minutes_of_day())]
    near_midnight = any(m < MIDNIGHT_GUARD_MIN or m >= MINUTES_PER_DAY - MIDNIGHT_GUARD_MIN for m in minutes)
    if near_midnight and not accept_midnight:
        raise ParachuteRefused(
            "the window is within 15 min of 00:00 UTC, where the firmware's rule is loose (23:46 matches "
            "00:14) and HH:MM is easily misread; wait until after 00:15Z or confirm the midnight wrap"
        )
    warnings = [
        "a PARACHUTE outside the window is downloaded, ignored and lost; nothing is ever acknowledged"
    ]
    if max(then) > LONG_INTERVAL_MIN or covered == 1:
        warnings.append(
            f"INTERVAL is {minutes_text(then)}: only {covered} cycle(s) accept {_hhmm(best)}; if that "
            "session fails the MT comes down later and is lost. Send [INTERVAL=2] first, or time the send"
        )
    if now - last.time > 3 * timedelta(minutes=max(first)):
        warnings.append(
            f"the last report is {int((now - last.time).total_seconds() // 60)} min old: cycles may have "
            "been missed; the prediction assumes the capsule is still on its grid"
        )
    if near_midnight:
        warnings.append("the window crosses midnight UTC (confirmed by the operator)")
    return ParachutePlan(
        hour=best // 60,
        minute=best % 60,
        intervals=then,
        queue_by=queue_by,
        cycles=tuple(chosen),
        accepted_window=_range_text(accepted),
        warnings=tuple(warnings),
    )


def _hhmm(minute: int) -> str:
    return f"{minute // 60:02d}:{minute % 60:02d}"


def _range_text(minutes: list[int]) -> str:
    """A minute set that may wrap midnight, as ``HH:MM-HH:MM``."""
    ordered = sorted(minutes)
    gaps = [(b - a, i) for i, (a, b) in enumerate(zip(ordered, ordered[1:], strict=False)) if b - a > 1]
    if gaps:
        _, index = gaps[0]
        ordered = ordered[index + 1 :] + ordered[: index + 1]
    return f"{_hhmm(ordered[0])}-{_hhmm(ordered[-1])}"
