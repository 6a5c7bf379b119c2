"""The descent model as a chain of small terms, each one physical effect, run by one compiled integrator.

Why a chain: the calibration work (``drs calibrate``) must be able to try an effect, fit its
parameters and keep it or drop it without touching the integrator. So the integrator
(``predictor.descent.integrate``) knows only three slots, one per family, and calls each with the local
environment; everything physical lives here.

How a step sees the terms. For every altitude step the integrator fills ``env`` (see the ``ENV_*``
indices: midpoint altitude, time since release, air density, gravity, the weather's wind, the
step's height …) and a velocity vector ``vel`` = (down, east, north) m/s starting at zero. Then:

1. ``timing`` terms add to ``env[ENV_TIME_SHIFT]`` (seconds); the weather is sampled at t + shift;
2. ``vertical`` terms add to ``vel[VEL_DOWN]``; the integrator then sets ``env[ENV_DT]`` = Δz / down;
3. ``horizontal`` terms add to ``vel[VEL_EAST]`` and ``vel[VEL_NORTH]``.

Each term adds its increment to what the terms before it produced; a scale factor λ adds
(λ − 1)·(sum so far), which is the same as multiplying. Terms run in ``stage`` order (base terms,
then corrections, then dynamics such as ``wind_lag`` that must see the final wind), and in the given
order within a stage.

Why a registry and not Python callbacks: the whole descent runs compiled (numba), for 1000 members
at once, and a compiled loop cannot call arbitrary Python objects. Each term class therefore carries
its ``kernel``, a small ``@njit`` function ``(p, p_off, s_off, env, vel, state)`` that reads its
parameters at ``p[p_off + i]`` and its per-trajectory state at ``state[s_off + j]``. ``TERMS`` lists
every term once; a term's kind is its place in that list, and the compiled dispatch is built from
it, so a model is a table of (family, kind, p_off, s_off) rows that ``apply_family`` walks. One
compiled integrator serves every model, and numba caches it on disk.

Adding a term (see docs/architecture.md): a frozen dataclass subclass of ``Term`` in this file whose
float fields are its parameters, with ``name``, ``family``, ``stage`` and its ``kernel``, and its
class in ``TERMS``. Parameters may be per-trajectory arrays (ensemble members, one value per flight):
a field then holds an array with one value per trajectory instead of a float.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, NamedTuple

import numpy as np
from numba import njit
from numba.core.dispatcher import Dispatcher

from predictor.descent.payload import Payload
from predictor.errors import PredictorError
from predictor.numba_cache import ensure_cache_dir

ensure_cache_dir(__file__)  # before the first @njit(cache=True): predictor/numba_cache.py

ENV_Z = 0
"""Midpoint altitude of the step, m above mean sea level."""
ENV_T_REL = 1
"""Seconds since release at the step midpoint."""
ENV_RHO = 2
"""Air density at the midpoint, kg/m³."""
ENV_G = 3
"""Gravity at the midpoint altitude, m/s²."""
ENV_U_WIND = 4
"""Eastward wind of the weather at the midpoint, m/s."""
ENV_V_WIND = 5
"""Northward wind of the weather at the midpoint, m/s."""
ENV_DZ = 6
"""Height of this step, m (positive)."""
ENV_DT = 7
"""Duration of this step, s (set after the vertical terms)."""
ENV_LAT = 8
"""Latitude of the midpoint, degrees."""
ENV_TIME_SHIFT = 9
"""Seconds added to the time at which the weather is sampled (timing terms add to it)."""
ENV_T_START = 10
"""Seconds since release at the start of the step."""
ENV_SIZE = 11

VEL_DOWN = 0
VEL_EAST = 1
VEL_NORTH = 2

FAMILIES = ("timing", "vertical", "horizontal")
FAMILY_TIMING = 0
FAMILY_VERTICAL = 1
FAMILY_HORIZONTAL = 2

BASE_STAGE = 0
"""The stage of the terms a chain is built on (a drag law, the wind); every later stage is an effect."""
STANDARD_SEA_LEVEL_DENSITY = 1.225

Kernel = Callable[[np.ndarray, int, int, np.ndarray, np.ndarray, np.ndarray], None]
"""A term's compiled step: (p, p_off, s_off, env, vel, state), adding the term's increment in place."""


@dataclass(frozen=True)
class Term:
    """One effect of the model; subclasses are frozen dataclasses whose fields are the parameters."""

    name: ClassVar[str] = ""
    family: ClassVar[str] = ""
    stage: ClassVar[int] = 1
    n_state: ClassVar[int] = 0
    kernel: ClassVar[Dispatcher[Kernel]]
    """Compiled, because the dispatch (``apply_term``) is compiled and numba calls only compiled code."""

    def columns(self) -> list[float | np.ndarray]:
        """One entry per parameter slot: a float, or an array with one value per trajectory."""
        return [getattr(self, f.name) for f in fields(self)]

    def initial_state(self) -> list[float]:
        return []

    def parameters(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


@njit(cache=True)
def _bin_of(p: np.ndarray, p_off: int, n_bins: int, z: float) -> int:
    if z < p[p_off] or z >= p[p_off + n_bins]:
        return -1
    b = 0
    while b < n_bins - 1 and z >= p[p_off + b + 1]:
        b += 1
    return b


def _check_bins(edges: Sequence[float], values: Sequence[Sequence[float]], name: str) -> None:
    if len(edges) < 2 or any(b <= a for a, b in zip(edges[:-1], edges[1:], strict=False)):
        raise PredictorError(f"{name}: bin edges must be at least two strictly increasing altitudes")
    for column in values:
        if len(column) != len(edges) - 1:
            raise PredictorError(f"{name}: need one value per bin ({len(edges) - 1}), got {len(column)}")


# ---------------------------------------------------------------- base terms


@dataclass(frozen=True)
class TerminalVelocity(Term):
    """The drag law at terminal velocity: v = sqrt(2·m·g(z) / (ρ·Cd·A))."""

    mass_kg: float | np.ndarray
    cda_m2: float | np.ndarray
    name: ClassVar[str] = "terminal_velocity"
    family: ClassVar[str] = "vertical"
    stage: ClassVar[int] = BASE_STAGE

    @classmethod
    def of(cls, payload: Payload) -> TerminalVelocity:
        return cls(mass_kg=payload.mass_kg, cda_m2=payload.cda_m2)

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_DOWN] += math.sqrt(2.0 * p[p_off] * env[ENV_G] / (env[ENV_RHO] * p[p_off + 1]))


@dataclass(frozen=True)
class SeaLevelRate(Term):
    """The descent given by its rate at sea level: v = rate·sqrt(ρ_ref/ρ), as Tawhiri/SondeHub specify it.

    An alternative base term to ``terminal_velocity`` for operators who know a payload's landing
    speed rather than its mass and Cd·A. The default ρ_ref = 1.1045² is Tawhiri's constant, so its
    answers can be reproduced.
    """

    rate_ms: float | np.ndarray
    reference_density: float | np.ndarray = 1.1045**2
    name: ClassVar[str] = "sea_level_rate"
    family: ClassVar[str] = "vertical"
    stage: ClassVar[int] = BASE_STAGE

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_DOWN] += p[p_off] * math.sqrt(p[p_off + 1] / env[ENV_RHO])


@dataclass(frozen=True)
class MeasuredDescentRate(Term):
    """The descent rate a flight was measured to have, per altitude bin (the nearest bin outside them).

    A base term instead of ``terminal_velocity``: calibration replays a flight's measured
    altitude–time profile with it, so that a horizontal effect is fitted to where the wind carried the
    capsule while it really was at each altitude, and a descent-rate error cannot masquerade as wind.
    """

    bottom_m: float = 0.0
    bin_m: float = 100.0
    """Equal bins from ``bottom_m`` up: a 1 Hz log becomes hundreds of bins, found in one division."""
    rates_ms: tuple[float, ...] = (5.0,)
    name: ClassVar[str] = "measured_descent_rate"
    family: ClassVar[str] = "vertical"
    stage: ClassVar[int] = BASE_STAGE

    def __post_init__(self) -> None:
        if not self.rates_ms or not self.bin_m > 0:
            raise PredictorError(f"{self.name}: needs at least one bin of positive height")
        if not all(r > 0 for r in self.rates_ms):
            raise PredictorError(f"{self.name}: every rate must be positive")

    def columns(self) -> list[float | np.ndarray]:
        return [
            float(len(self.rates_ms)),
            float(self.bottom_m),
            float(self.bin_m),
            *map(float, self.rates_ms),
        ]

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        n_bins = int(p[p_off])
        b = int(math.floor((env[ENV_Z] - p[p_off + 1]) / p[p_off + 2]))
        vel[VEL_DOWN] += p[p_off + 3 + min(max(b, 0), n_bins - 1)]


@dataclass(frozen=True)
class Wind(Term):
    """Horizontal motion with the weather's wind."""

    name: ClassVar[str] = "wind"
    family: ClassVar[str] = "horizontal"
    stage: ClassVar[int] = BASE_STAGE

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_EAST] += env[ENV_U_WIND]
        vel[VEL_NORTH] += env[ENV_V_WIND]


