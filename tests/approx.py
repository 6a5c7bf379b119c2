"""A regenerated artefact against its committed copy, with a stated tolerance instead of bit for bit.

Why a tolerance at all: the artefacts are deterministic, but numpy's reductions (sums, means, medians
over SIMD lanes) and libm differ between CPUs and builds in the last bit, so a float written on one
machine is regenerated 1–3 units of its 17th significant digit away on the next (``log_sigma``
0.14798773985965155 against …52, issue 31). A value the code rounds before writing can then flip by
one unit of its rounding when it lies on the boundary.

The one rule, for numbers in a structure and in a report alike: equal within one unit of the committed
value's last written digit, or within ``REL`` of it, whichever is larger. ``REL`` = 1e-9 leaves six
orders of magnitude above the ~1e-15 that a different summation order makes, while any real change of
a measurement (the data, the estimator, a term of the law) moves its 3rd–5th digit and still fails.
Everything that is not a float (counts, names, flags, the words of a report) stays exact.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

REL = 1e-9
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def last_digit_unit(written: str) -> float:
    """One unit of the last digit as written: '3.83' → 0.01, '194' → 1, '1.5e-3' → 1e-4."""
    mantissa, _, exponent = written.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def numbers_close(actual: float, committed: float, written: str | None = None) -> bool:
    unit = last_digit_unit(written if written is not None else repr(float(committed)))
    if math.isnan(committed) or math.isinf(committed):
        return actual == committed or (math.isnan(actual) and math.isnan(committed))
    return abs(actual - committed) <= max(unit, REL * abs(committed)) * (1 + 1e-12)


def assert_close(actual: Any, committed: Any, where: str = "") -> None:
    """Dataclasses, mappings and sequences field by field; floats by the rule above, the rest exactly."""
    if dataclasses.is_dataclass(committed) and not isinstance(committed, type):
        assert type(actual) is type(committed), (
            f"{where}: {type(actual).__name__} != {type(committed).__name__}"
        )
        for field in dataclasses.fields(committed):
            assert_close(getattr(actual, field.name), getattr(committed, field.name), f"{where}.{field.name}")
    elif isinstance(committed, dict):
        assert isinstance(actual, dict) and actual.keys() == committed.keys(), f"{where}: keys differ"
        for key, value in committed.items():
            assert_close(actual[key], value, f"{where}[{key!r}]")
    elif isinstance(committed, list | tuple):
        assert isinstance(actual, list | tuple) and len(actual) == len(committed), f"{where}: lengths differ"
        for i, (a, c) in enumerate(zip(actual, committed, strict=True)):
            assert_close(a, c, f"{where}[{i}]")
    elif isinstance(committed, float) and isinstance(actual, int | float) and not isinstance(actual, bool):
        assert numbers_close(float(actual), committed), f"{where}: {actual!r} is not {committed!r}"
    else:
        assert actual == committed, f"{where}: {actual!r} != {committed!r}"


def assert_text_close(actual: str, committed: str) -> None:
    """A report's words exactly, its numbers by the rule above (the unit of each as it is written)."""
    actual_words, committed_words = _NUMBER.split(actual), _NUMBER.split(committed)
    actual_numbers, committed_numbers = _NUMBER.findall(actual), _NUMBER.findall(committed)
    if actual_words != committed_words or len(actual_numbers) != len(committed_numbers):
        assert actual == committed  # not only numbers differ: show pytest's diff of the two texts
    for index, (a, c) in enumerate(zip(actual_numbers, committed_numbers, strict=True)):
        assert numbers_close(float(a), float(c), c), f"number #{index}: {a} is not {c}"
