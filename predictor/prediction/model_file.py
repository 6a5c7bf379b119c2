"""The calibrated model: what `drs calibrate --save-model` learned, in one file every prediction can fly.

Why a file: the calibration loop finds the effect the model lacks and measures the error before and
after, but a finding that stays in a report changes no landing. The file carries everything a
prediction needs (the payload, the selected terms with their fitted parameters, the binned correction
when it passed, the landing-ellipse model) and where it came from, so `drs predict --model`, `drs plan
--model` and a capsule's `model` key in drs.toml fly exactly what was calibrated, and say so.

Loading is strict: a missing, corrupt or future-schema file, an unknown term or an impossible value is
refused in one line that names the file and the field. Nothing falls back to defaults, because a
prediction that silently ignored its calibration is worse than none.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import stat
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from predictor.descent import (
    EFFECTS,
    DescentRateScale,
    Model,
    Payload,
    PreflightSpread,
    RatePrior,
    Term,
    payload_profile,
)
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError, UsageError
from predictor.prediction.live import (
    DEFAULT_DISCREPANCY,
    DEFAULT_ELLIPSE_NOTE,
    LIVE_ERROR_MODEL,
    LIVE_LAWS,
    NO_CORRECTION,
    OWN_RATE,
    Band,
    LiveCorrection,
    LiveErrorModel,
    LivePredictor,
    LiveSettings,
    RateDiscrepancy,
    WindGain,
)
from predictor.prediction.setup import FlightSetup
from predictor.prediction.uncertainty import ERROR_MODELS, ErrorModel

PAYLOAD_LIMITS = {"mass_kg": (0.05, 50.0), "cda_m2": (0.02, 50.0)}
"""A balloon payload under a parachute: 50 g to 50 kg, Cd·A 0.02–50 m² (a 1 kg capsule under a 4 ft
canopy is 0.43 m²). Outside them no calibration was run; a 10⁶ kg payload falls as a stone."""

ALTITUDE_LIMITS_M = (-500.0, 50_000.0)
WIND_LIMITS_MS = (-60.0, 60.0)
PARAMETER_LIMITS: dict[tuple[str, str], tuple[float, float]] = {
    ("descent_rate_scale", "scale"): (0.5, 2.0),
    ("drag_density_exponent", "exponent"): (-0.5, 0.5),
    ("deployment_delay", "delay_s"): (0.0, 240.0),
    ("two_regime_rate", "factor"): (0.5, 2.0),
    ("wind_scale", "scale"): (0.3, 2.0),
    ("wind_rotation", "angle_deg"): (-60.0, 60.0),
    ("wind_band_scale", "scale"): (0.0, 2.5),
    ("wind_lag", "time_constant_s"): (0.0, 600.0),
    ("weather_time_offset", "offset_s"): (-14400.0, 14400.0),
    ("drag_density_exponent", "reference_density"): (0.5, 2.0),
    ("deployment_delay", "speed_factor"): (1.0, 10.0),
    ("two_regime_rate", "height_m"): ALTITUDE_LIMITS_M,
    ("wind_band_scale", "bottom_m"): ALTITUDE_LIMITS_M,
    ("wind_band_scale", "top_m"): ALTITUDE_LIMITS_M,
    ("vertical_air_motion", "speed_ms"): (-5.0, 5.0),
    ("wind_offset", "east_ms"): WIND_LIMITS_MS,
    ("wind_offset", "north_ms"): WIND_LIMITS_MS,
    ("binned_descent_rate", "edges_m"): ALTITUDE_LIMITS_M,
    ("binned_descent_rate", "factors"): (0.5, 2.0),
    ("binned_wind", "edges_m"): ALTITUDE_LIMITS_M,
    ("binned_wind", "east_ms"): WIND_LIMITS_MS,
    ("binned_wind", "north_ms"): WIND_LIMITS_MS,
}
"""(effect, parameter) → the (low, high) a model file may carry: the first nine are the ranges the
calibration fits within (``calibration.effects.Candidate.bounds`` reads them here), the rest what it
never fits but may hold fixed or get from the binned fit (a reference density of sea-level air give or
take, a fast fall at most 10× the canopy's, heights inside the weather, ±60 m/s of added wind, the binned
fit's own factor bounds). A model file with a value outside them was not made by a calibration and is
refused (an exponent of 5 is an 8-minute fall from 28 km, a wind scale of −1 blows backwards)."""

SCHEMA_VERSION = 6
"""2 added the optional ``live`` section, 3 the optional ``rate_prior``, 4 each term's ``flown`` (the
pre-flight gate), 5 the live section's ``law`` (what live re-prediction restarts from; absent: the
model's terms, as every older file flew), 6 the optional ``preflight_spread`` (the λ spread about the
pre-flight law, with the ellipse now fitted on that law's landings) and the live section's ``wind_gain``
(the share of the measured wind error carried down; absent: all of it, as every older file flew): a drs
that reads an older schema refuses such a file rather than fly the model without what was measured for
it (a schema-3 reader would fly a live-only term before release, a schema-4 one the model's terms with a
λ table measured on the payload's law, a schema-5 one the pre-flight descent-time interval of the live
law's prior and all of a wind error its training flights said did not carry)."""
FLOWN = ("both", "live-only", "pre-flight-only")
"""A term's ``flown`` in a schema-4 file: by both laws; only once the flight's own λ is known (the
pre-flight gate found it made the held-out pre-flight prediction worse); only before release (the
pre-flight λ, the training flights' median under the pre-flight terms, when it differs from the live one)."""
FILE_KIND = "drs-calibrated-model"

MAX_MODEL_BYTES = 1_000_000
"""A calibrated model is about 10 kB (docs/planning/superbit-2018-2019-model.json); a provenance listing a
thousand flights stays under 100 kB. A larger "model" is not one, and is refused before it is read."""
MAX_NESTING = 16
"""The model's deepest value is four levels down (live → discrepancy → heights_km → a number); provenance
may nest a little more. Python's JSON reader recurses, and a few thousand brackets were a traceback."""
MAX_NUMBER_CHARACTERS = 40
"""Longer than any float repr (at most 24 characters) and any count a model holds; a 5,000-digit integer
exceeded Python's int-string limit and was a ValueError traceback."""


class ModelFileError(PredictorError):
    """A calibrated-model file cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class CalibratedModel:
    payload: Payload
    terms: tuple[Term, ...]
    """The selected effect terms with their fitted parameters, then the binned correction if it passed."""
    ellipse: ErrorModel | None
    """The landing-ellipse model fitted on the held-out errors (None when too few flights)."""
    provenance: dict[str, Any] = field(default_factory=dict)
    """Flights, weather, held-out before/after per metric, date, command and project version."""
    source_path: Path | None = None
    live: LiveSettings | None = None
    """The live corrections, λ discrepancy and live ellipse measured with this model's law (``drs live
    evaluate --save-model``); None: not evaluated live, and live re-prediction flies the shape with this
    flight's own λ update and the default ellipse, and says so."""
    rate_prior: RatePrior | None = None
    """The spread of each calibration flight's own rate factor λ around the shared law (None: the
    calibration did not fit λ per flight)."""
    preflight: tuple[Term, ...] | None = None
    """What a prediction before release flies (``terms`` without the live-only ones, with the pre-flight
    λ); None: a file written before the pre-flight gate (schema ≤ 3), whose terms all fly pre-flight
    unjudged, which ``drs model show`` says."""
    preflight_spread: PreflightSpread | None = None
    """The held-out spread of the flights' own λ about the pre-flight law's λ, which the pre-flight
    descent-time interval flies (None: a file written before schema 6, which flies the prior's sd)."""

    def preflight_law(self) -> tuple[Term, ...]:
        """The terms a pre-flight prediction flies (``drs predict``, ``drs plan``, the console before
        release). Live re-prediction flies ``terms``."""
        return self.terms if self.preflight is None else self.preflight

    def live_only(self) -> tuple[str, ...]:
        """Names of the terms live re-prediction flies and a pre-flight prediction leaves out."""
        before = {_key(t) for t in self.preflight_law()}
        return tuple(t.name for t in self.terms if _key(t) not in before and t.name != "descent_rate_scale")

    def live_predictor(
        self, cube: WeatherCube, terrain: Terrain | None = None, corrected: bool = True
    ) -> LivePredictor:
        """A live predictor flying this model's law with its own λ prior and live settings (``corrected``:
        its bands; otherwise the plain restart from each report). Without live settings of its own it
        flies its shape with this flight's own λ update, and every prediction says what is not its own."""
        notes = []
        if self.live is None:
            notes.append(
                "no live settings of its own: its shape with this flight's own λ update (the conservative default discrepancy and prior, measured on SuperBIT and EOSS flights), no wind correction"
            )
            notes.append(DEFAULT_ELLIPSE_NOTE)
            settings = LiveSettings(OWN_RATE, LIVE_ERROR_MODEL, DEFAULT_DISCREPANCY)
        else:
            settings = self.live
        on_terms = settings.law == "model"
        prior = (self._prior_on_terms() if on_terms else None) or settings.prior
        if self.live is None and settings.discrepancy.remaining_log_mean:
            pass  # the default's own prior by height, said in the first note
        elif prior is None:
            notes.append("no λ prior in the model: λ from this descent alone")
        elif not on_terms:
            notes.append(
                "live law: the payload's drag law with this flight's own λ (its live evaluation's prior); "
                "the model's terms fly before release"
            )
        elif self.rate_prior is None:
            notes.append("λ prior from the model's live evaluation (its calibration gave none)")
        correction = settings.correction if corrected else NO_CORRECTION
        return LivePredictor(
            cube, self.payload, terrain, correction, settings.error_model,
            effects=self.terms if on_terms else (),
            restart_effects=self.terms if settings.restart == "model" else (),
            prior=prior, discrepancy=settings.discrepancy, notes=notes,
        )  # fmt: skip

    def _prior_on_terms(self) -> RatePrior | None:
        """The calibration's λ prior as a factor on the law the terms fly, which is what live re-prediction
        scales: a ``descent_rate_scale`` among the terms is the prior's median already flown (the
        calibration's convention), so the update then starts from 1 with the prior's spread."""
        if self.rate_prior is None:
            return None
        flown = math.prod(float(t.scale) for t in self.terms if isinstance(t, DescentRateScale))
        return dataclasses.replace(self.rate_prior, median=self.rate_prior.median / flown)

    def model(self) -> Model:
        return Model.for_payload(self.payload, *self.terms)

    def shape_terms(self) -> tuple[Term, ...]:
        """The terms without the rate prior's median λ: what live re-prediction multiplies by the
        flight's own λ. A calibration that fitted a rate prior saves its median as the first term
        (``descent_rate_scale``), so that every command flying ``terms`` flies the pre-flight law."""
        if self.rate_prior is not None and self.terms and self.terms[0].name == "descent_rate_scale":
            return self.terms[1:]
        return self.terms

    def flight_setup(
        self,
        terrain: Terrain,
        step_m: float = 100.0,
        error_model: str | None = None,
        probabilities: Sequence[float] = (),
    ) -> FlightSetup:
        """This model flown before release over ``terrain``: its payload and pre-flight terms (live-only
        ones left out), and the ellipse ``chosen_ellipse`` picks, so every command and the console fly a
        model file alike. Live re-prediction flies ``terms`` through ``live_predictor``."""
        return FlightSetup(
            payload=self.payload,
            effects=self.preflight_law(),
            terrain=terrain,
            step_m=step_m,
            error_model=self.chosen_ellipse(error_model),
            probabilities=tuple(probabilities),
        )

    def chosen_ellipse(self, name: str | None) -> ErrorModel:
        """The ellipse a prediction carries: ``name`` (``--error-model``) when given, else this model's
        fitted ellipse (what its own held-out errors measured), else the launch parameters of the paper."""
        if name is not None:
            return ERROR_MODELS[name]
        return self.ellipse if self.ellipse is not None else ERROR_MODELS["launch"]

    def document(self, path: str | Path) -> dict[str, Any]:
        """This model as the JSON outputs name it, so a reader can fly it again."""
        return {
            "path": str(path),
            "label": self.label(),
            "terms": [{"effect": t.name, "parameters": t.parameters()} for t in self.terms],
            **(
                {
                    "preflight_terms": [
                        {"effect": t.name, "parameters": t.parameters()} for t in self.preflight
                    ]
                }
                if self.preflight is not None and self.preflight != self.terms
                else {}
            ),
            "provenance": self.provenance,
        }

    def label(self) -> str:
        """How a prediction names the model that made it."""
        if self.source_path is None and not self.terms:
            return f"{self.payload.name} profile"
        where = self.source_path.name if self.source_path else "calibrated model"
        when = self.provenance.get("created_utc", "")[:10]
        flights = self.provenance.get("flights")
        count = f" on {len(flights)} flights" if isinstance(flights, list) else ""
        label = f"{where} (calibrated {when}{count})" if when else where
        unstable = self.provenance.get("unstable_terms")
        if isinstance(unstable, list) and unstable:
            # Visible wherever the model is named (drs predict, plan, live, the console).
            label += f" [FLAG: {', '.join(map(str, unstable))} chosen in under 2/3 of the selection's folds]"
        return label

    def to_dict(self) -> dict[str, Any]:
        ellipse = None
        if self.ellipse is not None:
            ellipse = {k: getattr(self.ellipse, k) for k in ("sigma0_km", "h", "k_km2_per_h2", "q")}
        return {
            "kind": FILE_KIND,
            "schema": SCHEMA_VERSION,
            "payload": self.payload.to_dict(),
            "terms": _terms_to_list(self.terms, self.preflight_law()),
            "ellipse": ellipse,
            **({"live": _live_to_dict(self.live)} if self.live is not None else {}),
            **({"rate_prior": self.rate_prior.to_dict()} if self.rate_prior is not None else {}),
            **(
                {"preflight_spread": self.preflight_spread.to_dict()}
                if self.preflight_spread is not None
                else {}
            ),
            "provenance": self.provenance,
        }


