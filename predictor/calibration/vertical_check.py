"""A calibrated descent law checked on flights it never saw, on the vertical record alone.

Why: the vertical family's metrics (time at each altitude, altitude at each time, the time to reach
the end of the record) need neither a landing nor the wind, so a flight that cannot be calibrated on
(the 1 Hz V4 record from Spain ends in the air at 867 m) can still say whether a law learned
elsewhere describes its fall. Such a record is scored down to its last fix, which stands in for the
ground: the run ends at that altitude and the descent time is the time to reach it.

The flight's payload is not the calibration's (V4's mass and Cd·A are not in its record), and a wrong
payload makes every law wrong by a constant factor that would swamp the law's shape. So every law
is scored on the shape record, with the flight's own descent-rate factor λ profiled out (the same one
free parameter for each, in closed form: ``residuals.Scores.shape_time_rms_s``), and what is compared
is the law's shape: ρ^-½ against the model's. The model's shape terms are the calibration's, fitted
without this flight (its ``descent_rate_scale``, the rate prior's median for the calibration's own
payload, is replaced by this flight's λ). Beside them, "on its own": the model's shape terms fitted
with λ profiled on this flight alone (in-sample, so a bound on what a law of that form can do here,
not a prediction).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from predictor.calibration.effects import LIBRARY
from predictor.calibration.residuals import FlightCase, flight_case
from predictor.calibration.selection import Fit, FlightBatch, fit_candidate
from predictor.environment import WeatherCube
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel
from predictor.tracks import Flight

SCALE = next(c for c in LIBRARY if c.name == "descent_rate_scale")
"""λ: the one factor each law gets on the flight's own record (its payload is unknown)."""
MIN_DESCENT_FIXES = 3


def vertical_case(flight: Flight, cube: WeatherCube) -> FlightCase:
    """The flight as the vertical record scores it: to its landing, or to its last fix when the
    record ends in the air (the run then ends at that fix's altitude)."""
    if flight.usable:
        return flight_case(flight, cube)
    if flight.descent_start is None or len(flight.descent) < MIN_DESCENT_FIXES:
        raise PredictorError(f"flight {flight.name} has no descent to check: {'; '.join(flight.exclusions)}")
    return flight_case(dataclasses.replace(flight, landing=flight.descent[-1], exclusions=()), cube)


@dataclass(frozen=True)
class LawScore:
    """One law on one flight: its fitted parameters and its vertical-record scores."""

    law: str
    parameters: dict[str, float]
    time_rms_s: float
    altitude_rms_km: float
    descent_time_error_s: float


@dataclass(frozen=True)
class FlightCheck:
    name: str
    end_alt_m: float
    landed: bool
    fixes: int
    descent_s: float
    scores: tuple[LawScore, ...]


def _library_fits(model: CalibratedModel) -> list[Fit]:
    """The model's terms as the calibration's fits (refused when a term is not a library effect)."""
    known = {c.name: c for c in LIBRARY}
    fits = []
    for term in model.terms:
        if term.name == SCALE.name:
            continue
        candidate = known.get(term.name)
        if candidate is None or candidate.variants != ({},):
            raise PredictorError(
                f"the vertical check flies library effects with one variant; the model has {term.name}"
            )
        if candidate.family != "vertical":
            continue
        fits.append(Fit(candidate, 0, float(term.parameters()[candidate.parameter])))
    if not fits:
        raise PredictorError("the model has no vertical term to check")
    return fits


def _score(batch: FlightBatch, fits: list[Fit], law: str) -> LawScore:
    s = batch.scores(0, [fits])
    return LawScore(
        law,
        {f.candidate.name: round(f.value, 5) for f in fits},
        float(s.time_rms_s[0]),
        float(s.altitude_rms_km[0]),
        float(s.descent_time_error_s[0]),
    )


