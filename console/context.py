"""What the screens work on, typed: the session's setup, the fleet state, and the calls into ``drs_link``.

The app builds one context for its mode (``context_for``) and hands it to each screen it opens,
instead of itself: the app imports the screens, so a screen that took the app could only type it
``Any``. The screens read the fleet, the clock and the settings from it and ask it for go/no-go,
arming, checklists, approvals and the audit log. A live or demo console gets a
``CommandingContext``: it acts through the operations server (``drs_link.server.Client``: ARM, FIRE,
disarm, approvals, MT sends, power-on, reset, sync, MT resolve) and shows what the server pushes (the
ARM windows, the approvals) and holds for it (``drs_link.server.desk``: its waivers, the checklists'
ticks, the PARACHUTE overrides, History, the recovery and Iridium views), and its fleet is the
telemetry the server polls and pushes; it opens no store and holds no ``drs_link.ops.OperatorOps``. A replay gets a
``ReplayContext``, which reads the server's audit and checklist ticks and has no commanding side at all:
asked for one, it refuses with ``REPLAY_REFUSAL`` (its keys are disabled too, so that is a last guard,
not a path a screen takes). Nothing here imports Textual: it
is the plain-Python side of the console.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from datetime import datetime, timedelta
from pathlib import Path

from console.predictions import PredictionService
from drs_link.errors import ConfigError, LinkError
from drs_link.feeds import BalloonFeed
from drs_link.ops import (
    PROCEDURE_DIR,
    AuditRecord,
    Checklist,
    ExclusionZone,
    FleetState,
    GoNoGoReport,
    IridiumHealthView,
    LandedEvidence,
    LiveSource,
    ParachuteOverride,
    RecordedViews,
    RecoveryView,
    ReleaseOrigin,
    SessionLoss,
    StepRecord,
    StepStatus,
    TelemetryRecord,
    TelemetryRecorder,
    ViewSource,
    Waiver,
    descent_along,
    evaluate,
    load_checklists,
    release_origin,
    statuses_of,
    utc_now,
    write_audit_export,
)
from drs_link.server import (
    POLL_PERIOD_S,
    PROTOCOL,
    TIMEOUT_S,
    ApprovalView,
    ArmState,
    Client,
    Desk,
    DeskView,
    Done,
    Event,
    Hello,
    HistoryView,
    MtSendRequest,
    MtView,
    ParachuteView,
    Pending,
    ReleaseView,
    Second,
)

ARMED, FIRING, FIRED = "armed", "firing", "fired"
"""The server's ARM window states (``ArmState.state``, ``drs_link.ops.ArmState`` values) a console tells
apart."""
READ_TIMEOUT_S = 5.0
"""The longest a background read of the desk or the audit waits. Not for a server stopping under it (the
console quitting): that one answers or closes each connection within its grace (``STOP_GRACE_S``, 3 s,
``drs_link.server.app``), and a read once left unanswered there was its bug, now fixed. It is for a server
alive but stuck (its store locked by another process, a worker pool full): the read answers in
milliseconds when all is well, nobody waits on it, and a worker held for the verbs' 600 s would hold the
console's quit, which waits for its workers."""
LOW_BANDWIDTH_AGE_STEP_S = 10.0
AGE_STEP_S = 5.0
"""The view time's step on an ordinary link: fresh readings' ages (0s…4s between heartbeats) ticking
every second were most of the idle fleet's 3.5 kB/s at ×1 (issue #25)."""


@dataclass
class ConsoleSetup:
    """Everything the app runs on; built by ``console.commands.console`` for live, demo and replay."""

    mode: str
    capsules: list[str]
    clock: Callable[[], datetime] = utc_now
    server: Path | None = None
    """The operations server's socket: every action, read and poll of a live or demo console goes through it,
    and a replay reads History from it (``context_for`` refuses a console without one)."""
    stop_server: Callable[[], None] | None = None
    """Ends the demo's in-process server with the session (a shared or on-demand one lives on)."""
    zones: tuple[ExclusionZone, ...] = ()
    """The exclusion zones the console draws and judges its own go/no-go with (``[console]
    exclusion_zones_file``, read by ``drs_link.ops.load_exclusion_zones``); the server judges with its own."""
    zones_file: Path | None = None
    """Their file, for the release-window sweep (the planner reads it itself)."""
    recorder: TelemetryRecorder | None = None
    """The session's recording (this account's own file), of the telemetry the console was shown."""
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
        """Stop what runs beside the app (the balloon feed's reader, the demo's server, the recording)."""
        if self.balloon_feed is not None:
            self.balloon_feed.stop()
        if self.stop_server is not None:
            self.stop_server()
        if self.recorder is not None:
            self.recorder.close()


REPLAY_REFUSAL = "a replay cannot command: there is no link behind a recording"


