"""The release-authority owner file on the Pi, read, taken over and given up the same way by every backend.

Both backends keep the authority in ``tools_dir`` as shell around their scripts (see
``drs_link.link.remote``), so seeing it and handing it over does not depend on which scripts run.
"""

from __future__ import annotations

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError, RefusedError
from drs_link.link import remote
from drs_link.link.backends import AuthorityStatus, raise_for
from drs_link.link.ssh import CapsuleLink, CommandResult


class PiReleaseAuthority:
    """Mixed into a backend that has ``capsule`` and ``link``."""

    capsule: CapsuleConfig
    link: CapsuleLink

    def _status(self, result: CommandResult) -> AuthorityStatus:
        c = self.capsule
        report = remote.authority_report(result.stdout)
        if report is None:
            tail = (result.stdout.strip() or result.stderr.strip())[-200:]
            raise LinkError(f"{c.name}: the Pi did not report its release authority (it said {tail!r})")
        pi_time_s, lease_end_s, holder = report
        if holder and not remote.HOLDER_RE.match(holder):
            raise LinkError(
                f"{c.name}: {c.tools_dir}/{remote.AUTHORITY_OWNER} on the Pi names {holder!r}, which no "
                "console writes: inspect it on the Pi"
            )
        return AuthorityStatus(holder or None, lease_end_s, pi_time_s)

    def authority(self) -> AuthorityStatus:
        result = self.link.run(remote.authority(self.capsule.tools_dir))
        if not result.ok:
            raise_for("reading the release authority", result, self.capsule.name)
        return self._status(result)

    def take_over_authority(self, holder: str, seen: AuthorityStatus, lease_s: float) -> AuthorityStatus:
        """Become the holder for ``lease_s``, refused unless the Pi still shows exactly ``seen``."""
        c = self.capsule
        command = remote.authority_take_over(
            c.tools_dir, holder, seen.holder or "", seen.lease_end_s, lease_s
        )
        result = self.link.run(command)
        if result.exit_status == remote.EXIT_AUTHORITY_CHANGED:
            now = self._status(result)
            raise RefusedError(
                f"{c.name}: the release authority changed since it was shown ({seen.describe()}): it is now "
                f"{now.describe()}; look again before taking it over"
            )
        if not result.ok:
            raise_for("taking over the release authority", result, c.name)
        return self._status(result)

    def release_authority(self, holder: str) -> AuthorityStatus:
        """Give up ``holder``'s authority; returns what was given up (free if there was nothing)."""
        result = self.link.run(remote.authority_release(self.capsule.tools_dir, holder))
        if not result.ok:
            raise_for("giving up the release authority", result, self.capsule.name)
        return self._status(result)
