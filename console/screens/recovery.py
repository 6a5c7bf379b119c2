"""Recovery of one capsule: where it landed and how sure, how far from the team, the phone line, exports.

While it is still descending (fixes arriving, no landing detected) it also shows the live
re-prediction from the latest fix (``predictor.prediction.live``, computed in the same worker that reads the
reports), so the team drives towards where it is going now, not where it was predicted at release.

The team also needs, on this one screen, what the sounder, the report interval and the parachute
release were commanded to and how far each command got (``drs_link.iridium.commanded``: the unit
reports none of them, so the screen says what is known and no more), and to command them from
here with the Iridium screen's own confirmation flow (``console.screens.commanding``).
"""

from __future__ import annotations

import math
import time
from datetime import datetime
from typing import Any

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Static

from console.context import ConsoleContext
from console.screens.commanding import CommandingScreen, command_bindings
from console.screens.iridium import IridiumScreen
from console.widgets import LandingMap, MapLayers, set_content
from drs_link.iridium import (
    CommandedSettings,
    LandingEstimate,
    TrackPoint,
    commanded_settings,
    detect_landing,
    distance_bearing,
    phone_summary,
    track_from_reports,
    write_gpx,
    write_kml,
)
from drs_link.ops import (
    ParachuteOverride,
    PredictionSample,
    ReportSample,
    after_drop,
    drop_schedule,
    format_age,
    parachute_override,
)
from predictor.errors import PredictorError

RELOAD_S = 2.0


