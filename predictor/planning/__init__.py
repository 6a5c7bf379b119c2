"""Release planning: where the balloon goes next, and which release times land well.

``balloon`` carries the balloon forward at float altitude (or along an altitude plan), ``batch`` runs
thousands of descents from different times and places in one compiled call, ``sweep`` turns them into
per-candidate landings, zone probabilities, target distances and go/no-go with ranked windows, and
``strip`` writes the landing strip as KML/GeoJSON. Live re-prediction during a descent is in
``predictor.prediction.live``; its evaluation on real flights is ``live_evaluation``.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .balloon import AltitudePlan as AltitudePlan
    from .limits import MAX_MEMBER_DESCENTS as MAX_MEMBER_DESCENTS
    from .strip import write_geojson as write_geojson, write_kml as write_kml
    from .sweep import ReleasePlan as ReleasePlan, Thresholds as Thresholds, plan_release as plan_release

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
