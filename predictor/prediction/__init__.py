"""Landing predictions and how sure they are, as an operator and other tools receive them.

``landings`` runs one descent or an ensemble, ``uncertainty`` gives the ellipse, ``zones`` says what it
touches, ``live`` re-predicts from each position report during the descent, ``plausibility`` flags
inputs an operator probably did not mean, and ``export`` writes the results as files.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .export import to_json as to_json
    from .export import to_kml as to_kml
    from .export import write_geojson as write_geojson
    from .export import write_gpx as write_gpx
    from .export import write_kml as write_kml
    from .landings import DEFAULT_RATE_SIGMA as DEFAULT_RATE_SIGMA
    from .landings import DEFAULT_WIND_SIGMA_MS as DEFAULT_WIND_SIGMA_MS
    from .landings import EnsemblePrediction as EnsemblePrediction
    from .landings import Point as Point
    from .landings import Prediction as Prediction
    from .landings import coverage_error as coverage_error
    from .landings import iso_z as iso_z
    from .landings import predict as predict
    from .landings import predict_ensemble as predict_ensemble
    from .live import CONSTANT_WIND_M as CONSTANT_WIND_M
    from .live import DEFAULT_ELLIPSE_NOTE as DEFAULT_ELLIPSE_NOTE
    from .live import LIVE_ERROR_MODEL as LIVE_ERROR_MODEL
    from .live import NO_CORRECTION as NO_CORRECTION
    from .live import NO_DISCREPANCY as NO_DISCREPANCY
    from .live import OWN_RATE as OWN_RATE
    from .live import Band as Band
    from .live import DescentRecord as DescentRecord
    from .live import LiveCorrection as LiveCorrection
    from .live import LiveErrorModel as LiveErrorModel
    from .live import LivePrediction as LivePrediction
    from .live import LivePredictor as LivePredictor
    from .live import LiveSettings as LiveSettings
    from .live import RateDiscrepancy as RateDiscrepancy
    from .live import RateEstimate as RateEstimate
    from .live import Report as Report
    from .plausibility import emit as emit
    from .plausibility import far_features_warning as far_features_warning
    from .plausibility import far_team_warning as far_team_warning
    from .plausibility import release_altitude_warning as release_altitude_warning
    from .uncertainty import ERROR_MODELS as ERROR_MODELS
    from .uncertainty import GEOD as GEOD
    from .uncertainty import HINDSIGHT as HINDSIGHT
    from .uncertainty import LAUNCH as LAUNCH
    from .uncertainty import Ellipse as Ellipse
    from .uncertainty import ErrorModel as ErrorModel
    from .uncertainty import coverage as coverage
    from .uncertainty import parametric_ellipse as parametric_ellipse
    from .zones import Feature as Feature
    from .zones import LocalPlane as LocalPlane
    from .zones import ZoneFileError as ZoneFileError
    from .zones import distance_at_center_km as distance_at_center_km
    from .zones import ellipse_covariance as ellipse_covariance
    from .zones import expected_distance_km as expected_distance_km
    from .zones import inside_any as inside_any
    from .zones import load_targets as load_targets
    from .zones import load_zones as load_zones
    from .zones import zone_probabilities as zone_probabilities

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "Band": "live",
        "CONSTANT_WIND_M": "live",
        "DEFAULT_ELLIPSE_NOTE": "live",
        "DEFAULT_RATE_SIGMA": "landings",
        "DEFAULT_WIND_SIGMA_MS": "landings",
        "DescentRecord": "live",
        "ERROR_MODELS": "uncertainty",
        "Ellipse": "uncertainty",
        "EnsemblePrediction": "landings",
        "ErrorModel": "uncertainty",
        "Feature": "zones",
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
        "NO_CORRECTION": "live",
        "NO_DISCREPANCY": "live",
        "OWN_RATE": "live",
        "Point": "landings",
        "Prediction": "landings",
        "Report": "live",
        "RateDiscrepancy": "live",
        "RateEstimate": "live",
        "ZoneFileError": "zones",
        "coverage_error": "landings",
        "coverage": "uncertainty",
        "distance_at_center_km": "zones",
        "ellipse_covariance": "zones",
        "emit": "plausibility",
        "expected_distance_km": "zones",
        "far_features_warning": "plausibility",
        "far_team_warning": "plausibility",
        "inside_any": "zones",
        "iso_z": "landings",
        "load_targets": "zones",
        "load_zones": "zones",
        "parametric_ellipse": "uncertainty",
        "predict": "landings",
        "predict_ensemble": "landings",
        "release_altitude_warning": "plausibility",
        "to_json": "export",
        "to_kml": "export",
        "write_geojson": "export",
        "write_gpx": "export",
        "write_kml": "export",
        "zone_probabilities": "zones",
    },
)
