"""Leave-one-flight-out selection of effects, each family scored on the record that shows it.

With a few dozen flights, any effect with a free parameter lowers the error on the flights it was
fitted to. So every number that decides anything here is HELD OUT: for each flight i, the effect is
fitted on all the other flights and scored on flight i.

Which error: a single 3-D track score is dominated on real flights by the wind error, so a vertical
effect the altitude–time record shows plainly could not pass, and a descent law got fitted to
horizontal error. Each family is therefore fitted and scored on its own record (``RECORDS``):

* vertical effects on the vertical record, which the wind does not touch: the RMS over the fixes of
  predicted − measured time since descent start at each fix's altitude (s; the landing fix's term is
  the descent-time error). The altitude-at-time RMS (km) is reported beside it but does not decide:
  it weights the fast fall high up, where a small rate error makes kilometres, and on the 30 SuperBIT
  flights a law fitted to it made the descent-time error worse (298 → 361 s) while the time RMS
  weights where the time is spent;
* horizontal effects on the horizontal record: the RMS horizontal error (km, along and across the
  drift) of a run that replays the flight's measured altitude–time profile (``residuals.run(...,
  replay=True)``), so a descent-rate error cannot masquerade as wind;
* timing effects on both: fitted to the sum of both squared scores, each in units of its record's
  floor, and kept only when BOTH records show the improvement (a weather time offset that only moves the horizontal track is a wind story).

The margin (when is an improvement more than noise): the per-flight held-out improvements
d_i = score_before_i − score_with_effect_i are paired (the same flights, the same weather), so the
flight-to-flight spread of the weather error cancels. Their mean is resampled over flights (paired
bootstrap, ``BOOTSTRAP_SAMPLES`` draws, fixed seed); the effect passes a record only when the lower
α/K quantile of the resampled mean is above zero, α = 0.05 one-sided and K the number of candidates
tried in that round (Bonferroni), and the mean improvement is at least that record's floor
(``Record.floor``): with synthetic flights the statistics alone would keep effects that shave
metres off an already perfect model (the difference between two integration steps).

Forward selection: round 1 tries every candidate against the plain model, each on its family's
records; among those that pass, the one with the largest mean held-out improvement (summed over its
records, each in units of the record's floor, so a timing effect that both records show outranks a
vertical or a horizontal effect that explains only one of them) is kept. Round 2 tries the rest with
it in the model (its parameters refitted per fold, held while the new one is fitted), and so on, up to
``max_effects``. When more than one effect was kept, each is then refitted with the others in the
model (``JOINT_SWEEPS`` sweeps, per fold, on its own records). Last, the altitude-binned correction is
fitted per fold from the training flights' residuals on top of whatever was selected: its
descent-rate factors are scored on the vertical record, its added wind on the replayed horizontal
record; a part that still clears the margin means the library lacks something. When the binned rate
factors pass with no vertical term selected, they meet the best vertical term of the last round
(``Contest``): the one-parameter term wins unless the factors beat it beyond their held-out interval,
so which describes the shape does not turn on one flight.

Then the pre-flight gate (``preflight_gate``; the rule in ``calibration.preflight_gate``): each shipped
term is judged as a prediction before release flies it (shape × the other flights' median λ), held out,
on the descent time and the landing, and then λ itself (that law against the same with λ = 1); one that
does not earn its place there is live-only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from predictor.calibration.effects import BIN_EDGES_M, LIBRARY, BinnedCorrection, Candidate, fit_binned
from predictor.calibration.preflight_gate import TermGate, compare, verdict
from predictor.calibration.residuals import (
    BinBudget,
    FlightCase,
    FlightResiduals,
    Runs,
    Scores,
    bin_budget,
    residuals,
    run,
    score,
)
from predictor.descent import BinnedDescentRate, BinnedWind, Payload, PreflightSpread, RatePrior, Term
from predictor.errors import PredictorError

Progress = Callable[[str, int, int | None], None]
"""``progress(stage, done, total)``: told at a long run's outer loops (the command line draws a bar)."""
ALPHA = 0.05
BOOTSTRAP_SAMPLES = 4000
DEFAULT_MAX_EFFECTS = 3
JOINT_SWEEPS = 2
ONE_SIGMA = math.erf(1.0 / math.sqrt(2.0))
"""0.6827: the share of a normal error within ±1σ, which the pre-flight descent-time interval states."""
STABLE_SHARE = 2.0 / 3.0
"""A term chosen in fewer than this share of the leave-one-flight-out folds of the decision is flagged."""
RATE_SCALE = next(c for c in LIBRARY if c.name == "descent_rate_scale")
"""λ as a term: how a model flies its rate prior's median on top of the shape."""
FAMILY_ORDER = ("vertical", "horizontal", "timing")
"""The order families are reported in."""


@dataclass(frozen=True)
class Record:
    """What a family is fitted and scored on."""

    name: str
    metric: str
    """The per-flight score (a field of ``Scores`` and ``HeldOut``)."""
    unit: str
    replay: bool
    """Score runs that replay the measured altitude–time profile."""
    floor: float
    """The least mean held-out improvement that counts, in ``unit``."""


VERTICAL = Record("vertical", "shape_time_rms_s", "s", replay=False, floor=10.0)
"""The shape record: time at altitude with each flight's own rate factor λ profiled out (see
``residuals.Scores.shape_time_rms_s``), so a law is chosen for its shape, which a payload family
shares, and not for the flight-to-flight scatter of λ, which no shared law can explain.
10 s: 50 m of altitude at the 5 m/s of a parachute near the ground, 100 m of drift in a 10 m/s wind."""
HORIZONTAL = Record("horizontal", "horizontal_rms_km", "km", replay=True, floor=0.1)
"""100 m: no recovery decision turns on less."""
RECORDS: dict[str, tuple[Record, ...]] = {
    "vertical": (VERTICAL,),
    "horizontal": (HORIZONTAL,),
    "timing": (VERTICAL, HORIZONTAL),
}


@dataclass(frozen=True)
class Fit:
    """A candidate with its fitted (variant, value)."""

    candidate: Candidate
    variant: int
    value: float
    refined: float | None = None
    """The candidate's ``refined`` key fitted between its variants (None: the variant's own)."""

    def term(self) -> Term:
        return self.candidate.term(self.variant, self.value, self.refined)

    def parameters(self) -> dict[str, float]:
        """The candidate's parameters as this fit flies them."""
        return self.candidate.parameters(self.variant, self.value, self.refined)

    def place(self) -> float:
        """The value of the candidate's ``refined`` key this fit flies."""
        return self.parameters()[self.candidate.refined]

    def describe(self) -> dict[str, object]:
        c = self.candidate
        return {"effect": c.name, "family": c.family, "parameters": self.parameters()}


