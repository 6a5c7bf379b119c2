"""What the screens work on, typed: the session's setup, the fleet state, and the calls into ``drs_link``.

The app builds one ``ConsoleContext`` and hands it to each screen it opens, instead of itself: the app
imports the screens, so a screen that took the app could only type it ``Any``. The screens read
the fleet, the clock and the settings from it and ask it for go/no-go, arming, checklists and
approvals. Nothing here imports Textual: it is the plain-Python side of the console.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

from console.predictions import PredictionService
from drs_link.feeds import BalloonFeed
from drs_link.ops import (
    PROCEDURE_DIR,
    ArmingController,
    Checklist,
    ChecklistRun,
    FleetState,
    GoNoGoReport,
    Operations,
    ParachuteOverride,
    ReleaseOrigin,
    TelemetryRecord,
    evaluate,
    load_checklists,
    parachute_override,
    release_origin,
)
from drs_link.store import Store, utc_now

POLL_PERIOD_S = 5.0
OVERRIDE_READ_S = 1.0
"""How often the store is read for PARACHUTE overrides: every screen in sight asks once a second."""
LOW_BANDWIDTH_AGE_STEP_S = 10.0
AGE_STEP_S = 5.0
"""The view time's step on an ordinary link: fresh readings' ages (0s…4s between heartbeats) ticking
every second were most of the idle fleet's 3.5 kB/s at ×1 (issue #25)."""


@dataclass
class ConsoleSetup:
    """Everything the app runs on; built by ``console.commands.console`` for live, demo and replay."""

    mode: str
    capsules: list[str]
    store: Store
    clock: Callable[[], datetime] = utc_now
    operations: Operations | None = None
    predictions: PredictionService | None = None
    balloon_feed: BalloonFeed | None = None
    """The configured ground-station feed of the balloon's position (started and stopped by the caller)."""
    replay_feed: Callable[[], list[TelemetryRecord]] | None = None
    team_position: tuple[float, float] | None = None
    export_dir: Path = Path(".")
    banner_note: str = ""
    low_bandwidth: bool = False
    """``--low-bandwidth`` or ``[console] low_bandwidth``: see ``ConsoleContext.view_time``."""
    poll_period_s: float = POLL_PERIOD_S
    prediction_period_s: float = 60.0
    time_scale: float = 1.0
    """Simulated seconds per real second (the demo): timers are real, telemetry times are not."""

    def close(self) -> None:
        """Stop what runs beside the app (the balloon feed's reader); the store closes with Operations."""
        if self.balloon_feed is not None:
            self.balloon_feed.stop()


class ConsoleContext:
    """The session's state and the domain calls a screen makes; one per app, shared by its screens."""

    def __init__(self, setup: ConsoleSetup, warn: Callable[[str], None]) -> None:
        self.setup = setup
        poll_period = 2.0 * setup.poll_period_s * setup.time_scale
        self.fleet = FleetState.for_capsules(setup.capsules, poll_period if setup.operations else 0.0)
        self.checklists: list[Checklist] = (
            setup.operations.checklists if setup.operations else load_checklists(PROCEDURE_DIR)
        )
        """The procedure the operations layer ticks, so the screen shows the steps it completes."""
        self.warn = warn
        """Tells the operator something from any thread (the app posts it as a notice)."""
        self._overrides: tuple[float, list[ParachuteOverride]] = (-OVERRIDE_READ_S, [])

    @property
    def mode(self) -> str:
        return self.setup.mode

    @property
    def commanding(self) -> bool:
        """Replay can never command: there is no Operations behind it, and the keys are disabled."""
        return self.setup.operations is not None and self.setup.mode != "replay"

    @property
    def ops(self) -> Operations | None:
        return self.setup.operations

    @property
    def store(self) -> Store:
        return self.setup.store

    @property
    def operator(self) -> str:
        return self.ops.operator if self.ops else "replay"

    def now(self) -> datetime:
        return self.setup.clock()

    def view_time(self) -> datetime:
        """The time the fleet's ages are shown at: ``now`` in steps of ``AGE_STEP_S``, or on a thin link of
        ``LOW_BANDWIDTH_AGE_STEP_S``, so the many ages on screen change every 5 or 10 s instead of every
        second (each change is bytes on the link). Countdowns, the clock and every decision use ``now``."""
        now = self.now()
        step = LOW_BANDWIDTH_AGE_STEP_S if self.setup.low_bandwidth else AGE_STEP_S
        return now - timedelta(seconds=now.timestamp() % step)

    def banner(self) -> str:
        words = {"demo": "DEMO — simulated capsules, gateway and weather", "replay": "REPLAY — commanding disabled",
                 "live": "LIVE"}  # fmt: skip
        text = words.get(self.mode, self.mode.upper())
        return f"{text} {self.setup.banner_note}".strip()

    def arming(self, capsule: str) -> ArmingController:
        """The capsule's ARM/FIRE controller; only a commanding console has one (check ``commanding``)."""
        assert self.ops is not None
        return self.ops.ops(capsule).arming

    def parachute_overrides(self) -> list[ParachuteOverride]:
        """Each capsule's PARACHUTE queued without landed evidence (``drs_link.ops.override``), from any
        console on the store; read at most once per ``OVERRIDE_READ_S``."""
        read_at, found = self._overrides
        if self.ops is None or time.monotonic() - read_at < OVERRIDE_READ_S:
            return found
        found = []
        for capsule in self.setup.capsules:
            override = parachute_override(capsule, self.store.audit(capsule, action="mt.parachute"),
                                          self.ops.commands(capsule))  # fmt: skip
            if override is not None:
                found.append(override)
        self._overrides = (time.monotonic(), found)
        return found

    def checklist_run(self, capsule: str, checklist: Checklist) -> ChecklistRun:
        return ChecklistRun(self.store, checklist, capsule, self.now)

    def gonogo(self, capsule: str) -> GoNoGoReport:
        telemetry = self.fleet.capsules[capsule]
        zones = self.ops.zones if self.ops else ()
        waivers = self.ops.ops(capsule).waivers.waivers if self.ops else []
        return evaluate(capsule, telemetry.gonogo_inputs(self.now(), zones), self.now(), waivers)

    def prediction_origin(self, capsule: str) -> ReleaseOrigin | None:
        """Where a release would start (the rule is ``drs_link.ops.origin.release_origin``)."""
        return release_origin(self.fleet, capsule, self.now())
