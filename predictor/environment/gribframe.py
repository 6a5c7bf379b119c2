"""A GRIB file's framing read in Python, byte by byte, before eccodes is handed a single message.

Why: eccodes trusts the lengths and packing a header states. A section 7 length of 4,294,967,295, a
bits-per-value of 1, 31, 32, 33 or 64 against a data section sized for another, killed `drs predict`
and `drs weather info` in native code (SIGSEGV, glibc heap corruption: no message, exit 139 or 134),
and a section 5 length of 0 made eccodes loop for ever (issue #31 item 1). Python reads the same bytes
without any of those outcomes, so every length is checked here against the message, the file and the
other sections, and the packing against the data section it must fit in and the grid it covers.

What is checked, per message (GRIB2; GRIB1 gets its section lengths and bits per value):
- the indicator: "GRIB", edition 1 or 2, a total length that fits the file and ends in "7777";
- every section: a length of at least its fixed part, inside the message, numbered in GRIB2's order
  (1, 2?, 3, 4, 5, 6, 7, then again from 2, 3 or 4), with the sections' lengths adding up exactly to
  the message;
- section 5: a packing template this reader knows; bits per value within the template's limits (at most
  ``MAX_BITS_PER_VALUE``); for simple packing, section 7 at least as long as the values need;
- section 6: a bitmap exactly as long as section 3's grid needs, with as many points set as section 5
  says it packs; without a bitmap, section 5 packs one value per grid point.

Nothing here allocates from a header value beyond one section (a bitmap is at most ``MAX_GRID_POINTS``
bits), and every refusal is a ``WeatherFileError`` naming the file, the message and the fault.
"""

from __future__ import annotations

import mmap
import struct
from dataclasses import dataclass
from pathlib import Path

from predictor.errors import WeatherFileError

MAX_GRID_POINTS = 10_000_000
"""More points than any weather product the predictor reads holds in one field (ECMWF's 0.1° globe has
6.5 million, GFS 0.25° 1.04 million); one such field decodes to 80 MB."""

MAX_BITS_PER_VALUE = 32
"""No weather centre packs a field in more than 32 bits (GFS uses 0–24; ECMWF at most 24 in GRIB2 and
32 in IEEE). eccodes' simple-packing decoder reads up to 64 but shifts by the full width at 64, and a
width that disagrees with section 7 was read past its end; above 32 nothing real is lost by refusing."""

SIMPLE_PACKING = 0
BITS_TEMPLATES = frozenset({0, 2, 3, 40, 41, 42})
"""GRIB2 section 5 templates whose octet 20 is the bits per value: simple (0), complex (2), complex with
spatial differencing (3, GFS), JPEG 2000 (40, GFS), PNG (41), CCSDS (42, ECMWF)."""
IEEE_PACKING = 4
IEEE_BYTES = {1: 4, 2: 8}
"""Template 5.4's precision code → bytes per value (code 3, 128 bits, eccodes cannot decode)."""
KNOWN_TEMPLATES = BITS_TEMPLATES | {IEEE_PACKING}

_FIXED_LENGTH = {1: 21, 2: 5, 3: 14, 4: 9, 5: 11, 6: 6, 7: 5}
"""The fixed part of each GRIB2 section in octets (5 of them for the length and number): a shorter
section cannot hold the fields every reader takes from it."""
_NEXT_SECTIONS = {0: {1}, 1: {2, 3}, 2: {3}, 3: {4}, 4: {5}, 5: {6}, 6: {7}, 7: {2, 3, 4, 8}}
"""Which section may follow which in a GRIB2 message (8 is the end marker "7777")."""


@dataclass
class _Message:
    """What the checks of later sections need from earlier ones of the same message."""

    where: str
    points: int | None = None
    packed: int | None = None
    template: int | None = None
    bits: int | None = None
    ieee_bytes: int | None = None
    bitmap_set: int | None = None
    """Points a bitmap of this message marks present (kept for a later "bitmap as before", code 254)."""
    field_bitmap: int | None = None
    """Points the current field's bitmap marks present, or None: no bitmap (every point has a value)."""


def check_grib_framing(path: str | Path) -> int:
    """Check every message's framing and packing; return the number of messages, or raise
    WeatherFileError naming the file, the message and what is wrong with it."""
    file = Path(path)
    try:
        with open(file, "rb") as stream:
            size = _regular_size(file, stream.fileno())
            if size == 0:
                raise WeatherFileError(file, "empty, not a GRIB file")
            with mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as data:
                return _walk(file, data, size)
    except OSError as exc:
        raise WeatherFileError(file, f"cannot be read ({exc.strerror or exc})") from exc


def _regular_size(file: Path, fd: int) -> int:
    import os
    import stat

    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        raise WeatherFileError(file, "not a regular file (a device, FIFO or directory); give a GRIB file")
    return info.st_size


