"""A Tawhiri v1 question, read from a URL's query and checked whole before any weather is read or made.

Why a grammar of our own: Python's ``float`` reads ``5_0`` as 50 and ``٥`` (an Arabic-Indic five) as 5,
so a typo or a hostile client was flown as something nobody wrote. A number here is what a URL carries:
ASCII digits with an optional sign, point and exponent, nothing else. Every rate, altitude and time is
checked here, and the flight's length with them, so a request no balloon could fly is a 400 at once
instead of hours of generated weather and a 500.

The profiles are Tawhiri's: ``standard_profile`` (ascent, burst, descent), ``float_profile`` (ascent
to ``float_altitude``, then drifting until ``stop_datetime``) and SondeHub's ``reverse_profile``
(from where an ascending balloon is now, back in time to where it was launched).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

STANDARD_PROFILE = "standard_profile"
FLOAT_PROFILE = "float_profile"
REVERSE_PROFILE = "reverse_profile"
PROFILES = (STANDARD_PROFILE, FLOAT_PROFILE, REVERSE_PROFILE)
FORMATS = ("json", "csv", "kml")
TAWHIRI_DESCENT = "tawhiri"
CAPSULE_DESCENT = "capsule"

NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)
"""A URL's number: ASCII digits, an optional sign, point and exponent; no ``_``, no other scripts,
no ``inf`` or ``nan``, no spaces."""
MAX_NUMBER_CHARS = 40
"""Longer than any number a client writes (``repr`` of a float is at most 24): a 5,000-digit value is
refused before Python converts it."""
MIN_RATE_MS = 0.2
"""Tawhiri raises slower ascent and descent rates to this (its ``rate_clip``); chasemapper sends 0.1."""
MIN_ACCEPTED_RATE_MS = 0.05
"""Slower is refused, not raised: 1e-300 is nobody's rate, and raised to 0.2 it was flown for 14 h."""
MAX_ASCENT_RATE_MS = 50.0
MAX_DESCENT_RATE_MS = 150.0
"""Faster than any balloon rises or any payload falls at sea level: a typo or an attack."""
MIN_ALTITUDE_M = -500.0
MAX_ALTITUDE_M = 60_000.0
"""Below the Dead Sea shore or above the highest balloon flight: no weather has it."""
MAX_FLIGHT_S = 12 * 3600.0
"""An ascent and descent longer than this is refused before any weather is made: a 5 m/s radiosonde to
35 km and down is 3 h, and a 0.2 m/s descent from 30 km (14 h) is no parachute's."""
MAX_FLOAT_S = 24 * 3600.0
"""A float prediction is flown for at most a day after launch (the demo writes weather for all of it)."""
EARLIEST, LATEST = datetime(1990, 1, 1, tzinfo=UTC), datetime(2100, 1, 1, tzinfo=UTC)
"""Launch and stop times outside these years are typos: no forecast exists for them."""


class ApiError(Exception):
    """One of Tawhiri's error types, with its HTTP status."""

    def __init__(self, kind: str, status: int, description: str) -> None:
        super().__init__(description)
        self.kind = kind
        self.status = status
        self.description = description


def request_error(description: str) -> ApiError:
    return ApiError("RequestException", 400, description)


@dataclass(frozen=True)
class ApiRequest:
    """A question, checked; ``launch_longitude`` in degrees east as given. The profile says which of
    the optional fields are set: ``burst_altitude`` and ``descent_rate`` (standard), ``float_altitude``
    and ``stop_datetime`` (float), neither (reverse)."""

    profile: str
    launch_latitude: float
    launch_longitude: float
    launch_datetime: datetime
    launch_altitude: float | None
    ascent_rate: float
    dataset: datetime | None
    format: str
    burst_altitude: float | None = None
    descent_rate: float | None = None
    float_altitude: float | None = None
    stop_datetime: datetime | None = None
    descent: str = TAWHIRI_DESCENT
    """``TAWHIRI_DESCENT`` or ``CAPSULE_DESCENT``, from the path or a capsule's position report."""
    capsule: str | None = None
    clipped: tuple[str, ...] = ()
    """The rate parameters raised to ``MIN_RATE_MS``."""


def _single(query: Mapping[str, Sequence[str]], name: str) -> str | None:
    values = query.get(name)
    if not values:
        return None
    if len(values) > 1:
        raise request_error(f"Parameter '{name}' given {len(values)} times; give it once.")
    return values[0]


def _required(query: Mapping[str, Sequence[str]], name: str) -> str:
    value = _single(query, name)
    if value is None:
        raise request_error(f"Parameter '{name}' not provided in request.")
    return value


def parse_number(name: str, text: str) -> float:
    """``text`` as a number of the URL grammar (``NUMBER``), finite; else a 400 naming the parameter."""
    shown = text if len(text) <= MAX_NUMBER_CHARS else text[:MAX_NUMBER_CHARS] + "…"
    if len(text) > MAX_NUMBER_CHARS or NUMBER.fullmatch(text) is None:
        raise request_error(
            f"Unable to parse parameter '{name}': {shown!r} (not a number: ASCII digits with an optional "
            "sign, point and exponent, e.g. 5, -0.4 or 1.2e3)."
        )
    value = float(text)
    if not math.isfinite(value):
        raise request_error(f"Invalid value for parameter '{name}': {shown} (too large).")
    return value