@dataclass(frozen=True)
class HeldOut:
    """Per flight held-out numbers of one model (NaN where its run failed)."""

    track_rms_km: np.ndarray
    time_rms_s: np.ndarray
    """Pooled: flown as predicted (with whatever λ the model flies), the pre-flight error."""
    shape_time_rms_s: np.ndarray
    """The shape record: the same with the flight's own λ profiled out."""
    rate_factor: np.ndarray
    """The flight's own best λ on top of the model (1: the model's rate is this flight's)."""
    pressure_time_rms_s: np.ndarray
    """NaN for a flight that logged no pressure."""
    altitude_rms_km: np.ndarray
    horizontal_rms_km: np.ndarray
    """Of the replayed run (the wind's error alone)."""
    landing_error_km: np.ndarray
    descent_time_error_s: np.ndarray
    landing_x: np.ndarray
    landing_y: np.ndarray

    @classmethod
    def of(cls, scores: Sequence[Scores], replayed: Sequence[Scores]) -> HeldOut:
        def col(source: Sequence[Scores], name: str) -> np.ndarray:
            return np.array([float(getattr(s, name)[0]) for s in source])

        return cls(
            col(scores, "track_rms_km"), col(scores, "time_rms_s"), col(scores, "shape_time_rms_s"),
            col(scores, "rate_factor"), col(scores, "pressure_time_rms_s"),
            col(scores, "altitude_rms_km"),
            col(replayed, "horizontal_rms_km"),
            col(scores, "landing_error_km"), col(scores, "descent_time_error_s"),
            col(scores, "landing_x"), col(scores, "landing_y"),
        )  # fmt: skip

    def summary(self) -> dict[str, dict[str, float | None]]:
        return {
            "track_rms_km": mean_median(self.track_rms_km),
            "time_rms_s": mean_median(self.time_rms_s),
            "shape_time_rms_s": mean_median(self.shape_time_rms_s),
            "pressure_time_rms_s": _with_pressure(self.pressure_time_rms_s),
            "altitude_rms_km": mean_median(self.altitude_rms_km),
            "horizontal_rms_km": mean_median(self.horizontal_rms_km),
            "landing_error_km": mean_median(self.landing_error_km),
            "descent_time_error_s": mean_median(
                np.abs(self.descent_time_error_s), signed=self.descent_time_error_s
            ),
        }


def mean_median(values: np.ndarray, signed: np.ndarray | None = None) -> dict[str, float | None]:
    """Mean and median; None (JSON null) when any flight's run failed, so a failure cannot hide."""

    def number(x: float) -> float | None:
        return round(float(x), 4) if np.isfinite(x) else None

    out = {"mean": number(np.mean(values)), "median": number(np.median(values))}
    if signed is not None:
        out["mean_signed"] = number(np.mean(signed))
    return out


def _with_pressure(values: np.ndarray) -> dict[str, float | None]:
    """Mean and median over the flights that logged a pressure, and how many did."""
    logged = values[np.isfinite(values)]
    out: dict[str, float | None] = {"mean": None, "median": None}
    if logged.size:
        out = mean_median(logged)
    return {**out, "flights": int(logged.size)}


@dataclass(frozen=True)
class Test:
    """The paired held-out comparison of a model against the reference model of its round, on one record."""

    record: str
    unit: str
    mean_improvement: float
    lower_bound: float
    margin: float
    wins: int
    flights: int
    passed: bool

    def to_dict(self) -> dict[str, object]:
        return {
            "record": self.record,
            "unit": self.unit,
            "mean_improvement": round(self.mean_improvement, 4),
            "margin": round(self.margin, 4),
            "lower_bound": round(self.lower_bound, 4),
            "flights_improved": self.wins,
            "flights": self.flights,
            "passed": self.passed,
        }


def paired_test(
    before: np.ndarray, after: np.ndarray, alpha: float, seed: int, floor: float, record: Record | None = None
) -> Test:
    """Paired bootstrap of the mean held-out improvement; passed when its lower α quantile is > 0
    and the mean improvement is at least ``floor``."""
    name, unit = (record.name, record.unit) if record else ("", "")
    d = np.asarray(before) - np.asarray(after)
    if not np.all(np.isfinite(d)):
        return Test(name, unit, float("nan"), float("nan"), float("nan"), 0, len(d), False)
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), (BOOTSTRAP_SAMPLES, len(d)))].mean(axis=1)
    lower = float(np.quantile(means, alpha))
    mean = float(d.mean())
    return Test(
        name, unit, mean, lower, mean - lower, int((d > 0).sum()), len(d), lower > 0.0 and mean >= floor
    )


def _tests(
    records: Sequence[Record], reference: HeldOut, heldout: HeldOut, alpha: float, seed: int
) -> tuple[Test, ...]:
    return tuple(
        paired_test(getattr(reference, r.metric), getattr(heldout, r.metric), alpha, seed, r.floor, r)
        for r in records
    )


@dataclass(frozen=True)
class CandidateResult:
    round: int
    full: Fit
    """Fitted on all flights (the parameters reported)."""
    folds: tuple[Fit, ...]
    """Fitted without flight i, for each i."""
    heldout: HeldOut
    tests: tuple[Test, ...]
    """One per record of the candidate's family (timing: vertical and horizontal)."""

    @property
    def passed(self) -> bool:
        return all(t.passed for t in self.tests)

    @property
    def improvement(self) -> float:
        """What ranks candidates of one family within a round: the mean held-out improvement, summed
        over the family's records in units of each record's floor."""
        floors = {r.name: r.floor for r in (VERTICAL, HORIZONTAL)}
        total = sum(t.mean_improvement / floors[t.record] for t in self.tests)
        return total if np.isfinite(total) else -np.inf


@dataclass(frozen=True)
class FamilyResult:
    """One family's selection: what its record showed before, what was kept, and after."""

    family: str
    records: tuple[Record, ...]
    before: HeldOut
    """Held out, the plain model."""
    rounds: tuple[tuple[CandidateResult, ...], ...]
    selected: tuple[Fit, ...]
    after: HeldOut
    """Held out, the plain model with this family's selected effects only (as refitted jointly)."""


