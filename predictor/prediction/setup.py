"""How a descent is flown and judged, and how an ensemble's members are drawn: the request values of
``predict``, ``predict_ensemble`` and ``plan_release``.

Why values: every caller (the CLI, the console, the Tawhiri API, live re-prediction, calibration) states
the same few things (what falls, onto what ground, in what altitude steps, judged by which error model),
and a calibrated model states most of them itself (``CalibratedModel.flight_setup``). One value keeps
those callers from drifting apart on a default, and keeps each entry point to a few arguments.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from predictor.descent import DEFAULT_TIME_TOLERANCE_S, PROFILES, Model, Payload, Term
from predictor.environment import Terrain
from predictor.prediction.uncertainty import LAUNCH, ErrorModel

DEFAULT_RATE_SIGMA = 0.07
DEFAULT_WIND_SIGMA_MS = 1.5


def _drs_profile() -> Payload:
    return PROFILES["drs"]


@dataclass(frozen=True)
class FlightSetup:
    """What falls (the payload's drag law and the model's extra terms), onto which ground, stepped how,
    and the error model its ellipse is drawn from."""

    payload: Payload = field(default_factory=_drs_profile)
    effects: tuple[Term, ...] = ()
    """Terms after the payload's drag law and the wind (a calibrated model's selected effects)."""
    terrain: Terrain = field(default_factory=Terrain.sea_level)
    step_m: float = 100.0
    """Altitude step of the stepper."""
    error_model: ErrorModel = LAUNCH
    probabilities: tuple[float, ...] = ()
    """Extra ellipse levels to report beside 1σ/2σ/3σ."""
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S
    """How far beyond the weather's first/last time it is held constant."""
    model: Model | None = None
    """A whole chain instead of the payload's (a closed-form law in a test); the payload is then only
    reported."""

    def chain(self) -> Model:
        """The model chain flown: ``model``, else the payload's drag law, the wind and ``effects``."""
        return self.model or Model.for_payload(self.payload, *self.effects)


@dataclass(frozen=True)
class EnsembleSpread:
    """How a perturbed ensemble is drawn: each member's descent-rate factor is log-normal (median 1, σ of
    the log ``rate_sigma``: Cd·A, mass and density errors together) and its wind error normal with
    ``wind_sigma_ms`` per component, both held for the whole descent; ``seed`` makes it repeatable."""

    members: int = 1000
    seed: int = 0
    rate_sigma: float = DEFAULT_RATE_SIGMA
    wind_sigma_ms: float = DEFAULT_WIND_SIGMA_MS