def _key(term: Term) -> tuple[str, str]:
    return term.name, json.dumps(term.parameters(), sort_keys=True)


def _terms_to_list(live: Sequence[Term], preflight: Sequence[Term]) -> list[dict[str, Any]]:
    """One list, each term with where it is flown: the live law's terms in order (a pre-flight λ that
    differs from the live one right after the live one)."""
    before = {_key(t) for t in preflight}
    after = {_key(t) for t in live}
    out = []
    for term in live:
        out.append({"effect": term.name, "parameters": term.parameters(),
                    "flown": "both" if _key(term) in before else "live-only"})  # fmt: skip
        if term is live[0]:
            out += [{"effect": t.name, "parameters": t.parameters(), "flown": "pre-flight-only"}
                    for t in preflight if _key(t) not in after]  # fmt: skip
    if not live:
        out = [
            {"effect": t.name, "parameters": t.parameters(), "flown": "pre-flight-only"} for t in preflight
        ]
    return out


def _bound(value: float) -> float | None:
    """JSON has no infinity: an open end of a band or an unlimited window is null."""
    return value if math.isfinite(value) else None


def _live_to_dict(live: LiveSettings) -> dict[str, Any]:
    def band(b: Band) -> dict[str, Any]:
        return {"lower_m": _bound(b.lower_m), "upper_m": _bound(b.upper_m), "use_rate": b.use_rate,
                "wind_decay_m": b.decay_m}  # fmt: skip

    e = live.error_model
    d = live.discrepancy
    return {
        "law": live.law,
        "restart": live.restart,
        "bands": [band(b) for b in live.correction.bands],
        "wind_window_m": live.correction.wind_window_m,
        **(
            {"wind_gain": {"heights_km": list(g.heights_km), "gains": list(g.gains)}}
            if (g := live.correction.wind_gain) is not None
            else {}
        ),
        "discrepancy": {
            "heights_km": list(d.heights_km),
            "log_bias": list(d.log_bias),
            "log_sigma": list(d.log_sigma),
            **(
                {
                    "remaining_log_mean": list(d.remaining_log_mean),
                    "remaining_log_sigma": list(d.remaining_log_sigma),
                    "remaining_flights": list(d.remaining_flights),
                }
                if d.remaining_log_mean
                else {}
            ),
        },
        **({"prior": live.prior.to_dict()} if live.prior is not None else {}),
        "error_model": {
            "heights_km": list(e.heights_km),
            "sigma_parallel_km": list(e.sigma_parallel_km),
            "sigma_perpendicular_km": list(e.sigma_perpendicular_km),
            **(
                {"growth_exponent": e.growth_exponent, "typical_km_h": list(e.typical_km_h)}
                if e.typical_km_h
                else {}
            ),
            **({"time_log_sigma": list(e.time_log_sigma)} if e.time_log_sigma else {}),
        },
    }


