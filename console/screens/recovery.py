"""Recovery of one capsule: where it landed and how sure, how far from the team, the phone line, exports.

The sounder, the interval and the parachute are Iridium commands: ``i`` opens that screen with
its confirmations; this one only reads (in a worker) and exports.
"""

from __future__ import annotations

import math
import time
from typing import Any

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Static

from console.screens.base import ConsoleScreen
from console.widgets.landing_map import MapLayers, render_map
from drs_link.iridium.recovery import (
    LandingEstimate,
    TrackPoint,
    detect_landing,
    distance_bearing,
    phone_summary,
    track_from_reports,
    write_gpx,
    write_kml,
)

RELOAD_S = 2.0


class RecoveryScreen(ConsoleScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        Binding("i", "iridium", "Iridium cmds"),
        Binding("e", "export", "Export GPX/KML"),
    ]

    def __init__(self, capsule: str) -> None:
        super().__init__()
        self.capsule = capsule
        self.track: list[TrackPoint] = []
        self.landing: LandingEstimate | None = None
        self.loaded_at = time.monotonic()

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Horizontal(id="recovery-body"):
            yield Static(id="recovery-text", markup=False)
            yield Static(id="recovery-map", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.load()

    @work(thread=True, exit_on_error=False, group="recovery-read")
    def load(self) -> None:
        ops = self.console.ops
        reports = ops.stored_reports(self.capsule) if ops else []
        track = track_from_reports(reports)
        self.app.call_from_thread(self.show, track, detect_landing(track))

    def show(self, track: list[TrackPoint], landing: LandingEstimate | None) -> None:
        self.track, self.landing = track, landing
        self.refresh_view()

    def update_view(self) -> None:
        if time.monotonic() - self.loaded_at >= RELOAD_S:
            self.loaded_at = time.monotonic()
            self.load()
        team = self.console.setup.team_position
        last = self.track[-1] if self.track else None
        lines = [f"{self.capsule} recovery", ""]
        if self.landing is not None:
            landing = self.landing
            std = "?" if math.isnan(landing.std_m) else f"{landing.std_m:.0f}"
            lines.append(f"Landed {landing.landed_at:%H:%M:%S}Z at {landing.lat:.5f}, {landing.lon:.5f}")
            lines.append(f"  scatter ±{std} m (1σ per axis) from {landing.count} fixes, {landing.rejected} rejected")
            if team is not None:
                distance, bearing = distance_bearing(team[0], team[1], landing.lat, landing.lon)
                lines.append(f"  from the team: {distance / 1000:.2f} km at {bearing:.0f}°")
        elif last is not None:
            lines.append(f"Not landed (visibly): last fix {last.lat:.5f}, {last.lon:.5f} at {last.alt_m:.0f} m")
        else:
            lines.append("No GNSS fix received yet")
        reading = self.console.fleet.capsules[self.capsule].reading("report")
        value: dict[str, Any] = reading.value or {}
        now = self.console.now()
        lines += [
            "",
            "Last report: " + reading.label(now, lambda v: f"VBAT {v.get('vbat')} V, interval {v.get('interval_min')} min"),
            f"Sounder/interval/parachute: press i ({value.get('interval_min', '?')} min interval assumed)",
            "",
            "Phone: " + phone_summary(self.capsule, self.landing, last, team),
        ]
        self.query_one("#recovery-text", Static).update("\n".join(lines))
        prediction = self.console.fleet.capsules[self.capsule].reading("prediction").value
        layers = MapLayers(
            path=[(p.lon, p.lat) for p in self.track],
            ellipse=[tuple(p) for p in prediction["outline_2sigma"]] if prediction else (),
            landing=(self.landing.lon, self.landing.lat) if self.landing else None,
            team=(team[1], team[0]) if team else None,
            scatter=[(p.lon, p.lat) for p in self.track[-10:]] if self.landing else [],
        )
        widget = self.query_one("#recovery-map", Static)
        widget.update(render_map(layers, max(20, widget.size.width or 40), max(6, widget.size.height or 12)))

    def action_iridium(self) -> None:
        from console.screens.iridium import IridiumScreen

        self.app.push_screen(IridiumScreen(self.capsule))

    def action_export(self) -> None:
        directory = self.console.setup.export_dir
        directory.mkdir(parents=True, exist_ok=True)
        stamp = f"{self.console.now():%Y%m%dT%H%M%SZ}"
        prediction = self.console.fleet.capsules[self.capsule].reading("prediction").value
        predicted = [(lat, lon, 0.0) for lon, lat in prediction["path"]] if prediction else []
        gpx = directory / f"{self.capsule}-recovery-{stamp}.gpx"
        kml = directory / f"{self.capsule}-recovery-{stamp}.kml"
        try:
            write_gpx(gpx, self.capsule, self.track, predicted, self.landing)
            write_kml(kml, self.capsule, self.track, predicted, self.landing)
        except OSError as exc:
            self.app.notify(f"export failed: {exc}", severity="error")
            return
        self.app.notify(f"exported {gpx.name} and {kml.name}")