HELP = """\
`e` export GPX + KML · `n` INTERVAL · `o`/`O` sounder off/on · `c`/`C` parachute
(the same confirmations as on the Iridium screen; sounder and parachute cannot be confirmed by telemetry)"""
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class RecoveryScreen(CommandingScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back", show=False),
        Binding("i", "iridium", "Iridium"),
        Binding("e", "export", "Export"),
        *command_bindings(paired=True),
    ]

    def __init__(self, context: ConsoleContext, capsule: str) -> None:
        super().__init__(context)
        self.capsule = capsule
        self.track: list[TrackPoint] = []
        self.landing: LandingEstimate | None = None
        self.live: dict[str, Any] | None = None
        self.live_error: str | None = None
        self.settings: CommandedSettings | None = None
        self.drop: tuple[ParachuteOverride, datetime | None, str] | None = None
        """A PARACHUTE queued without landed evidence, when release B opens, and that in words."""
        self.loaded_at = time.monotonic()

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Horizontal(id="recovery-body"):
            yield Static(id="recovery-text", markup=False)
            yield LandingMap(id="recovery-map")
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.load()

    @work(thread=True, exit_on_error=False, group="recovery-read")
    def load(self) -> None:
        ops = self.context.ops
        reports = ops.stored_reports(self.capsule) if ops else []
        commands = ops.commands(self.capsule) if ops else []
        settings = commanded_settings(commands, reports) if ops else None
        parachutes = self.context.store.audit(self.capsule, action="mt.parachute")
        override = parachute_override(self.capsule, parachutes, commands)
        drop = (override, *drop_schedule(override, reports)) if override is not None else None
        track = track_from_reports(reports)
        landing = detect_landing(track)
        live, error = None, None
        service = self.context.setup.predictions
        if landing is None and track and service is not None:
            try:
                live = service.live(self.capsule, track)
            except PredictorError as exc:
                error = str(exc)
        self.app.call_from_thread(self.show, track, landing, live, error, settings, drop)

    def show(
        self,
        track: list[TrackPoint],
        landing: LandingEstimate | None,
        live: dict[str, Any] | None,
        error: str | None,
        settings: CommandedSettings | None,
        drop: tuple[ParachuteOverride, datetime | None, str] | None = None,
    ) -> None:
        self.track, self.landing, self.live, self.live_error = track, landing, live, error
        self.settings, self.drop = settings, drop
        self.refresh_view()

    def drop_lines(self, landing_time: datetime | None) -> list[str]:
        """The override's drop, as the firmware does it, and what the descent becomes after it."""
        if self.drop is None:
            return []
        override, drop, words = self.drop
        return [
            f"⚠ {override.text} queued WITHOUT landed evidence: {words}",
            f"  {after_drop(drop, landing_time)}",
        ]

    def reload_after_send(self) -> None:
        self.load()

    def settings_lines(self) -> list[Text]:
        """Setting and value in bold: what a team in the field looks for first (is the sounder ON?)."""
        if self.settings is None:
            state = "reading" if self.context.ops else "not known in replay"
            return [Text(f"Sounder, interval, parachute: {state}")]
        lines = []
        for status in self.settings.statuses():
            line = Text(status.line)
            line.stylize("bold", 0, len(status.heading))
            lines.append(line)
        return lines

    def live_lines(self) -> list[str]:
        if self.landing is not None or not self.track:
            return []
        if self.live_error is not None:
            return [f"Live re-prediction failed: {self.live_error}"]
        if self.live is None:
            return ["Live re-prediction: computing"]
        live, landing, ellipse = self.live, self.live["landing"], self.live["ellipse"]
        report_time = datetime.fromisoformat(live["report"]["time"])
        age = format_age((self.context.now() - report_time).total_seconds())
        rate = live["measured_rate_factor"]
        measured = "— (needs two fixes)" if rate is None else f"{rate:.2f}"
        lines = [
            f"Live re-prediction from the {report_time:%H:%M:%S}Z fix ({age} ago) at {live['report']['alt_m']:.0f} m:",
            f"  landing {landing['lat']:.4f}, {landing['lon']:.4f} at {landing['time'][11:19]}Z,"
            f" {live['remaining_drift_km']:.1f} km to go",
            f"  σ∥ {ellipse['sigma_parallel_km']:.2f} km  σ⊥ {ellipse['sigma_perpendicular_km']:.2f} km",
            f"  measured rate factor {measured} from {live['legs_used']} leg{'' if live['legs_used'] == 1 else 's'}",
            f"  correction: {live['correction']}",
            *self.drop_lines(datetime.fromisoformat(landing["time"])),
        ]
        team = self.context.setup.team_position
        if team is not None:
            distance, bearing = distance_bearing(team[0], team[1], landing["lat"], landing["lon"])
            lines.append(f"  from the team: {distance / 1000:.2f} km at {bearing:.0f}°")
        return lines

    def update_view(self) -> None:
        if time.monotonic() - self.loaded_at >= RELOAD_S:
            self.loaded_at = time.monotonic()
            self.load()
        team = self.context.setup.team_position
        last = self.track[-1] if self.track else None
        lines: list[str | Text] = [f"{self.capsule} recovery", ""]
        if self.landing is not None:
            landing = self.landing
            std = "?" if math.isnan(landing.std_m) else f"{landing.std_m:.0f}"
            lines.append(f"Landed {landing.landed_at:%H:%M:%S}Z at {landing.lat:.5f}, {landing.lon:.5f}")
            lines.append(
                f"  scatter ±{std} m (1σ per axis) from {landing.count} fixes, {landing.rejected} rejected"
            )
            if team is not None:
                distance, bearing = distance_bearing(team[0], team[1], landing.lat, landing.lon)
                lines.append(f"  from the team: {distance / 1000:.2f} km at {bearing:.0f}°")
        elif last is not None:
            lines.append(
                f"Not landed (visibly): last fix {last.lat:.5f}, {last.lon:.5f} at {last.alt_m:.0f} m"
            )
            lines += self.live_lines()
            if self.live is None:
                lines += self.drop_lines(None)
        else:
            lines.append("No GNSS fix received yet")
        reading = self.context.fleet.capsules[self.capsule].reading(ReportSample)
        lines += [
            "",
            "Last report: " + reading.label(self.context.now(), lambda v: f"VBAT {v.vbat} V"),
            *self.settings_lines(),
            "",
            "Phone: " + phone_summary(self.capsule, self.landing, last, team),
        ]
        set_content(
            self.query_one("#recovery-text", Static),
            Text("\n").join(Text(line) if isinstance(line, str) else line for line in lines),
        )
        prediction = self.context.fleet.capsules[self.capsule].reading(PredictionSample).value
        descending = self.live if self.landing is None and self.track else None
        outline = descending["outline_2sigma"] if descending else prediction.outline_2sigma if prediction else ()
        self.query_one("#recovery-map", LandingMap).layers = MapLayers(
            path=[(p.lon, p.lat) for p in self.track],
            ahead=[tuple(p) for p in descending["path"]] if descending else (),
            ellipse=[tuple(p) for p in outline],
            landing=self.map_landing(),
            team=(team[1], team[0]) if team else None,
            scatter=[(p.lon, p.lat) for p in self.track[-10:]] if self.landing else [],
        )

    def map_landing(self) -> tuple[float, float] | None:
        """Where it landed, else where the live re-prediction says it will land."""
        if self.landing is not None:
            return self.landing.lon, self.landing.lat
        if self.live is not None and self.track:
            return self.live["landing"]["lon"], self.live["landing"]["lat"]
        return None

    def action_iridium(self) -> None:
        self.app.push_screen(IridiumScreen(self.context, self.capsule))

    def action_export(self) -> None:
        directory = self.context.setup.export_dir
        directory.mkdir(parents=True, exist_ok=True)
        stamp = f"{self.context.now():%Y%m%dT%H%M%SZ}"
        prediction = self.context.fleet.capsules[self.capsule].reading(PredictionSample).value
        predicted = [(lat, lon, 0.0) for lon, lat in prediction.path] if prediction else []
        gpx = directory / f"{self.capsule}-recovery-{stamp}.gpx"
        kml = directory / f"{self.capsule}-recovery-{stamp}.kml"
        try:
            demo = prediction is not None and prediction.is_demo
            write_gpx(gpx, self.capsule, self.track, predicted, self.landing, predicted_is_demo=demo)
            write_kml(kml, self.capsule, self.track, predicted, self.landing, predicted_is_demo=demo)
        except (OSError, PredictorError) as exc:
            self.app.notify(f"export failed: {exc}", severity="error")
            return
        self.app.notify(f"exported {gpx.name} and {kml.name}")