def save_model(model: CalibratedModel, path: str | Path) -> Path:
    """Write atomically (a temporary file, fsync, rename): a crash never leaves half a model."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(model.to_dict(), indent=2, ensure_ascii=False) + "\n"
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            out.write(text)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return target


def load_model(path: str | Path) -> CalibratedModel:
    source = Path(path)

    def refuse(where: str, problem: str) -> ModelFileError:
        return ModelFileError(
            f"model file {source}: {where}: {problem}" if where else f"model file {source}: {problem}"
        )

    try:
        raw = _parse(_bounded_text(source, refuse), refuse)
    except FileNotFoundError:
        raise ModelFileError(f"model file {source} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise refuse("", f"cannot be read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise refuse("", f"is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") from None
    if not isinstance(raw, dict) or raw.get("kind") != FILE_KIND:
        raise refuse("kind", f"not a calibrated model (expected kind {FILE_KIND!r})")
    schema = raw.get("schema")
    if not isinstance(schema, int) or isinstance(schema, bool) or schema < 1:
        raise refuse("schema", f"must be a whole number ≥ 1, got {schema!r}")
    if schema > SCHEMA_VERSION:
        raise refuse(
            "schema", f"version {schema} is newer than this drs reads ({SCHEMA_VERSION}); update drs"
        )
    payload = _payload(raw.get("payload"), refuse)
    terms, preflight = _flown(raw.get("terms"), _terms(raw.get("terms"), refuse), schema, refuse)
    ellipse = _ellipse(raw.get("ellipse"), refuse)
    live = _live(raw["live"], refuse) if "live" in raw else None
    rate_prior = _rate_prior(raw["rate_prior"], refuse) if "rate_prior" in raw else None
    spread = _preflight_spread(raw["preflight_spread"], refuse) if "preflight_spread" in raw else None
    provenance = raw.get("provenance", {})
    if not isinstance(provenance, dict):
        raise refuse("provenance", "must be an object")
    return CalibratedModel(payload, terms, ellipse, provenance, source, live, rate_prior, preflight, spread)


def _bounded_text(source: Path, refuse: Any) -> str:
    """The file's text, read only when it is a regular file of at most ``MAX_MODEL_BYTES``: /dev/zero never
    ends, /dev/urandom is not text, a FIFO blocks a reader for ever (opened without blocking here)."""
    handle = os.open(source, os.O_RDONLY | os.O_NONBLOCK)
    if not stat.S_ISREG(os.fstat(handle).st_mode):
        os.close(handle)
        raise refuse("", "is not a regular file (a device, FIFO or directory); give a model file")
    with os.fdopen(handle, "rb") as stream:
        data = stream.read(MAX_MODEL_BYTES + 1)
    if len(data) > MAX_MODEL_BYTES:
        raise refuse("", f"is over {MAX_MODEL_BYTES:,} bytes; a calibrated model is about 10 kB")
    return data.decode("utf-8")


_STRINGS = re.compile(r'"(?:[^"\\]|\\.)*"')
_NOT_BRACKETS = re.compile(r"[^\[\]{}]")


def _parse(text: str, refuse: Any) -> Any:
    """JSON with its nesting and number lengths bounded before Python's reader sees them."""
    depth = deepest = 0
    for bracket in _NOT_BRACKETS.sub("", _STRINGS.sub("", text)):
        depth += 1 if bracket in "[{" else -1
        deepest = max(deepest, depth)
    if deepest > MAX_NESTING:
        raise refuse("", f"nests {deepest} levels deep; a model file nests at most {MAX_NESTING}")

    def number(kind: type) -> Any:
        def read(literal: str) -> Any:
            if len(literal) > MAX_NUMBER_CHARACTERS:
                raise refuse("", f"holds a number of {len(literal):,} characters ({literal[:12]}…); damaged")
            return kind(literal)

        return read

    return json.loads(text, parse_int=number(int), parse_float=number(float))


