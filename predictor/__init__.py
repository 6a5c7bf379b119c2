"""Where a capsule will land and how sure we are: weather, terrain, descent physics, uncertainty."""

from __future__ import annotations

from predictor.cube import WeatherCube
from predictor.errors import OutOfCoverageError, PredictorError, TerrainError, WeatherError
from predictor.model import EFFECTS, Model, Term
from predictor.payload import PROFILES, Payload, payload_profile
from predictor.prediction import (
    EnsemblePrediction,
    LandingSet,
    Prediction,
    predict,
    predict_ensemble,
    predict_landings,
)
from predictor.terrain import Terrain
from predictor.uncertainty import HINDSIGHT, LAUNCH, Ellipse, ErrorModel
from predictor.weather import load_weather

__all__ = [
    "EFFECTS",
    "HINDSIGHT",
    "LAUNCH",
    "PROFILES",
    "Ellipse",
    "LandingSet",
    "EnsemblePrediction",
    "ErrorModel",
    "Model",
    "OutOfCoverageError",
    "Payload",
    "Prediction",
    "PredictorError",
    "Term",
    "Terrain",
    "TerrainError",
    "WeatherCube",
    "WeatherError",
    "load_weather",
    "payload_profile",
    "predict",
    "predict_ensemble",
    "predict_landings",
]
