"""What the screens work on, typed: the session's setup, the fleet state, and the calls into ``drs_link``.

The app builds one context for its mode (``context_for``) and hands it to each screen it opens,
instead of itself: the app imports the screens, so a screen that took the app could only type it
``Any``. The screens read the fleet, the clock and the settings from it and ask it for go/no-go,
arming, checklists, approvals and the audit log. A live or demo console gets a
``CommandingContext``: it acts through the operations server (``drs_link.server.Client``: ARM, FIRE,
disarm, approvals, MT sends) and shows the ARM windows and approvals the server pushes; its fleet is
still polled through ``Operations``. A replay gets a ``ReplayContext``, which
has no commanding side at all: asked for one, it refuses with ``REPLAY_REFUSAL`` (its keys are
disabled too, so that is a last guard, not a path a screen takes). Nothing here imports Textual: it
is the plain-Python side of the console.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

from console.predictions import PredictionService
from drs_link.errors import LinkError
from drs_link.feeds import BalloonFeed
from drs_link.ops import (
    PROCEDURE_DIR,
    AuditLog,
    Checklist,
    ChecklistRun,
    ExclusionZone,
    FleetState,
    GoNoGoReport,
    LiveSource,
    Operations,
    ParachuteOverride,
    RecordedViews,
    ReleaseOrigin,
    StoreViews,
    TelemetryRecord,
    ViewSource,
    Waiver,
    evaluate,
    load_checklists,
    parachute_override,
    release_origin,
)
from drs_link.server import (
    POLL_PERIOD_S,
    PROTOCOL,
    ApprovalView,
    ArmState,
    Client,
    Done,
    Event,
    Hello,
    MtSendRequest,
    Pending,
    Second,
)
from drs_link.store import Store, utc_now

ARMED, FIRING, FIRED = "armed", "firing", "fired"
"""The server's ARM window states (``ArmState.state``, ``drs_link.ops.ArmState`` values) a console tells
apart."""
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
    server: Path | None = None
    """The operations server's socket: every action of a live or demo console goes through it."""
    stop_server: Callable[[], None] | None = None
    """Ends the demo's in-process server with the session (a shared or on-demand one lives on)."""
    weather: tuple[Path, ...] = ()
    """The GRIB2 files the server's go/no-go judges the "release now" prediction on (ARM and FIRE)."""
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
    """How often the server polls each capsule (its pace at the wall clock's), which ages are judged by."""
    prediction_period_s: float = 60.0
    time_scale: float = 1.0
    """Simulated seconds per real second (the demo): timers are real, telemetry times are not."""

    def close(self) -> None:
        """Stop what runs beside the app (the balloon feed's reader, the demo's server); the store closes
        with Operations."""
        if self.balloon_feed is not None:
            self.balloon_feed.stop()
        if self.stop_server is not None:
            self.stop_server()


REPLAY_REFUSAL = "a replay cannot command: there is no link behind a recording"


