"""From a raw track to a ``Flight``: stated rules, each reported as what it removed and why.

Calibration is only as honest as its inputs. Every fix that is dropped is dropped by a named rule
with its file lines, so a reader of a calibration report can check each decision; a flight that
cannot be used says why instead of silently disappearing. Rules, in the order they run:

1. ``invalid-date``: a date before 2000 (the receiver's default date before its first fix, e.g. 1970).
2. ``zero-position``: latitude and longitude both exactly 0 (no fix).
3. ``position-out-of-range`` / ``altitude-out-of-range``: |lat| > 90, lon outside [-180, 360],
   altitude outside [-500, 60000] m.
   A pressure outside 0.5-2x the standard atmosphere at the fix's altitude is a sensor fault (19-7-30
   logs 1 Pa at 50 fixes): the pressure is discarded, the position kept, and that is noted.
4. ``duplicate-time``: a second fix with the same time as an earlier one (the first is kept). Fixes
   out of time order are re-sorted (GNSS times are trusted over file order) and that is noted.
5. ``impossible-jump``: a fix that implies more than 200 m/s horizontally or 150 m/s vertically
   to both neighbours (a balloon in the strongest jet moves ~110 m/s; a falling capsule < 100 m/s).
6. ``other-session``: fixes more than 3 h apart split the file into sessions; the session with the
   largest altitude range is the flight (it must span 1000 m), the others are ground tests,
   previous days, or the payload found days later.
7. ``before-launch``: fixes on the ground before the ascent. Walking back from the peak, the ascent
   continues while the climb rate over >= 60 s is above 1 m/s or the fix is more than 2000 m above
   the lowest fix before the peak (balloons slow down near burst; nothing launches from there).
   The fix where it stops is on the ground; the launch is the last fix still within 100 m of it.
8. Descent start is the first fix after the highest point (as the DRS paper did). A floater (the
   altitude falls slower than 3 m/s for at least 20 min after the peak) starts its descent at the
   first fix after the float, and is flagged. A track whose first fix is its highest is a
   descent-only track; its descent starts at its first fix.
9. ``after-landing``: landing is the first fix after descent start from which the altitude changes
   by less than 50 m over the next >= 60 s (the descent has reached a steady altitude: a parachute
   falls 2-5 m/s near the ground, GNSS altitude on the ground scatters by tens of metres). When the
   track ends first, its last fix is the landing only if the receiver reported a ground speed below
   0.5 m/s there (the capsule had stopped; flagged ``landing-at-last-fix``). With high-rate logs
   (>= 5 fixes in that 60 s) the landing moves on to the first fix within 15 m of the window's
   median altitude, the ground. Every row after the landing is dropped: the payload on the
   ground, then often driven home.
   With terrain (``--dem``), a track that ends during the descent with its last fix within
   ``TERRAIN_LANDING_TOLERANCE_M`` of the ground height under it has landed there (a logger that
   stops at touchdown, a log cut at the landing): the last fix is the landing, flagged
   ``landing-at-terrain``. A last fix where no DEM answers (the terrain would be a guessed sea level)
   is not taken as a landing. Without terrain, the rules above stand.

Flags (kept, but the calibration should know): ``floater``, ``landing-at-last-fix``,
``landing-at-terrain``, ``data-gap``
(no fix for more than 15 min between the peak and the landing), ``descent-only``, ``starts-in-air``.
Exclusions (the flight cannot be used for calibration): no flight found, no descent recorded, no
landing observed, fewer than 3 descent fixes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime

import numpy as np

from predictor.environment import SEA_LEVEL_SOURCE, Terrain
from predictor.prediction import GEOD
from predictor.tracks.reading import Fix, Track
from predictor.tracks.standard_atmosphere import pressure_temperature

EARLIEST_VALID_TIME = datetime(2000, 1, 1, tzinfo=UTC)
MIN_ALT_M = -500.0
MAX_ALT_M = 60_000.0
PLAUSIBLE_PRESSURE_RATIO = (0.5, 2.0)
"""Measured over standard-atmosphere pressure: real weather stays within ~0.7-1.4 at balloon altitudes."""
MAX_HORIZONTAL_SPEED_MS = 200.0
MAX_VERTICAL_SPEED_MS = 150.0
SESSION_GAP_S = 3 * 3600.0
MIN_FLIGHT_RANGE_M = 1000.0
RATE_WINDOW_S = 60.0
"""Vertical rates are taken over at least this long, so 1 Hz GNSS noise cannot fake a climb or a landing."""
ASCENT_MIN_RATE_MS = 1.0
LAUNCH_SEARCH_BAND_M = 2000.0
GROUND_BAND_M = 100.0
FLOAT_MAX_FALL_MS = 3.0
FLOAT_MIN_DURATION_S = 20 * 60.0
LANDED_BAND_M = 50.0
HIGH_RATE_WINDOW_FIXES = 5
TOUCHDOWN_BAND_M = 15.0
STOPPED_SPEED_MS = 0.5
GAP_S = 15 * 60.0
TERRAIN_LANDING_TOLERANCE_M = 50.0
"""Last fix to DEM ground height: SRTM's vertical error (~16 m, 90 % of points) plus GNSS altitude
error (~15 m) plus the last few seconds of a 5 m/s fall; a track cut off in the air at 2–5 min
telemetry ends hundreds of metres up."""
MIN_DESCENT_FIXES = 3


@dataclass(frozen=True)
class Removal:
    """Fixes one rule dropped, with the file lines, so the decision can be checked by hand."""

    rule: str
    reason: str
    lines: tuple[int, ...]

    @property
    def count(self) -> int:
        return len(self.lines)


@dataclass(frozen=True)
class Flag:
    """Something about a usable flight that an analysis of it should take into account."""

    code: str
    message: str


@dataclass(frozen=True)
class Flight:
    """A cleaned flight: its segments, its key fixes, and everything that was done to get there."""

    name: str
    source: str
    n_read: int
    fixes: tuple[Fix, ...]
    """The fixes kept: launch (or first airborne fix) to landing (or the last fix)."""
    removals: tuple[Removal, ...]
    notes: tuple[str, ...]
    launch: Fix | None
    peak: Fix | None
    descent_start: Fix | None
    landing: Fix | None
    ascent: tuple[Fix, ...]
    """Launch to peak, both included; empty for a descent-only track."""
    descent: tuple[Fix, ...]
    """Descent start to landing (or to the last fix when no landing was observed), both included."""
    flags: tuple[Flag, ...]
    exclusions: tuple[str, ...]

    @property
    def usable(self) -> bool:
        return not self.exclusions

    @property
    def n_dropped(self) -> int:
        return sum(r.count for r in self.removals)

    @property
    def descent_time_s(self) -> float | None:
        if self.descent_start is None or self.landing is None:
            return None
        return (self.landing.time - self.descent_start.time).total_seconds()

    @property
    def drift_km(self) -> float | None:
        """Geodesic distance from descent start to landing."""
        if self.descent_start is None or self.landing is None:
            return None
        return distance_m(self.descent_start, self.landing) / 1000.0

    def has_flag(self, code: str) -> bool:
        return any(flag.code == code for flag in self.flags)


def distance_m(a: Fix, b: Fix) -> float:
    return float(GEOD.inv(a.lon, a.lat, b.lon, b.lat)[2])


def clean(track: Track, terrain: Terrain | None = None) -> Flight:
    """The flight in ``track`` by the module's rules; ``terrain`` adds the landing-at-terrain rule."""
    removals: list[Removal] = []
    notes: list[str] = []
    fixes = _drop_invalid(list(track.fixes), removals)
    fixes = _discard_implausible_pressure(fixes, notes)
    fixes = _time_order(fixes, removals, notes)
    fixes = _drop_impossible_jumps(fixes, removals)
    session = _flight_session(fixes, removals)

    def result(
        *,
        fixes: tuple[Fix, ...] | None = None,
        launch: Fix | None = None,
        peak: Fix | None = None,
        descent_start: Fix | None = None,
        landing: Fix | None = None,
        ascent: tuple[Fix, ...] = (),
        descent: tuple[Fix, ...] = (),
        flags: tuple[Flag, ...] = (),
        exclusions: tuple[str, ...] = (),
    ) -> Flight:
        """The flight as far as it was found; the whole session's fixes unless told which were kept."""
        return Flight(
            name=track.name,
            source=track.source,
            n_read=len(track.fixes),
            fixes=tuple(session) if fixes is None else fixes,
            removals=tuple(removals),
            notes=tuple(notes),
            launch=launch,
            peak=peak,
            descent_start=descent_start,
            landing=landing,
            ascent=ascent,
            descent=descent,
            flags=flags,
            exclusions=exclusions,
        )

    if len(session) < 2 or _altitude_range(session) < MIN_FLIGHT_RANGE_M:
        return result(
            exclusions=(
                f"no flight: no part of the track spans {MIN_FLIGHT_RANGE_M:.0f} m of altitude "
                f"(range {_altitude_range(session):.0f} m)",
            )
        )
    times = np.array([f.time.timestamp() for f in session])
    alts = np.array([f.alt_m for f in session])
    flags: list[Flag] = []
    exclusions: list[str] = []
    peak = int(np.argmax(alts))

    if peak == 0:
        launch = None
        start = 0
        flags.append(Flag("descent-only", f"the track starts at its highest point, {alts[0]:.0f} m"))
    else:
        launch = _launch_index(times, alts, peak)
        if launch > 0:
            removals.append(
                Removal(
                    "before-launch",
                    f"on the ground before launch at {_hm(session[launch])} ({session[launch].alt_m:.0f} m)",
                    tuple(f.line for f in session[:launch]),
                )
            )
        elif _rate(times, alts, 0) > ASCENT_MIN_RATE_MS:
            flags.append(Flag("starts-in-air", f"the track starts during the ascent, at {alts[0]:.0f} m"))
        start = peak + 1
        float_end = _float_end(times, alts, peak)
        float_s = times[float_end] - times[peak]
        if float_s >= FLOAT_MIN_DURATION_S:
            start = float_end + 1
            flags.append(
                Flag(
                    "floater",
                    f"floated {float_s / 60:.0f} min after the {alts[peak]:.0f} m peak, falling slower than "
                    f"{FLOAT_MAX_FALL_MS:g} m/s down to {alts[float_end]:.0f} m; "
                    "descent starts after the float",
                )
            )
    first = 0 if launch is None else launch
    if start >= len(session):
        return result(
            fixes=tuple(session[first:]),
            launch=_at(session, launch),
            peak=session[peak],
            ascent=tuple(session[first : peak + 1]),
            flags=tuple(flags),
            exclusions=("no descent recorded: the track ends at its highest point",),
        )
    landing = _landing_index(times, alts, start)
    last = session[-1]
    if landing is None and terrain is not None and start < len(session) - 1:
        ground = _ground_under(terrain, last)
        if ground is not None and abs(last.alt_m - ground) <= TERRAIN_LANDING_TOLERANCE_M:
            landing = len(session) - 1
            flags.append(
                Flag(
                    "landing-at-terrain",
                    f"the track ends at {last.alt_m:.0f} m ({_hm(last)}), {last.alt_m - ground:+.0f} m from the "
                    f"terrain height {ground:.0f} m (tolerance {TERRAIN_LANDING_TOLERANCE_M:.0f} m): "
                    "taken as the landing",
                )
            )
    if (
        landing is None
        and last.speed_ms is not None
        and last.speed_ms < STOPPED_SPEED_MS
        and start < len(session) - 1
    ):
        landing = len(session) - 1
        flags.append(
            Flag(
                "landing-at-last-fix",
                f"the track ends at {last.alt_m:.0f} m ({_hm(last)}) where the receiver reported "
                f"{last.speed_ms:g} m/s ground speed: taken as the landing",
            )
        )
    end = len(session) - 1 if landing is None else landing
    if landing is not None and landing < len(session) - 1:
        after = session[landing + 1 :]
        farthest = max(distance_m(session[landing], f) for f in after) / 1000.0
        removals.append(
            Removal(
                "after-landing",
                f"after landing at {_hm(session[landing])} ({session[landing].alt_m:.0f} m): "
                f"on the ground or being recovered, up to {farthest:.1f} km from the landing",
                tuple(f.line for f in after),
            )
        )
    if landing is None:
        exclusions.append(
            f"no landing observed: the track ends during the descent at {alts[-1]:.0f} m ({_hm(session[-1])})"
        )
    descent = tuple(session[start : end + 1])
    if len(descent) < MIN_DESCENT_FIXES:
        exclusions.append(f"descent has only {len(descent)} fixes (need {MIN_DESCENT_FIXES})")
    flags.extend(_gaps(session, peak, end))
    return result(
        fixes=tuple(session[first : end + 1]),
        launch=_at(session, launch),
        peak=session[peak],
        descent_start=session[start],
        landing=_at(session, landing),
        ascent=() if launch is None else tuple(session[launch : peak + 1]),
        descent=descent,
        flags=tuple(flags),
        exclusions=tuple(exclusions),
    )


