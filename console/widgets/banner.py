"""The top line: what this session is (LIVE, DEMO, REPLAY) and the console's own clock."""

from __future__ import annotations

from datetime import datetime

from rich.cells import cell_len
from rich.text import Text
from textual.widgets import Static

from console.context import ConsoleContext
from console.widgets.quiet import set_content


def cut(text: str, width: int) -> str:
    """``text`` in at most ``width`` cells, an ellipsis marking where it was cut."""
    rich = Text(text)
    rich.truncate(max(width, 0), overflow="ellipsis")
    return rich.plain


def banner_line(mode: str, note: str, now: datetime, operator: str, width: int) -> str:
    """The banner cut to ``width`` by giving up the least needed words first.

    At 80 columns the demo's line ran to 89 and the terminal cut the operator's name. The mode's
    first word (DEMO, REPLAY, LIVE), its note (the time scale, the replayed file) and the operator
    are what a glance needs, so the mode's description goes first, then the date (the time
    stays); only a line still too long is cut at its end.
    """
    first, _, description = mode.partition(" ")
    head, suffix = f" {first}", f" {note}" if note else ""
    words = f" {description}" if description else ""
    for clock in (f"{now:%Y-%m-%d %H:%M:%S}Z", f"{now:%H:%M:%S}Z"):
        tail = f"{suffix} │ {clock} │ operator {operator}"
        room = width - cell_len(head) - cell_len(tail)
        if width <= 0 or room >= cell_len(words):
            return f"{head}{words}{tail}"
        if room >= 0:
            return f"{head}{cut(words, room) if room > 2 else ''}{tail}"
    return cut(f"{head}{suffix} │ {now:%H:%M:%S}Z │ operator {operator}", width)


class ModeBanner(Static):
    """Shown on every screen, so a DEMO or REPLAY session can never be taken for the live one."""

    def __init__(self, context: ConsoleContext, *, id: str | None = None) -> None:
        super().__init__(id=id, markup=False)
        self.context = context

    def refresh_banner(self) -> None:
        context = self.context
        self.set_class(context.mode == "demo", "demo")
        self.set_class(context.mode == "replay", "replay")
        mode, note = context.banner(), context.setup.banner_note
        mode = mode.removesuffix(note).rstrip() if note else mode
        set_content(self, banner_line(mode, note, context.now(), context.operator, self.size.width))

    def on_mount(self) -> None:
        self.refresh_banner()

    def on_resize(self) -> None:
        self.refresh_banner()


class OverrideBanner(Static):
    """Under the mode banner on every screen while a PARACHUTE is queued without landed evidence: an
    override in flight must never look like a normal recovery (issue #23). Hidden otherwise."""

    def __init__(self, context: ConsoleContext, *, id: str | None = None) -> None:
        super().__init__(id=id, markup=False)
        self.context = context

    def refresh_banner(self) -> None:
        lines = [f"⚠ {override.banner()}" for override in self.context.parachute_overrides()]
        if self.display != bool(lines):  # only a change costs a layout (console/widgets/quiet.py)
            self.display = bool(lines)
        if lines:
            set_content(self, "\n".join(lines))

    def on_mount(self) -> None:
        self.refresh_banner()
