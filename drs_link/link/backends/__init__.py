"""How the console drives the Pi for release: one interface, two implementations.

``stock`` runs the flown DRS_Python_Tools scripts unchanged (the default: it is what capsules
carry); ``agent`` would install a maintained script of our own. The release state machine only
sees this interface, so the two stay interchangeable.

Each backend is a module of this package named as the config's ``backend`` key, declaring its class
as ``BACKEND`` (``drs_link.link.backends.registry`` builds it). ``backend_names`` lists them by module
name without importing any, so the config can validate the key on every read without loading the
backends (or paramiko) and without importing the registry, whose backends take the config.
"""

from __future__ import annotations

import pkgutil
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from typing import TYPE_CHECKING, Protocol

from drs_link.errors import LinkError, RefusedError
from drs_link.link import remote
from drs_link.store import iso_utc
from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from drs_link.link.ssh import CommandResult

    from .registry import build_backend as build_backend

SUPPORT_MODULES = frozenset({"authority", "pi_agent", "registry"})
"""The modules of this package that are not backends: the shared authority lock, the agent's Pi
script and the registry. A module missing here and from the backends fails the registry's test."""


def backend_names() -> tuple[str, ...]:
    """Every backend a capsule's ``backend`` key may name: the package's other modules, by name only."""
    return tuple(
        module.name
        for module in pkgutil.iter_modules(__path__)
        if module.name not in SUPPORT_MODULES and not module.ispkg
    )


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


class AuthorityState(StrEnum):
    FREE = "free"
    HELD = "held"
    EXPIRED = "expired"


@dataclass(frozen=True)
class AuthorityStatus:
    """Who holds a capsule's release authority, as the owner file on the Pi says, by the Pi's clock.

    Times are whole epoch seconds exactly as the owner file holds them, so a take-over can hand back
    precisely what the operator saw for the Pi to compare; seconds left are counted on the Pi's
    clock, so a console whose own clock is off still reads the lease right.
    """

    holder: str | None
    lease_end_s: int
    pi_time_s: int

    @property
    def state(self) -> AuthorityState:
        if self.holder is None:
            return AuthorityState.FREE
        return AuthorityState.HELD if self.lease_end_s > self.pi_time_s else AuthorityState.EXPIRED

    @property
    def lease_end(self) -> datetime | None:
        return datetime.fromtimestamp(self.lease_end_s, UTC) if self.holder is not None else None

    @property
    def seconds_left(self) -> int:
        return max(self.lease_end_s - self.pi_time_s, 0) if self.holder is not None else 0

    def describe(self) -> str:
        """One line for an operator: the holder, the lease end in UTC and what is left of it."""
        if self.lease_end is None:
            return "free"
        until = iso_utc(self.lease_end)
        if self.state is AuthorityState.EXPIRED:
            return f"expired (last held by {self.holder} until {until})"
        return f"held by {self.holder} until {until} ({self.seconds_left} s left)"


class CapsuleBackend(Protocol):
    def power_on(self, holder: str, lease_s: float) -> PowerOnResult: ...

    def read_serial(self, offset: int) -> list[str]: ...

    def go(self, holder: str) -> GoResult: ...

    def authority(self) -> AuthorityStatus: ...

    def take_over_authority(self, holder: str, seen: AuthorityStatus, lease_s: float) -> AuthorityStatus: ...

    def release_authority(self, holder: str) -> AuthorityStatus: ...


def raise_for(step: str, result: CommandResult, capsule: str) -> None:
    """A failed remote command as the operator's one-line error, the same for every backend.

    The authority lock's refusals are ``RefusedError`` (the Pi did nothing); the rest ``LinkError``.
    """
    if result.link_dropped:
        raise LinkError(f"{capsule}: the link dropped during {step}")
    if result.timed_out:
        raise LinkError(f"{capsule}: {step} did not finish in time")
    message = result.stderr.strip().splitlines()[-1] if result.stderr.strip() else ""
    if result.exit_status in (
        remote.EXIT_AUTHORITY_HELD,
        remote.EXIT_AUTHORITY_CHANGED,
        remote.EXIT_NO_AUTHORITY,
    ):
        raise RefusedError(f"{capsule}: {message.removeprefix('drs: ') or 'release authority refused'}")
    if result.exit_status == remote.EXIT_NO_TOOLS:
        raise LinkError(f"{capsule}: the tools directory is missing on the Pi")
    raise LinkError(
        f"{capsule}: {step} failed with exit status {result.exit_status}: {message or 'no message'}"
    )


# The registry imports every backend (and paramiko): opened only when a caller builds one.
__getattr__, __dir__, _ = lazy_door(__name__, {"build_backend": "registry"})