@dataclass(frozen=True)
class Calibration:
    names: tuple[str, ...]
    baseline: HeldOut
    rounds: tuple[tuple[CandidateResult, ...], ...]
    families: tuple[FamilyResult, ...]
    """Only the families that had candidates, in ``FAMILY_ORDER``."""
    selected: tuple[Fit, ...]
    """Refitted on all flights, in the order they were selected."""
    after: HeldOut
    binned: BinnedCorrection
    """Fitted on all flights on top of the selected effects: rate factors from the vertical record,
    added winds from the replayed horizontal record."""
    binned_heldout: HeldOut
    binned_tests: tuple[Test, ...]
    """The rate factors on the vertical record, the added wind on the horizontal one."""
    baseline_residuals: tuple[FlightResiduals, ...]
    """Of the plain model: the vertical record's residual (speed ratios)."""
    baseline_replayed: tuple[FlightResiduals, ...]
    """Of the plain model with the measured profile replayed: the horizontal record's residual."""
    after_residuals: tuple[FlightResiduals, ...]
    """Residuals of the held-out predictions with the selected effects (each flight's own fold). The
    pre-flight ellipse was fitted on them until it followed the gate (``preflight_residuals``);
    docs/calibration/preflight_held_out.py reports that ellipse's coverage beside the one stated now."""
    after_replayed: tuple[FlightResiduals, ...]
    """The same with the measured profile replayed (the horizontal record after selection)."""
    preflight_residuals: tuple[FlightResiduals, ...]
    """Residuals of the held-out predictions with what a pre-flight prediction flies (the gate's law, each
    flight's own fold): the pre-flight ellipse is fitted on their landings, so the uncertainty a
    prediction states before release describes the law it shows, not shape × median λ when the gate
    kept those out."""
    baseline_budgets: tuple[BinBudget, ...]
    """Of the plain model: time to cross each altitude bin (``BIN_EDGES_M``), measured and predicted."""
    predicted_drift_km: np.ndarray
    """Release→landing distance of each held-out pre-flight prediction (the pre-flight ellipse's d)."""
    t_future_h: np.ndarray
    rate_prior: RatePrior
    """The spread of the flights' own λ under the selected shape (fitted on all flights)."""
    rate_fit: Fit
    """λ = the prior's median as a ``descent_rate_scale`` fit: what a pre-flight prediction flies."""
    rate_factors: np.ndarray
    """Each flight's own λ under the selected shape (fitted on all flights)."""
    rate_only: HeldOut
    """The strongest simple baseline: the plain law with the median λ of the other flights, held out."""
    stability: dict[str, float]
    """Per candidate chosen in any fold: the share of the leave-one-flight-out folds that choose it."""
    stability_method: str = "decision"
    """"decision": the decisions replayed without each flight (``decision_stability``); "nested": the
    whole selection repeated without each flight (``nested_stability``)."""
    contest: Contest | None = None
    """The one-parameter vertical law against the binned rate factors, when both were in play."""
    gate: tuple[TermGate, ...] = ()
    """The pre-flight decision on each shipped term (selected, then the binned parts that passed)."""
    preflight_rate_fit: Fit | None = None
    """λ = the median of the flights' own λ under the pre-flight terms, or 1 where the gate found that
    median made the held-out pre-flight law worse (None: ``rate_fit``)."""
    preflight: HeldOut | None = None
    """Held out, what a pre-flight prediction flies (None: ``after``)."""

    def preflight_spread(self) -> PreflightSpread:
        """What the stated pre-flight descent-time interval is flown with (``PreflightSpread``): the
        |ln(predicted / measured descent time)| that 68.3 % of the held-out pre-flight predictions stay
        within. Not the prior's sd: that is about the live law's median, which does not fly before
        release when the gate kept it out."""
        misses = np.array([abs(r.descent_time_log_ratio) for r in self.preflight_residuals])
        return PreflightSpread(min(float(np.quantile(misses, ONE_SIGMA)), 1.0), len(misses))

    @property
    def live_only(self) -> tuple[str, ...]:
        """Terms the pre-flight gate kept out of the pre-flight law (live re-prediction flies them)."""
        return tuple(g.term for g in self.gate if not g.preflight)

    def preflight_terms(self) -> tuple[Term, ...]:
        """What a pre-flight prediction flies: λ under the pre-flight terms, then the terms that passed
        the gate, in ``terms()`` order."""
        rate = self.preflight_rate_fit or self.rate_fit
        dropped = set(self.live_only)
        return (rate.term(), *(t for t in self.terms()[1:] if t.name not in dropped))

    @property
    def unstable(self) -> tuple[str, ...]:
        """Selected terms chosen in fewer than ``STABLE_SHARE`` of the folds: shipped with a visible flag."""
        return tuple(
            f.candidate.name
            for f in self.selected
            if self.stability.get(f.candidate.name, 0.0) < STABLE_SHARE
        )

    def terms(self) -> tuple[Term, ...]:
        """What live re-prediction flies: λ (the prior's median under every shipped term), the shape, the
        binned parts that passed. Pre-flight flies ``preflight_terms()``, which leaves the live-only ones out."""
        return (self.rate_fit.term(), *(f.term() for f in self.selected), *self.binned_terms())

    @property
    def unexplained(self) -> bool:
        """A part of the binned correction beats the selected model on held-out flights: the library
        lacks something."""
        return any(t.passed for t in self.binned_tests)

    def binned_terms(self) -> tuple[Term, ...]:
        """The parts of the binned correction that passed their record's test (what a model file keeps)."""
        rate, wind = self.binned.terms()
        passed = {t.record for t in self.binned_tests if t.passed}
        return tuple(term for term, record in ((rate, "vertical"), (wind, "horizontal")) if record in passed)


class FlightBatch:
    """Runs many (effects, parameters) rows of one flight as one call of the stepper."""

    def __init__(self, cases: Sequence[FlightCase], payload: Payload, step_m: float) -> None:
        self.cases = cases
        self.payload = payload
        self.step_m = step_m

    def terms(self, rows: Sequence[Sequence[Fit]]) -> tuple[Term, ...]:
        """Rows share their candidates in order; each term gets one parameter value per row."""
        terms: list[Term] = []
        for k, fit in enumerate(rows[0]):
            variants = np.array([row[k].variant for row in rows])
            values = np.array([row[k].value for row in rows])
            places = np.array([row[k].place() for row in rows]) if fit.candidate.refined else None
            terms.append(fit.candidate.term(variants, values, places))
        return tuple(terms)

    def runs(
        self, j: int, rows: Sequence[Sequence[Fit]], extra: tuple[Term, ...] = (), replay: bool = False
    ) -> Runs:
        return run(self.cases[j], self.payload, self.terms(rows) + extra, len(rows), self.step_m, replay)

    def scores(
        self, j: int, rows: Sequence[Sequence[Fit]], extra: tuple[Term, ...] = (), replay: bool = False
    ) -> Scores:
        return score(self.cases[j], self.runs(j, rows, extra, replay))

    def heldout(self, per_flight: Sequence[Sequence[Fit]], extra: Sequence[tuple[Term, ...]] = ()) -> HeldOut:
        """Flight i flown with ``per_flight[i]`` (its own fold's fits), plain and replayed."""
        more = list(extra) or [()] * len(self.cases)
        plain = [self.scores(i, [list(fits)], more[i]) for i, fits in enumerate(per_flight)]
        replayed = [self.scores(i, [list(fits)], more[i], replay=True) for i, fits in enumerate(per_flight)]
        return HeldOut.of(plain, replayed)


