"""How the console drives the Pi for release: one interface, two implementations.

``stock`` runs the flown DRS_Python_Tools scripts unchanged (the default: it is what capsules
carry); ``agent`` would install a maintained script of our own. The release state machine only
sees this interface, so the two stay interchangeable.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


@dataclass(frozen=True)
class PowerOnResult:
    """``log_offset`` is the serial log's size before power-on: only bytes after it are new NMEA."""

    log_offset: int
    output: str


@dataclass(frozen=True)
class GoResult:
    """What the Pi said during Go; ``link_dropped`` right after ``shutting_down`` is success."""

    go_written: bool
    shutting_down: bool
    link_dropped: bool
    exit_status: int | None
    output: str
    acknowledged: bool = False


class CapsuleBackend(Protocol):
    def power_on(self, holder: str, lease_s: float) -> PowerOnResult: ...

    def read_serial(self, offset: int) -> list[str]: ...

    def go(self, holder: str) -> GoResult: ...
