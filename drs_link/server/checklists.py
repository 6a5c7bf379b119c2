"""The checklists service: each capsule's ticks and skips, recorded by the server for the account's operator.

A console keeps the procedure (the checklist files) and its telemetry's facts, and is handed the steps
recorded (``StepRecord``) to judge the rest with them (``statuses_of``), the same as ``ChecklistRun``.
"""

from __future__ import annotations

from drs_link.errors import ConfigError, RefusedError
from drs_link.ops import ChecklistRun, StepRecord, step_records
from drs_link.server.desks import Desks
from drs_link.server.peers import Peer
from drs_link.server.protocol import StepRequest


class ChecklistService:
    def __init__(self, desks: Desks) -> None:
        self.desks = desks

    def records(self, peer: Peer, name: str) -> tuple[StepRecord, ...]:
        capsule = self.desks.desk(peer).state.config.capsule(name).name
        return tuple(step_records(self.desks.store, capsule))

    def all_records(self, peer: Peer) -> dict[str, tuple[StepRecord, ...]]:
        return {name: self.records(peer, name) for name in self.desks.desk(peer).state.capsules}

    def step(self, peer: Peer, name: str, request: StepRequest) -> tuple[StepRecord, ...]:
        """Tick (or with a reason, skip) a step of the desk's procedure: a command or automatic step is
        refused by ``ChecklistRun``, as from any face."""
        state = self.desks.desk(peer).state
        capsule = state.config.capsule(name).name
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every tick is audited with it")
        checklist = next((c for c in state.checklists if c.id == request.checklist), None)
        if checklist is None:
            raise RefusedError(f"no checklist {request.checklist!r} in the server's procedure")
        run = ChecklistRun(self.desks.store, checklist, capsule, self.desks.clock)
        if request.reason is None:
            run.tick(request.step, peer.operator)
        else:
            run.skip(request.step, peer.operator, request.reason)
        return self.records(peer, capsule)
