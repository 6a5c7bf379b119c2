"""The descent physics as a chain of small terms, and the one compiled engine that steps them.

``model`` holds every physical effect as a registered term, ``payload`` the two numbers the drag law
needs, ``integrate`` the stepper that knows no physics (``descend``), ``landing`` where a path
meets the ground, and ``rate_prior`` what a flight's own rate factor is expected to be.
"""

from predictor.lazy_door import lazy_door

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
        "RatePrior": "rate_prior",
        "Record": "integrate",
        "Release": "integrate",
        "STATUS_ABOVE_TOP": "integrate",
        "STATUS_NOT_DESCENDING": "integrate",
        "STATUS_OK": "integrate",
        "STATUS_OUTSIDE_REGION": "integrate",
        "STATUS_OUTSIDE_TIME": "integrate",
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