# ---------------------------------------------------------------- vertical effects


@dataclass(frozen=True)
class DescentRateScale(Term):
    """λ: the fitted factor on the drag-law descent rate (the paper's single calibration number)."""

    scale: float | np.ndarray = 1.0
    name: ClassVar[str] = "descent_rate_scale"
    family: ClassVar[str] = "vertical"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_DOWN] += (p[p_off] - 1.0) * vel[VEL_DOWN]


@dataclass(frozen=True)
class DragDensityExponent(Term):
    """Drag that changes with density (Reynolds number): rate × (ρ/ρ_ref)^(−exponent).

    exponent 0 is the plain drag law; a positive exponent makes the descent relatively faster in
    thin air and slower near the ground, the pattern the SuperBIT flights showed.
    """

    exponent: float | np.ndarray = 0.0
    reference_density: float | np.ndarray = STANDARD_SEA_LEVEL_DENSITY
    name: ClassVar[str] = "drag_density_exponent"
    family: ClassVar[str] = "vertical"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        factor = (env[ENV_RHO] / p[p_off + 1]) ** (-p[p_off])
        vel[VEL_DOWN] += (factor - 1.0) * vel[VEL_DOWN]


@dataclass(frozen=True)
class VerticalAirMotion(Term):
    """The air itself rises at ``speed_ms`` (sinks when negative), so over the ground the capsule falls
    that much slower than through the air: rate − w.

    Why it is its own effect: the 1 Hz descents of issue #11 fell about 6 % slower than the drag law in
    the last 3 km. A density exponent explains that as drag changing with density, a slowing that grows
    smoothly all the way down; rising air (lee waves, a convective boundary layer) explains it as a
    constant speed, which weighs most where the fall is slowest, near the ground. They are told apart
    by the altitude–time record of the last kilometres, so calibration needs both to choose between them.
    An updraft faster than the fall stops the descent, which the integrator reports as not descending.
    """

    speed_ms: float | np.ndarray = 0.0
    name: ClassVar[str] = "vertical_air_motion"
    family: ClassVar[str] = "vertical"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_DOWN] -= p[p_off]


