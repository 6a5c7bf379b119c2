"""A room's door that opens the module behind a name on first use (PEP 562).

Why lazy: a door that imported every module behind it would make ``drs --help`` and every
``drs X --help`` pay for numba, xarray, eccodes and paramiko they never use, because importing any
module of a room runs the room's ``__init__`` first. Names are looked up on each access rather than
cached in the door, so a test that patches a module is never outlived by a stale copy here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_door(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``__getattr__``, ``__dir__`` and ``__all__`` for ``package``, whose ``exports`` map each public
    name to the module (relative to the package) that defines it.

    A name mapped to itself is a module the door hands out whole (``"lifecycle": "lifecycle"``): a
    module whose functions share names with another's (each bench's ``run_bench``) is opened as one.
    """

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        opened = importlib.import_module(f"{package}.{module}")
        return opened if module == name else getattr(opened, name)

    def __dir__() -> list[str]:
        return sorted({*vars(importlib.import_module(package)), *exports})

    return __getattr__, __dir__, sorted(exports)