def _number(value: Any, where: str, refuse: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise refuse(where, f"must be a finite number, got {value!r}")
    return float(value)


def _payload(raw: Any, refuse: Any) -> Payload:
    if not isinstance(raw, dict):
        raise refuse("payload", "missing (it must give mass_kg and cda_m2)")
    mass = _number(raw.get("mass_kg"), "payload.mass_kg", refuse)
    cda = _number(raw.get("cda_m2"), "payload.cda_m2", refuse)
    if mass <= 0:
        raise refuse("payload.mass_kg", f"must be a positive number of kg, got {mass:g}")
    if cda <= 0:
        raise refuse("payload.cda_m2", f"must be a positive number of m², got {cda:g}")
    for key, value in (("mass_kg", mass), ("cda_m2", cda)):
        low, high = PAYLOAD_LIMITS[key]
        if not low <= value <= high:
            raise refuse(
                f"payload.{key}", f"{value:g} is outside the payloads drs calibrates ({low:g}–{high:g})"
            )
    name = str(raw.get("name", "calibrated"))
    return Payload(mass, cda, name=name, source=str(raw.get("source", "calibrated model file")))


def _terms(raw: Any, refuse: Any) -> tuple[Term, ...]:
    if not isinstance(raw, list):
        raise refuse("terms", "must be a list (empty when calibration selected nothing)")
    terms = []
    limits = PARAMETER_LIMITS
    for index, item in enumerate(raw):
        where = f"terms[{index}]"
        if not isinstance(item, dict):
            raise refuse(where, "must be an object with effect and parameters")
        kind = EFFECTS.get(str(item.get("effect")))
        if kind is None:
            raise refuse(
                f"{where}.effect",
                f"{item.get('effect')!r} is not a known effect (known: {', '.join(EFFECTS)})",
            )
        parameters = item.get("parameters", {})
        if not isinstance(parameters, dict):
            raise refuse(f"{where}.parameters", "must be an object")
        known = {f.name: f for f in dataclasses.fields(kind)}
        values: dict[str, Any] = {}
        for key, value in parameters.items():
            if key not in known:
                raise refuse(
                    f"{where}.parameters.{key}", f"is not a parameter of {kind.name} ({', '.join(known)})"
                )
            if "tuple" in str(known[key].type):  # a list per altitude bin; every other parameter one number
                values[key] = _numbers(value, f"{where}.parameters.{key}", refuse)
            else:
                values[key] = _number(value, f"{where}.parameters.{key}", refuse)
            _within(values[key], limits.get((kind.name, key)), f"{where}.parameters.{key}", refuse)
        if kind.name == "wind_band_scale" and values.get("bottom_m", 8000.0) >= values.get("top_m", 14000.0):
            raise refuse(f"{where}.parameters", "wind_band_scale: bottom_m must be below top_m")
        try:
            terms.append(kind(**values))
        except (PredictorError, TypeError) as exc:
            raise refuse(where, str(exc)) from None
    return tuple(terms)


def _flown(
    raw: Any, terms: tuple[Term, ...], schema: int, refuse: Any
) -> tuple[tuple[Term, ...], tuple[Term, ...] | None]:
    """(the live law, the pre-flight law) from each term's ``flown``; a file before schema 4 has no
    ``flown``: every term flies both ways, unjudged (pre-flight law None)."""
    if schema < 4:
        return terms, None
    flown = []
    for index, item in enumerate(raw):
        value = item.get("flown")
        if value not in FLOWN:
            raise refuse(f"terms[{index}].flown", f"must be one of {', '.join(FLOWN)}, got {value!r}")
        flown.append(value)
    live = tuple(t for t, f in zip(terms, flown, strict=True) if f != "pre-flight-only")
    before = tuple(t for t, f in zip(terms, flown, strict=True) if f != "live-only")
    for law, name in ((live, "live"), (before, "pre-flight")):
        if sum(t.name == "descent_rate_scale" for t in law) > 1:
            raise refuse("terms", f"the {name} law has more than one descent_rate_scale")
    return live, before


def _within(
    value: float | tuple[float, ...], limits: tuple[float, float] | None, where: str, refuse: Any
) -> None:
    """Refuse a value outside the calibration's own bounds (``PARAMETER_LIMITS``)."""
    if limits is None:
        return
    low, high = limits
    for v in value if isinstance(value, tuple) else (value,):
        if not low <= v <= high:
            raise refuse(where, f"{v:g} is outside the calibration's bounds {low:g}…{high:g}")


def _ellipse(raw: Any, refuse: Any) -> ErrorModel | None:
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise refuse("ellipse", "must be an object or null")
    sigma0_km, h, k_km2_per_h2, q = (
        _number(raw.get(key), f"ellipse.{key}", refuse) for key in ("sigma0_km", "h", "k_km2_per_h2", "q")
    )
    try:
        return ErrorModel(sigma0_km, h, k_km2_per_h2, q, name="calibrated")
    except PredictorError as exc:
        raise refuse("ellipse", str(exc)) from None


def _flights(value: Any, where: str, refuse: Any) -> int:
    """A count of flights: a JSON integer (``true`` is not one, though Python's bool is an int)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise refuse(where, f"must be a whole number of flights, got {value!r}")
    return value


def _rate_prior(raw: Any, refuse: Any) -> RatePrior:
    if not isinstance(raw, dict):
        raise refuse("rate_prior", "must be an object with median, log_sigma and flights")
    flights = _flights(raw.get("flights"), "rate_prior.flights", refuse)
    try:
        return RatePrior(
            _number(raw.get("median"), "rate_prior.median", refuse),
            _number(raw.get("log_sigma"), "rate_prior.log_sigma", refuse),
            flights,
        )
    except PredictorError as exc:
        raise refuse("rate_prior", str(exc)) from None


def _preflight_spread(raw: Any, refuse: Any) -> PreflightSpread:
    if not isinstance(raw, dict):
        raise refuse("preflight_spread", "must be an object with log_sigma and flights")
    flights = _flights(raw.get("flights"), "preflight_spread.flights", refuse)
    try:
        return PreflightSpread(_number(raw.get("log_sigma"), "preflight_spread.log_sigma", refuse), flights)
    except PredictorError as exc:
        raise refuse("preflight_spread", str(exc)) from None


def _numbers(raw: Any, where: str, refuse: Any, positive: bool = False) -> tuple[float, ...]:
    if not isinstance(raw, list) or not raw:
        raise refuse(where, "must be a non-empty list of numbers")
    values = tuple(_number(v, f"{where}[{i}]", refuse) for i, v in enumerate(raw))
    if positive and min(values) <= 0.0:
        raise refuse(where, f"must all be positive, got {min(values):g}")
    return values


def _optional(raw: Any, where: str, refuse: Any, unbounded: float) -> float:
    return unbounded if raw is None else _number(raw, where, refuse)


def _live(raw: Any, refuse: Any) -> LiveSettings | None:
    """The live section; None for one written before live re-prediction updated each flight's own λ
    (no ``discrepancy``): its bands chose among estimators that no longer exist, so the model then flies
    as one without live settings, which every live prediction says."""
    if not isinstance(raw, dict):
        raise refuse("live", "must be an object with bands, wind_window_m, discrepancy and error_model")
    if "discrepancy" not in raw:
        return None
    if not isinstance(raw.get("bands"), list):
        raise refuse("live.bands", "must be a list (empty: a plain re-prediction at every height)")
    bands = []
    for i, item in enumerate(raw["bands"]):
        where = f"live.bands[{i}]"
        if not isinstance(item, dict) or not isinstance(item.get("use_rate"), bool):
            raise refuse(
                where, "must be an object with lower_m, upper_m, use_rate (true/false) and wind_decay_m"
            )
        lower = _optional(item.get("lower_m"), f"{where}.lower_m", refuse, -math.inf)
        upper = _optional(item.get("upper_m"), f"{where}.upper_m", refuse, math.inf)
        if lower >= upper:
            raise refuse(where, f"lower_m {lower:g} must be below upper_m {upper:g}")
        decay = item.get("wind_decay_m")
        decay_m = None if decay is None else _number(decay, f"{where}.wind_decay_m", refuse)
        if decay_m is not None and decay_m <= 0.0:
            raise refuse(where, "wind_decay_m must be a positive length (or null)")
        bands.append(Band(lower, upper, item["use_rate"], decay_m))
    wind_window = _number(raw.get("wind_window_m"), "live.wind_window_m", refuse)
    law, restart = raw.get("law", "model"), raw.get("restart", "model")
    for key, value in (("law", law), ("restart", restart)):
        if value not in LIVE_LAWS:
            raise refuse(
                f"live.{key}", f"must be one of {', '.join(LIVE_LAWS)} (absent: model), got {value!r}"
            )
    return LiveSettings(
        LiveCorrection(tuple(bands), wind_window, _wind_gain(raw["wind_gain"], refuse) if "wind_gain" in raw else None),
        _error_model(raw.get("error_model"), refuse),
        _discrepancy(raw.get("discrepancy"), refuse),
        _rate_prior(raw["prior"], lambda field, problem: refuse(field.replace("rate_prior", "live.prior"), problem))
        if "prior" in raw else None,
        law,
        restart,
    )  # fmt: skip


def _wind_gain(raw: Any, refuse: Any) -> WindGain:
    """The share of the measured wind error carried down, by height (absent from a model evaluated
    before it was learned: it then carries all of it, as it flew)."""
    where = "live.wind_gain"
    if not isinstance(raw, dict):
        raise refuse(where, "must be an object with heights_km and gains")
    heights, gains = (
        _numbers(raw.get(k), f"{where}.{k}", refuse, positive=False) for k in ("heights_km", "gains")
    )
    if len(heights) != len(gains):
        raise refuse(where, "heights_km and gains must be as long as each other")
    if not all(0.0 <= g <= 1.0 for g in gains):
        raise refuse(
            f"{where}.gains", "must be within 0–1 (none of the measured error carried, or all of it)"
        )
    return WindGain(heights, gains)


def _error_model(raw: Any, refuse: Any) -> LiveErrorModel:
    """The live ellipse by height; its growth with the distance from the ascent (``growth_exponent``,
    ``typical_km_h``) and the remaining time's σ (``time_log_sigma``) are absent from a
    model evaluated before they were measured (it then flies σ(h) alone and λ's own σ)."""
    where = "live.error_model"
    heights, parallel, perpendicular = _table(
        raw, where, ("heights_km", "sigma_parallel_km", "sigma_perpendicular_km"), refuse
    )
    columns: dict[str, Any] = {}
    for key in ("typical_km_h", "time_log_sigma"):
        if key not in raw:
            continue
        values = _numbers(raw.get(key), f"{where}.{key}", refuse, positive=False)
        if len(values) != len(heights) or min(values) < 0.0:
            raise refuse(f"{where}.{key}", "must be as long as heights_km and never negative")
        columns[key] = values
    if "typical_km_h" in columns:
        beta = _number(raw.get("growth_exponent"), f"{where}.growth_exponent", refuse)
        if not 0.0 <= beta <= 3.0:
            raise refuse(f"{where}.growth_exponent", f"must be within 0–3, got {beta:g}")
        columns["growth_exponent"] = beta
    elif (
        "growth_exponent" in raw
    ):  # a growth with no distance to grow from: an edited file, not flown as if whole
        raise refuse(f"{where}.growth_exponent", "needs typical_km_h beside it (the distance it grows from)")
    return LiveErrorModel(heights, parallel, perpendicular, **columns)


def _discrepancy(raw: Any, refuse: Any) -> RateDiscrepancy:
    """The record-to-remaining table; the remaining-descent prior columns are absent from a model
    evaluated before they were measured (it then flies its whole-descent prior)."""
    heights, bias, spread = _table(raw, "live.discrepancy", ("heights_km", "log_bias", "log_sigma"), refuse)
    if "remaining_log_mean" not in raw:
        return RateDiscrepancy(heights, bias, spread)
    where = "live.discrepancy"
    prior = [_numbers(raw.get(k), f"{where}.{k}", refuse, positive=False)
             for k in ("remaining_log_mean", "remaining_log_sigma", "remaining_flights")]  # fmt: skip
    if any(len(c) != len(heights) for c in prior):
        raise refuse(where, "the remaining_* columns must be as long as heights_km")
    if not all(0.0 <= v <= 1.0 for v in prior[1]):
        raise refuse(f"{where}.remaining_log_sigma", "must be within 0–1")
    if not all(v >= 1 and float(v).is_integer() for v in prior[2]):
        raise refuse(f"{where}.remaining_flights", "must be whole numbers ≥ 1")
    if not all(abs(v) <= math.log(5.0) for v in prior[0]):
        raise refuse(f"{where}.remaining_log_mean", "must be within ±ln 5 (λ 0.2–5)")
    return RateDiscrepancy(heights, bias, spread, prior[0], prior[1], tuple(int(v) for v in prior[2]))


def _table(raw: Any, where: str, keys: tuple[str, str, str], refuse: Any) -> list[tuple[float, ...]]:
    """Three lists as long as each other: heights, then two values per height (sigmas positive, a log
    spread never negative)."""
    if not isinstance(raw, dict):
        raise refuse(where, f"must be an object with {', '.join(keys)}")
    columns = [_numbers(raw.get(k), f"{where}.{k}", refuse, positive=k.startswith("sigma")) for k in keys]
    if len({len(c) for c in columns}) != 1:
        raise refuse(where, f"{', '.join(keys)} must be as long as each other")
    if keys[2] == "log_sigma" and min(columns[2]) < 0.0:
        raise refuse(f"{where}.log_sigma", f"must not be negative, got {min(columns[2]):g}")
    return columns


def flown_model(
    model_path: str | Path | None, profile: str | None, mass_kg: float | None, cda_m2: float | None
) -> CalibratedModel:
    """What a command flies: a calibrated model file, or a payload profile (with --mass/--cda overrides)
    as a model without calibrated terms. One rule for predict, plan and live: the file carries its payload,
    so both together are refused rather than one silently winning."""
    if model_path is not None:
        if profile is not None or mass_kg is not None or cda_m2 is not None:
            raise UsageError(
                "give --model or --payload/--mass/--cda, not both: the model carries its payload"
            )
        return load_model(model_path)
    return CalibratedModel(
        payload_profile(profile or "drs").overridden(mass_kg=mass_kg, cda_m2=cda_m2), (), None
    )
