"""The stock backend: the flown DRS_Python_Tools scripts, run with the configured interpreter.

The scripts are byte-for-byte what capsules carry, so this backend adds nothing on the Pi: the
release-authority lock and the log offset are shell around the scripts (see ``drs_link.link.remote``).
``DRS_GoGoGo.py`` prints ``Dropping in 30 seconds!`` itself after writing ``GoGoGo``; it does not
read the firmware's acknowledgement, so with this backend that line proves the write, not receipt.
"""

from __future__ import annotations

from drs_link.config import CapsuleConfig
from drs_link.link import remote
from drs_link.link.backends import GoResult, PowerOnResult, raise_for
from drs_link.link.backends.authority import PiReleaseAuthority
from drs_link.link.ssh import CapsuleLink

GO_WRITTEN_LINE = "Dropping in 30 seconds!"
SHUTTING_DOWN_LINE = "Shutting down..."
# DRS_GoGoGo.py: 3 s of logging, 5 s wait, 1 s, then shutdown; allow a slow Pi generously.
GO_TIMEOUT_S = 60.0


class StockBackend(PiReleaseAuthority):
    def __init__(self, capsule: CapsuleConfig, link: CapsuleLink) -> None:
        self.capsule = capsule
        self.link = link

    def power_on(self, holder: str, lease_s: float) -> PowerOnResult:
        c = self.capsule
        result = self.link.run(remote.power_on(c.tools_dir, c.python, holder, lease_s))
        if not result.ok:
            raise_for("power-on", result, c.name)
        return PowerOnResult(log_offset=remote.log_offset(result.stdout), output=result.stdout)

    def read_serial(self, offset: int) -> list[str]:
        c = self.capsule
        result = self.link.run(remote.read_serial(c.tools_dir, c.python, offset))
        if not result.ok:
            raise_for("reading the serial log", result, c.name)
        return result.stdout.splitlines()

    def go(self, holder: str) -> GoResult:
        c = self.capsule
        result = self.link.run(remote.go(c.tools_dir, c.python, holder), timeout_s=GO_TIMEOUT_S)
        if result.exit_status not in (0, None):
            raise_for("Go", result, c.name)
        lines = [line.strip() for line in result.stdout.splitlines()]
        return GoResult(
            go_written=GO_WRITTEN_LINE in lines,
            shutting_down=SHUTTING_DOWN_LINE in lines,
            link_dropped=result.link_dropped,
            exit_status=result.exit_status,
            output=result.stdout,
        )


BACKEND = StockBackend
"""This module's backend, as ``drs_link.link.backends.registry`` finds it."""
