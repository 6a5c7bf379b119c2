"""Leave-one-flight-out selection of effects: an effect is kept only if it helps flights it never saw.

With a few dozen flights, any effect with a free parameter lowers the error on the flights it was
fitted to. So every number that decides anything here is HELD OUT: for each flight i, the effect is
fitted on all the other flights and scored on flight i. The score of a flight is the RMS of its
3-D position error over all its descent fixes (``residuals``), in km; ``metric="landing_error_km"``
scores the landing alone (fewer numbers per flight, so a larger margin, but the one recovery needs).

The margin (when is an improvement more than noise): the per-flight held-out improvements
d_i = score_before_i − score_with_effect_i are paired (the same flights, the same weather), so the
flight-to-flight spread of the weather error cancels. Their mean is resampled over flights (paired
bootstrap, ``BOOTSTRAP_SAMPLES`` draws, fixed seed); the effect is selected only when the lower
α/K quantile of the resampled mean is above zero, α = 0.05 one-sided and K the number of candidates
tried in that round (Bonferroni: trying eight effects and keeping the best is eight chances to be
lucky). The margin reported is mean(d) minus that lower bound: the improvement an effect must beat.
An effect must also improve the mean held-out score by at least ``MIN_IMPROVEMENT_KM`` (100 m): with
synthetic flights the statistics alone would keep effects that shave metres off an already perfect
model (the difference between two integration steps), and no recovery decision turns on 100 m.

Forward selection: round 1 tries every candidate against the plain model; the best held-out one is
kept if it clears the margin; round 2 tries the rest with it in the model (its parameters refitted
per fold, held while the new one is fitted), against the held-out scores of round 1's model; and so
on, up to ``max_effects``. When more than one effect was kept, each is then refitted with the others
in the model (``JOINT_SWEEPS`` sweeps, per fold) and "after" is scored again, still held out.
Finally the altitude-binned correction is fitted (per fold, from the training flights' residuals)
on top of whatever was selected: if it still clears the margin, the residual has a systematic
altitude structure the selected effects do not explain.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from predictor.calibration.effects import BIN_EDGES_M, BinnedCorrection, Candidate, fit_binned
from predictor.calibration.residuals import (
    FlightCase,
    FlightResiduals,
    Runs,
    Scores,
    bin_budget,
    residuals,
    run,
    score,
)
from predictor.errors import PredictorError
from predictor.model import Term
from predictor.payload import Payload

ALPHA = 0.05
BOOTSTRAP_SAMPLES = 4000
DEFAULT_MAX_EFFECTS = 3
SCORES = ("track_rms_km", "landing_error_km")
"""What a flight is scored by: the RMS 3-D error over all its fixes (default), or the landing error alone."""
MIN_IMPROVEMENT_KM = 0.1
JOINT_SWEEPS = 2


@dataclass(frozen=True)
class Fit:
    """A candidate with its fitted (variant, value)."""

    candidate: Candidate
    variant: int
    value: float

    def term(self) -> Term:
        return self.candidate.term(self.variant, self.value)

    def describe(self) -> dict[str, object]:
        c = self.candidate
        return {"effect": c.name, "family": c.family, "parameters": c.parameters(self.variant, self.value)}


@dataclass(frozen=True)
class HeldOut:
    """Per flight held-out numbers of one model (NaN where its run failed)."""

    track_rms_km: np.ndarray
    landing_error_km: np.ndarray
    descent_time_error_s: np.ndarray
    landing_x: np.ndarray
    landing_y: np.ndarray

    @classmethod
    def of(cls, scores: Sequence[Scores]) -> HeldOut:
        def col(name: str) -> np.ndarray:
            return np.array([float(getattr(s, name)[0]) for s in scores])

        return cls(
            col("track_rms_km"), col("landing_error_km"), col("descent_time_error_s"),
            col("landing_x"), col("landing_y"),
        )  # fmt: skip

    def summary(self) -> dict[str, dict[str, float | None]]:
        return {
            "track_rms_km": _mean_median(self.track_rms_km),
            "landing_error_km": _mean_median(self.landing_error_km),
            "descent_time_error_s": _mean_median(
                np.abs(self.descent_time_error_s), signed=self.descent_time_error_s
            ),
        }


def _mean_median(values: np.ndarray, signed: np.ndarray | None = None) -> dict[str, float | None]:
    """Mean and median; None (JSON null) when any flight's run failed, so a failure cannot hide."""

    def number(x: float) -> float | None:
        return round(float(x), 4) if np.isfinite(x) else None

    out = {"mean": number(np.mean(values)), "median": number(np.median(values))}
    if signed is not None:
        out["mean_signed"] = number(np.mean(signed))
    return out


