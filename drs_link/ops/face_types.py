"""The values and catalogue the faces show and compose, handed on from the rooms behind the operations layer.

Why: the console and the ``drs`` commands import ``drs_link.ops`` and nothing below it (#22, the wall), yet
an operator composes an MT from the catalogue, reads a command's state and a report's time. These are
values, not actions: every action on them (send, plan, resolve, store) is a method of ``Operations``.
"""

from drs_link.iridium import (
    CATALOGUE,
    FLUSH_WARNING,
    LISTED,
    PARACHUTE,
    Command,
    Hazard,
    LandedEvidence,
    MtCommand,
    MtComposer,
    MtMessage,
    ParachutePlan,
    StoredReport,
    by_name,
    parse_hhmm,
)
from drs_link.iridium import lifecycle as lc
from drs_link.store import iso_utc

QUEUED = lc.QUEUED
"""An MT the gateway accepted: what ``drs mt send`` exits 0 on."""
RETRY_WARNING = lc.RETRY_WARNING
"""What a face prints before sending the text of a command whose delivery is still unknown."""

__all__ = [
    "CATALOGUE",
    "FLUSH_WARNING",
    "LISTED",
    "PARACHUTE",
    "QUEUED",
    "RETRY_WARNING",
    "Command",
    "Hazard",
    "LandedEvidence",
    "MtCommand",
    "MtComposer",
    "MtMessage",
    "ParachutePlan",
    "StoredReport",
    "by_name",
    "iso_utc",
    "parse_hhmm",
]