def check_flight(
    case: FlightCase, model: CalibratedModel, landed: bool, step_m: float = 200.0
) -> FlightCheck:
    """Four laws on one flight: ρ^-½ as the payload gives it, then ρ^-½, the model's law and the model's
    law refitted here, each with λ fitted on this flight. Refused for a flight the model was calibrated
    on: there its law is not held out (``drs live evaluate`` refits it without the flight)."""
    if case.name in (model.provenance.get("flights") or ()):
        raise PredictorError(
            f"{case.name}: the model was calibrated on this flight, so its law is not held out here"
        )
    law = _library_fits(model)
    batch = FlightBatch([case], model.payload, step_m)

    def with_scale(held: list[Fit]) -> list[Fit]:
        """The law with this flight's own λ, the one the shape record profiles out (closed form)."""
        return [*held, Fit(SCALE, 0, float(batch.scores(0, [held]).rate_factor[0]))]

    own: list[Fit] = []
    for fit in law:
        # Fitted on the shape record, so λ is profiled at every grid value (λ and a density law trade
        # off, both change the fall rate high up: fitting one then the other would stall short).
        full, _ = fit_candidate(batch, fit.candidate, [list(own)], list(own))
        own.append(full)
    scores = (
        _score(batch, [], "ρ^-½, λ = 1"),
        _score(batch, with_scale([]), "ρ^-½, λ fitted here"),
        _score(batch, with_scale(law), f"{model.label()}, λ fitted here"),
        _score(batch, with_scale(own), "its terms and λ fitted here (in-sample)"),
    )
    return FlightCheck(
        case.name, case.landing_alt_m, landed, int(case.fix_t.size), case.descent_time_s, scores
    )


def to_json(checks: Sequence[FlightCheck], model: CalibratedModel, command: str) -> dict[str, Any]:
    return {
        "command": command,
        "model": model.label(),
        "flights": [dataclasses.asdict(c) for c in checks],
    }


def write_vertical_report(
    path: Path, checks: Sequence[FlightCheck], model: CalibratedModel, command: str
) -> None:
    """The before/after of the vertical family on each flight, as Markdown."""
    lines = [
        f"# The vertical family on flights the model never saw: {', '.join(c.name for c in checks)}",
        "",
        f"Generated by `{command}` (do not edit by hand; rerun it).",
        "",
        f"Model: {model.label()}, payload `{model.payload.name}`; its terms were fitted on other flights, "
        "so on these they are held out as they stand. A record that ends in the air is scored down to its "
        "last fix, which stands in for the ground. The flight's payload is not the calibration's, and a "
        "wrong mass or Cd·A makes every law wrong by a constant factor, so each law gets one descent-rate "
        "factor λ fitted on the flight's own vertical record (one free parameter each, in closed form: the "
        "predicted times divided by the λ that fits them best, the calibration's shape record): what differs "
        "between the rows is the law's shape. The model's own `descent_rate_scale` (its rate prior's median, "
        "for the calibration's payload) is replaced by this flight's λ. The last row fits the model's shape "
        "terms with λ profiled on this flight alone (in-sample: what a law of that form can do here at best, "
        "not a prediction).",
        "",
        "Scores on the vertical record (the wind does not enter): time-at-altitude RMS (predicted − measured "
        "time since descent start at each fix's altitude), altitude-at-time RMS, and the error of the time "
        "to reach the record's end (predicted − measured).",
        "",
    ]
    for c in checks:
        end = "its landing" if c.landed else f"its last fix at {c.end_alt_m:.0f} m (no landing in the record)"
        lines += [
            f"## {c.name}",
            "",
            f"{c.fixes} descent fixes scored, down to {end}; measured descent {c.descent_s:.0f} s.",
            "",
            "| law | fitted | time-at-altitude RMS s | altitude-at-time RMS km | time-to-end error s |",
            "|---|---|---|---|---|",
            *(
                f"| {s.law} | {', '.join(f'{k} {v:.4g}' for k, v in s.parameters.items()) or '–'} | "
                f"{s.time_rms_s:.0f} | {s.altitude_rms_km:.3f} | {s.descent_time_error_s:+.0f} |"
                for s in c.scores
            ),
            "",
        ]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines), encoding="utf-8")