@dataclass(frozen=True)
class Test:
    """The paired held-out comparison of a model against the reference model of its round."""

    mean_improvement_km: float
    lower_bound_km: float
    margin_km: float
    wins: int
    flights: int
    passed: bool

    def to_dict(self) -> dict[str, object]:
        return {
            "mean_improvement_km": round(self.mean_improvement_km, 4),
            "margin_km": round(self.margin_km, 4),
            "lower_bound_km": round(self.lower_bound_km, 4),
            "flights_improved": self.wins,
            "flights": self.flights,
            "passed": self.passed,
        }


def paired_test(
    before: np.ndarray, after: np.ndarray, alpha: float, seed: int, floor_km: float = MIN_IMPROVEMENT_KM
) -> Test:
    """Paired bootstrap of the mean held-out improvement; passed when its lower α quantile is > 0
    and the mean improvement is at least ``floor_km``."""
    d = np.asarray(before) - np.asarray(after)
    if not np.all(np.isfinite(d)):
        return Test(float("nan"), float("nan"), float("nan"), 0, len(d), False)
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), (BOOTSTRAP_SAMPLES, len(d)))].mean(axis=1)
    lower = float(np.quantile(means, alpha))
    mean = float(d.mean())
    return Test(mean, lower, mean - lower, int((d > 0).sum()), len(d), lower > 0.0 and mean >= floor_km)


@dataclass(frozen=True)
class CandidateResult:
    round: int
    full: Fit
    """Fitted on all flights (the parameters reported)."""
    folds: tuple[Fit, ...]
    """Fitted without flight i, for each i."""
    heldout: HeldOut
    test: Test


@dataclass(frozen=True)
class Calibration:
    metric: str
    """The per-flight score that selection used (one of ``SCORES``)."""
    names: tuple[str, ...]
    baseline: HeldOut
    rounds: tuple[tuple[CandidateResult, ...], ...]
    selected: tuple[Fit, ...]
    """Refitted on all flights, in the order they were selected."""
    after: HeldOut
    binned: BinnedCorrection
    """Fitted on all flights on top of the selected effects."""
    binned_heldout: HeldOut
    binned_test: Test
    baseline_residuals: tuple[FlightResiduals, ...]
    after_residuals: tuple[FlightResiduals, ...]
    """Residuals of the held-out predictions with the selected effects (each flight's own fold)."""
    predicted_drift_km: np.ndarray
    """Release→landing distance of each held-out prediction after selection (the ellipse's d)."""
    t_future_h: np.ndarray

    @property
    def unexplained(self) -> bool:
        """The binned correction beats the selected model on held-out flights: the library lacks something."""
        return self.binned_test.passed


class _Batch:
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
            terms.append(fit.candidate.term(variants, values))
        return tuple(terms)

    def runs(self, j: int, rows: Sequence[Sequence[Fit]], extra: tuple[Term, ...] = ()) -> Runs:
        return run(self.cases[j], self.payload, self.terms(rows) + extra, len(rows), self.step_m)

    def scores(self, j: int, rows: Sequence[Sequence[Fit]], extra: tuple[Term, ...] = ()) -> Scores:
        return score(self.cases[j], self.runs(j, rows, extra))


