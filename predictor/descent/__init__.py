"""The descent physics as a chain of small terms, and the one compiled engine that steps them.

``model`` holds every physical effect as a registered term, ``payload`` the two numbers the drag law
needs, ``integrate`` the stepper that knows no physics (``descend``), ``landing`` where a path
meets the ground, ``rate_prior`` what a flight's own rate factor is expected to be, and ``release`` where
and when a flight starts.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .integrate import (
        COMPILE_NOTICE as COMPILE_NOTICE,
        DEFAULT_TIME_TOLERANCE_S as DEFAULT_TIME_TOLERANCE_S,
        STATUS_ABOVE_TOP as STATUS_ABOVE_TOP,
        STATUS_NOT_DESCENDING as STATUS_NOT_DESCENDING,
        STATUS_OK as STATUS_OK,
        STATUS_OUTSIDE_REGION as STATUS_OUTSIDE_REGION,
        STATUS_OUTSIDE_TIME as STATUS_OUTSIDE_TIME,
        TOP_TOLERANCE_M as TOP_TOLERANCE_M,
        Record as Record,
        Starts as Starts,
        Stepping as Stepping,
        degrees_per_metre as degrees_per_metre,
        descend as descend,
        drift_at_float as drift_at_float,
        kernels_compiled as kernels_compiled,
        packed as packed,
        sample_weather as sample_weather,
    )
    from .landing import (
        HIGHEST_GROUND_M as HIGHEST_GROUND_M,
        LOWEST_GROUND_M as LOWEST_GROUND_M,
        ground_crossings as ground_crossings,
        wrap_lon as wrap_lon,
    )
    from .model import (
        EFFECTS as EFFECTS,
        BinnedDescentRate as BinnedDescentRate,
        BinnedWind as BinnedWind,
        DescentRateScale as DescentRateScale,
        MeasuredDescentRate as MeasuredDescentRate,
        Model as Model,
        Term as Term,
        Wind as Wind,
        WindOffset as WindOffset,
    )
    from .payload import PROFILES as PROFILES, Payload as Payload, payload_profile as payload_profile
    from .rate_prior import PreflightSpread as PreflightSpread, RatePrior as RatePrior
    from .release import Release as Release

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "BinnedDescentRate": "model",
        "BinnedWind": "model",
        "COMPILE_NOTICE": "integrate",
        "DEFAULT_TIME_TOLERANCE_S": "integrate",
        "DescentRateScale": "model",
        "EFFECTS": "model",
        "HIGHEST_GROUND_M": "landing",
        "LOWEST_GROUND_M": "landing",
        "MeasuredDescentRate": "model",
        "Model": "model",
        "PROFILES": "payload",
        "Payload": "payload",
        "PreflightSpread": "rate_prior",
        "RatePrior": "rate_prior",
        "Record": "integrate",
        "Release": "release",
        "STATUS_ABOVE_TOP": "integrate",
        "STATUS_NOT_DESCENDING": "integrate",
        "STATUS_OK": "integrate",
        "STATUS_OUTSIDE_REGION": "integrate",
        "STATUS_OUTSIDE_TIME": "integrate",
        "Starts": "integrate",
        "Stepping": "integrate",
        "TOP_TOLERANCE_M": "integrate",
        "Term": "model",
        "Wind": "model",
        "WindOffset": "model",
        "degrees_per_metre": "integrate",
        "descend": "integrate",
        "drift_at_float": "integrate",
        "ground_crossings": "landing",
        "kernels_compiled": "integrate",
        "packed": "integrate",
        "payload_profile": "payload",
        "sample_weather": "integrate",
        "wrap_lon": "landing",
    },
)