def calibrate(
    cases: Sequence[FlightCase],
    payload: Payload,
    candidates: Sequence[Candidate],
    *,
    step_m: float = 200.0,
    max_effects: int = DEFAULT_MAX_EFFECTS,
    alpha: float = ALPHA,
    seed: int = 0,
    nested: bool = False,
    progress: Progress | None = None,
) -> Calibration:
    """Forward selection over every candidate (each on its family's records, at most ``max_effects``),
    then the binned correction. ``nested``: the stability comes from the whole selection repeated
    without each flight (``nested_stability``, n times the cost) instead of its decisions replayed.
    ``progress(stage, done, total)`` is told at the outer loops (a run takes seconds to minutes)."""
    n = len(cases)
    if n < 3:
        raise PredictorError(f"leave-one-flight-out needs at least 3 usable flights, got {n}")
    unknown = {c.family for c in candidates} - set(FAMILY_ORDER)
    if unknown:
        raise PredictorError(f"unknown effect family {', '.join(sorted(unknown))}")
    # λ is each flight's own (profiled out of the shape record, pooled as the rate prior): as a shared
    # term it would only be seen where a flight's λ hits its bounds.
    candidates = [c for c in candidates if c.name != RATE_SCALE.name]
    batch = FlightBatch(cases, payload, step_m)
    baseline = batch.heldout([[]] * n)
    baseline_residuals = tuple(residuals(cases[i], batch.runs(i, [[]])) for i in range(n))
    baseline_replayed = tuple(residuals(cases[i], batch.runs(i, [[]], replay=True)) for i in range(n))
    chosen = _select(batch, baseline, candidates, max_effects, alpha, seed, progress)
    rounds, references, contest, settled = chosen.rounds, chosen.references, chosen.contest, chosen.settled
    selected_folds, selected_full = chosen.folds, chosen.full
    families = tuple(
        _family(batch, family, baseline, rounds, selected_folds, selected_full, chosen.reference(batch))
        for family in FAMILY_ORDER
        if any(c.family == family for c in candidates)
    )
    _, plain_folds, plain_rate, _ = rate_priors(batch, [[] for _ in range(n)], [])
    rate_only = batch.heldout([[f] for f in plain_folds])
    prior, rate_full, factors = settled.prior, settled.rate_full, settled.factors
    flown_folds, after = settled.flown_folds, settled.after
    binned, binned_heldout, binned_tests = settled.binned, settled.binned_heldout, settled.binned_tests
    gate = preflight_gate(
        batch, selected_folds, selected_full, settled, baseline, (rate_only, plain_folds, plain_rate), seed
    )
    after_residuals = tuple(residuals(cases[i], batch.runs(i, [flown_folds[i]])) for i in range(n))
    after_replayed = tuple(
        residuals(cases[i], batch.runs(i, [flown_folds[i]], replay=True)) for i in range(n)
    )
    preflight_residuals = tuple(
        residuals(cases[i], batch.runs(i, [gate.folds[i]], gate.extra[i])) for i in range(n)
    )
    return Calibration(
        names=tuple(c.name for c in cases),
        baseline=baseline,
        rounds=tuple(rounds),
        families=families,
        selected=tuple(selected_full),
        after=after,
        binned=binned,
        binned_heldout=binned_heldout,
        binned_tests=binned_tests,
        baseline_residuals=baseline_residuals,
        baseline_replayed=baseline_replayed,
        after_residuals=after_residuals,
        after_replayed=after_replayed,
        preflight_residuals=preflight_residuals,
        baseline_budgets=tuple(
            _whole_bins(cases[i], bin_budget(cases[i], batch.runs(i, [[]]), 0, np.asarray(BIN_EDGES_M)))
            for i in range(n)
        ),  # fmt: skip
        predicted_drift_km=np.array([r.predicted_drift_km for r in preflight_residuals]),
        t_future_h=np.array([t_future(c) for c in cases]),
        rate_prior=prior,
        rate_fit=rate_full,
        rate_factors=factors,
        rate_only=rate_only,
        stability=(
            nested_stability(cases, payload, candidates, step_m, max_effects, alpha, seed, progress)
            if nested
            else decision_stability(rounds, references, alpha, seed, contest)
        ),
        stability_method="nested" if nested else "decision",
        contest=contest,
        gate=gate.terms,
        preflight_rate_fit=gate.rate_fit,
        preflight=gate.heldout,
    )


@dataclass(frozen=True)
class Selection:
    """What the selection chose: forward selection, then the contest between the best one-parameter
    vertical term and the binned rate factors (``Contest``)."""

    rounds: list[tuple[CandidateResult, ...]]
    references: list[HeldOut]
    folds: list[list[Fit]]
    full: list[Fit]
    settled: Settled
    contest: Contest | None

    def reference(self, batch: FlightBatch) -> HeldOut:
        """Held out, the selected terms without λ (as refitted jointly)."""
        if len(self.full) > 1:
            return batch.heldout(self.folds)
        if self.contest is not None and self.contest.library_wins:
            return self.contest.library.heldout
        return self.references[-1]


def _select(
    batch: FlightBatch,
    baseline: HeldOut,
    candidates: Sequence[Candidate],
    max_effects: int,
    alpha: float,
    seed: int,
    progress: Progress | None = None,
) -> Selection:
    rounds, references, folds, full = _forward(
        batch, baseline, candidates, max_effects, alpha, seed, progress
    )
    if len(full) > 1:
        _refit_jointly(batch, folds, full)
    settled = _settle(batch, folds, full, alpha, seed)
    contest = _contest(rounds, len(full) < max_effects, settled, alpha, seed)
    if contest is not None and contest.library_wins:
        # The one-parameter law replaces the binned rate factors as the shape: the same steps as a
        # selected term (refitted jointly, the binned correction re-tested on top of it).
        full.append(contest.library.full)
        for i, row in enumerate(folds):
            row.append(contest.library.folds[i])
        if len(full) > 1:
            _refit_jointly(batch, folds, full)
        settled = _settle(batch, folds, full, alpha, seed)
    return Selection(rounds, references, folds, full, settled, contest)


