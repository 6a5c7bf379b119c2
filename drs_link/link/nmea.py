"""GNSS state from the NMEA the capsule's microcontroller echoes to the Pi.

The stock log (``DRS_serial_log.txt``) is raw serial bytes with no timestamps, often cut mid-line
by the 1 s read timeout, so garbage is normal: every sentence that does not parse or fails its
checksum is counted and skipped, and nothing in this module raises on input. Only GGA and RMC
matter (the firmware disables the rest); GP (flight configuration), GN (bench units whose GNSS
configuration was not saved) and IN (integrated navigation) talkers are accepted.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from datetime import UTC, date, datetime, time, timedelta

TALKERS = ("GP", "GN", "IN")
"""GP: GPS only (flight configuration); GN: several constellations; IN: an integrated (GNSS + inertial)
receiver, which some u-blox units report as; the sentences are the same."""
ALTITUDE_RANGE_M = (-1_000.0, 60_000.0)
"""Below the Dead Sea shore to above any balloon (a u-blox in airborne mode stops at 50 km)."""
MAX_SATELLITES = 64
"""More than every GNSS satellite a receiver can track at once; ``28000`` is a broken sentence."""
FIX_QUALITY_NAMES = {
    0: "no fix",
    1: "GPS fix",
    2: "DGPS fix",
    3: "PPS fix",
    4: "RTK fixed",
    5: "RTK float",
    6: "dead reckoning",
    7: "manual",
    8: "simulation",
}


@dataclass(frozen=True)
class GgaSentence:
    talker: str
    time_utc: time | None
    latitude: float | None
    longitude: float | None
    fix_quality: int
    satellites: int | None
    hdop: float | None
    altitude_m: float | None


@dataclass(frozen=True)
class RmcSentence:
    talker: str
    time_utc: time | None
    valid: bool
    latitude: float | None
    longitude: float | None
    speed_knots: float | None
    course_deg: float | None
    date_utc: date | None


@dataclass(frozen=True)
class NmeaCounts:
    """How much of the log was usable: the operator sees these to judge a noisy serial line."""

    parsed: int = 0
    malformed: int = 0
    bad_checksum: int = 0
    ignored: int = 0


@dataclass(frozen=True)
class GnssStatus:
    """What an operator needs before Go: is there a fix, how good, how old."""

    nmea_seen: bool
    fix_quality: int | None
    has_fix: bool
    satellites: int | None
    hdop: float | None
    latitude: float | None
    longitude: float | None
    altitude_m: float | None
    fix_time_utc: datetime | None
    age_s: float | None
    counts: NmeaCounts
    date_problem: str | None = None
    """An RMC date that was left out, and why (a GPS week rollover, or a date far from the clock)."""

    @property
    def fix_quality_name(self) -> str:
        if self.fix_quality is None:
            return "unknown"
        return FIX_QUALITY_NAMES.get(self.fix_quality, f"quality {self.fix_quality}")

    def as_dict(self) -> dict[str, object]:
        return {
            "nmea_seen": self.nmea_seen,
            "fix_quality": self.fix_quality,
            "fix_quality_name": self.fix_quality_name,
            "has_fix": self.has_fix,
            "satellites": self.satellites,
            "hdop": self.hdop,
            "latitude": self.latitude,
            "longitude": self.longitude,
            "altitude_m": self.altitude_m,
            "fix_time_utc": self.fix_time_utc.isoformat().replace("+00:00", "Z")
            if self.fix_time_utc
            else None,
            "age_s": self.age_s,
            "sentences_parsed": self.counts.parsed,
            "sentences_malformed": self.counts.malformed,
            "sentences_bad_checksum": self.counts.bad_checksum,
            "date_problem": self.date_problem,
        }


class _Malformed(Exception):
    """Internal: one sentence cannot be parsed (never escapes this module)."""


class _BadChecksum(Exception):
    """Internal: one sentence's checksum does not match (never escapes this module)."""


def nmea_checksum(body: str) -> int:
    """XOR of the characters between ``$`` and ``*``."""
    value = 0
    for char in body:
        value ^= ord(char)
    return value