def _walk(file: Path, data: mmap.mmap, size: int) -> int:
    count = 0
    offset = data.find(b"GRIB", 0)
    if offset < 0:
        raise WeatherFileError(
            file,
            "not a GRIB file (no GRIB messages in it)",
            said=f"{file} is not a GRIB file (no GRIB messages in it)",
        )
    while offset >= 0:
        count += 1
        where = f"GRIB message {count}"
        if size - offset < 16:
            raise WeatherFileError(
                file, f"{where} is truncated or corrupt: the file ends {size - offset} bytes after its start "
                f"at byte {offset:,}; download the file again",
            )  # fmt: skip
        edition = data[offset + 7]
        if edition == 2:
            length = struct.unpack_from(">Q", data, offset + 8)[0]
            _check_total(file, where, length, 16 + 4, offset, size, data)
            _check_grib2(file, where, data, offset, length)
        elif edition == 1:
            length = _grib1_total_length(data, offset)
            _check_total(file, where, length, 8 + 28 + 11 + 4, offset, size, data)
            _check_grib1(file, where, data, offset, length)
        else:
            raise WeatherFileError(file, f"{where} says GRIB edition {edition}; only editions 1 and 2 exist")
        offset = data.find(b"GRIB", offset + length)
    return count


def _check_total(
    file: Path, where: str, length: int, least: int, offset: int, size: int, data: mmap.mmap
) -> None:
    if length < least:
        raise WeatherFileError(
            file, f"{where} says it is {length:,} bytes long, shorter than any GRIB message"
        )
    if offset + length > size:
        raise WeatherFileError(
            file, f"{where} is truncated or corrupt: it says it is {length:,} bytes long but the file has "
            f"{size - offset:,} from its start at byte {offset:,}; download the file again",
        )  # fmt: skip
    if data[offset + length - 4 : offset + length] != b"7777":
        raise WeatherFileError(file, f"{where} does not end in 7777 where its length says it ends; damaged")


def _check_grib2(file: Path, where: str, data: mmap.mmap, start: int, length: int) -> None:
    end = start + length - 4  # the "7777"
    offset = start + 16
    previous = 0
    message = _Message(where)
    while offset < end:
        if end - offset < 5:
            raise WeatherFileError(file, f"{where}: {end - offset} stray bytes before 7777; damaged")
        section_length, number = struct.unpack_from(">IB", data, offset)
        if number not in _NEXT_SECTIONS.get(previous, set()):
            raise WeatherFileError(
                file, f"{where}: section {number} where section {_expected(previous)} must come; damaged"
            )
        if section_length < _FIXED_LENGTH[number]:
            raise WeatherFileError(
                file, f"{where}: section {number} says it is {section_length:,} bytes long, shorter than its "
                f"fixed {_FIXED_LENGTH[number]}; damaged",
            )  # fmt: skip
        if offset + section_length > end:
            raise WeatherFileError(
                file, f"{where}: section {number} says it is {section_length:,} bytes long but the message "
                f"has {end - offset:,} left; damaged",
            )  # fmt: skip
        _check_section(file, message, number, data, offset, section_length)
        previous = number
        offset += section_length
    if previous != 7:
        raise WeatherFileError(file, f"{where} ends after section {previous}, not after a data section 7")


def _expected(previous: int) -> str:
    return " or ".join(str(n) if n != 8 else "7777" for n in sorted(_NEXT_SECTIONS[previous]))


def _check_section(file: Path, message: _Message, number: int, data: mmap.mmap, at: int, length: int) -> None:
    where = message.where
    if number == 3:
        message.points = struct.unpack_from(">I", data, at + 6)[0]
        if message.points > MAX_GRID_POINTS:
            raise WeatherFileError(
                file,
                f"{where}: {message.points:,} grid points is implausible (more than {MAX_GRID_POINTS:,})",
            )
    elif number == 5:
        _check_packing(file, message, data, at)
    elif number == 6:
        _check_bitmap(file, message, data, at, length)
    elif number == 7:
        _check_data(file, message, length)


def _check_packing(file: Path, message: _Message, data: mmap.mmap, at: int) -> None:
    where = message.where
    message.packed, message.template = struct.unpack_from(">IH", data, at + 5)
    if message.points is None:
        raise WeatherFileError(file, f"{where}: section 5 before any grid (section 3); damaged")
    if message.packed > message.points:
        raise WeatherFileError(
            file, f"{where} packs {message.packed:,} values for {message.points:,} points; damaged"
        )
    message.bits = message.ieee_bytes = None
    if message.template in BITS_TEMPLATES:
        if at + 20 > len(data):
            raise WeatherFileError(file, f"{where}: section 5 is too short for its template; damaged")
        message.bits = data[at + 19]
        if message.bits > MAX_BITS_PER_VALUE:
            raise WeatherFileError(
                file, f"{where}: section 5 says {message.bits} bits per value (packing template "
                f"{message.template} allows 0–{MAX_BITS_PER_VALUE}); damaged",
            )  # fmt: skip
    elif message.template == IEEE_PACKING:
        precision = data[at + 11]
        if precision not in IEEE_BYTES:
            raise WeatherFileError(
                file, f"{where}: IEEE packing of precision code {precision} is not readable"
            )
        message.ieee_bytes = IEEE_BYTES[precision]
    else:
        raise WeatherFileError(
            file, f"{where}: packing template 5.{message.template} is not one this reader decodes "
            f"(known: {', '.join(str(t) for t in sorted(KNOWN_TEMPLATES))})",
        )  # fmt: skip