def _forward(
    batch: FlightBatch,
    baseline: HeldOut,
    candidates: Sequence[Candidate],
    max_effects: int,
    alpha: float,
    seed: int,
    progress: Progress | None = None,
) -> tuple[list[tuple[CandidateResult, ...]], list[HeldOut], list[list[Fit]], list[Fit]]:
    """The forward selection: (every round's results, the reference of each round and the last one's
    best, the selected fits per fold, the selected fits on all flights)."""
    n = len(batch.cases)
    reference = baseline
    references = [baseline]
    selected_folds: list[list[Fit]] = [[] for _ in range(n)]
    selected_full: list[Fit] = []
    rounds: list[tuple[CandidateResult, ...]] = []
    remaining = list(candidates)
    rounds_at_most = min(max_effects, len(candidates))
    while remaining and len(selected_full) < max_effects:
        if progress is not None:
            progress("forward selection (rounds)", len(rounds), rounds_at_most)
        share = alpha / len(remaining)
        results = tuple(
            _try(batch, c, selected_folds, selected_full, reference, share, seed, len(rounds) + 1)
            for c in remaining
        )
        rounds.append(results)
        passing = [r for r in results if r.passed]
        if not passing:
            break
        best = max(passing, key=lambda r: r.improvement)
        selected_full.append(best.full)
        for i in range(n):
            selected_folds[i].append(best.folds[i])
        reference = best.heldout
        references.append(reference)
        remaining = [c for c in remaining if c is not best.full.candidate]
    return rounds, references, selected_folds, selected_full


def nested_stability(
    cases: Sequence[FlightCase], payload: Payload, candidates: Sequence[Candidate], step_m: float,
    max_effects: int, alpha: float, seed: int, progress: Progress | None = None,
) -> dict[str, float]:  # fmt: skip
    """How often each candidate is selected when the WHOLE selection (every fit, every held-out score,
    every test, the contest with the binned rate factors) is repeated without each flight in turn:
    nested leave-one-flight-out. Returns, per
    candidate selected in any fold, the share of the n folds that selected it."""
    n = len(cases)
    chosen: dict[str, int] = {}
    for k in range(n):
        if progress is not None:
            progress("nested stability (the selection without each flight)", k, n)
        batch = FlightBatch([c for i, c in enumerate(cases) if i != k], payload, step_m)
        baseline = batch.heldout([[]] * (n - 1))
        selected = _select(batch, baseline, candidates, max_effects, alpha, seed).full
        for fit in selected:
            chosen[fit.candidate.name] = chosen.get(fit.candidate.name, 0) + 1
    return {name: count / n for name, count in sorted(chosen.items(), key=lambda kv: -kv[1])}


def _whole_bins(case: FlightCase, budget: BinBudget) -> BinBudget:
    """The budget without the bin that holds the descent start: the burst falls between two fixes, so
    the measured time below the first one includes the rest of the climb and the fall back to it (up
    to a fix interval, minutes at 2–5 min cadence), which no descent law should be asked to explain."""
    top = np.asarray(BIN_EDGES_M[1:]) > case.start_alt_m
    return dataclasses.replace(
        budget,
        measured_s=np.where(top, 0.0, budget.measured_s),
        predicted_s=np.where(top, 0.0, budget.predicted_s),
    )


@dataclass(frozen=True)
class Settled:
    """A selection flown as it ships: the rate prior under its shape, held out, and the binned correction
    fitted per fold on top of it and tested against it."""

    prior: RatePrior
    rate_full: Fit
    factors: np.ndarray
    flown_folds: list[list[Fit]]
    """Fold i's λ (the other flights' median) then fold i's selected fits."""
    after: HeldOut
    binned: BinnedCorrection
    binned_folds: list[BinnedCorrection]
    """Fitted without flight i, for each i."""
    binned_heldout: HeldOut
    binned_tests: tuple[Test, ...]


def _settle(
    batch: FlightBatch, selected_folds: list[list[Fit]], selected_full: list[Fit], alpha: float, seed: int
) -> Settled:
    n = len(batch.cases)
    prior, rate_folds, rate_full, factors = rate_priors(batch, selected_folds, selected_full)
    flown_folds = [[rate_folds[i], *selected_folds[i]] for i in range(n)]
    after = batch.heldout(flown_folds)
    folds = _binned_folds(batch, flown_folds, [rate_full, *selected_full])
    binned_heldout = batch.heldout(flown_folds, [fold.terms() for fold in folds[:-1]])
    tests = _tests((VERTICAL, HORIZONTAL), after, binned_heldout, alpha, seed)
    return Settled(
        prior, rate_full, factors, flown_folds, after, folds[-1], folds[:-1], binned_heldout, tests
    )


@dataclass(frozen=True)
class Contest:
    """The one-parameter vertical law against the binned rate factors for the shape (issue #30 item 3).

    Why: the binned rate correction is tried on top of whatever was selected. Where the best vertical
    library term clears the selection's margin it ships and the binned factors on top of it fail; where
    it misses the margin by a little, the binned factors pass on top of the plain law and ship instead.
    On the EOSS flights which one shipped turned on a single flight (4 folds against 5). Both describe
    the same departure of the rate from the law (the binned factors with one free value per 3 km bin,
    the term with one), so they are compared with each other: the one-parameter term wins unless the
    binned factors beat it on the shape record, held out, by more than their paired interval (the lower
    α quantile of the mean improvement above zero), and the term must itself improve the shape record
    by at least the record's floor over the law without it.
    """

    library: CandidateResult
    test: Test
    """The binned correction's shape record against the library term's, paired, held out."""
    library_improvement: float
    """The term's mean held-out shape-record improvement over the law without it (s)."""
    before: HeldOut
    """Held out, the law the contest was held on (λ, the selection before it)."""
    binned: HeldOut
    """Held out, that law with the binned correction on top."""

    @property
    def library_wins(self) -> bool:
        return not self.test.passed and self.library_improvement >= VERTICAL.floor

    def to_dict(self) -> dict[str, object]:
        return {
            "library_term": self.library.full.describe(),
            "library_improvement_s": round(self.library_improvement, 4),
            "binned_against_library": self.test.to_dict(),
            "winner": self.library.full.candidate.name if self.library_wins else "binned_descent_rate",
            "rule": (
                "the one-parameter term unless the binned rate factors beat it on the shape record by more "
                "than their held-out interval; the term must improve the shape record by the floor"
            ),
        }