def _split_checked(line: str) -> list[str]:
    start = line.rfind("$")
    if start < 0:
        raise _Malformed
    sentence = line[start + 1 :].strip()
    if "*" not in sentence:
        raise _Malformed
    body, _, checksum_text = sentence.rpartition("*")
    if len(checksum_text) != 2:
        raise _Malformed
    try:
        expected = int(checksum_text, 16)
    except ValueError:
        raise _Malformed from None
    if not body.isascii():
        raise _Malformed
    if nmea_checksum(body) != expected:
        raise _BadChecksum
    return body.split(",")


def _time(text: str) -> time | None:
    if not text:
        return None
    if len(text) < 6 or not text[:6].isdigit():
        raise _Malformed
    hour, minute, second = int(text[0:2]), int(text[2:4]), int(text[4:6])
    fraction = text[6:]
    micro = 0
    if fraction:
        if fraction[0] != "." or not fraction[1:].isdigit() or len(fraction) > 7:
            raise _Malformed
        micro = int((fraction[1:] + "000000")[:6])
    if hour > 23 or minute > 59 or second > 60:
        raise _Malformed
    return time(hour, minute, min(second, 59), micro, tzinfo=UTC)


def _century(two_digits: int) -> int:
    """NMEA's two-digit year: 80–99 are 1980–1999 (GPS began in 1980), 00–79 are 2000–2079.

    A receiver hit by the GPS week rollover reports 1024 weeks (19.6 years) in the past, e.g. `220899`
    for 2019-04-07; read as 2099 that became a fix 80 years in the future. Read as 1999 it is a date
    ``date_problem`` recognises as a rollover.
    """
    return 1900 + two_digits if two_digits >= 80 else 2000 + two_digits


GPS_WEEK_ROLLOVER = timedelta(weeks=1024)
DATE_TOLERANCE = timedelta(days=1, hours=12)
"""How far an RMC date may stand from the ground clock: a day either side (time zones of a fix taken
near midnight, a clock a little off), half a day more for the fix's own age."""


def date_problem(day: date, now: datetime) -> str | None:
    """Why an RMC date cannot be the fix's date, judged against the ground clock; None when plausible.

    A date a whole number of 1024-week GPS epochs behind the clock (± 2 days) is the receiver's week
    rollover, said as such so the team knows to update its firmware; any other date far from the clock
    is named with its distance. Either way the date is left out and the fix time falls back to the time
    of day nearest the clock.
    """
    noon = datetime.combine(day, time(12), tzinfo=UTC)
    gap = noon - now.astimezone(UTC)
    if abs(gap) <= DATE_TOLERANCE:
        return None
    epochs = round(-gap / GPS_WEEK_ROLLOVER)
    if epochs >= 1 and abs(-gap - epochs * GPS_WEEK_ROLLOVER) <= timedelta(days=2):
        return (
            f"RMC date {day.isoformat()} is {epochs}×1024 weeks behind the clock: the receiver's GPS week "
            f"rollover (update its firmware); date ignored"
        )
    direction = "ahead of" if gap > timedelta(0) else "behind"
    return f"RMC date {day.isoformat()} is {abs(gap.days)} days {direction} the clock; date ignored"


def _date(text: str) -> date | None:
    if not text:
        return None
    if len(text) != 6 or not text.isdigit():
        raise _Malformed
    day, month, year = int(text[0:2]), int(text[2:4]), _century(int(text[4:6]))
    try:
        return date(year, month, day)
    except ValueError:
        raise _Malformed from None


def _float(text: str) -> float | None:
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise _Malformed from None
    if value != value or value in (float("inf"), float("-inf")):
        raise _Malformed
    return value


def _int(text: str) -> int | None:
    if not text:
        return None
    if not text.isdigit():
        raise _Malformed
    return int(text)


def _coordinate(value: str, hemisphere: str, degree_digits: int) -> float | None:
    """ddmm.mmmm (or dddmm.mmmm) plus N/S/E/W to signed decimal degrees."""
    if not value and not hemisphere:
        return None
    if hemisphere not in ("N", "S", "E", "W") or len(value) < degree_digits + 2:
        raise _Malformed
    if (hemisphere in ("N", "S")) != (degree_digits == 2):
        raise _Malformed
    degrees = _int(value[:degree_digits])
    minutes = _float(value[degree_digits:])
    if degrees is None or minutes is None or not 0 <= minutes < 60:
        raise _Malformed
    decimal = degrees + minutes / 60.0
    if decimal > (90.0 if degree_digits == 2 else 180.0):
        raise _Malformed
    return -decimal if hemisphere in ("S", "W") else decimal