@dataclass(frozen=True)
class DeploymentDelay(Term):
    """The canopy opens ``delay_s`` after release; until then the capsule falls ``speed_factor`` faster.

    The step that contains the opening gets the exact mean rate of its two parts, so the answer
    does not depend on the step size.
    """

    delay_s: float | np.ndarray = 0.0
    speed_factor: float | np.ndarray = 3.0
    name: ClassVar[str] = "deployment_delay"
    family: ClassVar[str] = "vertical"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        fast_left = p[p_off] - env[ENV_T_START]
        if fast_left <= 0.0:
            return
        slow = vel[VEL_DOWN]
        fast = slow * p[p_off + 1]
        fast_height = fast_left * fast
        if fast_height >= env[ENV_DZ]:
            vel[VEL_DOWN] = fast
        else:
            duration = fast_left + (env[ENV_DZ] - fast_height) / slow
            vel[VEL_DOWN] = env[ENV_DZ] / duration


@dataclass(frozen=True)
class TwoRegimeRate(Term):
    """A canopy that opens further below a height: above ``height_m`` the fall is ``factor`` × faster.

    Why its own effect: a density exponent makes the rate change smoothly all the way down, a
    deployment delay makes it fast for a time after release; a canopy that is squeezed shut in thin air
    and opens out lower down does neither, it has two regimes split at an altitude. The step that
    contains ``height_m`` gets the exact mean rate of its two parts (time-weighted), so the answer does
    not depend on the step size.
    """

    height_m: float | np.ndarray = 20_000.0
    factor: float | np.ndarray = 1.0
    name: ClassVar[str] = "two_regime_rate"
    family: ClassVar[str] = "vertical"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        height = p[p_off]
        factor = p[p_off + 1]
        top = env[ENV_Z] + 0.5 * env[ENV_DZ]
        bottom = env[ENV_Z] - 0.5 * env[ENV_DZ]
        if bottom >= height:
            vel[VEL_DOWN] *= factor
        elif top > height and env[ENV_DZ] > 0.0:
            above = top - height
            below = height - bottom
            slow = vel[VEL_DOWN]
            vel[VEL_DOWN] = env[ENV_DZ] / (above / (slow * factor) + below / slow)