def calibrate(
    cases: Sequence[FlightCase],
    payload: Payload,
    candidates: Sequence[Candidate],
    *,
    step_m: float = 200.0,
    max_effects: int = DEFAULT_MAX_EFFECTS,
    alpha: float = ALPHA,
    seed: int = 0,
    metric: str = "track_rms_km",
) -> Calibration:
    if metric not in SCORES:
        raise PredictorError(f"unknown score {metric!r}; choose one of {', '.join(SCORES)}")
    n = len(cases)
    if n < 3:
        raise PredictorError(f"leave-one-flight-out needs at least 3 usable flights, got {n}")
    batch = _Batch(cases, payload, step_m)
    baseline_scores = [batch.scores(i, [[]]) for i in range(n)]
    baseline = HeldOut.of(baseline_scores)
    baseline_residuals = tuple(residuals(cases[i], batch.runs(i, [[]])) for i in range(n))
    reference = baseline
    selected_folds: list[list[Fit]] = [[] for _ in range(n)]
    selected_full: list[Fit] = []
    rounds: list[tuple[CandidateResult, ...]] = []
    remaining = list(candidates)
    while remaining and len(selected_full) < max_effects:
        results = tuple(
            _try(
                batch,
                c,
                selected_folds,
                selected_full,
                reference,
                alpha / len(remaining),
                seed,
                len(rounds) + 1,
                metric,
            )
            for c in remaining
        )
        rounds.append(results)
        best = min(results, key=lambda r: float(np.nanmean(getattr(r.heldout, metric))))
        if not best.test.passed:
            break
        selected_full.append(best.full)
        for i in range(n):
            selected_folds[i].append(best.folds[i])
        reference = best.heldout
        remaining = [c for c in remaining if c is not best.full.candidate]
    if len(selected_full) > 1:
        _refit_jointly(batch, selected_folds, selected_full, metric)
        reference = HeldOut.of([batch.scores(i, [selected_folds[i]]) for i in range(n)])
    after = reference
    binned, binned_heldout = _binned(batch, selected_folds, selected_full)
    binned_test = paired_test(getattr(after, metric), getattr(binned_heldout, metric), alpha, seed)
    after_residuals = tuple(residuals(cases[i], batch.runs(i, [selected_folds[i]])) for i in range(n))
    return Calibration(
        metric=metric,
        names=tuple(c.name for c in cases),
        baseline=baseline,
        rounds=tuple(rounds),
        selected=tuple(selected_full),
        after=after,
        binned=binned,
        binned_heldout=binned_heldout,
        binned_test=binned_test,
        baseline_residuals=baseline_residuals,
        after_residuals=after_residuals,
        predicted_drift_km=np.array([r.predicted_drift_km for r in after_residuals]),
        t_future_h=np.array([_t_future(c) for c in cases]),
    )


def _try(
    batch: _Batch,
    candidate: Candidate,
    selected_folds: list[list[Fit]],
    selected_full: list[Fit],
    reference: HeldOut,
    alpha: float,
    seed: int,
    round_no: int,
    metric: str,
) -> CandidateResult:
    """Fit the candidate per fold and on all flights (other selected effects held), score held out."""
    n = len(batch.cases)
    full, folds_fit = _fit(batch, candidate, selected_folds, selected_full, metric)
    heldout = HeldOut.of([batch.scores(i, [[*selected_folds[i], folds_fit[i]]]) for i in range(n)])
    test = paired_test(getattr(reference, metric), getattr(heldout, metric), alpha, seed)
    return CandidateResult(round_no, full, tuple(folds_fit), heldout, test)