def _parse_gga(talker: str, fields: list[str]) -> GgaSentence:
    if len(fields) < 15:
        raise _Malformed
    quality = _int(fields[6])
    satellites, altitude = _int(fields[7]), _float(fields[9])
    if satellites is not None and satellites > MAX_SATELLITES:
        raise _Malformed
    if altitude is not None and not ALTITUDE_RANGE_M[0] <= altitude <= ALTITUDE_RANGE_M[1]:
        raise _Malformed
    return GgaSentence(
        talker=talker,
        time_utc=_time(fields[1]),
        latitude=_coordinate(fields[2], fields[3], 2),
        longitude=_coordinate(fields[4], fields[5], 3),
        fix_quality=quality if quality is not None else 0,
        satellites=satellites,
        hdop=_float(fields[8]),
        altitude_m=altitude,
    )


def _parse_rmc(talker: str, fields: list[str]) -> RmcSentence:
    if len(fields) < 12 or fields[2] not in ("A", "V"):
        raise _Malformed
    return RmcSentence(
        talker=talker,
        time_utc=_time(fields[1]),
        valid=fields[2] == "A",
        latitude=_coordinate(fields[3], fields[4], 2),
        longitude=_coordinate(fields[5], fields[6], 3),
        speed_knots=_float(fields[7]),
        course_deg=_float(fields[8]),
        date_utc=_date(fields[9]),
    )


def parse_sentence(line: str) -> GgaSentence | RmcSentence | None | str:
    """One line → a sentence, ``None`` for a valid sentence we ignore, or a reason string.

    The reason is ``"malformed"`` or ``"bad_checksum"``; returning it instead of raising keeps
    the one promise of this module (bad input is never fatal) visible in the signature.
    """
    try:
        fields = _split_checked(line)
        address = fields[0]
        if len(address) != 5 or not address.isalpha():
            raise _Malformed
        talker, kind = address[:2], address[2:]
        if kind not in ("GGA", "RMC"):
            return None
        if talker not in TALKERS:
            return None
        return _parse_gga(talker, fields) if kind == "GGA" else _parse_rmc(talker, fields)
    except _BadChecksum:
        return "bad_checksum"
    except (_Malformed, ValueError, IndexError, OverflowError):
        return "malformed"


def find_sentence(line: str) -> str | None:
    """The NMEA sentence in a noisy line: from its last ``$``, or None when there is none.

    Receivers on a shared serial line (u-blox in mixed UBX/NMEA mode) put binary bytes before the ``$``;
    the checksum then decides whether what follows is a sentence. Every reader of NMEA here (the capsule's
    GNSS log and the balloon feed) finds it this way.
    """
    start = line.rfind("$")
    return None if start < 0 else line[start:]


def summarise(lines: Iterable[str], now: datetime) -> GnssStatus:
    """Fold a log (oldest line first) into the latest GNSS state; ``now`` gives the fix age."""
    counts = NmeaCounts()
    latest_gga: GgaSentence | None = None
    latest_date: date | None = None
    rejected_date: str | None = None
    for raw in lines:
        line = raw.strip()
        if not line:
            continue
        sentence = find_sentence(line)
        if sentence is None:
            counts = replace(counts, malformed=counts.malformed + 1)
            continue
        result = parse_sentence(sentence)
        if result == "malformed":
            counts = replace(counts, malformed=counts.malformed + 1)
        elif result == "bad_checksum":
            counts = replace(counts, bad_checksum=counts.bad_checksum + 1)
        elif result is None:
            counts = replace(counts, ignored=counts.ignored + 1)
        else:
            counts = replace(counts, parsed=counts.parsed + 1)
            if isinstance(result, GgaSentence):
                latest_gga = result
            elif isinstance(result, RmcSentence) and result.date_utc is not None:
                problem = date_problem(result.date_utc, now)
                if problem is None:
                    latest_date = result.date_utc
                else:
                    rejected_date = problem
    if latest_gga is None:
        return GnssStatus(
            nmea_seen=counts.parsed > 0,
            fix_quality=None,
            has_fix=False,
            satellites=None,
            hdop=None,
            latitude=None,
            longitude=None,
            altitude_m=None,
            fix_time_utc=None,
            age_s=None,
            counts=counts,
            date_problem=rejected_date,
        )
    fix_time = _fix_datetime(latest_gga.time_utc, latest_date, now)
    age = (now - fix_time).total_seconds() if fix_time is not None else None
    has_fix = latest_gga.fix_quality > 0 and latest_gga.latitude is not None
    return GnssStatus(
        nmea_seen=True,
        fix_quality=latest_gga.fix_quality,
        has_fix=has_fix,
        satellites=latest_gga.satellites,
        hdop=latest_gga.hdop,
        latitude=latest_gga.latitude,
        longitude=latest_gga.longitude,
        altitude_m=latest_gga.altitude_m,
        fix_time_utc=fix_time,
        age_s=age,
        counts=counts,
        date_problem=rejected_date,
    )