def _contest(
    rounds: Sequence[tuple[CandidateResult, ...]], tried_all: bool, settled: Settled, alpha: float, seed: int
) -> Contest | None:
    """The contest, when the binned rate factors passed with no vertical term selected and the last
    round tried the vertical terms against the same law (None otherwise: nothing to decide)."""
    vertical_passed = any(t.passed for t in settled.binned_tests if t.record == VERTICAL.name)
    if not rounds or not tried_all or not vertical_passed:
        return None
    if any(f.candidate.family == "vertical" for f in settled.flown_folds[0][1:]):
        return None
    tried = [r for r in rounds[-1] if r.full.candidate.family == "vertical"]
    if not tried:
        return None
    best = max(tried, key=lambda r: r.improvement)
    metric = VERTICAL.metric
    test = paired_test(
        getattr(best.heldout, metric), getattr(settled.binned_heldout, metric), alpha, seed, 0.0, VERTICAL
    )
    return Contest(best, test, best.tests[0].mean_improvement, settled.after, settled.binned_heldout)


@dataclass(frozen=True)
class Gate:
    terms: tuple[TermGate, ...]
    rate_fit: Fit
    heldout: HeldOut
    folds: list[list[Fit]]
    """Fold i's pre-flight law (its λ where λ passed, then the terms that passed), fitted without flight i."""
    extra: list[tuple[Term, ...]]
    """Fold i's binned parts that passed (empty when none)."""


def preflight_gate(
    batch: FlightBatch,
    selected_folds: list[list[Fit]],
    selected_full: list[Fit],
    settled: Settled,
    plain: HeldOut,
    rate_only: tuple[HeldOut, list[Fit], Fit],
    seed: int,
) -> Gate:
    """Each shipped term judged as the pre-flight law flies it (``preflight_gate`` module). The shape
    terms first, added in selection order to the pre-flight set kept so far, λ the median of the other
    flights' λ under that set, its held-out descent time and landing compared with the set's without it,
    starting from ``rate_only`` (the plain law × median λ held out, each fold's λ, and that λ on all
    flights); then λ itself: the kept set with that λ against the kept set with λ = 1 (``plain``, the
    plain law held out, when no shape term passed); then the binned parts, which were fitted on top of λ
    and every shape term and so are judged only when all of them passed. Returns the decision per term,
    the pre-flight λ (1 when λ failed), the pre-flight law's held-out numbers and its fits per fold
    (what its held-out residuals, and so the pre-flight ellipse, are flown with)."""
    n = len(batch.cases)
    current, rate_folds, rate_fit = rate_only
    current_folds = [[f] for f in rate_folds]
    kept: list[int] = []
    decisions: list[TermGate] = []
    for k, fit in enumerate(selected_full):
        trial = [*kept, k]
        folds = [[row[m] for m in trial] for row in selected_folds]
        full = [selected_full[m] for m in trial]
        if trial == list(range(len(selected_full))):
            trial_rate, trial_folds, heldout = settled.rate_full, settled.flown_folds, settled.after
        else:
            _, fold_rates, trial_rate, _ = rate_priors(batch, folds, full)
            trial_folds = [[fold_rates[i], *folds[i]] for i in range(n)]
            heldout = batch.heldout(trial_folds)
        decision = verdict(fit.candidate.name, compare(_gated(current), _gated(heldout), seed))
        decisions.append(decision)
        if decision.preflight:
            kept.append(k)
            current, rate_fit, current_folds = heldout, trial_rate, trial_folds
    without_folds = [[row[m] for m in kept] for row in selected_folds]
    without = batch.heldout(without_folds) if kept else plain
    rate = verdict(RATE_SCALE.name, compare(_gated(without), _gated(current), seed))
    if not rate.preflight:
        rate = dataclasses.replace(rate, reason=rate.reason + "; the pre-flight law flies λ = 1")
        current, rate_fit, current_folds = without, Fit(RATE_SCALE, 0, 1.0), without_folds
    decisions.append(rate)
    every_term = rate.preflight and len(kept) == len(selected_full)
    passed = {t.record for t in settled.binned_tests if t.passed}
    extra: list[tuple[Term, ...]] = [() for _ in range(n)]
    for part, record in ((0, VERTICAL.name), (1, HORIZONTAL.name)):
        if record not in passed:
            continue
        name = settled.binned.terms()[part].name
        if not every_term:
            decisions.append(TermGate(name, False, (), "live-only: fitted on top of a live-only term"))
            continue
        trial_extra = [(*extra[i], settled.binned_folds[i].terms()[part]) for i in range(n)]
        heldout = batch.heldout(settled.flown_folds, trial_extra)
        decision = verdict(name, compare(_gated(current), _gated(heldout), seed))
        decisions.append(decision)
        if decision.preflight:
            extra, current, current_folds = trial_extra, heldout, settled.flown_folds
    return Gate(tuple(decisions), rate_fit, current, current_folds, extra)


def _gated(h: HeldOut) -> dict[str, np.ndarray]:
    return {"descent_time_error_s": h.descent_time_error_s, "landing_error_km": h.landing_error_km}


def rate_priors(
    batch: FlightBatch, folds: Sequence[Sequence[Fit]], full: Sequence[Fit]
) -> tuple[RatePrior, list[Fit], Fit, np.ndarray]:
    """The distribution of the flights' own λ under a shape: on all flights, and per fold without
    flight i (its λ is then the median of the OTHER flights' λ, each under fold i's shape, so a held-out
    flight's pre-flight rate never saw its own descent).

    Why a median and the spread of ln λ: λ is a factor (log-normal across a payload family), and the
    median is not pulled by one flight whose rigging failed. Returns (the all-flights prior, fold i's
    λ as a fit, the all-flights λ as a fit, each flight's λ under the all-flights shape).
    """
    n = len(batch.cases)
    shared = all(not row for row in folds) and not full
    factors = np.full((n, n + 1), np.nan)
    for j in range(n):
        rows = [list(full)] if shared else [*map(list, folds), list(full)]
        found = batch.scores(j, rows).rate_factor
        factors[j] = found[0] if shared else found
    fold_fits = []
    for i in range(n):
        others = np.delete(factors[:, i], i)
        fold_fits.append(Fit(RATE_SCALE, 0, _prior(others).median))
    prior = _prior(factors[:, n])
    return prior, fold_fits, Fit(RATE_SCALE, 0, prior.median), factors[:, n]


def _prior(factors: np.ndarray) -> RatePrior:
    usable = factors[np.isfinite(factors)]
    if usable.size == 0:
        raise PredictorError("no flight's descent could be fitted with its own rate factor")
    logs = np.log(usable)
    spread = float(np.std(logs, ddof=1)) if usable.size > 1 else 0.0
    return RatePrior(float(np.exp(np.median(logs))), min(spread, 1.0), int(usable.size))


