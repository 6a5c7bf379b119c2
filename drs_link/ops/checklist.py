"""Procedures as data: checklists read from TOML, run per capsule, every tick audited and kept.

The flown procedure (drs_protocol.md 5) lived in a Markdown file and an operator's head. Here a
checklist is a file of steps of three kinds: *manual* (ticked by a named operator, with the time),
*auto* (a live predicate on telemetry, shown met or not met as the data change, never ticked by
hand) and *command* (completed only by running the command through its normal confirmation, so
a checklist can never become a way around it). Progress lives in the store, so a restarted console
shows what was done and by whom.

Which step a command completes is decided here (``complete_command``), not by a front end, so the
CLI and the console tick the same step: the first one in procedure order that names the command,
is not yet done, and whose own ``when`` holds. A command step's ``when`` says when running the
command counts for it: "Sounder off once the capsule is in hand" is not completed by a SOUNDER_OFF
sent during the descent.
"""

from __future__ import annotations

import operator as op
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from enum import StrEnum
from pathlib import Path
from typing import Any

from drs_link.errors import ConfigError, RefusedError
from drs_link.ops.typed_text import typed_text
from drs_link.store import Store, iso_utc, parse_iso_utc, utc_now

FACTS: dict[str, type] = {
    "link_up": bool,
    "powered": bool,
    "nmea_seen": bool,
    "gnss_fix": bool,
    "gnss_sats": int,
    "gnss_hdop": float,
    "sync_fraction": float,
    "raid_healthy": bool,
    "storage_free_fraction": float,
    "released": bool,
    "reports_received": int,
    "landed": bool,
    "vbat": float,
    "interval_min": int,
}
"""The telemetry facts an auto step may test; the console computes each from live data."""

OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "==": op.eq,
    "!=": op.ne,
    ">=": op.ge,
    "<=": op.le,
    ">": op.gt,
    "<": op.lt,
}
COMMANDS = ("power-on", "fire", "mt-interval", "mt-sounder-off", "mt-parachute", "reset")
"""Commands a command step may name (each has its own confirmation, in the CLI and the console)."""
PROCEDURE_DIR = Path(__file__).parent / "checklists"
"""The flown procedure (drs_protocol.md 5) as checklists, in file-name order."""

_DDL = """
CREATE TABLE IF NOT EXISTS checklist_step (
    capsule TEXT NOT NULL,
    checklist TEXT NOT NULL,
    step TEXT NOT NULL,
    state TEXT NOT NULL,
    operator TEXT NOT NULL,
    at TEXT NOT NULL,
    note TEXT,
    PRIMARY KEY (capsule, checklist, step)
);
"""


class StepKind(StrEnum):
    MANUAL = "manual"
    AUTO = "auto"
    COMMAND = "command"


class StepState(StrEnum):
    PENDING = "pending"
    DONE = "done"
    SKIPPED = "skipped"
    MET = "met"
    NOT_MET = "not met"
    NO_DATA = "no data"


@dataclass(frozen=True)
class Predicate:
    fact: str
    operator: str
    value: bool | int | float

    def text(self) -> str:
        return f"{self.fact} {self.operator} {str(self.value).lower()}"

    def evaluate(self, facts: Mapping[str, object]) -> StepState:
        actual = facts.get(self.fact)
        if actual is None:
            return StepState.NO_DATA
        return StepState.MET if OPERATORS[self.operator](actual, self.value) else StepState.NOT_MET


@dataclass(frozen=True)
class Step:
    id: str
    kind: StepKind
    text: str
    predicate: Predicate | None = None
    """Auto step: when it is met. Command step: when running the command counts for it."""
    command: str | None = None


@dataclass(frozen=True)
class Checklist:
    id: str
    title: str
    source: str
    steps: tuple[Step, ...]

    def step(self, step_id: str) -> Step:
        for step in self.steps:
            if step.id == step_id:
                return step
        raise RefusedError(f"checklist {self.id}: no step {step_id!r}")


def _predicate(where: str, table: Any) -> Predicate:
    if not isinstance(table, dict) or set(table) != {"fact", "op", "value"}:
        raise ConfigError(f'{where}.when: write it as {{ fact = "...", op = "==", value = ... }}')
    fact, operator, value = table["fact"], table["op"], table["value"]
    if fact not in FACTS:
        raise ConfigError(f"{where}.when.fact: unknown fact {fact!r} (known: {', '.join(sorted(FACTS))})")
    if operator not in OPERATORS:
        raise ConfigError(f"{where}.when.op: {operator!r} is not one of {' '.join(OPERATORS)}")
    expected = FACTS[fact]
    ok = isinstance(value, bool) if expected is bool else (
        isinstance(value, int | float) and not isinstance(value, bool)
    )  # fmt: skip
    if not ok:
        raise ConfigError(f"{where}.when.value: {fact} is a {expected.__name__}, got {value!r}")
    return Predicate(fact, operator, value)


