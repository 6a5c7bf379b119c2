"""The help screen: every key, and what the safety rules are, in the operator's words."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Markdown

HELP = """\
# DRS console — keys

**Everywhere**: `?`/`F1` help · `Ctrl+P` command palette · `t` dark/light theme · `q` quit (asks first; disarms an open ARM; refused while Go is being sent) · `Esc` back

**Fleet** (a row per capsule with the columns that fit; the highlighted capsule in full words below;
⌛ marks a value older than twice its period, and the words say STALE; the balloon's position and
its feed's health at the bottom):
`↑`/`↓` choose · `Enter`/`r` release · `p` predictions · `i` Iridium · `v` recovery · `h` history ·
`A` approvals (a second operator's hazardous commands waiting for your login)

**Release**: `[` `]` switch checklist · `Space` tick a manual step · `x` skip (reason) ·
`o` power on (confirm; cannot be undone by software) · `s` sync data · `w` waive a go/no-go item
(GNSS fix or sync only; logged): the first `w` moves onto one, `↑`/`↓` another, `w` again asks
why · `a` ARM (only on GO; opens a countdown) · `d` disarm ·
`f` FIRE (only while armed; type the capsule's name; second operator or a logged waiver) ·
`R` reset after recovery (type the name)

**Predictions**: `+`/`-` release lead time · `←`/`→` release-window cursor · `e` export KML + GeoJSON + GPX

**Iridium**: `n` INTERVAL · `o`/`O` sounder off/on · `c` parachute (helper picks HH:MM) ·
`R` refresh

**Recovery**: `e` export GPX + KML · `n` INTERVAL · `o`/`O` sounder off/on · `c`/`C` parachute
(the same confirmations as on the Iridium screen; sounder and parachute cannot be confirmed by telemetry)

**History**: type to search (the search box has the focus) · `↓`/`Enter` the entries, the highlighted
one's detail (reasons) below · `e` export JSONL (from the entries)

Any change, lost link or stale critical input disarms. REPLAY sessions cannot command.
"""


class HelpScreen(ModalScreen[None]):
    """The keys in a scrolling pane, focused on opening: at 80×24 they run to twice the screen's height."""

    BINDINGS = [Binding("escape,q,question_mark", "app.pop_screen", "Close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help") as pane:
            pane.border_title = "Help"
            pane.border_subtitle = "↑/↓ PgUp/PgDn Home/End scroll · Esc closes"
            yield Markdown(HELP)

    def on_mount(self) -> None:
        self.query_one("#help", VerticalScroll).focus()
