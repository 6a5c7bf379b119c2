"""The operator console: one Textual app over the fleet state, every blocking call in a worker thread.

The app owns no release rules: it folds telemetry into ``FleetState``, shows it, and turns keys
into intents: ARM, FIRE, disarm, approvals and MT sends go to the operations server (``drs_link.server``),
whose ARM windows and waiting approvals it pushes back (``follow_events``), as are the checklists, waivers,
audit, session and views (``drs_link.server.desk``, read again when the audit moves on: ``audit_moved``);
the server also polls the capsules, checks the gateway and reads the Iridium reports once for every
console and pushes the telemetry (``follow_telemetry``). Those accept or refuse them. HTTP and
predictions run in thread workers (the release in its own group,
never exclusive, so a refresh can never cancel a FIRE); their results come back as messages
(``console.messages``). The screens never see the app: each is handed the ``ConsoleContext``
(``console.context``) it works on, and the fleet opens them from ``console.screens.registry``.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import threading
import time
from collections.abc import Iterable
from datetime import datetime

from textual import on, work
from textual.app import App, SystemCommand
from textual.binding import Binding
from textual.notifications import SeverityLevel
from textual.screen import ModalScreen, Screen
from textual.worker import Worker

from console.context import ARMED, FIRING, ConsoleContext, ConsoleSetup, context_for
from console.messages import AuditRead, OperatorNotice, TelemetryArrived, ViewRead, ViewWanted, failure_notice
from console.predictions import PredictionService
from console.screens import ConfirmModal, FleetScreen
from drs_link.errors import LinkError
from drs_link.ops import (
    BalloonSample,
    Checklist,
    FleetState,
    GnssSample,
    GoNoGoReport,
    LinkSample,
    LiveSource,
    PredictionSample,
    PredictionStatus,
    ReleaseOrigin,
    ReleaseWindow,
    ReportSample,
    TelemetryRecord,
    ViewSource,
    unprotected_ssh_warning,
)
from predictor.descent import COMPILE_NOTICE, kernels_compiled
from predictor.errors import PredictorError

EVENTS_RETRY_S = 2.0
"""How soon a dropped event or telemetry stream from the operations server is followed again."""
PREDICTION_LEAD_MIN = (0, 10)
BALLOON_READ_S = 0.1
"""How often the feed's latest fix is taken (a lock and a copy, nothing drawn unless a fix is new): a first
fix starts a prediction within a tenth of a second of its arrival, where every 0.5 s it waited 0.25 s on
average (``make bench-console``)."""
NO_WEATHER = "no weather loaded: start with --weather FILES (or drs weather fetch)"
WAITING_FOR_POSITION = "waiting for a position: the capsule's GNSS fix or the balloon feed"
GO_FINISH_S = 120.0
"""How long a lost session waits for a Go in flight to finish and be recorded before the process ends."""
LOST_SIGNALS = (signal.SIGHUP, signal.SIGTERM)
SHUTDOWN_GRACE_S = 5.0
"""After a lost session, how long an orderly shutdown may take before the process simply ends."""


class DrsConsole(App[int]):
    CSS_PATH = ["styles/console.tcss"]
    TITLE = "DRS console"
    BINDINGS = [
        Binding("question_mark,f1", "help", "Help"),
        Binding("t", "toggle_theme", "Theme", show=False),
        Binding("q", "quit", "Quit"),
    ]

    def __init__(self, setup: ConsoleSetup, live_timers: bool = True) -> None:
        super().__init__()
        self.context: ConsoleContext = context_for(setup, self._warn, self._live)
        """What the screens work on (``console.context``), commanding or a replay's: each screen the app
        opens is handed it."""
        self.live_timers = live_timers
        self.predicting: set[str] = set()
        """Capsules with a prediction running: one at a time each, so a slow first one never piles up."""
        self.theme = "textual-dark"
        if setup.low_bandwidth:
            self.animation_level = "none"
        self._audit_seen = self.context.desk.audit_id
        """The newest audit row this console has shown or written: what another console wrote comes after."""
        self._views_reading: set[tuple[str, str]] = set()
        self._views_stale: set[tuple[str, str]] = set()
        self._events: asyncio.Task[None] | None = None
        """The server's push, followed for the app's life (a task, not a worker: it never completes)."""
        self._telemetry: asyncio.Task[None] | None = None
        """The server's telemetry, followed likewise (``follow_telemetry``)."""
        self._reports_seen: set[str] = set()
        """The Iridium reports folded so far: a stream followed again starts with all of them."""
        self._windows: dict[str, tuple[datetime, ReleaseWindow | None]] = {}
        """Each capsule's release window and the "release now" time it was swept after."""

    # The context's state and calls, as the app's own code (and its tests) name them ------------

    @property
    def setup(self) -> ConsoleSetup:
        return self.context.setup

    @setup.setter
    def setup(self, setup: ConsoleSetup) -> None:
        self.context.setup = setup

    @property
    def fleet(self) -> FleetState:
        return self.context.fleet

    @property
    def checklists(self) -> list[Checklist]:
        return self.context.checklists

    @property
    def commanding(self) -> bool:
        return self.context.commanding

    @property
    def views(self) -> ViewSource:
        return self.context.views

    @property
    def operator(self) -> str:
        return self.context.operator

    def now(self) -> datetime:
        return self.context.now()

    def view_time(self) -> datetime:
        return self.context.view_time()

    def banner(self) -> str:
        return self.context.banner()

    def gonogo(self, capsule: str) -> GoNoGoReport:
        return self.context.gonogo(capsule)

    def prediction_origin(self, capsule: str) -> ReleaseOrigin | None:
        return self.context.prediction_origin(capsule)

    # Lifecycle --------------------------------------------------------------------------------

    def on_mount(self) -> None:
        self.push_screen(FleetScreen(self.context))
        if self.commanding:  # what the server holds (ARM windows, approvals) shows as it changes
            self._events = asyncio.get_running_loop().create_task(self.follow_events())
        if not self.live_timers:
            return
        if self.commanding:
            self._start_session()
            self.start_telemetry()
        if self.setup.predictions is not None:
            self.set_interval(self.setup.prediction_period_s, self.refresh_predictions)
        elif self.context.mode != "replay":  # a replay shows the predictions it recorded
            for name in self.setup.capsules:
                self.fleet.apply(self.prediction_status(name, "no weather", NO_WEATHER))
        if self.setup.balloon_feed is not None:
            self.read_balloon()  # a fix already there starts its prediction now, not a period later
            self.set_interval(BALLOON_READ_S, self.read_balloon)
        if self.setup.replay_feed is not None:
            self.set_interval(0.2, self.replay_step)
        self.set_interval(1.0, self.tick)

    def _start_session(self) -> None:
        """Say what ended the last session if nobody has since, and survive this one being cut off."""
        try:
            loss = self.context.session_started()
        except LinkError as exc:
            self.notify(f"the session's start is not on the record: {exc}", severity="error", timeout=30)
            loss = None
        if loss is not None:
            self.notify(f"last console: {loss.describe()}", severity="warning", timeout=60)
        warning = unprotected_ssh_warning(os.environ)
        if warning is not None:
            self.notify(warning, severity="warning", timeout=30)
        loop = asyncio.get_running_loop()
        for sig in LOST_SIGNALS:
            loop.add_signal_handler(sig, self.session_lost, sig)

    def session_lost(self, sig: signal.Signals) -> None:
        """SIGHUP (the SSH session dropped) or SIGTERM: disarm on the record, let a Go in flight finish
        and be recorded by its worker, then end (``drs_link.ops.session``)."""
        self.run_worker(self._end_after_go(sig), group="session-lost")

    async def _end_after_go(self, sig: signal.Signals) -> None:
        # The loss is on the record before anything else, in a thread: a server or store held by another
        # console's action must not freeze the event loop that is ending the session.
        firing = self.arm_states(FIRING)
        disarmed = await asyncio.to_thread(self.disarm_mine, f"session lost ({sig.name})")
        with contextlib.suppress(LinkError):  # no server to write it to: nothing else can be done as it ends
            await asyncio.to_thread(self.context.session_lost, sig.name, disarmed, firing)
        code = 128 + sig.value
        deadline = time.monotonic() + GO_FINISH_S
        while self.firing_here() and time.monotonic() < deadline:
            await asyncio.sleep(0.2)
        if not self.is_headless:
            # With the terminal hung up, Textual's shutdown can block for good flushing output nobody
            # reads (its writer thread stops on the dead pty; a console was found alive hours later,
            # holding the store and its links). Everything owed is on the record by now.
            threading.Timer(SHUTDOWN_GRACE_S, os._exit, args=(code,)).start()
        self.exit(code)

    def arm_states(self, state: str) -> list[str]:
        """The capsules whose ARM window, as the server last said, is this account's and in ``state``."""
        found = []
        for name in self.setup.capsules:
            status = self.context.arm_state(name)
            if status is not None and status.mine and status.state == state:
                found.append(name)
        return found

    def firing_here(self) -> bool:
        """A Go of this account is in flight: a FIRE of this console still waits for its answer, or the
        server says a window of this account is FIRING."""
        waiting = any(worker.name == "fire_worker" and not worker.is_finished for worker in self.workers)
        return waiting or bool(self.arm_states(FIRING))

    def disarm_mine(self, reason: str) -> list[str]:
        """Close this account's open windows through the server (in a worker thread); the ones closed."""
        closed = []
        for name in self.arm_states(ARMED):
            try:
                self.context.disarm(name, reason)
            except LinkError as exc:
                self.call_from_thread(self.notify, str(exc), severity="error")
                continue
            closed.append(name)
        return closed

    @work(thread=True, exit_on_error=False, group="audit")
    def audit_moved(self) -> None:
        """The server's audit moved on (``Event.audit_id``): this console's desk (waivers, ticks, PARACHUTE
        overrides) is read again, and what another console or a drs command did is shown with who did it,
        within a second, without any screen polling on its own."""
        try:
            self.context.read_desk()
            after = self.context.audit_after(self._audit_seen)
        except LinkError as exc:
            self.post_message(OperatorNotice(f"the audit cannot be read: {exc}", "warning"))
            return
        self.post_message(AuditRead(after))

    @on(AuditRead)
    def show_audit(self, message: AuditRead) -> None:
        after = message.after
        for row in after.records:
            if row.id <= self._audit_seen:  # two reads overlapped: each entry is told once
                continue
            self._audit_seen = row.id
            where = after.elsewhere(row)
            if where is not None:
                about = f"{row.capsule}: " if row.capsule else ""
                hint = " (A on the fleet: approvals)" if row.action == "approval.requested" else ""
                self.notify(f"{about}{row.action} {row.result} — {row.operator}, {where}{hint}", timeout=8)
        self.read_views()
        self.refresh_screen()

    def tick(self) -> None:
        """Once a second: ages grow, ARM windows run out, first predictions start, the screen shows all."""
        if self.commanding:
            self.watch_arming(self.setup.capsules, set())
        if self.setup.predictions is not None:
            self.first_predictions()
        self.refresh_screen()

    def watch_arming(self, capsules: Iterable[str], links_lost: set[str]) -> None:
        """Close this account's open ARM windows of ``capsules`` whose poll here turned NO-GO or whose
        link was lost, through the server (on the record) in a worker thread. FIRE polls again on the
        server, so a disarm a moment later never lets a Go through."""
        mine = set(self.arm_states(ARMED))
        reasons = {}
        for name in capsules:
            if name not in mine:
                continue
            if name in links_lost:
                reasons[name] = "link lost"
                continue
            poll = self.gonogo(name)
            if not poll.go:
                reasons[name] = f"no longer GO: {poll.summary()}"
        if not reasons:
            return

        def close() -> None:
            for name, reason in reasons.items():
                try:
                    self.context.disarm(name, reason)
                except LinkError as exc:
                    self.post_message(OperatorNotice(str(exc), "warning"))
            self.call_from_thread(self.refresh_screen)

        self.run_worker(close, thread=True, group="arming-watch", exit_on_error=False)

    async def follow_events(self) -> None:
        """The server's push: ARM windows and waiting approvals, shown as they change (in this loop,
        cancelled with the app). A dropped stream is said once and followed again."""
        while True:
            try:
                async for event in self.context.client().event_stream():
                    self.context.apply_event(event)
                    if event.audit_id != self._audit_seen:
                        self.audit_moved()
                    self.refresh_screen()
            except (OSError, LinkError) as exc:
                self.notify(
                    f"the operations server's updates stopped: {exc}; reconnecting", severity="warning"
                )
            await asyncio.sleep(EVENTS_RETRY_S)

    def start_telemetry(self) -> None:
        """Follow the server's telemetry from now on (at mount, with the live timers; a test, when it
        wants the capsules' records)."""
        if self._telemetry is None:
            self._telemetry = asyncio.get_running_loop().create_task(self.follow_telemetry())

    async def follow_telemetry(self) -> None:
        """The capsules' telemetry as the server polls it for every console: its snapshot first, then
        each batch, recorded and folded as any telemetry (in this loop, cancelled with the app). A
        dropped stream is said once and followed again."""
        told = False
        while True:
            try:
                async for records in self.context.client().telemetry_stream():
                    told = False
                    fresh = self._unseen(records)
                    if fresh:
                        await asyncio.to_thread(self.context.record, fresh)
                        self.post_message(TelemetryArrived(fresh))
            except (OSError, LinkError) as exc:
                if not told:
                    self.notify(
                        f"the operations server's telemetry stopped: {exc}; reconnecting", severity="warning"
                    )
                    told = True
            await asyncio.sleep(EVENTS_RETRY_S)

    def _unseen(self, records: list[TelemetryRecord]) -> list[TelemetryRecord]:
        """``records`` without the Iridium reports already folded: each report adds to a capsule's count
        and track, and a stream followed again starts with every report the server read."""
        fresh = []
        for record in records:
            if isinstance(record.data, ReportSample):
                key = record.to_json()
                if key in self._reports_seen:
                    continue
                self._reports_seen.add(key)
            fresh.append(record)
        return fresh

    def refresh_screen(self) -> None:
        """Every screen in sight: the top one and, under a dialog, the screens it shows: time must not
        stand still behind a dialog (an ARM countdown frozen under the FIRE dialog ran out unseen).

        A screen hidden under another is redrawn when it comes back (``ConsoleScreen.on_screen_resume``),
        not while hidden: Textual repaints the whole top screen for any change to the screen beneath
        it, which was a full-screen repaint every second on the release screen over the fleet."""
        for screen in reversed(self.screen_stack):
            if hasattr(screen, "refresh_view"):
                screen.refresh_view()
            if not isinstance(screen, ModalScreen):
                break

    # Workers ----------------------------------------------------------------------------------

    def read_balloon(self) -> None:
        assert self.setup.balloon_feed is not None
        record = self.setup.balloon_feed.latest()
        if record is not None:
            self.post_message(TelemetryArrived([record]))

    def replay_step(self) -> None:
        assert self.setup.replay_feed is not None
        records = self.setup.replay_feed()
        if records:
            self.post_message(TelemetryArrived(records))

    def refresh_predictions(self, names: Iterable[str] | None = None) -> None:
        for name in self.setup.capsules if names is None else names:
            if self.fleet.capsules[name].released or name in self.predicting:
                continue
            origin = self.prediction_origin(name)
            if origin is None:
                self.fleet.apply(self.prediction_status(name, "waiting", WAITING_FOR_POSITION))
                continue
            self.predicting.add(name)
            self.run_prediction(name, origin)

    def first_predictions(self) -> None:
        """Every second until a capsule has its first prediction: its first position may arrive at any
        moment (the balloon feed's first fix, a GNSS fix after power-on), and the operator should see a
        landing within seconds of it, not a whole prediction period later."""
        self.refresh_predictions(
            [
                name
                for name in self.setup.capsules
                if self.fleet.capsules[name].reading(PredictionSample).value is None
            ]
        )

    def prediction_status(self, name: str, short: str, text: str) -> TelemetryRecord:
        """What the console is doing about a capsule's first prediction, shown until it has one."""
        return TelemetryRecord(self.now(), name, PredictionStatus(short, text))

    @work(thread=True, exit_on_error=False, group="predictions")
    def run_prediction(self, name: str, origin: ReleaseOrigin) -> None:
        assert self.setup.predictions is not None
        try:
            first = "compiling" if not kernels_compiled() else "computing…"
            text = COMPILE_NOTICE if first == "compiling" else f"computing the landing from {origin.source}…"
            self.post_message(TelemetryArrived([self.prediction_status(name, first, text)]))
            records = self.setup.predictions.predict(name, origin, release_in=PREDICTION_LEAD_MIN)
        except PredictorError as exc:
            self.post_message(TelemetryArrived([self.prediction_status(name, "failed", f"failed: {exc}")]))
            self.post_message(OperatorNotice(f"{name}: prediction failed: {exc}", "warning"))
            return
        finally:
            self.predicting.discard(name)  # one atomic set operation: safe from this worker thread
        self.context.record(records)
        self.post_message(TelemetryArrived(records))

    def read_views(self, capsules: Iterable[str] | None = None) -> None:
        """Read afresh each view a screen in the stack shows (of ``capsules``, or all)."""
        for screen in self.screen_stack:
            shows = getattr(screen, "shows", None)
            if shows is not None and (capsules is None or shows[1] in capsules):
                self.read_view(*shows)

    def read_view(self, kind: str, capsule: str) -> None:
        """One read at a time per view; a change while it runs reads once more when it ends.

        The release window is swept again only after a new "release now" prediction (its basis)."""
        key = (kind, capsule)
        if key in self._views_reading:
            self._views_stale.add(key)
            return
        if kind == "window":
            origin, basis = self.prediction_origin(capsule), self.window_basis(capsule)
            service = self.setup.predictions
            if basis is None or origin is None or service is None:
                return
            if capsule in self._windows and self._windows[capsule][0] == basis:
                return
            self._windows[capsule] = (basis, self._windows.get(capsule, (basis, None))[1])
            self._views_reading.add(key)
            self._sweep(service, capsule, origin, basis)
            return
        self._views_reading.add(key)
        self._read_view(kind, capsule)

    def window_basis(self, capsule: str) -> datetime | None:
        """The "release now" prediction a release window is swept after (its release time)."""
        reading = self.fleet.capsules[capsule].predictions.get(0)
        return reading.value.release_time if reading is not None and reading.value is not None else None

    @work(thread=True, exit_on_error=False, group="views")
    def _read_view(self, kind: str, capsule: str) -> None:
        try:
            view = self.views.recovery(capsule) if kind == "recovery" else self.views.iridium(capsule)
            self.post_message(ViewRead(kind, capsule, view))
        finally:
            self.call_from_thread(self._view_done, (kind, capsule))

    @work(thread=True, exit_on_error=False, group="release-window")
    def _sweep(
        self, service: PredictionService, capsule: str, origin: ReleaseOrigin, basis: datetime
    ) -> None:
        """The release window from ``origin`` (``drs_link.ops.ReleaseWindow``), for the predictions screen."""
        try:
            window = service.release_window(origin, self.context.zones_file, capsule=capsule)
        except PredictorError as exc:
            self.post_message(OperatorNotice(f"release window failed: {exc}", "warning"))
        else:
            self.call_from_thread(self._windows.__setitem__, capsule, (basis, window))
            self.post_message(ViewRead("window", capsule, window))
        finally:
            self.call_from_thread(self._view_done, ("window", capsule))

    def _view_done(self, key: tuple[str, str]) -> None:
        self._views_reading.discard(key)
        if key in self._views_stale:
            self._views_stale.discard(key)
            self.read_view(*key)

    def _warn(self, text: str) -> None:
        """Tell the operator something, from any thread."""
        self.post_message(OperatorNotice(text, "warning"))

    def _live(self) -> LiveSource | None:
        """The live re-prediction, once the prediction service (the weather) is there."""
        service = self.setup.predictions
        return service.live if service is not None else None

    # Messages ---------------------------------------------------------------------------------

    @on(ViewWanted)
    def want_view(self, message: ViewWanted) -> None:
        window = self._windows.get(message.capsule, (None, None))[1] if message.kind == "window" else None
        if window is not None:  # a screen opened again on the window already swept: show it now
            self.show_view(ViewRead("window", message.capsule, window))
        self.read_view(message.kind, message.capsule)

    @on(ViewRead)
    def show_view(self, message: ViewRead) -> None:
        for screen in self.screen_stack:
            if getattr(screen, "shows", None) == (message.kind, message.capsule):
                screen.post_message(ViewRead(message.kind, message.capsule, message.view))

    @on(TelemetryArrived)
    def fold(self, message: TelemetryArrived) -> None:
        for record in message.records:
            self.fleet.apply(record)
        self.views.observe(message.records)
        if self.commanding:
            touched = sorted({r.capsule for r in message.records if r.capsule} & set(self.setup.capsules))
            links_lost = {
                r.capsule
                for r in message.records
                if isinstance(r.data, LinkSample) and not r.data.up and r.capsule
            }
            self.watch_arming(touched, links_lost)
        self.read_views({r.capsule for r in message.records if r.capsule})
        if self.setup.predictions is not None and any(
            isinstance(r.data, BalloonSample | GnssSample) for r in message.records
        ):
            self.first_predictions()  # a first position: predict now, not at the next tick
        self.refresh_screen()

    @on(OperatorNotice)
    def show_notice(self, message: OperatorNotice) -> None:
        self.notify(message.text, severity=message.severity, timeout=8)

    @on(Worker.StateChanged)
    def worker_failed(self, event: Worker.StateChanged) -> None:
        notice = failure_notice(event)
        if notice is not None:
            self.show_notice(notice)

    # Actions ----------------------------------------------------------------------------------

    def action_help(self) -> None:
        from console.screens import HelpScreen  # Markdown and every screen's help: only when asked for

        self.push_screen(HelpScreen())

    async def action_quit(self) -> None:
        """A stray ``q`` must not end an ARM window or the polls: quitting a commanding console asks first.

        Refused while a Go is being sent (the answer is what tells the operator whether it dropped);
        an ARM window still open is disarmed and audited as closed with the console.
        """
        if not self.commanding:
            self.exit(0)
            return
        firing = self.arm_states(FIRING)
        if firing:
            self.notify(
                f"not quitting: Go is being sent to {', '.join(firing)}; wait for FIRED", severity="error"
            )
            return
        armed = self.arm_states(ARMED)
        powered = [n for n in self.setup.capsules if self.fleet.capsules[n].powered]
        lines = ["The capsules keep their state and the store keeps every record; polls, predictions and the",
                 "balloon feed stop until the console is started again."]  # fmt: skip
        if armed:
            lines.append(f"ARMED, will be disarmed: {', '.join(armed)}.")
        if powered:
            lines.append(f"Powered on and waiting for Go: {', '.join(powered)}.")

        def disarm_and_exit() -> None:
            """In a worker: the disarms go through the server, and the console ends once they are recorded."""
            try:
                self.disarm_mine("console closed")
            finally:
                self.call_from_thread(self.exit, 0)

        def confirmed(yes: bool | None) -> None:
            if yes:
                self.run_worker(disarm_and_exit, thread=True, group="store-write", exit_on_error=False)

        self.push_screen(ConfirmModal("Quit the DRS console?", "\n".join(lines), "Quit"), confirmed)

    def action_toggle_theme(self) -> None:
        self.theme = "textual-light" if self.theme == "textual-dark" else "textual-dark"

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        from console.screens import palette_commands

        yield from palette_commands(self.context, self.push_screen)

    def notify(
        self,
        message: str,
        *,
        title: str = "",
        severity: SeverityLevel = "information",
        timeout: float | None = None,
        markup: bool = False,
    ) -> None:
        """Operator messages quote commands like ``[PARACHUTE=12:13]``: never read them as markup."""
        super().notify(message, title=title, severity=severity, timeout=timeout, markup=markup)

    def on_unmount(self) -> None:
        for task in (self._events, self._telemetry):
            if task is not None:
                task.cancel()
        if self.commanding and self.live_timers:
            loop = asyncio.get_running_loop()
            for sig in LOST_SIGNALS:
                loop.remove_signal_handler(sig)
