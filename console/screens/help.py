"""The help screen: every key, and what the safety rules are, in the operator's words."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Markdown

from console.screens.registry import SCREENS

HEADER = """\
# DRS console — keys

**Everywhere**: `?`/`F1` help · `Ctrl+P` command palette · `t` dark/light theme · `q` quit (asks first; disarms an open ARM; refused while Go is being sent) · `Esc` back

**Fleet** (a row per capsule with the columns that fit; the highlighted capsule in full words below;
⌛ marks a value older than twice its period, and the words say STALE; the balloon's position and
its feed's health at the bottom):
`↑`/`↓` choose"""
FOOTNOTE = "Any change, lost link or stale critical input disarms. REPLAY sessions cannot command."


def help_text() -> str:
    """The help as Markdown: the fleet's key for each screen, then each screen's own keys, in registry order."""
    fleet_keys = " · ".join([HEADER, *(entry.keys_help for entry in SCREENS)])
    sections = [f"**{entry.title}**: {entry.help()}" for entry in SCREENS if entry.help()]
    return "\n\n".join([fleet_keys, *sections, FOOTNOTE]) + "\n"


class HelpScreen(ModalScreen[None]):
    """The keys in a scrolling pane, focused on opening: at 80×24 they run to twice the screen's height."""

    BINDINGS = [Binding("escape,q,question_mark", "app.pop_screen", "Close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help") as pane:
            pane.border_title = "Help"
            pane.border_subtitle = "↑/↓ PgUp/PgDn Home/End scroll · Esc closes"
            yield Markdown(help_text())

    def on_mount(self) -> None:
        self.query_one("#help", VerticalScroll).focus()
