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
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from predictor.errors import PredictorError
from predictor.model import EFFECTS, Model, Term
from predictor.payload import Payload, payload_profile
from predictor.uncertainty import ErrorModel

SCHEMA_VERSION = 1
FILE_KIND = "drs-calibrated-model"


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

    def model(self) -> Model:
        return Model.for_payload(self.payload, *self.terms)

    def label(self) -> str:
        """How a prediction names the model that made it."""
        if self.source_path is None and not self.terms:
            return f"{self.payload.name} profile"
        where = self.source_path.name if self.source_path else "calibrated model"
        when = self.provenance.get("created_utc", "")[:10]
        flights = self.provenance.get("flights")
        count = f" on {len(flights)} flights" if isinstance(flights, list) else ""
        return f"{where} (calibrated {when}{count})" if when else where

    def to_dict(self) -> dict[str, Any]:
        ellipse = None
        if self.ellipse is not None:
            ellipse = {k: getattr(self.ellipse, k) for k in ("sigma0_km", "h", "k_km2_per_h2", "q")}
        return {
            "kind": FILE_KIND,
            "schema": SCHEMA_VERSION,
            "payload": self.payload.to_dict(),
            "terms": [{"effect": t.name, "parameters": t.parameters()} for t in self.terms],
            "ellipse": ellipse,
            "provenance": self.provenance,
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
        return ModelFileError(f"model file {source}: {where}: {problem}" if where else f"model file {source}: {problem}")

    try:
        raw = json.loads(source.read_text(encoding="utf-8"))
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
        raise refuse("schema", f"version {schema} is newer than this drs reads ({SCHEMA_VERSION}); update drs")
    payload = _payload(raw.get("payload"), refuse)
    terms = _terms(raw.get("terms"), refuse)
    ellipse = _ellipse(raw.get("ellipse"), refuse)
    provenance = raw.get("provenance", {})
    if not isinstance(provenance, dict):
        raise refuse("provenance", "must be an object")
    return CalibratedModel(payload, terms, ellipse, provenance, source)


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
    name = str(raw.get("name", "calibrated"))
    return Payload(mass, cda, name=name, source=str(raw.get("source", "calibrated model file")))


def _terms(raw: Any, refuse: Any) -> tuple[Term, ...]:
    if not isinstance(raw, list):
        raise refuse("terms", "must be a list (empty when calibration selected nothing)")
    terms = []
    for index, item in enumerate(raw):
        where = f"terms[{index}]"
        if not isinstance(item, dict):
            raise refuse(where, "must be an object with effect and parameters")
        kind = EFFECTS.get(str(item.get("effect")))
        if kind is None:
            raise refuse(f"{where}.effect", f"{item.get('effect')!r} is not a known effect (known: {', '.join(EFFECTS)})")
        parameters = item.get("parameters", {})
        if not isinstance(parameters, dict):
            raise refuse(f"{where}.parameters", "must be an object")
        known = {f.name: f for f in dataclasses.fields(kind)}
        values: dict[str, Any] = {}
        for key, value in parameters.items():
            if key not in known:
                raise refuse(f"{where}.parameters.{key}", f"is not a parameter of {kind.name} ({', '.join(known)})")
            if isinstance(value, list):
                values[key] = tuple(_number(v, f"{where}.parameters.{key}[{i}]", refuse) for i, v in enumerate(value))
            else:
                values[key] = _number(value, f"{where}.parameters.{key}", refuse)
        try:
            terms.append(kind(**values))
        except (PredictorError, TypeError) as exc:
            raise refuse(where, str(exc)) from None
    return tuple(terms)


def _ellipse(raw: Any, refuse: Any) -> ErrorModel | None:
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise refuse("ellipse", "must be an object or null")
    values = [_number(raw.get(key), f"ellipse.{key}", refuse) for key in ("sigma0_km", "h", "k_km2_per_h2", "q")]
    try:
        return ErrorModel(*values, name="calibrated")
    except PredictorError as exc:
        raise refuse("ellipse", str(exc)) from None


def flown_model(
    model_path: str | Path | None, profile: str | None, mass_kg: float | None, cda_m2: float | None
) -> CalibratedModel:
    """What a command flies: a calibrated model file, or a payload profile (with --mass/--cda overrides)
    as a model without calibrated terms. One rule for predict, plan and live: the file carries its payload,
    so both together are refused rather than one silently winning."""
    if model_path is not None:
        if profile is not None or mass_kg is not None or cda_m2 is not None:
            raise PredictorError("give --model or --payload/--mass/--cda, not both: the model carries its payload")
        return load_model(model_path)
    return CalibratedModel(payload_profile(profile or "drs").overridden(mass_kg=mass_kg, cda_m2=cda_m2), (), None)