def _step(where: str, table: Any) -> Step:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: expected a [[step]] table")
    allowed = {"id", "kind", "text", "when", "command"}
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]}: unknown key (allowed: {', '.join(sorted(allowed))})")
    for key in ("id", "kind", "text"):
        if not isinstance(table.get(key), str) or not table[key].strip():
            raise ConfigError(f"{where}.{key}: required text is missing")
    try:
        kind = StepKind(table["kind"])
    except ValueError:
        raise ConfigError(f"{where}.kind: {table['kind']!r} is not manual, auto or command") from None
    predicate = command = None
    if kind is StepKind.AUTO and "when" not in table:
        raise ConfigError(f"{where}.when: an auto step needs a predicate")
    if "when" in table:
        if kind is StepKind.MANUAL:
            raise ConfigError(f"{where}.when: only auto and command steps have a predicate")
        predicate = _predicate(where, table["when"])
    if kind is StepKind.COMMAND:
        command = table.get("command")
        if command not in COMMANDS:
            raise ConfigError(f"{where}.command: {command!r} is not one of {', '.join(COMMANDS)}")
    elif "command" in table:
        raise ConfigError(f"{where}.command: only command steps name a command")
    return Step(table["id"], kind, table["text"].strip(), predicate, command)


def parse_checklist(document: dict[str, Any], origin: str) -> Checklist:
    for key in ("id", "title"):
        if not isinstance(document.get(key), str) or not document[key].strip():
            raise ConfigError(f"{origin}: {key}: required text is missing")
    raw_steps = document.get("step")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise ConfigError(f"{origin}: step: a checklist needs at least one [[step]]")
    steps = tuple(_step(f"{origin}: step[{i}]", table) for i, table in enumerate(raw_steps))
    ids = [s.id for s in steps]
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise ConfigError(f"{origin}: step id {duplicates[0]!r} is used twice")
    return Checklist(document["id"], document["title"], str(document.get("source", "")), steps)


def load_checklist(path: Path) -> Checklist:
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    return parse_checklist(document, str(path.name))


def load_checklists(directory: Path) -> list[Checklist]:
    """Every ``*.toml`` in a directory, in file-name order (number them to order the procedure)."""
    paths = sorted(directory.glob("*.toml"))
    if not paths:
        raise ConfigError(f"no checklists (*.toml) in {directory}")
    checklists = [load_checklist(path) for path in paths]
    ids = [c.id for c in checklists]
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise ConfigError(f"{directory}: checklist id {duplicates[0]!r} is used by two files")
    return checklists


@dataclass(frozen=True)
class StepStatus:
    step: Step
    state: StepState
    operator: str | None
    at: datetime | None
    note: str | None

    @property
    def finished(self) -> bool:
        """Done, skipped with a reason, or an automatic step the telemetry meets: nothing left to do."""
        return self.state in (StepState.DONE, StepState.SKIPPED, StepState.MET)


@dataclass(frozen=True)
class StepRecord:
    """A step ticked, skipped or completed by a command, as the store keeps it: what a console that does
    not hold the store is handed (``drs_link.server``), to show with the telemetry it folds itself."""

    checklist: str
    step: str
    state: StepState
    operator: str
    at: datetime
    note: str | None


def statuses_of(
    checklist: Checklist, recorded: Sequence[StepRecord], facts: Mapping[str, object]
) -> list[StepStatus]:
    """Each step's state: as recorded, else an automatic step judged on ``facts``, else pending."""
    by_step = {r.step: r for r in recorded if r.checklist == checklist.id}
    out = []
    for step in checklist.steps:
        row = by_step.get(step.id)
        if row is not None:
            out.append(StepStatus(step, row.state, row.operator, row.at, row.note))
        elif step.kind is StepKind.AUTO and step.predicate is not None:
            out.append(StepStatus(step, step.predicate.evaluate(facts), None, None, None))
        else:
            out.append(StepStatus(step, StepState.PENDING, None, None, None))
    return out