def _drop_invalid(fixes: list[Fix], removals: list[Removal]) -> list[Fix]:
    rules: tuple[tuple[str, str, Callable[[Fix], bool]], ...] = (
        (
            "invalid-date",
            "date before 2000: the receiver's default date before a fix",
            lambda f: f.time < EARLIEST_VALID_TIME,
        ),
        (
            "zero-position",
            "latitude and longitude both 0: no position fix",
            lambda f: f.lat == 0 and f.lon == 0,
        ),
        (
            "position-out-of-range",
            "latitude outside ±90° or longitude outside -180…360°",
            lambda f: abs(f.lat) > 90 or not -180 <= f.lon <= 360,
        ),
        (
            "altitude-out-of-range",
            f"altitude outside {MIN_ALT_M:.0f}…{MAX_ALT_M:.0f} m",
            lambda f: not MIN_ALT_M <= f.alt_m <= MAX_ALT_M,
        ),
    )
    kept = fixes
    for rule, reason, bad in rules:
        dropped = [f for f in kept if bad(f)]
        if dropped:
            removals.append(Removal(rule, reason, tuple(f.line for f in dropped)))
            kept = [f for f in kept if not bad(f)]
    return kept


def _discard_implausible_pressure(fixes: list[Fix], notes: list[str]) -> list[Fix]:
    low, high = PLAUSIBLE_PRESSURE_RATIO
    faulty = [
        f
        for f in fixes
        if f.pressure_pa is not None
        and not low <= f.pressure_pa / float(pressure_temperature(f.alt_m)[0]) <= high
    ]
    if not faulty:
        return fixes
    example = faulty[0]
    notes.append(
        f"pressure discarded at {len(faulty)} fixes, outside {low:g}-{high:g}x the standard atmosphere "
        f"at their altitude (sensor fault, e.g. {example.pressure_pa:g} Pa at {example.alt_m:.0f} m); "
        "positions kept"
    )
    bad = {id(f) for f in faulty}
    return [replace(f, pressure_pa=None) if id(f) in bad else f for f in fixes]


