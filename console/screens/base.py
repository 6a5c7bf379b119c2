"""What every console screen shares: the mode banner on top, the key bindings at the bottom."""

from __future__ import annotations

from typing import Any

from textual.app import ComposeResult
from textual.screen import Screen
from textual.widgets import Footer

from console.widgets.banner import ModeBanner


class ConsoleScreen(Screen[None]):
    """Screens re-render from the fleet state in ``refresh_view`` (each second and on new telemetry)."""

    @property
    def console(self) -> Any:
        """The DrsConsole app (typed loosely: screens and app import each other)."""
        return self.app

    def compose_banner(self) -> ComposeResult:
        yield ModeBanner(id="banner")

    def compose_footer(self) -> ComposeResult:
        yield Footer()

    def refresh_view(self) -> None:
        self.query_one(ModeBanner).refresh_banner()
