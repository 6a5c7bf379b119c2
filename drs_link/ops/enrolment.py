"""Enrolment of a capsule's host key (``drs capsule enrol``): what the Pi offers, and trusting it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from drs_link.errors import LinkError, RefusedError
from drs_link.link import enrol_host_key, fingerprint, known_hosts_name, scan_host_key
from drs_link.ops.ops_state import OpsState

if TYPE_CHECKING:
    import paramiko


@dataclass(frozen=True)
class HostKeyOffer:
    """The host key a capsule's Pi offers, for the operator to compare with the one read on the Pi."""

    address: str
    """As known_hosts names it (``[host]:port``)."""
    key_type: str
    fingerprint: str
    key: paramiko.PKey
    """The key itself (paramiko's), saved as it was offered once the operator confirms it."""


class Enrolment:
    """A capsule's host key: offered by its Pi, trusted only on the fingerprint read on the Pi itself."""

    def __init__(self, state: OpsState) -> None:
        self.state = state

    def host_key_offer(self, name: str) -> HostKeyOffer:
        """The host key the Pi offers now (``drs capsule enrol``), before anything is trusted."""
        capsule = self.state.ops(name).config
        if capsule.jump_host:
            raise LinkError(
                f"{capsule.name}: enrol through a jump host is not supported; add the key by hand"
            )
        key = scan_host_key(capsule.host, capsule.port, capsule.connect_timeout_s)
        return HostKeyOffer(
            known_hosts_name(capsule.host, capsule.port), key.get_name(), fingerprint(key), key
        )

    def enrol(self, name: str, offer: HostKeyOffer, read_on_pi: str) -> Path:
        """Trust ``offer`` only if it is the fingerprint the operator read on the Pi itself; audited."""
        capsule = self.state.ops(name).config
        if read_on_pi != offer.fingerprint:
            raise RefusedError(
                f"{capsule.name}: enrol refused: the Pi offers {offer.fingerprint}, not {read_on_pi}"
            )
        self.state.store.append_audit(
            self.state.operator, capsule.name, "enrol", "ok", {"fingerprint": offer.fingerprint}
        )
        enrol_host_key(capsule.known_hosts, capsule.host, capsule.port, offer.key)
        return capsule.known_hosts
