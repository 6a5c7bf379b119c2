"""The calibration loop: measured descents against predicted ones, and what is learned from them.

``residuals`` compares, ``effects`` lists the fit-able effects and the binned correction, ``selection``
chooses effects family by family leave-one-flight-out, ``ellipse_fit`` fits the landing ellipse,
``report`` writes the results, and ``run`` is what ``drs calibrate`` runs. The model it saves is
``predictor.prediction.model_file``, which every prediction can fly; ``live_evaluation`` (with ``live_bench``) measures live
re-prediction on real descents and adds its settings to that model; ``prior_spread`` flies a prediction
at the model's rate prior's ±1σ of λ (its descent-time interval); ``vertical_check`` flies a saved
law on flights it never saw, on the vertical record alone (``drs calibrate vertical``).
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .live_bench import bench as bench
    from .live_evaluation import (
        evaluate_live as evaluate_live,
        live_settings as live_settings,
        write_live_report as write_live_report,
    )
    from .prior_spread import descent_spread as descent_spread
    from .run import run_bench as run_bench, run_calibrate as run_calibrate, run_vertical as run_vertical

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "bench": "live_bench",
        "live_settings": "live_evaluation",
        "descent_spread": "prior_spread",
        "evaluate_live": "live_evaluation",
        "run_bench": "run",
        "run_calibrate": "run",
        "run_vertical": "run",
        "write_live_report": "live_evaluation",
    },
)