class ServerHistory:
    """The audit log as the operations server reads it; the export is written here, the operator's file."""

    def __init__(self, client: Callable[[], Client]) -> None:
        self.client = client
        self.read: HistoryView | None = None
        """The last answer: which entries came from another console is judged against it."""

    def newest(self, text: str | None = None) -> list[AuditRecord]:
        with self.client() as client:
            self.read = Desk(client).history(text)
        return list(self.read.records)

    def elsewhere(self, record: AuditRecord) -> str | None:
        return self.read.elsewhere(record) if self.read is not None else None

    def export(self, path: Path, text: str | None = None) -> int:
        with self.client() as client:
            every = Desk(client).history(text, limit=0)
        return write_audit_export(path, every.records)


class ServerViews:
    """A live console's recovery and Iridium views, read by the operations server from what it holds; the
    live re-prediction of a descent is the console's own (its weather), added to the track it was given."""

    def __init__(self, client: Callable[[], Client], live: Callable[[], LiveSource | None]) -> None:
        self.client = client
        self.live = live

    def recovery(self, capsule: str) -> RecoveryView:
        with self.client() as client:
            view = Desk(client).recovery(capsule)
        live = self.live()
        if live is None:
            return view
        return replace(view, descent=descent_along(view.descent.track, capsule, live))

    def iridium(self, capsule: str) -> IridiumHealthView:
        with self.client() as client:
            return Desk(client).iridium(capsule)

    def observe(self, records: Iterable[TelemetryRecord]) -> None:
        """The server's store already holds what was folded."""


class ConsoleContext:
    """The session's state and the calls every console makes, commanding or not; one per app.

    ``operations`` and ``client`` are the commanding side: only ``CommandingContext`` has one, and
    here they refuse (``LinkError``), so a screen calls them inside the ``try`` that shows a refusal.
    """

    commanding = False
    """Whether this console can command (a live or demo console): the screens dim their keys without."""

    def __init__(
        self,
        setup: ConsoleSetup,
        warn: Callable[[str], None],
        history: ServerHistory,
        poll_period_s: float = 0.0,
    ) -> None:
        self.setup = setup
        self.fleet = FleetState.for_capsules(setup.capsules, poll_period_s)
        self.checklists: list[Checklist] = load_checklists(PROCEDURE_DIR)
        """The procedure the operations layer ticks, so the screen shows the steps it completes."""
        self.warn = warn
        """Tells the operator something from any thread (the app posts it as a notice)."""
        self.history = history
        """The audit log as History reads and exports it, from the server."""
        self.desk = DeskView({}, {}, ())
        """What the server holds of this console's desk (its waivers, the ticks, the PARACHUTE overrides),
        as it last said: read again when the audit moves on (``read_desk``)."""
        self.in_flight: dict[str, list[Client]] = {}
        """Actions in progress per capsule (each its own connection), which ``c`` can withdraw."""
        self.views: ViewSource = RecordedViews()
        """Where the per-capsule screens' views come from: the recording here, the store when commanding."""

    @property
    def mode(self) -> str:
        return self.setup.mode

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

    def client(self, timeout_s: float = TIMEOUT_S) -> Client:
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

    def arm(self, capsule: str) -> ArmState:
        """ARM through the server, which polls go/no-go itself, with the waivers it holds for this account."""
        with self.client() as client:
            state = client.capsule(capsule).arm((), self._weather(), say=lambda _: None, held_waivers=True)
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
                typed_name, (), self._weather(), second, lambda _: None, on_pending, held_waivers=True
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

    def power_on(self, capsule: str) -> Done:
        """Latch the relay (confirmed by the operator first), then wait for the microcontroller's NMEA."""
        with self.client() as client:
            return client.capsule(capsule).power_on(True, say=lambda _: None)

    def reset(self, capsule: str, typed_name: str) -> ReleaseView:
        with self.client() as client:
            return client.capsule(capsule).reset(typed_name)

    def sync(self, capsule: str) -> None:
        """Upload the capsule's configured source, each file verified on the Pi."""
        with self.client() as client:
            client.capsule(capsule).sync(say=lambda _: None)

    def resolve_mt(self, capsule: str, command_id: int, gateway_id: int | None, note: str) -> list[MtView]:
        with self.client() as client:
            return client.iridium.resolve_mt(capsule, command_id, gateway_id, note)

    def plan_parachute(self, capsule: str, requested: tuple[int, int] | None) -> ParachuteView:
        """When a PARACHUTE can fire and the landed evidence the operator reads before sending."""
        with self.client() as client:
            return Desk(client).plan_parachute(capsule, requested)

    def landed(self, capsule: str) -> LandedEvidence:
        with self.client() as client:
            return Desk(client).landed(capsule)

    def waive(self, capsule: str, item: str, reason: str) -> None:
        """Waive a go/no-go item for this account at the server (audited there, once)."""
        with self.client() as client:
            held = Desk(client).waive(capsule, item, reason)
        self.desk = self.desk.with_waivers(capsule, held)

    def tick(self, capsule: str, checklist: str, step: str, reason: str | None = None) -> None:
        """Tick a manual step (or, with a reason, skip it), recorded by the server with this operator."""
        with self.client() as client:
            desk = Desk(client)
            if reason is None:
                recorded = desk.tick(capsule, checklist, step)
            else:
                recorded = desk.skip(capsule, checklist, step, reason)
        self.desk = self.desk.with_steps(capsule, recorded)

    def read_desk(self) -> None:
        """The desk as the server holds it now (in a worker: when the audit moved on)."""
        with self.client(READ_TIMEOUT_S) as client:
            self.desk = Desk(client).view()

    def audit_after(self, entry: int) -> HistoryView:
        """The audit entries after ``entry``, to show what another console did."""
        with self.client(READ_TIMEOUT_S) as client:
            return Desk(client).after(entry)

    def session_started(self) -> SessionLoss | None:
        with self.client() as client:
            return Desk(client).session_started()

    def session_lost(self, signal: str, disarmed: list[str], go_in_flight: list[str]) -> SessionLoss:
        with self.client() as client:
            return Desk(client).session_lost(signal, disarmed, go_in_flight)

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
        """Each capsule's PARACHUTE queued without landed evidence, from any console (none in a replay)."""
        return list(self.desk.overrides)

    def waivers(self, capsule: str) -> list[Waiver]:
        """This account's waivers of ``capsule``, as the server holds them."""
        return list(self.desk.waivers.get(capsule, ()))

    def step_records(self, capsule: str) -> tuple[StepRecord, ...]:
        return self.desk.checklists.get(capsule, ())

    def record(self, records: list[TelemetryRecord]) -> None:
        """Keep ``records`` in the session's recording; a replay records nothing."""

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

    def step_statuses(
        self, capsule: str, checklist: Checklist, facts: Mapping[str, object]
    ) -> list[StepStatus]:
        """Each step of ``checklist``: as recorded, else judged on the capsule's telemetry ``facts``."""
        return statuses_of(checklist, self.step_records(capsule), facts)

    def gonogo(self, capsule: str) -> GoNoGoReport:
        telemetry = self.fleet.capsules[capsule]
        now = self.now()
        return evaluate(capsule, telemetry.gonogo_inputs(now, self.zones), now, self.waivers(capsule))

    def prediction_origin(self, capsule: str) -> ReleaseOrigin | None:
        """Where a release would start (the rule is ``drs_link.ops.origin.release_origin``)."""
        return release_origin(self.fleet, capsule, self.now())