def step_records(store: Store, capsule: str) -> list[StepRecord]:
    """Every step recorded for ``capsule``, of every checklist."""
    store.ensure_schema(_DDL)
    rows = store.query("SELECT * FROM checklist_step WHERE capsule = ?", (capsule,))
    return [StepRecord(row["checklist"], row["step"], StepState(row["state"]), row["operator"],
                       parse_iso_utc(row["at"]), row["note"]) for row in rows]  # fmt: skip


class ChecklistRun:
    """One checklist for one capsule: ticks, skips and command completions, durable and audited."""

    def __init__(
        self, store: Store, checklist: Checklist, capsule: str, clock: Callable[[], datetime] = utc_now
    ) -> None:
        self.store = store
        self.checklist = checklist
        self.capsule = capsule
        self.clock = clock
        store.ensure_schema(_DDL)

    def _record(self, step: Step, state: StepState, operator: str, note: str | None) -> None:
        if not operator.strip():
            raise RefusedError(f"checklist {self.checklist.id}: a tick needs the operator's name")
        now = self.clock()
        with self.store.transaction() as conn:
            conn.execute(
                "INSERT OR REPLACE INTO checklist_step (capsule, checklist, step, state, operator, at, note)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (self.capsule, self.checklist.id, step.id, state.value, operator.strip(), iso_utc(now), note),
            )
        self.store.append_audit(
            operator.strip(), self.capsule, f"checklist.{state.value}",
            f"{self.checklist.id}/{step.id}", {"text": step.text, "note": note}, when=now,
        )  # fmt: skip

    def tick(self, step_id: str, operator: str) -> None:
        step = self.checklist.step(step_id)
        if step.kind is StepKind.AUTO:
            raise RefusedError(f"{step.id}: an automatic step follows the telemetry; it cannot be ticked")
        if step.kind is StepKind.COMMAND:
            raise RefusedError(
                f"{step.id}: a command step is done by running {step.command!r}, not by a tick"
            )
        self._record(step, StepState.DONE, operator, None)

    def skip(self, step_id: str, operator: str, reason: str) -> None:
        step = self.checklist.step(step_id)
        typed_text("the reason for skipping a step", reason)
        if not reason.strip():
            raise RefusedError(f"{step.id}: skipping a step needs a reason")
        self._record(step, StepState.SKIPPED, operator, reason.strip())

    def command_done(self, step_id: str, operator: str, result: str) -> None:
        """Called after the named command ran through its confirmation and succeeded."""
        step = self.checklist.step(step_id)
        if step.kind is not StepKind.COMMAND:
            raise RefusedError(f"{step.id}: not a command step")
        self._record(step, StepState.DONE, operator, result)

    def statuses(self, facts: Mapping[str, object]) -> list[StepStatus]:
        return statuses_of(self.checklist, step_records(self.store, self.capsule), facts)

    def complete(self, facts: Mapping[str, object]) -> bool:
        return all(s.finished for s in self.statuses(facts))


def start_new_flight(
    store: Store, capsule: str, operator: str, clock: Callable[[], datetime] = utc_now
) -> int:
    """Forget the capsule's ticks, skips and command completions: a reset after a recovered release
    starts the next flight, whose checklists begin empty (the last flight's FIRE once stayed ticked).
    The audit log keeps every one of them; returns how many were cleared."""
    store.ensure_schema(_DDL)
    now = clock()
    with store.transaction() as conn:
        cleared = conn.execute("DELETE FROM checklist_step WHERE capsule = ?", (capsule,)).rowcount
    store.append_audit(
        operator, capsule, "checklist.new-flight", "cleared", {"steps": cleared}, when=now
    )  # fmt: skip
    return int(cleared)


def complete_command(
    store: Store,
    checklists: Sequence[Checklist],
    capsule: str,
    command: str,
    operator: str,
    result: str,
    facts: Mapping[str, object],
    clock: Callable[[], datetime] = utc_now,
) -> tuple[Checklist, Step] | None:
    """Mark done the one step a command that ran (and succeeded) completes; ``None`` when none applies.

    The step is the first, in procedure order, that names ``command``, is not already done or skipped,
    and whose ``when`` holds on ``facts`` (no data is not "holds": a step is never completed on a guess).
    """
    for checklist in checklists:
        run = ChecklistRun(store, checklist, capsule, clock)
        for status in run.statuses(facts):
            step = status.step
            if step.command != command or status.state in (StepState.DONE, StepState.SKIPPED):
                continue
            if step.predicate is not None and step.predicate.evaluate(facts) is not StepState.MET:
                continue
            run.command_done(step.id, operator, result)
            return checklist, step
    return None
