"""The rules an MT must pass before it is requested, the same for `drs mt send` and the console.

Most commands need only the capsule's name typed (the lifecycle checks it). A CRITICAL one (its
catalogue entry's ``hazard``: PARACHUTE, which drops the parachute) also needs the two-person rule and
landed evidence (``drs_link.iridium.landed``); without that evidence it can only be forced by an explicit
override with a reason, given by a second operator or under a logged single-operator waiver (with
``require_second_operator``, only another login's approval). Evidence from reports without a verified
JWT (UNVERIFIED) needs another login's approval, whatever the configuration. ``IridiumOps.send_mt`` runs this gate itself,
so no caller can queue a PARACHUTE past it. Every refusal and every authorisation is in the
audit log with the evidence and the last fix, so nobody has to reconstruct later why it went out.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime
from typing import Any

from drs_link.errors import RefusedError
from drs_link.iridium import Hazard, MtCommand, MtMessage, StoredReport, landed_evidence, read_text
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.ops.arming import check_second_operator
from drs_link.ops.gonogo import WAIVER_REASON_MAX
from drs_link.ops.typed_text import typed_optional
from drs_link.store import Store


def hazard_of(message: MtMessage) -> MtCommand | None:
    """The message's CRITICAL command, by each catalogue command's ``hazard``; None when all are routine."""
    for text in message.commands:
        found = read_text(text)
        if found is not None and found[0].hazard is Hazard.CRITICAL:
            return found[0]
    return None


def approval_command(message: MtMessage, override_landed: str | None) -> str:
    """What a PARACHUTE approval is given for: the exact text and, when the landed gate is overridden, the
    override and its reason, so the approver sees an in-flight drop and an approval for the text alone
    never stands for one."""
    override = (override_landed or "").strip()
    return f"{message.text} (OVERRIDE of the landed gate: {override})" if override else message.text


def carries_parachute(message: MtMessage) -> bool:
    """Whether the two-person rule and the landed gate apply: the MT carries a CRITICAL command."""
    return hazard_of(message) is not None


def authorize_mt(
    store: Store,
    capsule: str,
    operator: str,
    message: MtMessage,
    reports: Sequence[StoredReport],
    *,
    second_operator: str | None = None,
    single_operator_waiver: str | None = None,
    require_second_operator: bool = False,
    crew: tuple[str, ...] = (),
    override_landed: str | None = None,
    ground_m: float | None = None,
    queue_by: datetime | None = None,
    now: datetime | None = None,
    approval: int | None = None,
    login: Login | None = None,
    spend: bool = True,
) -> dict[str, Any]:
    """Refuse ``message`` (RefusedError, audited) unless its rules hold; return what to audit with it.

    ``queue_by`` is the PARACHUTE plan's deadline: checked here, at submit, against ``now``, because a
    dialog may have stood open past it (the firmware would reject the time and the command be lost).
    ``approval`` is a request another login approved (``drs_link.ops.approval``): it stands for the second
    operator. Every rule is checked before it is spent; with ``spend`` it is spent here, once, by the
    login that requested it, else the caller spends it in the transaction that records the MT
    (``IridiumOps.send_mt``: ``ApprovalBook.spend_in``), so an approval is never spent on a refused send.

    Landed evidence that rests on reports without a verified JWT (``LandedEvidence.verified`` False: with
    ``mo.require_jwt = false`` anyone who reaches the receiver can post them, issue #31) is accepted only
    with another login's approval: a typed second name or a single-operator waiver is one person's word.
    """
    if not carries_parachute(message):
        return {}
    evidence = landed_evidence(reports, ground_m)

    def refuse(reason: str) -> RefusedError:
        store.append_audit(operator, capsule, "mt.parachute", "refused",
                           {"text": message.text, "reason": reason, "landed": evidence.audit()})  # fmt: skip
        return RefusedError(f"{capsule}: PARACHUTE refused: {reason}")

    override = (typed_optional("the override reason", override_landed) or "").strip()
    if queue_by is not None and now is not None and now > queue_by:
        raise refuse(
            f"the queue-before deadline {queue_by:%H:%M:%S}Z passed ({(now - queue_by).total_seconds():.0f} s ago) "
            "while the dialog was open; plan the time again"
        )
    if not evidence.on_ground:
        if len(override) > WAIVER_REASON_MAX:
            raise refuse(
                f"an override reason is at most {WAIVER_REASON_MAX} characters (this one has {len(override)})"
            )
        if not override:
            raise refuse(
                f"no landed evidence ({evidence.summary}); it would drop the parachute in flight. To override, "
                "give a reason and a second operator (or a logged single-operator waiver)"
            )
    try:
        if approval is not None:
            book, requester = ApprovalBook(store), login or current_login()
            bound = approval_command(message, override_landed)
            if spend:
                people = book.use(approval, capsule, "parachute", requester, bound)
            else:
                request = book.check(approval, capsule, "parachute", requester, bound)
                people = {
                    "approved_by": f"{request.decided_by} ({request.decider})",
                    "approval": str(approval),
                }
        else:
            people = check_second_operator(
                operator, second_operator, single_operator_waiver, require_second_operator, crew
            )
    except RefusedError as exc:
        raise refuse(str(exc)) from None
    details: dict[str, Any] = {"text": message.text, "landed": evidence.audit(), **people}
    if not evidence.on_ground:
        if not people:
            raise refuse(
                "overriding the landed check needs a second operator or a logged single-operator waiver"
            )
        details["override_landed"] = override
    elif not evidence.verified and approval is None:
        raise refuse(
            f"the landed evidence rests on reports without a verified JWT ({evidence.summary}); anyone "
            "who can reach the receiver could have posted them: another login must approve it (--await-approval, "
            "or the console's 'Ask another login'); a typed second operator or a single-operator waiver "
            "is not accepted"
        )
    store.append_audit(operator, capsule, "mt.parachute", "authorised", details)
    return details
