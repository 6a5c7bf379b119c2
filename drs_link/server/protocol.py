"""The operations server's protocol: every message a client and the server exchange, as typed values.

Why msgspec: each message is a frozen ``Struct`` decoded straight from JSON bytes with its types checked
(a string where an int belongs, an unknown field, a missing one: refused with the field's path), so the
server never parses a dict back into a value, and a malformed message is a one-line error that changes
nothing. It is one small C extension, faster than pydantic on both ends, and it validates on decode
only, which is where an untrusted message enters.

Why versioned twice: the routes live under ``/v1/`` and every request carries ``protocol``; a client
and a server of different versions (an old ``drs`` on a new ground machine) are refused with both
numbers named, before anything is read as a command.
"""

from __future__ import annotations

from datetime import datetime
from typing import Literal

import msgspec

PROTOCOL = 1
"""Bumped on any change a client of the previous version would misread."""
ROOT = f"/v{PROTOCOL}"
MAX_BODY_BYTES = 64 * 1024
"""A request is a few hundred bytes; anything larger is refused before it is read as JSON."""
MAX_TEXT = 400
"""The longest free text (a reason, a waiver, a typed name) a request may carry."""


class Request(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    protocol: int


class Waive(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One go/no-go item waived for this request (``drs capsule arm/go --waive ITEM=REASON``)."""

    item: str
    reason: str


class Second(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """How the two-person rule is met: a typed crew name or a waiver (refused under
    ``require_second_operator``), or another account's live approval (``await_approval``)."""

    name: str | None = None
    waiver: str | None = None
    await_approval: bool = False


class ArmRequest(Request, frozen=True):
    waivers: tuple[Waive, ...] = ()
    weather: tuple[str, ...] = ()
    """GRIB2 files the server reads for the "release now" prediction go/no-go judges."""


class FireRequest(Request, frozen=True):
    typed_name: str
    waivers: tuple[Waive, ...] = ()
    weather: tuple[str, ...] = ()
    second: Second = Second()


class DisarmRequest(Request, frozen=True):
    reason: str = "operator disarmed (drs capsule disarm)"


class MtSendRequest(Request, frozen=True):
    """``drs mt send``: each catalogue command's option as typed (``{"interval": 5, "parachute": "next"}``)."""

    options: dict[str, int | str]
    confirm: str | None = None
    dry_run: bool = False
    flush: bool = False
    accept_midnight: bool = False
    override_landed: str | None = None
    second: Second = Second()


class DecideRequest(Request, frozen=True):
    approve: bool
    reason: str = ""


# Answers ------------------------------------------------------------------------------------------


class Hello(msgspec.Struct, frozen=True):
    """Who the server says you are (from the kernel, never from you) and what it is."""

    protocol: int
    mode: Literal["private", "shared"]
    uid: int
    account: str
    operator: str
    require_second_operator: bool
    capsules: tuple[str, ...]


class ArmState(msgspec.Struct, frozen=True):
    capsule: str
    state: str
    window: int | None
    until_utc: str | None
    remaining_s: float
    reason: str | None
    lines: tuple[str, ...] = ()
    """The go/no-go poll it was judged on, one line per item."""
    armed_until: datetime | None = None
    """When the open window closes (a console counts it down on its own clock between pushes)."""
    mine: bool = True
    """Whether the asking account holds the window (only its holder can FIRE in it)."""
    holder: str = ""
    """Who holds another account's window (``held by account@host …``), empty when it is the asker's."""


class ApprovalView(msgspec.Struct, frozen=True):
    id: int
    capsule: str
    action: str
    summary: str
    command: str | None
    requested_by: str
    requester_account: str
    state: str
    expires_utc: str
    decided_by: str | None
    decider_account: str | None
    described: str
    """The request as ``drs approve`` prints it (``Approval.describe``)."""
    expires: datetime | None = None
    """``expires_utc`` as a time, for a console's countdown."""


class Failure(msgspec.Struct, frozen=True, tag="failure"):
    """A refusal or an error, as the operator reads it: ``kind`` picks the client's exception."""

    kind: Literal["refused", "config", "link", "store", "usage", "protocol", "identity"]
    error: str


# A long action (FIRE, an MT) answers with a stream of these, one JSON line each: what to say while it
# works, the approval request it waits on, then its end (Done or Failure).


class Said(msgspec.Struct, frozen=True, tag="said"):
    line: str


class Pending(msgspec.Struct, frozen=True, tag="pending"):
    approval: int
    line: str


class Done(msgspec.Struct, frozen=True, tag="done"):
    lines: tuple[str, ...]
    ok: bool = True
    arm: ArmState | None = None
    """ARM's answer: the window it opened."""


Step = Said | Pending | Done | Failure


class Event(msgspec.Struct, frozen=True):
    """What ``/v1/events`` pushes whenever the store changed: every capsule's release and ARM state and
    the approvals that wait, for a view to redraw without asking."""

    release: dict[str, str]
    armed: dict[str, str]
    approvals: tuple[ApprovalView, ...]
    arms: dict[str, ArmState] = {}
    """Each capsule's ARM window as the subscribing account sees it (``mine`` is that account's)."""


def encode(value: object) -> bytes:
    return msgspec.json.encode(value)


def decode_step(line: bytes) -> Step:
    return msgspec.json.decode(line, type=Step)
