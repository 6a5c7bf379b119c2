"""The GRIB2 mutants that killed `drs predict` and `drs weather info` in native code or hung them (issue #31
item 1), generated deterministically from two small files eccodes writes, and a seeded fuzzer for new ones.

Two bases: ``ieee`` is the project's own writer (template 5.4, 32-bit IEEE; the issue's "bits per value" byte,
octet 20 of section 5, is there the second byte of section 7's length), ``simple`` the same fields re-packed
by eccodes with simple packing at 16 bits (octet 20 is then the real bits per value).
"""

from __future__ import annotations

import random
import struct
from datetime import datetime
from pathlib import Path

import numpy as np

SECTIONS = {"ieee": {5: 143, 6: 155, 7: 161}, "simple": {5: 143, 6: 164, 7: 170}}
"""Where sections 5, 6 and 7 start in each base's messages (checked when written)."""


def write_bases(folder: Path) -> dict[str, bytes]:
    import predictor.environment.native_libs  # noqa: F401

    # isort: split
    import eccodes

    from predictor.environment.gribwrite import write_gfs_grib2

    ramp = np.linspace(0.0, 1.0, 30).reshape(5, 6)
    ieee = folder / "ieee.grib2"
    write_gfs_grib2(
        ieee, datetime(2026, 7, 1, 6), 3, [500.0, 250.0], np.linspace(45.0, 47.0, 5), np.linspace(6.0, 8.5, 6),
        np.stack([10 + ramp, 20 + ramp]), np.stack([-3 + ramp, -4 + ramp]), np.stack([250 + ramp, 220 + ramp]),
        np.stack([5500 + 10 * ramp, 10300 + 10 * ramp]),
    )  # fmt: skip
    simple = bytearray()
    with open(ieee, "rb") as stream:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            values = eccodes.codes_get_values(handle)
            eccodes.codes_set(handle, "packingType", "grid_simple")
            eccodes.codes_set(handle, "bitsPerValue", 16)
            eccodes.codes_set_values(handle, values)
            simple += eccodes.codes_get_message(handle)
            eccodes.codes_release(handle)
    bases = {"ieee": ieee.read_bytes(), "simple": bytes(simple)}
    for name, data in bases.items():
        at = SECTIONS[name]
        assert len(data) % 8 == 0 and data[at[7] + 4] == 7 and data[at[5] + 4] == 5, name
    return bases


def _every(base: bytes, offset_in_message: int, value: bytes) -> bytes:
    out = bytearray(base)
    size = len(base) // 8
    for message in range(8):
        at = message * size + offset_in_message
        out[at : at + len(value)] = value
    return bytes(out)


def issue_mutants(bases: dict[str, bytes]) -> dict[str, bytes]:
    """The issue's triggers on both bases: bits per value 1, 31, 32, 33, 64; section 7 lengths 8722,
    3,154,189,911 and 4,294,967,295; a section 5 length of 0."""
    out = {}
    for name, base in bases.items():
        at = SECTIONS[name]
        for bits in (1, 31, 32, 33, 64):
            out[f"{name}-bits-per-value-{bits}"] = _every(base, at[5] + 19, bytes([bits]))
        for length in (8722, 3_154_189_911, 4_294_967_295):
            out[f"{name}-section-7-length-{length}"] = _every(base, at[7], struct.pack(">I", length))
        out[f"{name}-section-5-length-0"] = _every(base, at[5], struct.pack(">I", 0))
    return out


def fuzz_mutants(bases: dict[str, bytes], seed: int, count: int) -> dict[str, bytes]:
    """``count`` new mutants from ``seed``: a section length, octet 20 of section 5 or any byte of the
    first message's sections 3–7, set to a value drawn from the edges where readers break."""
    rng = random.Random(seed)
    edges = [0, 1, 2, 5, 7, 8, 15, 16, 31, 32, 33, 63, 64, 127, 128, 254, 255]
    out = {}
    for index in range(count):
        name = rng.choice(sorted(bases))
        base = bytearray(bases[name])
        at = SECTIONS[name]
        kind = rng.choice(("length", "bits", "byte", "byte"))
        if kind == "length":
            section = rng.choice(sorted(at))
            value = rng.choice(
                [0, 1, 4, 5, 6, 11, 2**31, 2**32 - 1, rng.randrange(2**32), rng.randrange(300)]
            )
            base[at[section] : at[section] + 4] = struct.pack(">I", value)
        elif kind == "bits":
            base[at[5] + 19] = rng.choice(edges)
        else:
            base[rng.randrange(37, at[7] + 8)] = rng.choice(edges + [rng.randrange(256)])
        out[f"fuzz-{seed}-{index}-{name}-{kind}"] = bytes(base)
    return out
