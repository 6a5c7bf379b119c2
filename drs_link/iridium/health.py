"""What the reports say about the capsule's health (drs_protocol.md 6.2 item 6).

The unit reports no status of its own, so health is read from the pattern of reports: battery
against the firmware's own 6.5 V cut-off, the iteration counter (back to 0 = processor reset; a
jump = sessions that started but whose report never came), MOMSN continuity (a jump = reports
the gateway took that this receiver never got) and fix spacing against the INTERVAL the unit runs at
that cycle (``drs_link.iridium.interval``: commanded, confirmed, and switched over as the firmware
does, so a new INTERVAL is not called a missed cycle).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from drs_link.iridium import lifecycle as lc
from drs_link.iridium.interval import interval_track, minutes_text
from drs_link.iridium.reports import StoredReport

LOW_BATTERY_V = 6.5
SPACING_SLACK_S = 60.0


@dataclass(frozen=True)
class Finding:
    kind: str
    report_id: int
    message: str


@dataclass(frozen=True)
class Health:
    reports: int
    last_vbat: float | None
    last_report: datetime | None
    findings: tuple[Finding, ...]

    def kinds(self) -> list[str]:
        return [f.kind for f in self.findings]


MOMSN_MODULUS = 65536


def _momsn_findings(reports: Sequence[StoredReport]) -> list[Finding]:
    """Missing and repeated MOMSNs, judged in MOMSN order, not arrival order.

    Why MOMSN order: a report without a transmit time (an email attachment imported later) sorts by its
    import time, and the modem's counter read in that order jumped back by a few and was reported as
    65,534 missing reports. The counter wraps at 65536, so the sequence starts after the largest
    circular gap between the MOMSNs present: that gap is the part of the counter not yet used.
    """
    if len(reports) < 2:
        return []
    ordered = sorted(reports, key=lambda r: (r.delivery.momsn, r.id))
    momsns = [r.delivery.momsn for r in ordered]
    steps = [(b - a) % MOMSN_MODULUS for a, b in zip(momsns, momsns[1:] + momsns[:1], strict=True)]
    start = (max(range(len(steps)), key=steps.__getitem__) + 1) % len(ordered)
    sequence = ordered[start:] + ordered[:start]
    findings: list[Finding] = []
    for previous, stored in zip(sequence, sequence[1:], strict=False):
        gap = (stored.delivery.momsn - previous.delivery.momsn) % MOMSN_MODULUS
        if gap == 0:
            findings.append(
                Finding(
                    "momsn_repeat",
                    stored.id,
                    f"MOMSN {stored.delivery.momsn} repeated "
                    "with different content (wrap or a second modem on this IMEI)",
                )
            )
        elif gap > 1:
            findings.append(
                Finding(
                    "momsn_gap",
                    stored.id,
                    f"{gap - 1} report(s) missing before MOMSN "
                    f"{stored.delivery.momsn}: sent by the capsule, never received here",
                )
            )
    return findings


def assess(reports: list[StoredReport], commands: Sequence[lc.Command] = ()) -> Health:
    """Findings over reports in time order; ``commands`` are the capsule's MTs, for the INTERVAL it runs."""
    track = interval_track(reports, commands)
    findings: list[Finding] = []
    battery_low = False
    previous_ok: StoredReport | None = None
    findings.extend(_momsn_findings(reports))
    for stored in reports:
        report = stored.report
        if report is None:
            findings.append(
                Finding(
                    "rejected",
                    stored.id,
                    f"MOMSN {stored.delivery.momsn} is not a DRS report: {stored.parsed.reason}",
                )
            )
            continue
        if report.vbat < LOW_BATTERY_V and not battery_low:
            findings.append(
                Finding(
                    "low_battery",
                    stored.id,
                    f"battery {report.vbat:.2f} V is below the "
                    f"firmware's {LOW_BATTERY_V} V cut-off: the unit sleeps without reporting",
                )
            )
        battery_low = report.vbat < LOW_BATTERY_V
        if previous_ok is not None and previous_ok.report is not None:
            before = previous_ok.report
            if report.iteration < before.iteration:
                findings.append(
                    Finding(
                        "reset",
                        stored.id,
                        f"iteration went from {before.iteration} to "
                        f"{report.iteration}: the processor reset (PARACHUTE flag lost, flash "
                        "settings kept)",
                    )
                )
            elif report.iteration > before.iteration + 1:
                findings.append(
                    Finding(
                        "iteration_gap",
                        stored.id,
                        f"{report.iteration - before.iteration - 1} "
                        "cycle(s) started the modem without a report arriving",
                    )
                )
            if report.fix is not None and before.fix is not None:
                spacing = (report.fix.time - before.fix.time).total_seconds()
                allowed = track.after(previous_ok)
                interval = minutes_text(allowed)
                if spacing < min(allowed) * 60 - SPACING_SLACK_S:
                    findings.append(
                        Finding(
                            "spacing",
                            stored.id,
                            f"reports {spacing / 60:.1f} min apart, faster than the INTERVAL of {interval}",
                        )
                    )
                elif spacing > 1.5 * max(allowed) * 60 + SPACING_SLACK_S:
                    findings.append(
                        Finding(
                            "spacing",
                            stored.id,
                            f"reports {spacing / 60:.1f} min apart for an "
                            f"INTERVAL of {interval}: about {round(spacing / 60 / max(allowed)) - 1} "
                            "cycle(s) missed",
                        )
                    )
        previous_ok = stored
    last_ok = previous_ok.report if previous_ok is not None else None
    position = {stored.id: index for index, stored in enumerate(reports)}
    findings.sort(key=lambda finding: position[finding.report_id])  # stable: time order, as reported
    return Health(
        reports=len(reports),
        last_vbat=last_ok.vbat if last_ok is not None else None,
        last_report=reports[-1].time if reports else None,
        findings=tuple(findings),
    )