def decision_stability(
    rounds: Sequence[tuple[CandidateResult, ...]],
    references: Sequence[HeldOut],
    alpha: float,
    seed: int,
    contest: Contest | None = None,
) -> dict[str, float]:
    """How often each candidate is chosen when one flight at a time is left out of the DECISION.

    For each flight k the forward selection is replayed on the other flights' held-out scores: each
    round's paired tests (same margin, same Bonferroni share) and the ranking, without flight k. A fold
    follows the selection as long as it picks the same term; where it picks another, that term is
    counted and the fold stops (its later rounds were never run). The fits are not repeated per fold
    (flight k still entered the other flights' fits), so this measures how much the decision rests on
    one flight, the knife edge of the margin, not the whole nested refit. A fold that follows the whole
    selection to its last round replays the ``contest`` too (the binned rate factors' test, then theirs
    against the one-parameter term): the winner is counted, ``binned_descent_rate`` when the factors win.
    Returns, per candidate chosen in any fold, the share of the n folds that chose it.
    """
    if not rounds:
        return {}
    n = len(references[0].time_rms_s)
    chosen: dict[str, int] = {}
    floors = {r.name: r.floor for r in (VERTICAL, HORIZONTAL)}
    for k in range(n):
        keep = np.arange(n) != k
        for number, results in enumerate(rounds):
            reference = references[number]
            share = alpha / len(results)
            passing = []
            for result in results:
                tests = [
                    paired_test(getattr(reference, t_record.metric)[keep], getattr(result.heldout, t_record.metric)[keep],
                                share, seed, t_record.floor, t_record)
                    for t_record in RECORDS[result.full.candidate.family]
                ]  # fmt: skip
                if all(t.passed for t in tests):
                    passing.append((sum(t.mean_improvement / floors[t.record] for t in tests), result))
            if not passing:
                if contest is not None and number == len(rounds) - 1:
                    name = _contest_without(contest, keep, alpha, seed)
                    if name is not None:
                        chosen[name] = chosen.get(name, 0) + 1
                break
            best = max(passing, key=lambda p: p[0])[1]
            name = best.full.candidate.name
            chosen[name] = chosen.get(name, 0) + 1
            followed = number + 1 < len(references) and references[number + 1] is best.heldout
            if not followed:
                break
    return {name: count / n for name, count in sorted(chosen.items(), key=lambda kv: -kv[1])}


def _contest_without(contest: Contest, keep: np.ndarray, alpha: float, seed: int) -> str | None:
    """The contest replayed on the flights ``keep``: None when the binned rate factors no longer pass."""
    metric = VERTICAL.metric
    before, binned = getattr(contest.before, metric)[keep], getattr(contest.binned, metric)[keep]
    if not paired_test(before, binned, alpha, seed, VERTICAL.floor).passed:
        return None
    library = getattr(contest.library.heldout, metric)[keep]
    factors_win = paired_test(library, binned, alpha, seed, 0.0).passed
    improvement = float(np.mean(before - library))
    if factors_win or improvement < VERTICAL.floor:
        return BinnedDescentRate.name
    return contest.library.full.candidate.name


def _family(
    batch: FlightBatch,
    family: str,
    baseline: HeldOut,
    rounds: Sequence[tuple[CandidateResult, ...]],
    selected_folds: list[list[Fit]],
    selected_full: list[Fit],
    after_all: HeldOut,
) -> FamilyResult:
    """One family's share of the selection: its candidates in every round, its effects, and the
    held-out scores of the plain model with only its effects (so "after" is what that family did)."""
    own = [k for k, fit in enumerate(selected_full) if fit.candidate.family == family]
    if len(own) == len(selected_full):
        after = after_all
    elif own:
        after = batch.heldout([[row[k] for k in own] for row in selected_folds])
    else:
        after = baseline
    return FamilyResult(
        family=family,
        records=RECORDS[family],
        before=baseline,
        rounds=tuple(
            kept for rnd in rounds if (kept := tuple(r for r in rnd if r.full.candidate.family == family))
        ),
        selected=tuple(selected_full[k] for k in own),
        after=after,
    )


def _try(
    batch: FlightBatch,
    candidate: Candidate,
    selected_folds: list[list[Fit]],
    selected_full: list[Fit],
    reference: HeldOut,
    alpha: float,
    seed: int,
    round_no: int,
) -> CandidateResult:
    """Fit the candidate per fold and on all flights (other selected effects held), score held out."""
    n = len(batch.cases)
    full, folds_fit = fit_candidate(batch, candidate, selected_folds, selected_full)
    heldout = batch.heldout([[*selected_folds[i], folds_fit[i]] for i in range(n)])
    tests = _tests(RECORDS[candidate.family], reference, heldout, alpha, seed)
    return CandidateResult(round_no, full, tuple(folds_fit), heldout, tests)


def fit_candidate(
    batch: FlightBatch, candidate: Candidate, held_folds: list[list[Fit]], held_full: list[Fit]
) -> tuple[Fit, list[Fit]]:
    """The candidate fitted on all flights and per fold, with the ``held`` effects in the model.

    Two passes: the candidate's coarse grid, then a fine grid (``Candidate.fine``) around the
    all-flights optimum, used by every fold whose coarse optimum falls inside it (the folds differ by
    one flight, so nearly always). A ``refined`` candidate's fine pass fits its height too, per fold
    from the fold's own sums (``Candidate.fit_refined``).
    """
    n = len(batch.cases)
    coarse = _losses(batch, candidate, held_folds, held_full)
    variant, value, _ = candidate.fit(coarse.sum(axis=0)[n])
    fine_candidate = candidate.fine(variant, value)
    fine = _losses(batch, fine_candidate, held_folds, held_full)
    fits: list[Fit] = []
    for i in range(n + 1):
        v0, x0, _ = candidate.fit(coarse.sum(axis=0)[i])
        refined = None
        if v0 == variant and fine_candidate.grid[0] <= x0 <= fine_candidate.grid[-1]:
            if candidate.refined:
                refined, x0, _ = fine_candidate.fit_refined(fine.sum(axis=0)[i])
            else:
                _, x0, _ = fine_candidate.fit(fine.sum(axis=0)[i])
        fits.append(Fit(candidate, v0, x0, refined))
    full = fits.pop()
    return full, fits


def _refit_jointly(batch: FlightBatch, selected_folds: list[list[Fit]], selected_full: list[Fit]) -> None:
    """Refit each selected effect on its own record with the others held at their latest values,
    ``JOINT_SWEEPS`` times (in place): an effect selected early was fitted without the later ones and
    has absorbed part of them. Fold i's fits still never see flight i."""
    for _ in range(JOINT_SWEEPS):
        for k in range(len(selected_full)):
            others_folds = [[f for m, f in enumerate(row) if m != k] for row in selected_folds]
            others_full = [f for m, f in enumerate(selected_full) if m != k]
            full, folds = fit_candidate(batch, selected_full[k].candidate, others_folds, others_full)
            selected_full[k] = full
            for i, fit in enumerate(folds):
                selected_folds[i][k] = fit


