"""Recovery of one capsule: where it landed and how sure, how far from the team, the phone line, exports.

While it is still descending (fixes arriving, no landing detected) it also shows the live
re-prediction from the latest fix, so the team drives towards where it is going now, not where it was
predicted at release. All of it comes as one ``RecoveryView`` (``drs_link.ops.recovery``), read by the
operations server (with this console's live re-prediction added) or played from a replay,
asked for by the app's worker when the store or the capsule's telemetry changes; the screen only shows it.

The team also needs, on this one screen, what the sounder, the report interval and the parachute
release were commanded to and how far each command got (``drs_link.iridium.commanded``: the unit
reports none of them, so the screen says what is known and no more), and to command them from
here with the Iridium screen's own confirmation flow (``console.screens.commanding``).
"""

from __future__ import annotations

import math
from datetime import datetime
from pathlib import Path

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Static

from console.context import ConsoleContext
from console.messages import ViewRead, ViewWanted
from console.recovery_map import draw_recovery_map, recovery_picture
from console.screens.commanding import CommandingScreen, command_bindings
from console.screens.iridium import IridiumScreen
from console.widgets import LandingMap, MapLayers, set_content
from drs_link.ops import (
    CommandedSettings,
    Descent,
    DropView,
    LandingEstimate,
    LiveView,
    PredictionSample,
    RecoveryView,
    ReportSample,
    TrackPoint,
    after_drop,
    distance_bearing,
    format_age,
    phone_summary,
    write_gpx,
    write_kml,
)
from predictor.errors import PredictorError

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
        self.shows = ("recovery", capsule)
        """The view the app delivers to this screen (``console.messages.ViewRead``)."""
        self.view: RecoveryView | None = None

    @property
    def descent(self) -> Descent:
        return self.view.descent if self.view is not None else Descent()

    @property
    def track(self) -> tuple[TrackPoint, ...]:
        return self.descent.track

    @property
    def landing(self) -> LandingEstimate | None:
        return self.descent.landing

    @property
    def live(self) -> LiveView | None:
        return self.descent.live

    @property
    def settings(self) -> CommandedSettings | None:
        return self.view.settings if self.view is not None else None

    @property
    def drop(self) -> DropView | None:
        return self.view.drop if self.view is not None else None

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Horizontal(id="recovery-body"):
            yield Static(id="recovery-text", markup=False)
            yield LandingMap(id="recovery-map")
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.ask_for_view()

    def ask_for_view(self) -> None:
        """Ask the app for this capsule's recovery now (it also re-reads it whenever the store changes)."""
        self.post_message(ViewWanted(*self.shows))

    @on(ViewRead)
    def show_view(self, message: ViewRead) -> None:
        if isinstance(message.view, RecoveryView):
            self.view = message.view
            self.refresh_view()

    def drop_lines(self, landing_time: datetime | None) -> list[str]:
        """The override's drop, as the firmware does it, and what the descent becomes after it."""
        if self.drop is None:
            return []
        drop = self.drop
        return [
            f"⚠ {drop.override.text} queued WITHOUT landed evidence: {drop.words}",
            f"  {after_drop(drop.opens_at, landing_time)}",
        ]

    def reload_after_send(self) -> None:
        self.ask_for_view()

    def settings_lines(self) -> list[Text]:
        """Setting and value in bold: what a team in the field looks for first (is the sounder ON?)."""
        if self.settings is None:
            state = "reading" if self.context.commanding else "not known in replay"
            return [Text(f"Sounder, interval, parachute: {state}")]
        lines = []
        for status in self.settings.statuses():
            line = Text(status.line)
            line.stylize("bold", 0, len(status.heading))
            lines.append(line)
        return lines

    def live_lines(self) -> list[str]:
        if not self.descent.descending:
            return []
        if self.descent.live_error is not None:
            return [f"Live re-prediction failed: {self.descent.live_error}"]
        live = self.live
        if live is None:
            return ["Live re-prediction: computing"]
        age = format_age((self.context.now() - live.report_time).total_seconds())
        rate = live.measured_rate_factor
        measured = "— (needs two fixes)" if rate is None else f"{rate:.2f}"
        legs = f"{live.legs_used} leg{'' if live.legs_used == 1 else 's'}"
        lines = [
            f"Live re-prediction from the {live.report_time:%H:%M:%S}Z fix ({age} ago)"
            f" at {live.report_alt_m:.0f} m:",
            f"  landing {live.landing_lat:.4f}, {live.landing_lon:.4f} at {live.landing_time:%H:%M:%S}Z,"
            f" {live.remaining_drift_km:.1f} km to go",
            f"  σ∥ {live.sigma_parallel_km:.2f} km  σ⊥ {live.sigma_perpendicular_km:.2f} km",
            f"  measured rate factor {measured} from {legs}",
            f"  correction: {live.correction}",
            *self.drop_lines(live.landing_time),
        ]
        team = self.context.setup.team_position
        if team is not None:
            distance, bearing = distance_bearing(team[0], team[1], live.landing_lat, live.landing_lon)
            lines.append(f"  from the team: {distance / 1000:.2f} km at {bearing:.0f}°")
        return lines

    def update_view(self) -> None:
        team = self.context.setup.team_position
        last = self.track[-1] if self.track else None
        # The last report's age and battery come first: whether the capsule still talks is the first
        # question, and below the live lines it fell off an 80×24 screen during the descent.
        reading = self.context.fleet.capsules[self.capsule].reading(ReportSample)
        lines: list[str | Text] = [
            f"{self.capsule} recovery",
            "Last report: " + reading.label(self.context.now(), lambda v: f"VBAT {v.vbat} V"),
            "",
        ]
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
        lines += [
            "",
            *self.settings_lines(),
            "",
            "Phone: " + phone_summary(self.capsule, self.landing, last, team),
        ]
        set_content(
            self.query_one("#recovery-text", Static),
            Text("\n").join(Text(line) if isinstance(line, str) else line for line in lines),
        )
        prediction = self.context.fleet.capsules[self.capsule].reading(PredictionSample).value
        descending = self.live if self.descent.descending else None
        outline = descending.outline_2sigma if descending else prediction.outline_2sigma if prediction else ()
        self.query_one("#recovery-map", LandingMap).map_layers = MapLayers(
            path=[(p.lon, p.lat) for p in self.track],
            ahead=list(descending.path) if descending else (),
            ellipse=list(outline),
            landing=self.map_landing(),
            team=(team[1], team[0]) if team else None,
            scatter=[(p.lon, p.lat) for p in self.track[-10:]] if self.landing else [],
        )

    def map_landing(self) -> tuple[float, float] | None:
        """Where it landed, else where the live re-prediction says it will land."""
        if self.landing is not None:
            return self.landing.lon, self.landing.lat
        if self.live is not None and self.track:
            return self.live.landing_lon, self.live.landing_lat
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
            write_gpx(gpx, self.capsule, list(self.track), predicted, self.landing, predicted_is_demo=demo)
            write_kml(kml, self.capsule, list(self.track), predicted, self.landing, predicted_is_demo=demo)
        except (OSError, PredictorError) as exc:
            self.app.notify(f"export failed: {exc}", severity="error")
            return
        self.app.notify(f"exported {gpx.name} and {kml.name}")
        if self.track:
            self.export_map(directory / f"{self.capsule}-recovery-{stamp}.png")

    def export_map(self, png: Path) -> None:
        """The recovery picture (as `drs recovery --map`), drawn in a worker: matplotlib takes a moment."""
        weather = self.context.setup.predictions is not None
        picture = recovery_picture(self.capsule, self.descent, self.context.setup.team_position, weather)

        def draw() -> None:
            try:
                draw_recovery_map(picture, png)
            except (OSError, PredictorError) as exc:
                self.app.call_from_thread(self.app.notify, f"map export failed: {exc}", severity="error")
                return
            self.app.call_from_thread(self.app.notify, f"exported {png.name}")

        self.run_worker(draw, thread=True, group="export-map", exit_on_error=False)