@dataclass(frozen=True)
class BinnedDescentRate(Term):
    """Non-parametric: a factor on the descent rate per altitude bin (1 outside the bins)."""

    edges_m: tuple[float, ...] = (0.0, 40000.0)
    factors: tuple[float, ...] = (1.0,)
    name: ClassVar[str] = "binned_descent_rate"
    family: ClassVar[str] = "vertical"

    def __post_init__(self) -> None:
        _check_bins(self.edges_m, (self.factors,), self.name)

    def columns(self) -> list[float | np.ndarray]:
        return [float(len(self.factors)), *map(float, self.edges_m), *map(float, self.factors)]

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        n_bins = int(p[p_off])
        b = _bin_of(p, p_off + 1, n_bins, env[ENV_Z])
        if b >= 0:
            vel[VEL_DOWN] += (p[p_off + n_bins + 2 + b] - 1.0) * vel[VEL_DOWN]


# ---------------------------------------------------------------- horizontal effects


@dataclass(frozen=True)
class WindScale(Term):
    """The forecast wind speed is wrong by a constant factor."""

    scale: float | np.ndarray = 1.0
    name: ClassVar[str] = "wind_scale"
    family: ClassVar[str] = "horizontal"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_EAST] += (p[p_off] - 1.0) * vel[VEL_EAST]
        vel[VEL_NORTH] += (p[p_off] - 1.0) * vel[VEL_NORTH]


@dataclass(frozen=True)
class WindRotation(Term):
    """The forecast wind direction is off by a constant angle (positive = veered, clockwise)."""

    angle_deg: float | np.ndarray = 0.0
    name: ClassVar[str] = "wind_rotation"
    family: ClassVar[str] = "horizontal"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        a = math.radians(p[p_off])
        east = vel[VEL_EAST]
        north = vel[VEL_NORTH]
        vel[VEL_EAST] = east * math.cos(a) + north * math.sin(a)
        vel[VEL_NORTH] = -east * math.sin(a) + north * math.cos(a)


