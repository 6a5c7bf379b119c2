"""Where a capsule will land and how sure we are: weather, terrain, descent physics, uncertainty.

The package's door: every name below is importable from ``predictor``. They are loaded on first use
(PEP 562), because importing them all costs numba, xarray and eccodes, and a command that only prints
its ``--help`` or reads a zones file should not pay for a descent engine it never runs.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "WeatherCube": "predictor.environment.cube",
    "OutOfCoverageError": "predictor.errors",
    "PredictorError": "predictor.errors",
    "TerrainError": "predictor.errors",
    "WeatherError": "predictor.errors",
    "EFFECTS": "predictor.descent.model",
    "Model": "predictor.descent.model",
    "Term": "predictor.descent.model",
    "PROFILES": "predictor.descent.payload",
    "Payload": "predictor.descent.payload",
    "payload_profile": "predictor.descent.payload",
    "EnsemblePrediction": "predictor.prediction.landings",
    "LandingSet": "predictor.prediction.landings",
    "Prediction": "predictor.prediction.landings",
    "predict": "predictor.prediction.landings",
    "predict_ensemble": "predictor.prediction.landings",
    "predict_landings": "predictor.prediction.landings",
    "Terrain": "predictor.environment.terrain",
    "HINDSIGHT": "predictor.prediction.uncertainty",
    "LAUNCH": "predictor.prediction.uncertainty",
    "Ellipse": "predictor.prediction.uncertainty",
    "ErrorModel": "predictor.prediction.uncertainty",
    "load_weather": "predictor.environment.weather",
}

__all__ = sorted(_EXPORTS)

def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'predictor' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