class ConsoleContext:
    """The session's state and the calls every console makes, commanding or not; one per app.

    ``operations`` and ``client`` are the commanding side: only ``CommandingContext`` has one, and
    here they refuse (``LinkError``), so a screen calls them inside the ``try`` that shows a refusal.
    """

    commanding = False
    """Whether this console can command (a live or demo console): the screens dim their keys without."""

    def __init__(self, setup: ConsoleSetup, warn: Callable[[str], None], poll_period_s: float = 0.0) -> None:
        self.setup = setup
        self.fleet = FleetState.for_capsules(setup.capsules, poll_period_s)
        self.checklists: list[Checklist] = load_checklists(PROCEDURE_DIR)
        """The procedure the operations layer ticks, so the screen shows the steps it completes."""
        self.warn = warn
        """Tells the operator something from any thread (the app posts it as a notice)."""
        self.history = AuditLog(setup.store)
        """The audit log as History reads and exports it (this machine's, in a replay too)."""
        self.in_flight: dict[str, list[Client]] = {}
        """Actions in progress per capsule (each its own connection), which ``c`` can withdraw."""
        self.views: ViewSource = RecordedViews()
        """Where the per-capsule screens' views come from: the recording here, the store when commanding."""

    @property
    def mode(self) -> str:
        return self.setup.mode

    @property
    def store(self) -> Store:
        return self.setup.store

    @property
    def operator(self) -> str:
        return "replay"

    @property
    def zones(self) -> tuple[ExclusionZone, ...]:
        """The exclusion zones go/no-go and the maps use (none known without the configuration)."""
        return ()

    @property
    def zones_file(self) -> Path | None:
        return None

    @property
    def require_second_operator(self) -> bool:
        return False

    def operations(self) -> Operations:
        """The operations layer behind a commanding console; a replay refuses (``REPLAY_REFUSAL``)."""
        raise LinkError(REPLAY_REFUSAL)

    def client(self) -> Client:
        """A connection to the operations server, one per action (a FIRE waiting for an approval holds
        its own); a replay refuses (``REPLAY_REFUSAL``)."""
        raise LinkError(REPLAY_REFUSAL)

    def arm_state(self, capsule: str) -> ArmState | None:
        """The capsule's ARM window as the server last said (none known in a replay)."""
        return None

    def remaining_s(self, state: ArmState) -> float:
        """Seconds left in an open window, on this console's clock (the push comes only on a change)."""
        if state.armed_until is None:
            return 0.0
        return max(0.0, (state.armed_until - self.now()).total_seconds())

    def waiting_approvals(self, capsule: str) -> list[ApprovalView]:
        """This account's requests for ``capsule`` that wait for another account."""
        return []

    def open_approvals(self) -> list[ApprovalView]:
        """Every account's requests that wait for a second operator, as the server pushed them."""
        return []

    def remember(self, state: ArmState) -> None:
        """A window the server answered with, shown until its next push."""

    def apply_event(self, event: Event) -> None:
        """What the server pushed (a replay has no server)."""

    def account(self) -> str:
        """Who the server knows this console as (``account as OPERATOR``); a replay is nobody."""
        return "replay"

    # The verbs: each one connection to the server (``client``, which a replay refuses) --------------

    def _waived(self, capsule: str) -> tuple[tuple[str, str], ...]:
        return tuple((w.item, w.reason) for w in self.waivers(capsule))

    def arm(self, capsule: str) -> ArmState:
        """ARM through the server, which polls go/no-go itself, with this console's waivers."""
        with self.client() as client:
            state = client.capsule(capsule).arm(self._waived(capsule), self._weather(), say=lambda _: None)
        self.remember(state)
        return state

    def disarm(self, capsule: str, reason: str) -> ArmState:
        with self.client() as client:
            state = client.capsule(capsule).disarm(reason)
        self.remember(state)
        return state

    def fire(
        self, capsule: str, typed_name: str, second: Second, on_pending: Callable[[Pending], None]
    ) -> Done:
        """FIRE through the server: it polls again, holds the two-person rule and sends Go."""
        with self.client() as client, self.held(capsule, client):
            return client.capsule(capsule).fire(
                typed_name, self._waived(capsule), self._weather(), second, lambda _: None, on_pending
            )

    def send_mt(
        self, capsule: str, options: dict[str, int | str], confirm: str, second: Second | None = None,
        override_landed: str | None = None, on_pending: Callable[[Pending], None] | None = None,
    ) -> Done:  # fmt: skip
        """An MT through the server, which composes it from the options as typed and gates it."""
        request = MtSendRequest(PROTOCOL, options, confirm, override_landed=override_landed,
                                second=second or Second())  # fmt: skip
        with self.client() as client, self.held(capsule, client):
            return client.iridium.send_mt(capsule, request, lambda _: None, on_pending)

    def poll(self, capsule: str) -> list[TelemetryRecord]:
        """Poll the capsule now through the server, which pushes the records to every console too."""
        with self.client() as client:
            return client.capsule(capsule).poll()

    def cancel_waiting(self, capsule: str) -> list[ApprovalView]:
        """Withdraw this account's requests for ``capsule``: the action waiting on each is aborted, and
        the server cancels the request of a connection that drops (nothing is sent on it)."""
        waiting = self.waiting_approvals(capsule)
        for client in self.in_flight.pop(capsule, []):
            client.abort()
        return waiting

    def decide(self, approval: int, approve: bool, reason: str) -> ApprovalView:
        with self.client() as client:
            if approve:
                return client.approvals.approve(approval)
            return client.approvals.reject(approval, reason)

    @contextlib.contextmanager
    def held(self, capsule: str, client: Client) -> Iterator[None]:
        """An action that may wait on another account, kept so ``cancel_waiting`` can withdraw it."""
        self.in_flight.setdefault(capsule, []).append(client)
        try:
            yield
        finally:
            with contextlib.suppress(ValueError):
                self.in_flight.get(capsule, []).remove(client)

    def _weather(self) -> tuple[str, ...]:
        return tuple(str(path) for path in self.setup.weather)

    def parachute_overrides(self) -> list[ParachuteOverride]:
        """Each capsule's PARACHUTE queued without landed evidence (none known in a replay)."""
        return []

    def waivers(self, capsule: str) -> list[Waiver]:
        return []

    def record(self, records: list[TelemetryRecord]) -> None:
        """Keep ``records`` in the session's recording; a replay records nothing."""

    def close(self) -> None:
        """What the context opened, closed with the app."""

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

    def checklist_run(self, capsule: str, checklist: Checklist) -> ChecklistRun:
        return ChecklistRun(self.store, checklist, capsule, self.now)

    def gonogo(self, capsule: str) -> GoNoGoReport:
        telemetry = self.fleet.capsules[capsule]
        now = self.now()
        return evaluate(capsule, telemetry.gonogo_inputs(now, self.zones), now, self.waivers(capsule))

    def prediction_origin(self, capsule: str) -> ReleaseOrigin | None:
        """Where a release would start (the rule is ``drs_link.ops.origin.release_origin``)."""
        return release_origin(self.fleet, capsule, self.now())