@dataclass(frozen=True)
class WindBandScale(Term):
    """The wind is wrong by a factor only between two altitudes (e.g. the jet stream)."""

    bottom_m: float | np.ndarray = 8000.0
    top_m: float | np.ndarray = 14000.0
    scale: float | np.ndarray = 1.0
    name: ClassVar[str] = "wind_band_scale"
    family: ClassVar[str] = "horizontal"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        if p[p_off] <= env[ENV_Z] < p[p_off + 1]:
            vel[VEL_EAST] += (p[p_off + 2] - 1.0) * vel[VEL_EAST]
            vel[VEL_NORTH] += (p[p_off + 2] - 1.0) * vel[VEL_NORTH]


@dataclass(frozen=True)
class WindOffset(Term):
    """A constant wind error (ensemble members draw one each)."""

    east_ms: float | np.ndarray = 0.0
    north_ms: float | np.ndarray = 0.0
    name: ClassVar[str] = "wind_offset"
    family: ClassVar[str] = "horizontal"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        vel[VEL_EAST] += p[p_off]
        vel[VEL_NORTH] += p[p_off + 1]


@dataclass(frozen=True)
class BinnedWind(Term):
    """Non-parametric: an added wind (east, north) per altitude bin, zero outside the bins."""

    edges_m: tuple[float, ...] = (0.0, 40000.0)
    east_ms: tuple[float, ...] = (0.0,)
    north_ms: tuple[float, ...] = (0.0,)
    name: ClassVar[str] = "binned_wind"
    family: ClassVar[str] = "horizontal"

    def __post_init__(self) -> None:
        _check_bins(self.edges_m, (self.east_ms, self.north_ms), self.name)

    def columns(self) -> list[float | np.ndarray]:
        return [
            float(len(self.east_ms)),
            *map(float, self.edges_m),
            *map(float, self.east_ms),
            *map(float, self.north_ms),
        ]

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        n_bins = int(p[p_off])
        b = _bin_of(p, p_off + 1, n_bins, env[ENV_Z])
        if b >= 0:
            vel[VEL_EAST] += p[p_off + n_bins + 2 + b]
            vel[VEL_NORTH] += p[p_off + 2 * n_bins + 2 + b]


@dataclass(frozen=True)
class WindLag(Term):
    """The payload's horizontal inertia: its velocity relaxes to the air's with a time constant.

    Exact for a wind that is constant over one step: V(t) = W + (V0 − W)·exp(−t/τ); the step moves
    with the mean of V over the step. State: the payload's own (east, north) velocity, which starts
    equal to the air's at release (it was carried by the balloon).
    """

    time_constant_s: float | np.ndarray = 1.0
    name: ClassVar[str] = "wind_lag"
    family: ClassVar[str] = "horizontal"
    stage: ClassVar[int] = 2
    n_state: ClassVar[int] = 2

    def initial_state(self) -> list[float]:
        return [math.nan, math.nan]

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        if math.isnan(state[s_off]):
            state[s_off] = vel[VEL_EAST]
            state[s_off + 1] = vel[VEL_NORTH]
        tau = p[p_off]
        dt = env[ENV_DT]
        decay = math.exp(-dt / tau) if tau > 0.0 else 0.0
        mean_weight = tau / dt * (1.0 - decay) if tau > 0.0 else 0.0
        for k in range(2):
            air = vel[VEL_EAST + k]
            lag = state[s_off + k] - air
            vel[VEL_EAST + k] = air + lag * mean_weight
            state[s_off + k] = air + lag * decay


# ---------------------------------------------------------------- timing effects