def _time_order(fixes: list[Fix], removals: list[Removal], notes: list[str]) -> list[Fix]:
    ordered = sorted(fixes, key=lambda f: f.time)
    moved = sum(1 for a, b in zip(fixes, ordered, strict=True) if a is not b)
    if moved:
        notes.append(f"{moved} fixes were out of time order and were re-sorted by their GNSS time")
    kept: list[Fix] = []
    duplicates: list[Fix] = []
    for fix in ordered:
        if kept and fix.time == kept[-1].time:
            duplicates.append(fix)
        else:
            kept.append(fix)
    if duplicates:
        removals.append(
            Removal(
                "duplicate-time",
                "same time as the fix before it (the first one is kept)",
                tuple(f.line for f in duplicates),
            )
        )
    return kept


def _impossible(a: Fix, b: Fix) -> bool:
    dt = (b.time - a.time).total_seconds()
    return (
        distance_m(a, b) > MAX_HORIZONTAL_SPEED_MS * dt or abs(b.alt_m - a.alt_m) > MAX_VERTICAL_SPEED_MS * dt
    )


def _drop_impossible_jumps(fixes: list[Fix], removals: list[Removal]) -> list[Fix]:
    """Drop spikes (impossible to both neighbours), then an end fix impossible to its only neighbour."""
    kept = list(fixes)
    dropped: list[Fix] = []
    while len(kept) >= 2:
        bad_step = [_impossible(a, b) for a, b in zip(kept, kept[1:], strict=False)]
        spikes = [i for i in range(1, len(kept) - 1) if bad_step[i - 1] and bad_step[i]]
        if not spikes:
            spikes = [0] if bad_step[0] else [len(kept) - 1] if bad_step[-1] else []
        if not spikes:
            break
        dropped.extend(kept[i] for i in spikes)
        kept = [f for i, f in enumerate(kept) if i not in set(spikes)]
    if dropped:
        removals.append(
            Removal(
                "impossible-jump",
                f"implies more than {MAX_HORIZONTAL_SPEED_MS:.0f} m/s horizontally or "
                f"{MAX_VERTICAL_SPEED_MS:.0f} m/s vertically to its neighbours",
                tuple(sorted(f.line for f in dropped)),
            )
        )
    return kept


