"""Where a capsule will land and how sure we are: weather, terrain, descent physics, uncertainty.

The package's door: every name below is importable from ``predictor``. They are loaded on first use
(PEP 562), because importing them all costs numba, xarray and eccodes, and a command that only prints
its ``--help`` or reads a zones file should not pay for a descent engine it never runs.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .descent.model import EFFECTS as EFFECTS, Model as Model, Term as Term
    from .descent.payload import PROFILES as PROFILES, Payload as Payload, payload_profile as payload_profile
    from .descent.release import Release as Release
    from .environment.cube import WeatherCube as WeatherCube
    from .environment.terrain import Terrain as Terrain
    from .environment.weather import load_weather as load_weather
    from .errors import (
        OutOfCoverageError as OutOfCoverageError,
        PredictorError as PredictorError,
        TerrainError as TerrainError,
        WeatherError as WeatherError,
    )
    from .prediction.landings import (
        EnsemblePrediction as EnsemblePrediction,
        LandingSet as LandingSet,
        Prediction as Prediction,
        predict as predict,
        predict_ensemble as predict_ensemble,
        predict_landings as predict_landings,
    )
    from .prediction.setup import EnsembleSpread as EnsembleSpread, FlightSetup as FlightSetup
    from .prediction.uncertainty import (
        HINDSIGHT as HINDSIGHT,
        LAUNCH as LAUNCH,
        Ellipse as Ellipse,
        ErrorModel as ErrorModel,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "WeatherCube": "environment.cube",
        "OutOfCoverageError": "errors",
        "PredictorError": "errors",
        "TerrainError": "errors",
        "WeatherError": "errors",
        "EFFECTS": "descent.model",
        "Model": "descent.model",
        "Term": "descent.model",
        "PROFILES": "descent.payload",
        "Payload": "descent.payload",
        "payload_profile": "descent.payload",
        "Release": "descent.release",
        "EnsembleSpread": "prediction.setup",
        "FlightSetup": "prediction.setup",
        "EnsemblePrediction": "prediction.landings",
        "LandingSet": "prediction.landings",
        "Prediction": "prediction.landings",
        "predict": "prediction.landings",
        "predict_ensemble": "prediction.landings",
        "predict_landings": "prediction.landings",
        "Terrain": "environment.terrain",
        "HINDSIGHT": "prediction.uncertainty",
        "LAUNCH": "prediction.uncertainty",
        "Ellipse": "prediction.uncertainty",
        "ErrorModel": "prediction.uncertainty",
        "load_weather": "environment.weather",
    },
)