def _fit(
    batch: _Batch,
    candidate: Candidate,
    held_folds: list[list[Fit]],
    held_full: list[Fit],
    metric: str,
) -> tuple[Fit, list[Fit]]:
    """The candidate fitted on all flights and per fold, with the ``held`` effects in the model.

    Two passes: the candidate's coarse grid, then a fine grid (``Candidate.fine``) around the
    all-flights optimum, used by every fold whose coarse optimum falls inside it (the folds differ by
    one flight, so nearly always).
    """
    n = len(batch.cases)
    coarse = _losses(batch, candidate, held_folds, held_full, metric)
    variant, value, _ = candidate.fit(coarse.sum(axis=0)[n])
    fine_candidate = candidate.fine(variant, value)
    fine = _losses(batch, fine_candidate, held_folds, held_full, metric)
    fits: list[Fit] = []
    for i in range(n + 1):
        v0, x0, _ = candidate.fit(coarse.sum(axis=0)[i])
        if v0 == variant and fine_candidate.grid[0] <= x0 <= fine_candidate.grid[-1]:
            _, x0, _ = fine_candidate.fit(fine.sum(axis=0)[i])
        fits.append(Fit(candidate, v0, x0))
    full = fits.pop()
    return full, fits


def _refit_jointly(
    batch: _Batch, selected_folds: list[list[Fit]], selected_full: list[Fit], metric: str
) -> None:
    """Refit each selected effect with the others held at their latest values, ``JOINT_SWEEPS`` times
    (in place): an effect selected early was fitted without the later ones and has absorbed part of
    them. Fold i's fits still never see flight i."""
    for _ in range(JOINT_SWEEPS):
        for k in range(len(selected_full)):
            others_folds = [[f for m, f in enumerate(row) if m != k] for row in selected_folds]
            others_full = [f for m, f in enumerate(selected_full) if m != k]
            full, folds = _fit(batch, selected_full[k].candidate, others_folds, others_full, metric)
            selected_full[k] = full
            for i, fit in enumerate(folds):
                selected_folds[i][k] = fit


def _losses(
    batch: _Batch,
    candidate: Candidate,
    selected_folds: list[list[Fit]],
    selected_full: list[Fit],
    metric: str,
) -> np.ndarray:
    """loss[j, i, g]: flight j's squared score at grid point g with fold i's selected effects (i = n:
    the all-flights fit; loss[j, j] = 0, a flight is never in its own fold). Without selected effects
    every fold sees the same rows, so each flight flies the grid once."""
    n = len(batch.cases)
    grid_fits = [Fit(candidate, v, x) for v, x in candidate.points()]
    g = len(grid_fits)
    loss = np.zeros((n, n + 1, g))
    for j in range(n):
        if not selected_full:
            loss[j, :, :] = getattr(batch.scores(j, [[f] for f in grid_fits]), metric) ** 2
            loss[j, j, :] = 0.0
        else:
            folds = [i for i in range(n) if i != j]
            rows = [[*selected_folds[i], f] for i in folds for f in grid_fits]
            rows += [[*selected_full, f] for f in grid_fits]
            sq = (getattr(batch.scores(j, rows), metric) ** 2).reshape(len(folds) + 1, g)
            loss[j, folds, :] = sq[:-1]
            loss[j, n, :] = sq[-1]
    return loss


def _binned(
    batch: _Batch, selected_folds: list[list[Fit]], selected_full: list[Fit]
) -> tuple[BinnedCorrection, HeldOut]:
    """The binned correction per fold from the training flights' residuals, scored on the held-out one."""
    n = len(batch.cases)
    edges = np.asarray(BIN_EDGES_M)
    budgets = []
    for j in range(n):
        rows = [*selected_folds, selected_full]
        runs = batch.runs(j, rows) if selected_full else batch.runs(j, [[]] * (n + 1))
        budgets.append([bin_budget(batch.cases[j], runs, i, edges) for i in range(n + 1)])
    scores = []
    for i in range(n):
        correction = fit_binned([budgets[j][i] for j in range(n) if j != i])
        scores.append(batch.scores(i, [selected_folds[i]], correction.terms()))
    full = fit_binned([budgets[j][n] for j in range(n)])
    return full, HeldOut.of(scores)


def _t_future(case: FlightCase) -> float:
    """Mean forecast lead time of the weather over the descent (0 for ascent-measured winds)."""
    times = case.cube.times.astype("datetime64[s]").astype(np.int64).astype(float)
    t0 = case.start_time.timestamp()
    at = np.linspace(t0, t0 + case.descent_time_s, 9)
    return float(np.mean(np.interp(at, times, case.cube.lead_h)))
