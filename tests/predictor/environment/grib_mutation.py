"""Damaged copies of one small GRIB2 file, for the fuzz test of the GRIB readers (issue #24 item 2).

How they were chosen: ``base.grib2`` is written by the project's eccodes writer (2 levels of u, v, t,
gh on a 6×5 grid, 8 messages of 290 bytes). Each mutant damages one thing the readers trust: every
header field an attack on the probe used (the grid's Ni and Nj, the dates, the message and section
lengths, the packing), the values (NaN, infinity), a cut, and ten single-byte flips at offsets drawn
from a fixed seed. The mutants are committed (``grib_mutants/``) so the test does not depend on this
generator; ``python -m tests.predictor.environment.grib_mutation`` writes them again, identically.
"""

from __future__ import annotations

import random
import struct
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

import numpy as np

FOLDER = Path(__file__).parent / "grib_mutants"
MESSAGE = 290
"""Bytes per message of the base file (checked when it is written)."""
SECTION_AT = {0: 0, 1: 16, 3: 37, 4: 109, 5: 143, 6: 155, 7: 161}
"""Where each section of a base message starts, in bytes from the message's start."""


CAP_BYTES = 1536 * 2**20
CHILD = """
import json, resource, sys, tempfile
from pathlib import Path
resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[1]), int(sys.argv[1])))
from predictor.environment.weather import load_weather
from predictor.errors import WeatherError
cache = tempfile.mkdtemp()
for file in sorted(Path(sys.argv[2]).glob("*.grib2")):
    try:
        load_weather([file], (45.5, 46.5, 6.5, 8.0), cache_dir=cache)
        answer = {"file": file.name, "outcome": "read"}
    except WeatherError as exc:
        answer = {"file": file.name, "outcome": "refused", "message": str(exc)}
    except BaseException as exc:
        answer = {"file": file.name, "outcome": "crashed", "message": f"{type(exc).__name__}: {exc}"}
    print(json.dumps(answer), flush=True)
"""
"""The caller every fuzz test loads its mutants in: `load_weather` on each file of a folder under an address-space
cap of ``CAP_BYTES``, one JSON answer per file (read, refused with its message, or crashed)."""


def write_base(path: Path) -> bytes:
    from predictor.environment.gribwrite import write_gfs_grib2

    shape = (2, 5, 6)
    layer = [np.full(shape[1:], value) for value in (250.0, 220.0)]
    height = [np.full(shape[1:], value) for value in (5_500.0, 10_300.0)]
    write_gfs_grib2(
        path, datetime(2026, 7, 1, 6), 3, [500.0, 250.0],
        np.linspace(45.0, 47.0, 5), np.linspace(6.0, 8.5, 6),
        np.full(shape, 10.0), np.full(shape, -3.0), np.stack(layer), np.stack(height),
    )  # fmt: skip
    data = path.read_bytes()
    assert len(data) == 8 * MESSAGE, "the section offsets above are for this layout"
    return data


def _put(data: bytes, offsets: list[int], value: bytes) -> bytes:
    out = bytearray(data)
    for offset in offsets:
        out[offset : offset + len(value)] = value
    return bytes(out)


def _first(section: int, octet: int) -> list[int]:
    """The 0-based offset in the file of a (1-based, as the GRIB2 tables number them) octet of the first
    message's section."""
    return [SECTION_AT[section] + octet - 1]


def _every(section: int, octet: int) -> list[int]:
    return [m * MESSAGE + SECTION_AT[section] + octet - 1 for m in range(8)]


def mutants(base: bytes) -> dict[str, bytes]:
    u32 = struct.Struct(">I").pack
    u16 = struct.Struct(">H").pack
    f32 = struct.Struct(">f").pack
    edits: dict[str, Callable[[bytes], bytes]] = {
        "ni-2386165793": lambda d: _put(d, _first(3, 31), u32(2_386_165_793)),
        "ni-2386165793-every-message": lambda d: _put(d, _every(3, 31), u32(2_386_165_793)),
        "nj-4000000000-every-message": lambda d: _put(d, _every(3, 35), u32(4_000_000_000)),
        "ni-100000-nj-100000": lambda d: _put(
            _put(d, _every(3, 31), u32(100_000)), _every(3, 35), u32(100_000)
        ),
        "ni-0": lambda d: _put(d, _every(3, 31), u32(0)),
        "ni-7-every-message": lambda d: _put(d, _every(3, 31), u32(7)),
        "data-points-huge": lambda d: _put(d, _every(3, 7), u32(3_000_000_000)),
        "values-count-huge": lambda d: _put(d, _every(5, 6), u32(3_000_000_000)),
        "year-0": lambda d: _put(d, _first(1, 13), u16(0)),
        "year-65535": lambda d: _put(d, _every(1, 13), u16(65_535)),
        "month-13": lambda d: _put(d, _every(1, 15), bytes([13])),
        "day-0": lambda d: _put(d, _every(1, 16), bytes([0])),
        "hour-99": lambda d: _put(d, _every(1, 17), bytes([99])),
        "minute-250": lambda d: _put(d, _every(1, 18), bytes([250])),
        "forecast-time-huge": lambda d: _put(d, _every(4, 19), u32(4_000_000_000)),
        "total-length-huge": lambda d: _put(d, [8], struct.pack(">Q", 2**62)),
        "total-length-short": lambda d: _put(d, [8], struct.pack(">Q", 100)),
        "section-3-length-huge": lambda d: _put(d, _first(3, 1), u32(0xFFFFFFF0)),
        "section-7-length-short": lambda d: _put(d, _first(7, 1), u32(9)),
        "edition-9": lambda d: _put(d, [7], bytes([9])),
        "latitude-first-900": lambda d: _put(d, _every(3, 47), u32(900_000_000)),
        "increment-0": lambda d: _put(d, _every(3, 64), u32(0)),
        "scanning-westward": lambda d: _put(d, _every(3, 72), bytes([0x80])),
        "packing-template-unknown": lambda d: _put(d, _every(5, 10), u16(0xFFFE)),
        "values-nan": lambda d: _put(d, [SECTION_AT[7] + 5 + 4 * k for k in range(30)], f32(float("nan"))),
        "values-infinity": lambda d: _put(d, [SECTION_AT[7] + 5], f32(float("inf"))),
        "cut-mid-message": lambda d: d[: 3 * MESSAGE + 120],
        "magic-broken": lambda d: _put(d, [0], b"GRIX"),
    }
    out = {name: edit(base) for name, edit in edits.items()}
    rng = random.Random(24)
    for index in range(10):
        offset = rng.randrange(len(base))
        flipped = bytearray(base)
        flipped[offset] ^= 1 << rng.randrange(8)
        out[f"flip-{index}-at-{offset}"] = bytes(flipped)
    return out


def main() -> None:
    FOLDER.mkdir(exist_ok=True)
    for old in FOLDER.glob("*.grib2"):
        old.unlink()
    base = write_base(FOLDER / "base.grib2")
    for name, data in mutants(base).items():
        (FOLDER / f"{name}.grib2").write_bytes(data)


if __name__ == "__main__":
    main()
