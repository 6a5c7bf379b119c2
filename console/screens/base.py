"""What every console screen shares: the context it works on, the mode banner on top, the keys at the bottom."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from textual import on
from textual.app import ComposeResult
from textual.css.query import NoMatches
from textual.screen import Screen
from textual.widgets import Footer
from textual.worker import Worker

from console.context import ConsoleContext
from console.messages import failure_notice
from console.widgets import ModeBanner, OverrideBanner
from drs_link.errors import LinkError

T = TypeVar("T")

FOOTER_ROOM = 100
"""Below this many columns the footer drops its "^p palette" hint (console.tcss): at 80 the hint,
docked right, covered the screen's last keys ("q Quit" on release and Iridium, more on recovery).
Ctrl+P still opens the palette, and the help says so."""


class ConsoleScreen(Screen[None]):
    """Screens re-render from the fleet state in ``update_view`` (each second and on new telemetry)."""

    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (FOOTER_ROOM, "-wide")]

    ready = False
    """Set once mounted: the app's one-second tick can reach a screen before its widgets exist."""

    def __init__(self, context: ConsoleContext) -> None:
        super().__init__()
        self.context = context
        """The fleet, the clock, the settings and the calls into ``drs_link``: never the app itself."""

    def compose_banner(self) -> ComposeResult:
        yield ModeBanner(self.context, id="banner")
        yield OverrideBanner(self.context, id="override-banner")

    def compose_footer(self) -> ComposeResult:
        yield Footer(compact=True)

    @on(Worker.StateChanged)
    def worker_failed(self, event: Worker.StateChanged) -> None:
        notice = failure_notice(event)
        if notice is not None:
            self.app.post_message(notice)

    def on_screen_resume(self) -> None:
        """Back on top: the app redraws only the screens in sight, so catch up with what changed."""
        self.refresh_view()

    def refresh_view(self) -> None:
        if not self.ready:
            return
        try:
            self.query_one(ModeBanner).refresh_banner()
            self.query_one(OverrideBanner).refresh_banner()
            self.update_view()
        except NoMatches:
            return  # the screen is being torn down (app exiting): nothing left to draw

    def update_view(self) -> None:
        """What the screen shows beyond the banner."""

    def write_off_ui(
        self, write: Callable[[], T], shown: Callable[[T], None], refused: Callable[[LinkError], None]
    ) -> None:
        """A key's write, a call to the operations server, in a worker thread: a server slow to answer (its
        store held by another write) must never freeze the screen. Its result, or its refusal, comes back on
        the UI thread."""

        def run() -> None:
            try:
                result = write()
            except LinkError as exc:
                self.app.call_from_thread(refused, exc)
                return
            self.app.call_from_thread(shown, result)

        self.run_worker(run, thread=True, group="store-write", exit_on_error=False)