class ReplayContext(ConsoleContext):
    """A console with no link: a replayed recording (or a session started without ``Operations``).

    It shows what was recorded through the same views; the commanding side does not exist."""


class CommandingContext(ConsoleContext):
    """A live or demo console: the same views, and the commanding side through the operations server."""

    commanding = True

    def __init__(
        self,
        setup: ConsoleSetup,
        warn: Callable[[str], None],
        ops: Operations,
        live: Callable[[], LiveSource | None],
        server: Path,
    ) -> None:
        super().__init__(setup, warn, 2.0 * setup.poll_period_s * setup.time_scale)
        self.ops = ops
        self.server = server
        self.checklists = ops.checklists
        self.views = StoreViews(ops, live)
        self._overrides: tuple[float, list[ParachuteOverride]] = (-OVERRIDE_READ_S, [])
        self.arms: dict[str, ArmState] = {}
        """Each capsule's ARM window as the server last pushed or answered it."""
        self.approvals: tuple[ApprovalView, ...] = ()
        self.stop_server: Callable[[], None] | None = None
        """Ends the server ``context_for`` started for this console alone."""
        with self.client() as client:
            self.hello: Hello = client.hello()
            """Who the server says this console is (its account, from the kernel)."""

    @property
    def operator(self) -> str:
        return self.ops.operator

    @property
    def zones(self) -> tuple[ExclusionZone, ...]:
        return self.ops.zones

    @property
    def zones_file(self) -> Path | None:
        return self.ops.config.console.exclusion_zones_file

    @property
    def require_second_operator(self) -> bool:
        return self.hello.require_second_operator

    def operations(self) -> Operations:
        return self.ops

    def client(self) -> Client:
        return Client(self.server)

    def apply_event(self, event: Event) -> None:
        """What the server pushed: the ARM windows (as this account sees them) and the open requests."""
        self.arms = dict(event.arms)
        self.approvals = event.approvals

    def arm_state(self, capsule: str) -> ArmState | None:
        return self.arms.get(capsule)

    def account(self) -> str:
        return f"{self.hello.account} as {self.hello.operator}"

    def remember(self, state: ArmState) -> None:
        self.arms[state.capsule] = state

    def waiting_approvals(self, capsule: str) -> list[ApprovalView]:
        account = self.hello.account
        return [a for a in self.approvals if a.capsule == capsule and a.requester_account == account]

    def open_approvals(self) -> list[ApprovalView]:
        return list(self.approvals)

    def waivers(self, capsule: str) -> list[Waiver]:
        return self.ops.ops(capsule).waivers.waivers

    def parachute_overrides(self) -> list[ParachuteOverride]:
        """Each capsule's PARACHUTE queued without landed evidence (``drs_link.ops.override``), from any
        console on the store; read at most once per ``OVERRIDE_READ_S``."""
        read_at, found = self._overrides
        if time.monotonic() - read_at < OVERRIDE_READ_S:
            return found
        found = []
        for capsule in self.setup.capsules:
            override = parachute_override(capsule, self.store.audit(capsule, action="mt.parachute"),
                                          self.ops.commands(capsule))  # fmt: skip
            if override is not None:
                found.append(override)
        self._overrides = (time.monotonic(), found)
        return found

    def record(self, records: list[TelemetryRecord]) -> None:
        if self.ops.recorder is not None:
            for record in records:
                self.ops.recorder.append(record)

    def close(self) -> None:
        """The operations layer closes the store with it; a server this context started ends too."""
        self.ops.close()
        if self.stop_server is not None:
            self.stop_server()


def context_for(
    setup: ConsoleSetup, warn: Callable[[str], None], live: Callable[[], LiveSource | None]
) -> ConsoleContext:
    """The context of the session's mode: commanding through the server, else a replay's. A console
    given ``Operations`` and no server gets a private one of its own, in this process, ended with it."""
    if setup.operations is None or setup.mode == "replay":
        return ReplayContext(setup, warn)
    if setup.server is not None:
        return CommandingContext(setup, warn, setup.operations, live, setup.server)
    from drs_link.server import InProcessServer

    ops = setup.operations
    server = InProcessServer(ops.config, environ=ops.environ, clock=ops.clock)
    context = CommandingContext(setup, warn, ops, live, server.socket)
    context.stop_server = server.stop
    return context