@dataclass(frozen=True)
class WeatherTimeOffset(Term):
    """The weather happens ``offset_s`` later than the forecast says (sample it at t + offset)."""

    offset_s: float | np.ndarray = 0.0
    name: ClassVar[str] = "weather_time_offset"
    family: ClassVar[str] = "timing"

    @staticmethod
    @njit(cache=True)
    def kernel(
        p: np.ndarray, p_off: int, s_off: int, env: np.ndarray, vel: np.ndarray, state: np.ndarray
    ) -> None:
        env[ENV_TIME_SHIFT] += p[p_off]


# ---------------------------------------------------------------- the registry

TERMS: tuple[type[Term], ...] = (
    TerminalVelocity,
    SeaLevelRate,
    MeasuredDescentRate,
    Wind,
    DescentRateScale,
    DragDensityExponent,
    VerticalAirMotion,
    DeploymentDelay,
    BinnedDescentRate,
    WindScale,
    WindRotation,
    WindBandScale,
    WindOffset,
    BinnedWind,
    WindLag,
    WeatherTimeOffset,
    TwoRegimeRate,
)
"""Every term the integrator can run, each once: its kind is its index here, and the compiled dispatch,
``KINDS`` and ``EFFECTS`` are all made from this tuple, so a term cannot be half registered."""

KINDS: dict[type[Term], int] = {cls: kind for kind, cls in enumerate(TERMS)}

EFFECTS: dict[str, type[Term]] = {cls.name: cls for cls in TERMS if cls.stage != BASE_STAGE}
"""Every effect term by name, for configuration files and the calibration library (the base terms
a chain is built on are not effects: a model file that listed a drag law among its effects would
fall at twice the rate)."""


def kind_of(term: Term) -> int:
    """The term's kind; a term class missing from ``TERMS`` is refused, since no compiled code runs it."""
    kind = KINDS.get(type(term))
    if kind is None:
        raise PredictorError(
            f"term {term.name!r} ({type(term).__name__}) is not registered in predictor.descent.model.TERMS, "
            "so the integrator has no kernel for it"
        )
    return kind


def _dispatch(kernels: Sequence[Dispatcher[Kernel]]) -> Any:
    """The compiled ``apply_term``: one branch per registered kernel, its kind being its index.

    Written as source from the registry (as ``dataclasses`` writes ``__init__``) because numba can only
    call a kernel it knows at compile time: the result is the switch a hand-written if/elif chain
    would be, with the kind tested once and the loop over trajectories calling its kernel directly,
    so it compiles and runs as fast. Past the last kind the ``else`` raises: a kind the registry
    does not know never leaves a step silently without its term.
    """
    branches = "".join(
        f"    {'if' if kind == 0 else 'elif'} kind == {kind}:\n"
        "        for i in range(lo, hi):\n"
        "            if active[i]:\n"
        f"                kernel_{kind}(params[i], p_off, s_off, env[i], vel[i], state[i])\n"
        for kind in range(len(kernels))
    )
    source = (
        "def apply_term(kind, params, p_off, s_off, env, vel, state, active, lo, hi):\n"
        f"{branches}"
        "    else:\n"
        "        raise PredictorError('the model table names a term kind that is not in predictor.descent.model.TERMS')\n"
    )
    namespace: dict[str, Any] = {f"kernel_{kind}": kernel for kind, kernel in enumerate(kernels)}
    namespace["PredictorError"] = PredictorError
    exec(compile(source, f"<apply_term generated by {__name__}._dispatch>", "exec"), namespace)
    return njit(namespace["apply_term"])


apply_term = _dispatch(tuple(cls.kernel for cls in TERMS))
"""Run the term of one kind on the active trajectories lo…hi−1 (unknown kinds raise)."""


