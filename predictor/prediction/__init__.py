"""Landing predictions and how sure they are, as an operator and other tools receive them.

``landings`` runs one descent or an ensemble (asked with the ``setup`` values), ``uncertainty`` gives
the ellipse, ``zones`` says what it touches, ``live`` re-predicts from each position report during the descent, ``plausibility`` flags
inputs an operator probably did not mean, ``export`` writes the results as files, and ``model_file`` is
the model a prediction flies: a calibrated model file or a payload profile (``flown_model``).
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .export import (
        to_json as to_json,
        to_kml as to_kml,
        write_geojson as write_geojson,
        write_gpx as write_gpx,
        write_kml as write_kml,
    )
    from .landings import (
        EnsemblePrediction as EnsemblePrediction,
        Point as Point,
        Prediction as Prediction,
        coverage_error as coverage_error,
        iso_z as iso_z,
        predict as predict,
        predict_ensemble as predict_ensemble,
    )
    from .live import (
        CONSTANT_WIND_M as CONSTANT_WIND_M,
        DEFAULT_ELLIPSE_NOTE as DEFAULT_ELLIPSE_NOTE,
        DISTANCE_RATIO_LIMITS as DISTANCE_RATIO_LIMITS,
        LIVE_ERROR_MODEL as LIVE_ERROR_MODEL,
        LIVE_PROBABILITIES as LIVE_PROBABILITIES,
        NO_CORRECTION as NO_CORRECTION,
        NO_DISCREPANCY as NO_DISCREPANCY,
        OWN_RATE as OWN_RATE,
        Band as Band,
        DescentRecord as DescentRecord,
        LiveCorrection as LiveCorrection,
        LiveErrorModel as LiveErrorModel,
        LivePrediction as LivePrediction,
        LivePredictor as LivePredictor,
        LiveSettings as LiveSettings,
        RateDiscrepancy as RateDiscrepancy,
        RateEstimate as RateEstimate,
        Report as Report,
        WindGain as WindGain,
    )
    from .model_file import (
        PARAMETER_LIMITS as PARAMETER_LIMITS,
        CalibratedModel as CalibratedModel,
        flown_model as flown_model,
        load_model as load_model,
        save_model as save_model,
    )
    from .plausibility import (
        emit as emit,
        far_features_warning as far_features_warning,
        far_team_warning as far_team_warning,
        release_altitude_warning as release_altitude_warning,
    )
    from .setup import (
        DEFAULT_RATE_SIGMA as DEFAULT_RATE_SIGMA,
        DEFAULT_WIND_SIGMA_MS as DEFAULT_WIND_SIGMA_MS,
        EnsembleSpread as EnsembleSpread,
        FlightSetup as FlightSetup,
    )
    from .uncertainty import (
        ERROR_MODELS as ERROR_MODELS,
        GEOD as GEOD,
        HINDSIGHT as HINDSIGHT,
        LAUNCH as LAUNCH,
        Ellipse as Ellipse,
        ErrorModel as ErrorModel,
        coverage as coverage,
        n_sigma_for as n_sigma_for,
        parametric_ellipse as parametric_ellipse,
    )
    from .zones import (
        Feature as Feature,
        LocalPlane as LocalPlane,
        ZoneFileError as ZoneFileError,
        distance_at_center_km as distance_at_center_km,
        ellipse_covariance as ellipse_covariance,
        expected_distance_km as expected_distance_km,
        inside_any as inside_any,
        load_targets as load_targets,
        load_zones as load_zones,
        zone_probabilities as zone_probabilities,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "Band": "live",
        "CalibratedModel": "model_file",
        "CONSTANT_WIND_M": "live",
        "DEFAULT_ELLIPSE_NOTE": "live",
        "DEFAULT_RATE_SIGMA": "setup",
        "DEFAULT_WIND_SIGMA_MS": "setup",
        "DescentRecord": "live",
        "ERROR_MODELS": "uncertainty",
        "Ellipse": "uncertainty",
        "EnsemblePrediction": "landings",
        "EnsembleSpread": "setup",
        "ErrorModel": "uncertainty",
        "Feature": "zones",
        "FlightSetup": "setup",
        "GEOD": "uncertainty",
        "HINDSIGHT": "uncertainty",
        "LAUNCH": "uncertainty",
        "LiveCorrection": "live",
        "LiveErrorModel": "live",
        "LivePrediction": "live",
        "LivePredictor": "live",
        "LiveSettings": "live",
        "LocalPlane": "zones",
        "LIVE_ERROR_MODEL": "live",
        "LIVE_PROBABILITIES": "live",
        "DISTANCE_RATIO_LIMITS": "live",
        "NO_CORRECTION": "live",
        "NO_DISCREPANCY": "live",
        "OWN_RATE": "live",
        "PARAMETER_LIMITS": "model_file",
        "Point": "landings",
        "Prediction": "landings",
        "Report": "live",
        "RateDiscrepancy": "live",
        "RateEstimate": "live",
        "WindGain": "live",
        "ZoneFileError": "zones",
        "coverage_error": "landings",
        "coverage": "uncertainty",
        "n_sigma_for": "uncertainty",
        "distance_at_center_km": "zones",
        "ellipse_covariance": "zones",
        "emit": "plausibility",
        "expected_distance_km": "zones",
        "far_features_warning": "plausibility",
        "far_team_warning": "plausibility",
        "flown_model": "model_file",
        "inside_any": "zones",
        "iso_z": "landings",
        "load_model": "model_file",
        "load_targets": "zones",
        "load_zones": "zones",
        "parametric_ellipse": "uncertainty",
        "predict": "landings",
        "predict_ensemble": "landings",
        "release_altitude_warning": "plausibility",
        "save_model": "model_file",
        "to_json": "export",
        "to_kml": "export",
        "write_geojson": "export",
        "write_gpx": "export",
        "write_kml": "export",
        "zone_probabilities": "zones",
    },
)
