"""The top line: what this session is (LIVE, DEMO, REPLAY) and the console's own clock."""

from __future__ import annotations

from typing import Any

from textual.widgets import Static


class ModeBanner(Static):
    """Shown on every screen, so a DEMO or REPLAY session can never be taken for the live one."""

    def refresh_banner(self) -> None:
        app: Any = self.app
        self.set_class(app.mode == "demo", "demo")
        self.set_class(app.mode == "replay", "replay")
        self.update(f" {app.banner()} │ {app.now():%Y-%m-%d %H:%M:%S}Z │ operator {app.operator}")

    def on_mount(self) -> None:
        self.refresh_banner()
