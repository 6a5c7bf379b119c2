"""Landing predictions and how sure they are, as an operator and other tools receive them.

``landings`` runs one descent or an ensemble, ``uncertainty`` gives the ellipse, ``zones`` says what it
touches, ``live`` re-predicts from each position report during the descent, ``plausibility`` flags
inputs an operator probably did not mean, and ``export`` writes the results as files.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "Band": "live",
        "DEFAULT_LIVE": "live",
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
        "LivePredictor": "live",
        "LiveSettings": "live",
        "LocalPlane": "zones",
        "NO_CORRECTION": "live",
        "Point": "landings",
        "Prediction": "landings",
        "Report": "live",
        "TypicalRate": "live",
        "ZoneFileError": "zones",
        "_coverage_error": "landings",
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
