"""Release planning: where the balloon goes next, and which release times land well (issue 7).

``balloon`` carries the balloon forward at float altitude (or along an altitude plan), ``batch`` runs
thousands of descents from different times and places in one compiled call, ``sweep`` turns them into
per-candidate landings, zone probabilities, target distances and go/no-go with ranked windows, and
``strip`` writes the landing strip as KML/GeoJSON. Live re-prediction during a descent is in
``predictor.prediction.live``; its evaluation on real flights is ``live_evaluation``.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "AltitudePlan": "balloon",
        "MAX_MEMBER_DESCENTS": "limits",
        "ReleasePlan": "sweep",
        "Thresholds": "sweep",
        "plan_release": "sweep",
        "write_geojson": "strip",
        "write_kml": "strip",
    },
)
