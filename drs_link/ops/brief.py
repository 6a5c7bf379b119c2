"""What an approver is shown before approving a hazardous command: the approver sees what they approve.

Why: a Go request once listed neither the waived go/no-go items nor the verdicts, and a PARACHUTE
request only its text (issue #29): the second operator approved a line, not the decision. The brief is
built by the operations layer when the request is made, from what the rules judged (the go/no-go poll
the ARM window was opened on, whose verdicts FIRE must still see; the landed evidence the gate read;
the override's reason), and stored with the request, so the approver's own process, which holds
neither the requester's waivers nor its reports, prints exactly that: `drs approve` and the console's
approvals screen both call ``Approval.for_approver``. Every text in it is shown through ``shown``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from drs_link.ops.typed_text import shown

if TYPE_CHECKING:  # the go/no-go loads shapely and numpy: `drs approve --help` must not
    from drs_link.ops.gonogo import GoNoGoReport, Waiver


@dataclass(frozen=True)
class VerdictShown:
    """One go/no-go item as it was judged: title, verdict (GO, NO-GO, WAIVED), detail."""

    title: str
    verdict: str
    detail: str


@dataclass(frozen=True)
class WaiverShown:
    """One waived item with its reason and its author."""

    item: str
    reason: str
    author: str


@dataclass(frozen=True)
class ApprovalBrief:
    command: str
    """The exact command: the MT text, the ARM window, the take-over and its reason."""
    verdicts: tuple[VerdictShown, ...] = ()
    waivers: tuple[WaiverShown, ...] = ()
    landed: str | None = None
    """PARACHUTE: the landed evidence the gate judged (its summary says UNVERIFIED when it is)."""
    override: str | None = None
    """PARACHUTE without landed evidence: the override's reason."""
    notes: tuple[str, ...] = field(default=())
    """Anything else the rule judged that the approver must read (say, the go/no-go poll was not kept)."""

    def lines(self) -> list[str]:
        """The brief as the approver reads it, one fact a line."""
        out = [f"  command: {shown(self.command)}"]
        if self.verdicts:
            out.append("  go/no-go:")
            out += [f"    {shown(v.verdict):7} {shown(v.title)}: {shown(v.detail)}" for v in self.verdicts]
        if self.waivers:
            out += [
                f"  waiver: {shown(w.item)} waived by {shown(w.author)}: {shown(w.reason)}"
                for w in self.waivers
            ]
        elif self.verdicts:
            out.append("  waivers: none")
        if self.override is not None:
            out.append(f"  OVERRIDE of the landed gate, reason: {shown(self.override)}")
        if self.landed is not None:
            out.append(f"  landed evidence: {shown(self.landed)}")
        out += [f"  note: {shown(note)}" for note in self.notes]
        return out

    def to_json(self) -> str:
        return json.dumps({
            "command": self.command,
            "verdicts": [[v.title, v.verdict, v.detail] for v in self.verdicts],
            "waivers": [[w.item, w.reason, w.author] for w in self.waivers],
            "landed": self.landed, "override": self.override, "notes": list(self.notes),
        })  # fmt: skip

    @classmethod
    def from_json(cls, text: str) -> ApprovalBrief:
        """A stored brief; one that cannot be read is shown as such, never trusted as empty."""
        try:
            raw: dict[str, Any] = json.loads(text)
            return cls(
                str(raw["command"]),
                tuple(VerdictShown(str(t), str(v), str(d)) for t, v, d in raw.get("verdicts", [])),
                tuple(WaiverShown(str(i), str(r), str(a)) for i, r, a in raw.get("waivers", [])),
                None if raw.get("landed") is None else str(raw["landed"]),
                None if raw.get("override") is None else str(raw["override"]),
                tuple(str(n) for n in raw.get("notes", [])),
            )
        except (ValueError, KeyError, TypeError):
            return cls("(the stored brief cannot be read: do not approve; ask for a new request)")


def go_brief(command: str, report_json: str | None) -> ApprovalBrief:
    """A Go request's brief: the command and the poll its ARM window was opened on (``report_json``)."""
    if report_json is None:
        return ApprovalBrief(command, notes=("the go/no-go poll of this ARM window was not kept",))
    parsed = ApprovalBrief.from_json(report_json)
    return ApprovalBrief(command, parsed.verdicts, parsed.waivers, notes=parsed.notes)


def report_json(report: GoNoGoReport, waivers: Sequence[Waiver]) -> str:
    """The poll ARM was granted on, with the waivers of its WAIVED items, as an ARM window keeps it."""
    waived = {item.key for item in report.items if item.verdict.value == "WAIVED"}
    return ApprovalBrief(
        f"ARM on {report.capsule}",
        tuple(VerdictShown(i.title, i.verdict.value, i.detail) for i in report.items),
        tuple(WaiverShown(w.item, w.reason, w.operator) for w in waivers if w.item in waived),
    ).to_json()
