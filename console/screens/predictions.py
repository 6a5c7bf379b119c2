"""Predictions for one capsule: release now and in N minutes, the ellipse in numbers, a map, export,
and the release-window timeline (when to drop), which the app sweeps in its worker whenever a new
"release now" prediction lands and hands to this screen (``console.messages.ViewRead``)."""

from __future__ import annotations

from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Static

from console.context import ConsoleContext
from console.messages import OperatorNotice, TelemetryArrived, ViewRead, ViewWanted
from console.predictions import PredictionService, ReleaseOrigin
from console.screens.base import ConsoleScreen
from console.widgets import LandingMap, MapLayers, default_cursor, render_timeline
from drs_link.errors import LinkError
from drs_link.ops import (
    STALE_GLYPH,
    PredictionSample,
    PredictionStatus,
    ReleaseWindow,
    format_age,
)
from predictor.errors import PredictorError

NEEDS_POSITION = "needs a fresh position: capsule GNSS or balloon feed"
RELEASED = "released: no more release predictions; where it is falling is on Recovery (Esc, then v)"


def describe(
    prediction: PredictionSample | None,
    age_s: float | None,
    stale: bool,
    title: str,
    pending: str = NEEDS_POSITION,
) -> str:
    """``pending`` says why there is none yet, as the console knows it (no weather, waiting, released)."""
    if prediction is None:
        return f"{title}: no prediction yet ({pending})"
    mark = f"{STALE_GLYPH}STALE " if stale else ""
    lines = [
        f"{title} — {mark}computed {format_age(age_s or 0.0)} ago",
        f"  from {prediction.origin_source or 'an unrecorded position'}",
        f"  landing {prediction.landing_lat:.4f}, {prediction.landing_lon:.4f}"
        f"  after {prediction.descent_s / 60:.1f} min, {prediction.distance_km:.1f} km at"
        f" {prediction.bearing_deg:.0f}°",
        f"  σ∥ {prediction.sigma_par_km:.2f} km  σ⊥ {prediction.sigma_perp_km:.2f} km"
        f"  major axis {prediction.major_axis_bearing_deg:.0f}°",
    ]
    for c in prediction.contours:
        lines.append(
            f"  {c.n_sigma:.3g}σ: {c.major_km:.2f} × {c.minor_km:.2f} km holds {c.probability * 100:.1f}%"
        )
    lines += [f"  ! {w}" for w in prediction.warnings]
    return "\n".join(lines)


HELP = "`+`/`-` release lead time · `←`/`→` release-window cursor · `e` export KML + GeoJSON + GPX"
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class PredictionScreen(ConsoleScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        Binding("plus,equals_sign", "lead(5)", "+5 min"),
        Binding("minus", "lead(-5)", "-5 min"),
        Binding("e", "export", "Export"),
        Binding("left", "cursor(-1)", "◀ time", show=False),
        Binding("right", "cursor(1)", "time ▶", show=False),
    ]

    def __init__(self, context: ConsoleContext, capsule: str) -> None:
        super().__init__(context)
        self.capsule = capsule
        self.lead_min = 10
        self.shows = ("window", capsule)
        """The view the app delivers to this screen: the release window."""
        self.window: ReleaseWindow | None = None
        self.cursor: int | None = None

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Horizontal(id="prediction-body"):
            yield Static(id="prediction-numbers", markup=False)
            yield LandingMap(id="prediction-map")
        yield Static(id="release-timeline", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.post_message(ViewWanted(*self.shows))
        self.refresh_view()

    @on(ViewRead)
    def show_window(self, message: ViewRead) -> None:
        if isinstance(message.view, ReleaseWindow):
            self.window = message.view
            self.refresh_view()

    def update_view(self) -> None:
        context = self.context
        now = context.now()
        telemetry = context.fleet.capsules[self.capsule]
        pending = self.pending()
        texts = []
        for minutes in (0, self.lead_min):
            reading = telemetry.predictions.get(minutes)
            title = "Release now" if minutes == 0 else f"Release in {minutes} min"
            value = reading.value if reading else None
            texts.append(describe(value, reading.age_s(now) if reading else None,
                                  bool(reading and not reading.is_fresh(now)), title, pending))  # fmt: skip
        self.query_one("#prediction-numbers", Static).update(f"{self.capsule}\n\n" + "\n\n".join(texts))
        now_pred = telemetry.predictions.get(0)
        value = now_pred.value if now_pred else None
        zones = [z.ring for z in context.zones]
        balloon = context.fleet.balloon.value
        self.query_one("#prediction-map", LandingMap).map_layers = MapLayers(
            path=list(value.path) if value else (),
            ellipse=list(value.outline_2sigma) if value else (),
            zones=zones,
            landing=(value.landing_lon, value.landing_lat) if value else None,
            release=(value.release_lon, value.release_lat) if value else None,
            balloon=(balloon.lon, balloon.lat) if balloon else None,
            team=(context.setup.team_position[1], context.setup.team_position[0])
            if context.setup.team_position
            else None,
        )
        self.update_timeline(value, pending)

    def pending(self) -> str:
        """Why a prediction is missing: released (they stop at Go), else what the console said it is doing."""
        telemetry = self.context.fleet.capsules[self.capsule]
        if telemetry.released:
            return RELEASED
        status = telemetry.reading(PredictionStatus).value
        return status.text if status is not None and status.text else NEEDS_POSITION

    def update_timeline(self, now_prediction: PredictionSample | None, pending: str) -> None:
        age = (
            "computing"
            if self.window is None
            else "computed "
            + format_age((self.context.now() - self.window.computed_at).total_seconds())
            + " ago"
        )
        cursor = self.cursor if self.cursor is not None else default_cursor(self.window) if self.window else 0
        missing = pending if now_prediction is None else "computing"
        timeline = render_timeline(self.window, cursor, age, missing=missing)
        self.query_one("#release-timeline", Static).update(timeline)

    def action_cursor(self, step: int) -> None:
        if self.window is None or not self.window.candidates:
            return
        start = self.cursor if self.cursor is not None else default_cursor(self.window)
        self.cursor = max(0, min(len(self.window.candidates) - 1, start + step))
        self.refresh_view()

    def action_lead(self, step: int) -> None:
        self.lead_min = max(5, min(120, self.lead_min + step))
        origin, service = self.context.prediction_origin(self.capsule), self.context.setup.predictions
        if origin is not None and service is not None:
            self.predict_lead(service, origin)
        self.refresh_view()

    @work(thread=True, exit_on_error=False, group="predictions")
    def predict_lead(self, service: PredictionService, origin: ReleaseOrigin) -> None:
        try:
            records = service.predict(self.capsule, origin, release_in=(self.lead_min,))
        except PredictorError as exc:
            self.app.post_message(OperatorNotice(f"prediction failed: {exc}", "warning"))
            return
        self.app.post_message(TelemetryArrived(records))

    def action_export(self) -> None:
        service = self.context.setup.predictions
        if service is None:
            self.app.notify("no predictor in this session (replay): nothing to export", severity="warning")
            return
        directory = self.context.setup.export_dir
        try:
            directory.mkdir(parents=True, exist_ok=True)
            paths = service.export(self.capsule, directory)
        except (OSError, PredictorError, LinkError) as exc:
            self.app.notify(f"export failed: {exc}", severity="error")
            return
        if not paths:
            self.app.notify("no prediction yet to export", severity="warning")
        else:
            self.app.notify("exported " + ", ".join(p.name for p in paths))