def _fix_datetime(moment: time | None, day: date | None, now: datetime) -> datetime | None:
    """GGA carries no date: take RMC's, else the date that puts the fix nearest before ``now``."""
    if moment is None:
        return None
    naive = moment.replace(tzinfo=None)
    if day is not None:
        return datetime.combine(day, naive, tzinfo=UTC)
    candidate = datetime.combine(now.astimezone(UTC).date(), naive, tzinfo=UTC)
    if candidate - now > timedelta(hours=12):
        candidate -= timedelta(days=1)
    return candidate


def nearest_datetime(moment: time, now: datetime) -> datetime:
    """A UTC time of day (GGA and the ground-station formats carry no date) as the instant nearest ``now``.

    A live feed's clock and ours disagree by seconds, so around midnight a fix may fall on either side
    of the date change: yesterday, today and tomorrow are all candidates.
    """
    naive = moment.replace(tzinfo=None)
    today = datetime.combine(now.astimezone(UTC).date(), naive, tzinfo=UTC)
    candidates = (today + timedelta(days=days) for days in (-1, 0, 1))
    return min(candidates, key=lambda candidate: abs(candidate - now))


def format_gga(
    moment: datetime,
    latitude: float | None,
    longitude: float | None,
    fix_quality: int,
    satellites: int,
    hdop: float | None,
    altitude_m: float | None,
    talker: str = "GP",
) -> str:
    """A checksummed GGA line, as the u-blox receiver sends it (used by the simulator and tests)."""
    body = ",".join(
        [
            f"{talker}GGA",
            moment.strftime("%H%M%S.00"),
            *_format_coordinate(latitude, 2, "NS"),
            *_format_coordinate(longitude, 3, "EW"),
            str(fix_quality),
            f"{satellites:02d}",
            f"{hdop:.2f}" if hdop is not None else "99.99",
            f"{altitude_m:.1f}" if altitude_m is not None else "",
            "M" if altitude_m is not None else "",
            "47.0" if latitude is not None else "",
            "M" if latitude is not None else "",
            "",
            "",
        ]
    )
    return f"${body}*{nmea_checksum(body):02X}"


def format_rmc(moment: datetime, latitude: float | None, longitude: float | None, talker: str = "GP") -> str:
    """A checksummed RMC line (status V without a position)."""
    valid = latitude is not None and longitude is not None
    body = ",".join(
        [
            f"{talker}RMC",
            moment.strftime("%H%M%S.00"),
            "A" if valid else "V",
            *_format_coordinate(latitude, 2, "NS"),
            *_format_coordinate(longitude, 3, "EW"),
            "0.011" if valid else "",
            "",
            moment.strftime("%d%m%y"),
            "",
            "",
            "A" if valid else "N",
        ]
    )
    return f"${body}*{nmea_checksum(body):02X}"


def _format_coordinate(value: float | None, degree_digits: int, hemispheres: str) -> list[str]:
    if value is None:
        return ["", ""]
    hemisphere = hemispheres[0] if value >= 0 else hemispheres[1]
    magnitude = abs(value)
    degrees = int(magnitude)
    minutes = round((magnitude - degrees) * 60.0, 5)
    if minutes >= 60.0:
        degrees, minutes = degrees + 1, 0.0
    return [f"{degrees:0{degree_digits}d}{minutes:08.5f}", hemisphere]