@njit(cache=True)
def apply_family(
    table: np.ndarray,
    family: int,
    params: np.ndarray,
    env: np.ndarray,
    vel: np.ndarray,
    state: np.ndarray,
    active: np.ndarray,
    lo: int,
    hi: int,
) -> None:
    """Run, in order, the terms of one family (FAMILY_TIMING, FAMILY_VERTICAL, FAMILY_HORIZONTAL).

    ``params``, ``env``, ``vel`` and ``state`` have one row per trajectory.
    """
    for row in range(table.shape[0]):
        if table[row, 0] == family:
            apply_term(table[row, 1], params, table[row, 2], table[row, 3], env, vel, state, active, lo, hi)


# ---------------------------------------------------------------- the chain


class Chain(NamedTuple):
    """A model as the compiled integrator takes it: arrays only, one row per trajectory."""

    table: np.ndarray
    """One row (family, kind, p_off, s_off) per term, in execution order."""
    params: np.ndarray
    """(n, P) parameters of every trajectory."""
    state: np.ndarray
    """(n, S) per-trajectory state of the terms that keep one."""

    def rows(self, lo: int, hi: int) -> Chain:
        """Trajectories lo…hi−1 alone, contiguous as the kernel needs them."""
        return Chain(
            self.table, np.ascontiguousarray(self.params[lo:hi]), np.ascontiguousarray(self.state[lo:hi])
        )


@dataclass(frozen=True)
class Model:
    """An ordered set of terms; the integrator runs whatever it is given."""

    terms: tuple[Term, ...]
    _order: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for term in self.terms:
            if term.family not in FAMILIES:
                raise PredictorError(f"term {term.name!r} has unknown family {term.family!r}")
            kind_of(term)
        if not any(term.family == "vertical" for term in self.terms):
            raise PredictorError("the model has no vertical term: nothing sets the descent rate")
        order = sorted(range(len(self.terms)), key=lambda i: self.terms[i].stage)
        object.__setattr__(self, "_order", tuple(order))

    @classmethod
    def for_payload(cls, payload: Payload, *effects: Term) -> Model:
        """The standard chain: the drag law for this payload, the weather's wind, then the effects."""
        return cls((TerminalVelocity.of(payload), Wind(), *effects))

    def with_terms(self, *terms: Term) -> Model:
        return Model((*self.terms, *terms))

    def ordered(self) -> list[Term]:
        return [self.terms[i] for i in self._order]

    def _offsets(self) -> list[tuple[Term, int, int]]:
        out = []
        p_off = s_off = 0
        for term in self.ordered():
            out.append((term, p_off, s_off))
            p_off += len(term.columns())
            s_off += term.n_state
        return out

    def parameter_matrix(self, n: int) -> np.ndarray:
        """Parameters of every trajectory, shape (n, P): scalar parameters are repeated.

        Each column is written in place: a broadcast view of each one, then a stack, took as long as the
        integration itself in the calibration's thousands of small flights (a replayed rate has a column
        per bin)."""
        values = [value for term in self.ordered() for value in term.columns()]
        if not values:
            return np.zeros((n, 1))
        matrix = np.empty((n, len(values)), dtype=np.float64)
        for column, value in enumerate(values):
            matrix[:, column] = value
        return matrix

    def state_matrix(self, n: int) -> np.ndarray:
        initial = [v for term in self.ordered() for v in term.initial_state()]
        return np.tile(np.asarray(initial or [0.0], dtype=np.float64), (n, 1))

    def table(self) -> np.ndarray:
        """One row (family, kind, p_off, s_off) per term, in execution order, for ``apply_family``."""
        rows = [(FAMILIES.index(t.family), kind_of(t), p_off, s_off) for t, p_off, s_off in self._offsets()]
        return np.asarray(rows, dtype=np.int64).reshape(-1, 4)

    def chain(self, n: int) -> Chain:
        """The model for ``n`` trajectories, as the integrator takes it."""
        return Chain(self.table(), self.parameter_matrix(n), self.state_matrix(n))

    def describe(self) -> list[dict[str, Any]]:
        return [{"effect": t.name, "family": t.family, "parameters": t.parameters()} for t in self.ordered()]