def _flight_session(fixes: list[Fix], removals: list[Removal]) -> list[Fix]:
    if not fixes:
        return []
    sessions: list[list[Fix]] = [[fixes[0]]]
    for prev, fix in zip(fixes, fixes[1:], strict=False):
        if (fix.time - prev.time).total_seconds() > SESSION_GAP_S:
            sessions.append([])
        sessions[-1].append(fix)
    best = max(range(len(sessions)), key=lambda i: _altitude_range(sessions[i]))
    for i, other in enumerate(sessions):
        if i != best:
            removals.append(
                Removal(
                    "other-session",
                    f"{_day_span(other)}: a separate session "
                    f"(more than {SESSION_GAP_S / 3600:.0f} h from the "
                    f"flight, altitude range {_altitude_range(other):.0f} m), not the flight",
                    tuple(f.line for f in other),
                )
            )
    return sessions[best]


def _altitude_range(fixes: Sequence[Fix]) -> float:
    return max(f.alt_m for f in fixes) - min(f.alt_m for f in fixes) if fixes else 0.0


def _window_end(times: np.ndarray, i: int) -> int | None:
    """The first fix at least RATE_WINDOW_S after fix i (the next fix for 2-5 min telemetry)."""
    j = int(np.searchsorted(times, times[i] + RATE_WINDOW_S, side="left"))
    return j if j < len(times) else None


