"""The agent backend: our own Python 3 script on the Pi (``pi_agent.py``), installed over SFTP.

Same interface and release-authority lock as the stock backend. What it adds: NMEA is logged
continuously with timestamps from power-on (no 5 s capture per look), and Go is confirmed by the
firmware's own ``Dropping in 30 seconds!`` rather than by the script's print; without that
acknowledgement the Pi stays up so Go can be retried. The script is (re)installed whenever the
copy on the Pi differs from this package's, and is verified by sha256 on the Pi before use.
"""

from __future__ import annotations

import hashlib
import posixpath
from pathlib import Path

import paramiko

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError
from drs_link.link import remote
from drs_link.link.backends import GoResult, PowerOnResult, raise_for
from drs_link.link.backends.authority import PiReleaseAuthority
from drs_link.link.backends.stock import GO_TIMEOUT_S, SHUTTING_DOWN_LINE
from drs_link.link.ssh import CapsuleLink

AGENT_SOURCE = Path(__file__).with_name("pi_agent.py")
ACK_LINE = "ACK Dropping in 30 seconds!"


class AgentBackend(PiReleaseAuthority):
    def __init__(self, capsule: CapsuleConfig, link: CapsuleLink) -> None:
        self.capsule = capsule
        self.link = link
        self.source = AGENT_SOURCE.read_bytes()
        self.digest = hashlib.sha256(self.source).hexdigest()

    @property
    def remote_path(self) -> str:
        return posixpath.join(self.capsule.tools_dir, remote.AGENT_NAME)

    def _installed_digest(self) -> str | None:
        result = self.link.run(remote.hash_file(self.remote_path))
        return remote.sha256_of(result.stdout) if result.ok else None

    def ensure_installed(self) -> bool:
        """Install or update the agent; True when a new copy was written."""
        if self._installed_digest() == self.digest:
            return False
        temporary = self.remote_path + ".drs-partial"
        sftp = self.link.sftp()
        try:
            with sftp.open(temporary, "wb") as handle:
                handle.write(self.source)
            sftp.chmod(temporary, 0o755)
            verify = self.link.run(remote.verify_file(temporary))
            if not verify.ok or remote.sha256_of(verify.stdout) != self.digest:
                raise LinkError(f"{self.capsule.name}: the agent copied to the Pi does not match its sha256")
            sftp.posix_rename(temporary, self.remote_path)
        except (OSError, EOFError, paramiko.SSHException) as exc:
            raise LinkError(
                f"{self.capsule.name}: cannot install the agent in {self.capsule.tools_dir}: {exc}"
            ) from None
        finally:
            sftp.close()
        return True

    def power_on(self, holder: str, lease_s: float) -> PowerOnResult:
        c = self.capsule
        self.ensure_installed()
        result = self.link.run(
            remote.agent_power_on(c.tools_dir, c.agent_python, holder, lease_s, c.serial_device)
        )
        if not result.ok:
            raise_for("power-on", result, c.name)
        return PowerOnResult(log_offset=remote.log_offset(result.stdout), output=result.stdout)

    def read_serial(self, offset: int) -> list[str]:
        c = self.capsule
        result = self.link.run(remote.agent_read(c.tools_dir, c.agent_python, offset))
        if not result.ok:
            raise_for("reading the agent's NMEA log", result, c.name)
        return result.stdout.splitlines()

    def go(self, holder: str) -> GoResult:
        c = self.capsule
        result = self.link.run(
            remote.agent_go(c.tools_dir, c.agent_python, holder, c.serial_device), timeout_s=GO_TIMEOUT_S
        )
        lines = [line.strip() for line in result.stdout.splitlines()]
        if result.exit_status == remote.EXIT_AGENT_NO_ACK:
            raise LinkError(
                f"{c.name}: GoGoGo was written twice but the microcontroller did not acknowledge it; "
                "the Pi stays up: check that NMEA is arriving, then retry Go"
            )
        if result.exit_status not in (0, None):
            raise_for("Go", result, c.name)
        return GoResult(
            go_written=any(line.startswith("GoGoGo written") for line in lines),
            shutting_down=SHUTTING_DOWN_LINE in lines,
            link_dropped=result.link_dropped,
            exit_status=result.exit_status,
            output=result.stdout,
            acknowledged=ACK_LINE in lines,
        )


BACKEND = AgentBackend
"""This module's backend, as ``drs_link.link.backends.registry`` finds it."""