def _number(name: str, text: str, check: Callable[[float], bool], rule: str) -> float:
    value = parse_number(name, text)
    if not check(value):
        raise request_error(f"Invalid value for parameter '{name}': {text} ({rule}).")
    return value


def _rfc3339(name: str, text: str) -> datetime:
    text = text.strip().replace(" ", "+")  # a '+' sent unescaped arrives as a space
    if not text.isascii() or len(text) > 40:
        raise request_error(f"Unable to parse parameter '{name}': {text[:40]!r} (an RFC 3339 time).")
    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        raise request_error(
            f"Unable to parse parameter '{name}': {text} (an RFC 3339 time such as 2024-05-01T06:30:00Z)."
        ) from None
    if moment.tzinfo is None:
        raise request_error(f"Invalid value for parameter '{name}': {text} (no time zone; end it with Z).")
    moment = moment.astimezone(UTC)
    if not EARLIEST <= moment < LATEST:
        raise request_error(
            f"Invalid value for parameter '{name}': {text} (must be between {EARLIEST.year} and {LATEST.year})."
        )
    return moment


def _rate(query: Mapping[str, Sequence[str]], name: str, most: float) -> float:
    return _number(
        name, _required(query, name), lambda x: MIN_ACCEPTED_RATE_MS <= x <= most,
        f"must be at least {MIN_ACCEPTED_RATE_MS:g} and at most {most:g} m/s; below {MIN_RATE_MS:g} it is "
        f"flown at {MIN_RATE_MS:g}",
    )  # fmt: skip


def _altitude(query: Mapping[str, Sequence[str]], name: str, above: float | None) -> float:
    floor = MIN_ALTITUDE_M if above is None else above
    return _number(
        name, _required(query, name), lambda x: floor < x < MAX_ALTITUDE_M,
        f"must be above {'launch_altitude' if above is not None else f'{MIN_ALTITUDE_M:g} m'} and below "
        f"{MAX_ALTITUDE_M:g} m",
    )  # fmt: skip


def parse_request(query: Mapping[str, Sequence[str]]) -> ApiRequest:
    """The query's parameters, checked one by one in Tawhiri's order: the first bad one is named."""
    profile = _single(query, "profile") or STANDARD_PROFILE
    if profile not in PROFILES:
        raise request_error(f"Unknown profile '{profile}'.")
    output = _single(query, "format") or "json"
    if output not in FORMATS:
        raise request_error(f"Invalid value for parameter 'format': {output} (one of {', '.join(FORMATS)}).")
    lat = _number(
        "launch_latitude", _required(query, "launch_latitude"), lambda x: -90 <= x <= 90, "-90 to 90"
    )
    lon = _number(
        "launch_longitude", _required(query, "launch_longitude"), lambda x: -180 <= x < 360, "0 to 360, or -180 to 180"
    )  # fmt: skip
    when = _rfc3339("launch_datetime", _required(query, "launch_datetime"))
    alt_text = _single(query, "launch_altitude")
    alt = None if alt_text is None else _number(
        "launch_altitude", alt_text, lambda x: MIN_ALTITUDE_M <= x < MAX_ALTITUDE_M,
        f"{MIN_ALTITUDE_M:g} to {MAX_ALTITUDE_M:g} m",
    )  # fmt: skip
    rate = _rate(query, "ascent_rate", MAX_ASCENT_RATE_MS)
    burst = descent = float_alt = None
    stop: datetime | None = None
    rates = [("ascent_rate", rate)]
    if profile == STANDARD_PROFILE:
        burst = _altitude(query, "burst_altitude", alt)
        descent = _rate(query, "descent_rate", MAX_DESCENT_RATE_MS)
        rates.append(("descent_rate", descent))
    elif profile == FLOAT_PROFILE:
        float_alt = _altitude(query, "float_altitude", alt)
        stop_text = _required(query, "stop_datetime")
        stop = _rfc3339("stop_datetime", stop_text)
        if stop <= when:
            raise request_error(
                f"Invalid value for parameter 'stop_datetime': {stop_text} (must be after launch_datetime)."
            )
        if (stop - when).total_seconds() > MAX_FLOAT_S:
            raise request_error(
                f"Invalid value for parameter 'stop_datetime': {stop_text} (at most "
                f"{MAX_FLOAT_S / 3600:.0f} h after launch_datetime is flown)."
            )
    dataset_text = _single(query, "dataset")
    dataset = None if dataset_text is None else _rfc3339("dataset", dataset_text)
    clipped = tuple(name for name, value in rates if value < MIN_RATE_MS)
    return ApiRequest(
        profile, lat, lon, when, alt, max(rate, MIN_RATE_MS), dataset, output, burst_altitude=burst,
        descent_rate=None if descent is None else max(descent, MIN_RATE_MS), float_altitude=float_alt,
        stop_datetime=stop, clipped=clipped,
    )  # fmt: skip
