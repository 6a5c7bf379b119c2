"""The console's screens, and the command palette entries that open them."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from textual.app import SystemCommand


def palette_commands(app: Any) -> Iterator[SystemCommand]:
    """Every screen for every capsule, reachable by typing its name in the palette (Ctrl+P)."""
    from console.screens.approvals import ApprovalScreen
    from console.screens.history import HistoryScreen
    from console.screens.iridium import IridiumScreen
    from console.screens.predictions import PredictionScreen
    from console.screens.recovery import RecoveryScreen
    from console.screens.release import ReleaseScreen

    yield SystemCommand("History", "Audit log: search and export", lambda: app.push_screen(HistoryScreen()))
    if app.commanding:
        yield SystemCommand("Approvals", "Hazardous commands waiting for a second operator",
                            lambda: app.push_screen(ApprovalScreen()))  # fmt: skip
    for name in app.setup.capsules:
        for title, screen in (
            ("Release", ReleaseScreen),
            ("Predictions", PredictionScreen),
            ("Iridium", IridiumScreen),
            ("Recovery", RecoveryScreen),
        ):
            yield SystemCommand(
                f"{title}: {name}", f"Open the {title.lower()} screen of {name}",
                lambda screen=screen, name=name: app.push_screen(screen(name)),
            )  # fmt: skip