def _losses(
    batch: FlightBatch, candidate: Candidate, selected_folds: list[list[Fit]], selected_full: list[Fit]
) -> np.ndarray:
    """loss[j, i, g]: flight j's squared score (summed over the family's records, each in units of its
    floor) at grid point g with fold i's selected effects (i = n: the all-flights fit; loss[j, j] = 0,
    a flight is never in its own fold). Without selected effects every fold sees the same rows, so
    each flight flies the grid once."""
    n = len(batch.cases)
    grid_fits = [Fit(candidate, v, x) for v, x in candidate.points()]
    g = len(grid_fits)
    loss = np.zeros((n, n + 1, g))
    for record in RECORDS[candidate.family]:
        # A record does not see the other family's effects (the replay drops the vertical ones; the
        # vertical record has no wind in it, up to the air and the terrain under a path moved by a
        # few km): leaving them out of the fit lets every fold share one grid run. Held-out scores
        # fly the whole model.
        unseen = "vertical" if record.replay else "horizontal"
        held_full = [f for f in selected_full if f.candidate.family != unseen]
        held_folds = [[f for f in row if f.candidate.family != unseen] for row in selected_folds]
        for j in range(n):
            if not held_full:
                scores = batch.scores(j, [[f] for f in grid_fits], replay=record.replay)
                sq = (getattr(scores, record.metric) / record.floor) ** 2
                loss[j, :, :] += sq
                loss[j, j, :] = 0.0
            else:
                folds = [i for i in range(n) if i != j]
                rows = [[*held_folds[i], f] for i in folds for f in grid_fits]
                rows += [[*held_full, f] for f in grid_fits]
                scores = batch.scores(j, rows, replay=record.replay)
                sq = ((getattr(scores, record.metric) / record.floor) ** 2).reshape(len(folds) + 1, g)
                loss[j, folds, :] += sq[:-1]
                loss[j, n, :] += sq[-1]
    return loss


def _binned_folds(
    batch: FlightBatch, selected_folds: list[list[Fit]], selected_full: list[Fit]
) -> list[BinnedCorrection]:
    """The binned correction fitted without each flight, then on all of them (n + 1 entries): rate
    factors from the plain runs (the vertical record), added winds from the replayed runs, whose
    horizontal error is the wind's alone."""
    n = len(batch.cases)
    edges = np.asarray(BIN_EDGES_M)
    plain, replayed = [], []
    for j in range(n):
        rows = [*selected_folds, selected_full] if selected_full else [[]] * (n + 1)
        runs = batch.runs(j, rows)
        runs_replayed = batch.runs(j, rows, replay=True)
        plain.append([bin_budget(batch.cases[j], runs, i, edges) for i in range(n + 1)])
        replayed.append([bin_budget(batch.cases[j], runs_replayed, i, edges) for i in range(n + 1)])

    def fold(i: int) -> BinnedCorrection:
        others = [j for j in range(n) if j != i] if i < n else list(range(n))
        rate = fit_binned([plain[j][i] for j in others])
        wind = fit_binned([replayed[j][i] for j in others])
        return BinnedCorrection(
            edges_m=rate.edges_m, rate_factor=rate.rate_factor, east_ms=wind.east_ms, north_ms=wind.north_ms,
            measured_s=rate.measured_s,
        )  # fmt: skip

    return [fold(i) for i in range(n + 1)]


def refit_without_each(
    cases: Sequence[FlightCase], payload: Payload, terms: Sequence[Term], step_m: float = 200.0
) -> tuple[tuple[Term, ...], list[tuple[Term, ...]]]:
    """A calibrated model's terms fitted again on all the flights, and without each one in turn.

    Why: a check of the model on the flights it was calibrated on (``drs live evaluate``) is honest
    only when each flight is flown with the law fitted WITHOUT it. The terms are refitted the way
    ``calibrate`` fitted what it selected: the library effects in their order, each with the earlier
    ones held per fold, then jointly when there are several, then the binned correction's parts the
    model keeps on top. Which terms the model has is taken as given (the selection is not repeated).
    ``step_m`` is ``drs calibrate``'s default step, which the committed models were calibrated with
    (a refit that does not give the model back shows a different one).
    Returns (the all-flights refit, one tuple of terms per flight in ``cases`` order).
    """
    known = {c.name: c for c in LIBRARY}
    # λ is not refitted as a shared term: it is the median of the training flights' own λ (the prior).
    library_terms = [t for t in terms if t.name in known and t.name != RATE_SCALE.name]
    flies_rate = any(t.name == RATE_SCALE.name for t in terms)
    binned_parts = {t.name for t in terms if t.name not in known}
    unknown = binned_parts - {BinnedDescentRate.name, BinnedWind.name}
    if unknown:
        raise PredictorError(
            f"cannot refit {', '.join(sorted(unknown))}: not a library effect or binned correction"
        )
    n = len(cases)
    if n < 3:
        raise PredictorError(f"leave-one-flight-out needs at least 3 usable flights, got {n}")
    batch = FlightBatch(cases, payload, step_m)
    folds: list[list[Fit]] = [[] for _ in range(n)]
    full: list[Fit] = []
    for term in library_terms:
        fit, per_fold = fit_candidate(batch, known[term.name], folds, full)
        full.append(fit)
        for row, fold_fit in zip(folds, per_fold, strict=True):
            row.append(fold_fit)
    if len(full) > 1:
        _refit_jointly(batch, folds, full)
    if flies_rate:
        _, rate_folds, rate_full, _ = rate_priors(batch, folds, full)
        folds = [[rate_folds[i], *folds[i]] for i in range(n)]
        full = [rate_full, *full]
    binned: list[tuple[Term, ...]] = [()] * (n + 1)
    if binned_parts:
        binned = [
            tuple(t for t in correction.terms() if t.name in binned_parts)
            for correction in _binned_folds(batch, folds, full)
        ]
    rows = [*folds, full]
    refits = [tuple(f.term() for f in row) + extra for row, extra in zip(rows, binned, strict=True)]
    return refits[-1], refits[:-1]


def t_future(case: FlightCase) -> float:
    """Mean forecast lead time of the weather over the descent (0 for ascent-measured winds)."""
    times = case.cube.times.astype("datetime64[s]").astype(np.int64).astype(float)
    t0 = case.start_time.timestamp()
    at = np.linspace(t0, t0 + case.descent_time_s, 9)
    return float(np.mean(np.interp(at, times, case.cube.lead_h)))
