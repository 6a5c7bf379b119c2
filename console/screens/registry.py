"""Every screen the fleet opens, in one place: its key, its palette entry, its help, how it is built.

The fleet screen's key bindings, the command palette (Ctrl+P) and the help screen are all made from
``SCREENS``, so a new screen is its own module and one line here (and its test), and the three cannot
disagree about which screens exist.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from textual.app import SystemCommand
from textual.screen import Screen

from console.context import ConsoleContext
from console.screens.base import ConsoleScreen


@dataclass(frozen=True)
class ScreenEntry:
    """One screen the fleet opens."""

    title: str
    """Its name: in the palette, as the heading of its keys on the help screen, and the fleet's action."""
    key: str
    """The fleet screen's key(s) that open it, as Textual binds them (``"enter,r"``)."""
    keys_help: str
    """How the help's fleet paragraph names that key (``"`p` predictions"``)."""
    module: str
    """Its module in ``console.screens``, imported when the screen is first opened or the help shown:
    importing every screen (and the help's Markdown) before the fleet's first frame cost 0.5 s."""
    class_name: str
    """Its class there: built from the context and a capsule, or from the context alone when ``about``
    is given. The module's ``HELP`` lists its own keys on the help screen (none: no paragraph)."""
    footer: str | None = None
    """Its label in the fleet's footer; None keeps the key out of the footer (still bound, in help and palette)."""
    about: str | None = None
    """A fleet-wide screen's line in the palette; None: a screen of one capsule, listed once per capsule."""
    commanding_only: bool = False
    """Offered by the palette only on a console that can command (not in replay)."""

    def screen(self) -> Callable[..., ConsoleScreen]:
        return getattr(importlib.import_module(f"console.screens.{self.module}"), self.class_name)

    def help(self) -> str:
        return getattr(importlib.import_module(f"console.screens.{self.module}"), "HELP", "")

    def build(self, context: ConsoleContext, capsule: str) -> ConsoleScreen:
        """The screen for ``capsule`` (the fleet's highlighted one; a fleet-wide screen shows them all)."""
        return self.screen()(context) if self.about is not None else self.screen()(context, capsule)


SCREENS: tuple[ScreenEntry, ...] = (
    ScreenEntry("Release", "enter,r", "`Enter`/`r` release", "release", "ReleaseScreen", "Release"),
    ScreenEntry("Predictions", "p", "`p` predictions", "predictions", "PredictionScreen", "Predict"),
    ScreenEntry("Iridium", "i", "`i` Iridium", "iridium", "IridiumScreen", "Iridium"),
    ScreenEntry("Recovery", "v", "`v` recovery", "recovery", "RecoveryScreen", "Recovery"),
    ScreenEntry("History", "h", "`h` history", "history", "HistoryScreen", "History",
                about="Audit log: search and export"),
    ScreenEntry("Approvals", "A", "`A` approvals (a second operator's hazardous commands waiting for your login)",
                "approvals", "ApprovalScreen", about="Hazardous commands waiting for a second operator",
                commanding_only=True),
    ScreenEntry("Checklists", "c", "`c` checklists (every capsule's, read-only)", "checklists", "ChecklistsScreen",
                about="Every capsule's checklists: steps finished, not met, the next one"),
)  # fmt: skip


def screen_entry(title: str) -> ScreenEntry:
    """The entry the fleet's action names (its binding carries the title)."""
    return next(entry for entry in SCREENS if entry.title == title)


def palette_commands(
    context: ConsoleContext, push: Callable[[Screen[None]], object]
) -> Iterator[SystemCommand]:
    """Every screen for every capsule, reachable by typing its name in the palette (Ctrl+P)."""
    for entry in SCREENS:
        if entry.about is not None and (context.commanding or not entry.commanding_only):
            yield SystemCommand(entry.title, entry.about, lambda entry=entry: push(entry.build(context, "")))
    for name in context.setup.capsules:
        for entry in SCREENS:
            if entry.about is None:
                yield SystemCommand(
                    f"{entry.title}: {name}", f"Open the {entry.title.lower()} screen of {name}",
                    lambda entry=entry, name=name: push(entry.build(context, name)),
                )  # fmt: skip
