"""Where a capsule will land and how sure we are: weather, terrain, descent physics, uncertainty.

The package's door: every name below is importable from ``predictor``. They are loaded on first use
(PEP 562), because importing them all costs numba, xarray and eccodes, and a command that only prints
its ``--help`` or reads a zones file should not pay for a descent engine it never runs.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .descent.model import EFFECTS as EFFECTS
    from .descent.model import Model as Model
    from .descent.model import Term as Term
    from .descent.payload import PROFILES as PROFILES
    from .descent.payload import Payload as Payload
    from .descent.payload import payload_profile as payload_profile
    from .environment.cube import WeatherCube as WeatherCube
    from .environment.terrain import Terrain as Terrain
    from .environment.weather import load_weather as load_weather
    from .errors import OutOfCoverageError as OutOfCoverageError
    from .errors import PredictorError as PredictorError
    from .errors import TerrainError as TerrainError
    from .errors import WeatherError as WeatherError
    from .prediction.landings import EnsemblePrediction as EnsemblePrediction
    from .prediction.landings import LandingSet as LandingSet
    from .prediction.landings import Prediction as Prediction
    from .prediction.landings import predict as predict
    from .prediction.landings import predict_ensemble as predict_ensemble
    from .prediction.landings import predict_landings as predict_landings
    from .prediction.uncertainty import HINDSIGHT as HINDSIGHT
    from .prediction.uncertainty import LAUNCH as LAUNCH
    from .prediction.uncertainty import Ellipse as Ellipse
    from .prediction.uncertainty import ErrorModel as ErrorModel

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
