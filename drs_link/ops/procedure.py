"""Which checklist step a queued MT completes: one rule for `drs mt send` and the console.

Both front ends call ``complete_mt_steps`` after a send: every command the MT carries (all of a
combined ``[INTERVAL=5][SOUNDER_OFF]``, not just how its text starts) completes the step the catalogue
names for it (``MtCommand.checklist_step``; SOUNDER_ON completes none) by the procedure's own rule
(``drs_link.ops.checklist.complete_command``), judged on facts read from the capsule's reports the same
way for both (landed = ``drs_link.iridium.landed``, the PARACHUTE gate's rule), so a SOUNDER_OFF sent
during the descent does not tick "Sounder off once the capsule is in hand".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import datetime

from drs_link.iridium import StoredReport, landed_evidence, lifecycle as lc, read_text
from drs_link.ops.checklist import Checklist, Step, complete_command
from drs_link.store import Store, utc_now


def report_facts(reports: Sequence[StoredReport]) -> dict[str, object]:
    """The checklist facts the reports alone establish (drs_link.ops.checklist.FACTS)."""
    return {
        "reports_received": len(reports),
        "landed": landed_evidence(reports).on_ground if reports else None,
    }


def complete_mt_steps(
    store: Store,
    checklists: Sequence[Checklist],
    operator: str,
    command: lc.Command,
    reports: Sequence[StoredReport],
    clock: Callable[[], datetime] = utc_now,
) -> list[Step]:
    """The steps a send completed: none unless the gateway queued it (a refused or failed send did nothing)."""
    if command.state != lc.QUEUED:
        return []
    facts = report_facts(reports)
    done = []
    for text in command.effects:
        found = read_text(text)
        name = found[0].checklist_step(found[1]) if found is not None else None
        if name is None:
            continue
        completed = complete_command(
            store,
            checklists,
            command.capsule,
            name,
            operator,
            f"{text} queued (MT {command.id})",
            facts,
            clock,
        )
        if completed is not None:
            done.append(completed[1])
    return done