def _check_bitmap(file: Path, message: _Message, data: mmap.mmap, at: int, length: int) -> None:
    where = message.where
    indicator = data[at + 5]
    if message.points is None or message.packed is None:
        raise WeatherFileError(file, f"{where}: section 6 before a grid and a packing; damaged")
    if indicator == 255:
        message.field_bitmap = None
        present = message.points
    elif indicator == 0:
        need = (message.points + 7) // 8
        if length - 6 != need:
            raise WeatherFileError(
                file, f"{where}: the bitmap has {length - 6:,} bytes for {message.points:,} points "
                f"({need:,} needed); damaged",
            )  # fmt: skip
        bits = int.from_bytes(data[at + 6 : at + 6 + need], "big") >> (need * 8 - message.points)
        message.bitmap_set = message.field_bitmap = present = bits.bit_count()
    elif indicator == 254:
        if message.bitmap_set is None:
            raise WeatherFileError(file, f"{where}: 'the bitmap as before' with no bitmap before it; damaged")
        message.field_bitmap = present = message.bitmap_set
    else:
        raise WeatherFileError(file, f"{where}: predefined bitmap {indicator} is not one this reader knows")
    if present != message.packed:
        raise WeatherFileError(
            file, f"{where}: section 5 packs {message.packed:,} values but the bitmap marks {present:,} of "
            f"{message.points:,} points; damaged",
        )  # fmt: skip


def _check_data(file: Path, message: _Message, length: int) -> None:
    """Section 7 holds at least what the packing needs (exactly checkable for simple and IEEE packing;
    compressed data at least its own header)."""
    payload = length - 5
    packed = message.packed or 0
    if message.template == SIMPLE_PACKING and message.bits is not None:
        need = (packed * message.bits + 7) // 8
    elif message.ieee_bytes is not None:
        need = packed * message.ieee_bytes
    else:
        need = 1 if packed and message.bits else 0
    if payload < need:
        raise WeatherFileError(
            file, f"{message.where}: section 7 holds {payload:,} bytes of data but {packed:,} values of "
            f"{message.bits if message.bits is not None else 8 * (message.ieee_bytes or 0)} bits need "
            f"{need:,}; damaged",
        )  # fmt: skip


# GRIB1: the indicator, then the product (PDS), optional grid (GDS) and bitmap (BMS) sections, the
# binary data (BDS) and "7777"; lengths are 3 octets.

_GRIB1_LARGE = 0x800000


def _grib1_total_length(data: mmap.mmap, offset: int) -> int:
    """GRIB1's 3-octet total length; ECMWF writes messages over 8 MB with the top bit set and the length
    in units of 120 bytes (eccodes' convention), the true length then found from the BDS."""
    length = int.from_bytes(data[offset + 4 : offset + 7], "big")
    if length & _GRIB1_LARGE:
        return (length & (_GRIB1_LARGE - 1)) * 120
    return length


def _check_grib1(file: Path, where: str, data: mmap.mmap, start: int, length: int) -> None:
    end = start + length - 4
    offset = start + 8
    flags = 0
    names = ["product (PDS)", "grid (GDS)", "bitmap (BMS)", "data (BDS)"]
    for index, name in enumerate(names):
        if index == 0:
            minimum = 28
        elif index == 1:
            if not flags & 0x80:
                continue
            minimum = 32
        elif index == 2:
            if not flags & 0x40:
                continue
            minimum = 6
        else:
            minimum = 11
        if end - offset < 3:
            raise WeatherFileError(file, f"{where}: no room for its {name} section; damaged")
        section_length = int.from_bytes(data[offset : offset + 3], "big")
        if section_length < minimum or offset + section_length > end:
            raise WeatherFileError(
                file, f"{where}: the {name} section says it is {section_length:,} bytes long "
                f"({end - offset:,} left in the message, at least {minimum} needed); damaged",
            )  # fmt: skip
        if index == 0:
            flags = data[offset + 7]
        if index == 3:
            bits = data[offset + 10]
            if bits > MAX_BITS_PER_VALUE:
                raise WeatherFileError(
                    file, f"{where}: the data section says {bits} bits per value "
                    f"(at most {MAX_BITS_PER_VALUE}); damaged",
                )  # fmt: skip
        offset += section_length