class ReplayContext(ConsoleContext):
    """A console with no link: a replayed recording.

    It shows what was recorded through the same views, and the operations server's audit and checklist
    ticks (read, never written: the commanding side does not exist)."""

    def __init__(self, setup: ConsoleSetup, warn: Callable[[str], None], server: Path) -> None:
        super().__init__(setup, warn, ServerHistory(lambda: Client(server, READ_TIMEOUT_S)))
        with Client(server, READ_TIMEOUT_S) as client:
            ticks = Desk(client).view().checklists
        self.desk = DeskView({}, ticks, ())
        """The ticks as the server holds them; no waivers or PARACHUTE overrides: a replay shows what was
        recorded, not what is held now."""


class CommandingContext(ConsoleContext):
    """A live or demo console: the same views, and the commanding side through the operations server."""

    commanding = True

    def __init__(
        self,
        setup: ConsoleSetup,
        warn: Callable[[str], None],
        live: Callable[[], LiveSource | None],
        server: Path,
    ) -> None:
        super().__init__(
            setup, warn, ServerHistory(self.client), 2.0 * setup.poll_period_s * setup.time_scale
        )
        self.server = server
        self.views = ServerViews(self.client, live)
        self.arms: dict[str, ArmState] = {}
        """Each capsule's ARM window as the server last pushed or answered it."""
        self.approvals: tuple[ApprovalView, ...] = ()
        with self.client() as client:
            self.hello: Hello = client.hello()
            """Who the server says this console is (its account, from the kernel)."""
            self.desk = Desk(client).view()

    @property
    def operator(self) -> str:
        """The name the server audits this console's steps with (its account's, from the kernel)."""
        return self.hello.operator

    @property
    def zones(self) -> tuple[ExclusionZone, ...]:
        return self.setup.zones

    @property
    def zones_file(self) -> Path | None:
        return self.setup.zones_file

    @property
    def require_second_operator(self) -> bool:
        return self.hello.require_second_operator

    def client(self, timeout_s: float = TIMEOUT_S) -> Client:
        return Client(self.server, timeout_s)

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

    def record(self, records: list[TelemetryRecord]) -> None:
        if self.setup.recorder is not None:
            for record in records:
                self.setup.recorder.append(record)


def context_for(
    setup: ConsoleSetup, warn: Callable[[str], None], live: Callable[[], LiveSource | None]
) -> ConsoleContext:
    """The context of the session's mode: commanding through the server, else a replay's (which reads
    History and the checklist ticks from it)."""
    if setup.server is None:
        raise ConfigError("a console needs its operations server (drs console finds or starts it)")
    if setup.mode == "replay":
        return ReplayContext(setup, warn, setup.server)
    return CommandingContext(setup, warn, live, setup.server)