def _rate(times: np.ndarray, alts: np.ndarray, i: int) -> float:
    j = _window_end(times, i)
    if j is None:
        return float("nan")
    return float((alts[j] - alts[i]) / (times[j] - times[i]))


def _launch_index(times: np.ndarray, alts: np.ndarray, peak: int) -> int:
    ceiling = float(np.min(alts[:peak])) + LAUNCH_SEARCH_BAND_M

    def climbing(i: int) -> bool:
        """The climb up to the peak at most: a window reaching past the burst would see the fall (a
        track that starts less than the search band below its peak has only this test)."""
        j = _window_end(times, i)
        end = peak if j is None or j > peak else j
        return bool(alts[i] > ceiling or (alts[end] - alts[i]) / (times[end] - times[i]) > ASCENT_MIN_RATE_MS)

    ground = peak - 1
    while ground > 0 and climbing(ground):
        ground -= 1
    if ground == 0 and climbing(0):
        return 0
    on_ground = np.nonzero(alts[ground:peak] <= alts[ground] + GROUND_BAND_M)[0]
    return ground + int(on_ground[-1])


def _float_end(times: np.ndarray, alts: np.ndarray, peak: int) -> int:
    """The last fix of the slow fall that follows the peak (the peak itself after a burst)."""
    i = peak
    while (j := _window_end(times, i)) is not None:
        if (alts[j] - alts[i]) / (times[j] - times[i]) <= -FLOAT_MAX_FALL_MS:
            break
        i = j
    return i


def _landing_index(times: np.ndarray, alts: np.ndarray, start: int) -> int | None:
    for k in range(start, len(times)):
        j = _window_end(times, k)
        if j is None:
            return None
        if abs(alts[j] - alts[k]) < LANDED_BAND_M:
            return _touchdown(alts, k, j)
    return None


def _touchdown(alts: np.ndarray, k: int, j: int) -> int:
    """With a high-rate log the steady window can start up to 50 m above the ground (10 s early at
    5 m/s); move on to the first fix that is at the ground, i.e. near the window's median altitude."""
    if j - k + 1 < HIGH_RATE_WINDOW_FIXES:
        return k
    ground = float(np.median(alts[k : j + 1]))
    return k + int(np.argmax(alts[k : j + 1] <= ground + TOUCHDOWN_BAND_M))


def _ground_under(terrain: Terrain, fix: Fix) -> float | None:
    """The DEM's ground height under the fix; None where no DEM covers it (sea level is a guess there)."""
    if terrain.source_at(fix.lat, fix.lon) == SEA_LEVEL_SOURCE:
        return None
    return float(terrain.elevation(fix.lat, fix.lon))


def _gaps(session: list[Fix], peak: int, end: int) -> list[Flag]:
    flags = []
    for a, b in zip(session[peak:end], session[peak + 1 : end + 1], strict=True):
        dt = (b.time - a.time).total_seconds()
        if dt > GAP_S:
            flags.append(
                Flag(
                    "data-gap",
                    f"no fix for {dt / 60:.0f} min between {a.alt_m:.0f} m ({_hm(a)}) "
                    f"and {b.alt_m:.0f} m ({_hm(b)})",
                )
            )
    return flags


def _at(fixes: Sequence[Fix], index: int | None) -> Fix | None:
    return None if index is None else fixes[index]


def _hm(fix: Fix) -> str:
    return fix.time.strftime("%H:%M:%S")


def _day_span(fixes: Sequence[Fix]) -> str:
    return f"{fixes[0].time:%Y-%m-%d %H:%M}–{fixes[-1].time:%Y-%m-%d %H:%M} UTC"
