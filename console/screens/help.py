"""The help screen: every key, and what the safety rules are, in the operator's words."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import ModalScreen
from textual.widgets import Markdown

HELP = """\
# DRS console — keys

**Everywhere**: `?`/`F1` help · `Ctrl+P` command palette · `t` dark/light theme · `q` quit (asks first; disarms an open ARM; refused while Go is being sent) · `Esc` back

**Fleet** (a row per capsule with the columns that fit; the highlighted capsule in full words below;
⌛ marks a value older than twice its period, and the words say STALE; the balloon's position and
its feed's health at the bottom):
`↑`/`↓` choose · `Enter`/`r` release · `p` predictions · `i` Iridium · `v` recovery · `h` history

**Release**: `[` `]` switch checklist · `Space` tick a manual step · `x` skip (reason) ·
`o` power on (confirm; cannot be undone by software) · `s` sync data · `w` waive the selected
go/no-go item (GNSS or sync only; logged) · `a` ARM (only on GO; opens a countdown) · `d` disarm ·
`f` FIRE (only while armed; type the capsule's name; second operator or a logged waiver) ·
`R` reset after recovery (type the name)

**Predictions**: `+`/`-` release lead time · `←`/`→` release-window cursor · `e` export KML + GeoJSON

**Iridium**: `n` INTERVAL · `o`/`O` sounder off/on · `c` parachute (helper picks HH:MM) ·
`R` refresh

**Recovery**: `e` export GPX + KML · `n` INTERVAL · `o`/`O` sounder off/on · `c`/`C` parachute
(the same confirmations as on the Iridium screen; sounder and parachute cannot be confirmed by telemetry)

**History**: type to search · `e` export JSONL

Any change, lost link or stale critical input disarms. REPLAY sessions cannot command.
"""


class HelpScreen(ModalScreen[None]):
    BINDINGS = [Binding("escape,q,question_mark", "app.pop_screen", "Close")]

    def compose(self) -> ComposeResult:
        yield Markdown(HELP, id="help")
