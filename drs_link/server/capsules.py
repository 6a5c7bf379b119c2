"""The capsule service: the steps around a release that are not ARM and FIRE (status, power-on, reset,
a fall recorded on evidence, the release authority on the Pi, the host key's enrolment, the upload to
its storage), for whichever
operator the kernel says is connected.

A thin service over each desk's ``drs_link.ops`` concerns (links, release, enrolment), as ``release`` is: every rule and every audit row stays
there. What it adds is the server's: the caller's desk (its operator name and holder), a take-over's
two-person rule met only by another account's live connection (``release.two_person_refusal``), and the
capsule's link closed after each verb, as the one ``drs`` process that ran it once closed it on exit.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import msgspec

from drs_link.errors import ConfigError
from drs_link.link.backends import AuthorityStatus
from drs_link.ops import (
    Approval,
    OperatorOps,
    ReleaseRecord,
    SecondOperator,
    iso_utc,
    record_as_dict,
    take_over_outcome,
)
from drs_link.server.desks import Desks
from drs_link.server.paths import readable_tree
from drs_link.server.peers import Mode, Peer
from drs_link.server.protocol import (
    AuthoritySeen,
    AuthorityView,
    CapsuleStatus,
    Done,
    HostKeyView,
    ReleaseView,
    SyncReportView,
    SyncStatusView,
    TakeOverRequest,
)
from drs_link.server.release import two_person_refusal

Say = Callable[[str], None]
PROGRESS_PERIOD_S = 1.0
"""How often an upload says how far a file has got (one line per file per period, and at its end)."""
NO_OPERATOR = "operator.name: set [operator] name; every release step is audited with it"


def release_view(record: ReleaseRecord) -> ReleaseView:
    return msgspec.convert(record_as_dict(record), ReleaseView)


def authority_view(name: str, status: AuthorityStatus, holder: str) -> AuthorityView:
    seen = AuthoritySeen(status.holder, status.lease_end_s, status.pi_time_s)
    return AuthorityView(name, seen, status.describe(), holder)


class CapsuleService:
    def __init__(self, desks: Desks, mode: Mode) -> None:
        self.desks = desks
        self.mode = mode

    @contextmanager
    def _desk(self, peer: Peer, name: str, need_operator: bool = False) -> Iterator[OperatorOps]:
        """The peer's engine for ``name`` (an unknown capsule refused first), its link closed afterwards:
        under the capsule's lock, so never under another request's poll on the same desk (a console's
        ARM while its power-on still waited for NMEA found the link closed mid-poll: "link down")."""
        desk = self.desks.desk(peer)
        capsule = desk.state.ops(name)
        if need_operator and not peer.operator:
            raise ConfigError(NO_OPERATOR)
        try:
            yield desk
        finally:
            with capsule.lock:
                capsule.link.close()

    def status(self, peer: Peer, name: str) -> CapsuleStatus:
        """``CapsuleLinks.capsule_status``: read-only; a refused host key is raised, never reported as down.
        Its report is the ``--json`` document (``record_as_dict``, ``StorageStatus.as_dict``, …), checked
        field by field against ``CapsuleStatus`` here, so a client receives a typed value."""
        with self._desk(peer, name) as desk:
            report, _ = desk.links.capsule_status(name)
        return msgspec.convert(report, CapsuleStatus)

    def power_on(self, peer: Peer, name: str, confirmed: bool, say: Say) -> Done:
        """``CapsuleLinks.power_on`` (the checklist step, a disarm, void approvals), then the wait for the
        microcontroller's NMEA; ``ok`` when it waits for Go."""
        with self._desk(peer, name, need_operator=True) as desk:
            desk.links.power_on(name, confirmed)
            say(f"{name}: power-on done; waiting for the microcontroller's NMEA (up to ~25 s)")
            report = desk.state.ops(name).machine.wait_for_microcontroller()
        lines = [f"{name}: {report.diagnosis}"]
        if report.waiting_for_go:
            gnss = report.gnss
            lines.append(
                f"{name}: GNSS {gnss.fix_quality_name}, {gnss.satellites} satellites, HDOP {gnss.hdop}"
            )
        return Done(tuple(lines), report.waiting_for_go)

    def reset(self, peer: Peer, name: str, typed_name: str) -> ReleaseView:
        """``CapsuleLinks.reset``: ARM possible again, waivers and approvals void, a new flight if it flew."""
        with self._desk(peer, name) as desk:
            desk.links.reset(name, typed_name)
            return release_view(desk.state.ops(name).machine.record())

    def released(self, peer: Peer, name: str, typed_name: str, evidence: str) -> ReleaseView:
        """``Release.record_released``: an unverified Go settled as released on the operator's evidence."""
        with self._desk(peer, name) as desk:
            return release_view(desk.release.record_released(name, typed_name, evidence))

    def authority(self, peer: Peer, name: str) -> AuthorityView:
        with self._desk(peer, name) as desk:
            return authority_view(name, desk.release.authority(name), desk.state.ops(name).machine.holder)

    def check_take_over(self, peer: Peer, name: str, reason: str) -> AuthorityView:
        """A take-over that can never be right is refused (and audited) before the name is asked; else who
        holds the authority now, for the operator to be shown before they type the name."""
        with self._desk(peer, name, need_operator=True) as desk:
            machine = desk.state.ops(name).machine
            machine.check_take_over(reason)
            return authority_view(name, desk.release.authority(name), machine.holder)

    def take_over(
        self,
        peer: Peer,
        name: str,
        request: TakeOverRequest,
        say: Say,
        on_pending: Callable[[Approval], None],
    ) -> Done:
        """``Release.take_over`` from what the operator was shown: under ``require_second_operator`` only
        another account's live approval lets it go ahead (a typed name or a waiver is refused there)."""
        second = request.second
        two_person_refusal(self.mode, peer, second.await_approval)
        with self._desk(peer, name, need_operator=True) as desk:
            seen = AuthorityStatus(request.seen.holder, request.seen.lease_end_s, request.seen.pi_time_s)
            chosen = SecondOperator(second.name, second.waiver, second.await_approval, on_pending)
            now = desk.release.take_over(name, seen, request.typed_name, request.reason, chosen)
            holder = desk.state.ops(name).machine.holder
            approvals = [a.detail for a in desk.state.store.audit(name) if a.action == "authority-take-over"
                         and a.result == "approved" and a.detail and "approved_by" in a.detail]  # fmt: skip
        lines = []
        if second.await_approval and approvals:
            lines.append(f"approval #{approvals[-1]['approval']}: approved by {approvals[-1]['approved_by']}")
        lines.append(f"{name}: release authority {take_over_outcome(seen, holder)}: {now.describe()}")
        return Done(tuple(lines))

    def release_authority(self, peer: Peer, name: str, reason: str) -> AuthorityView:
        """Give up the caller's own release authority; what was given up (a free one if it held none)."""
        with self._desk(peer, name, need_operator=True) as desk:
            given_up = desk.release.release_authority(name, reason)
            return authority_view(name, given_up, desk.state.ops(name).machine.holder)

    def host_key_offer(self, peer: Peer, name: str) -> HostKeyView:
        """The host key the Pi offers now, before anything is trusted."""
        with self._desk(peer, name) as desk:
            offer = desk.enrolment.host_key_offer(name)
        return HostKeyView(offer.address, offer.key_type, offer.fingerprint)

    def enrol(self, peer: Peer, name: str, read_on_pi: str) -> HostKeyView:
        """Trust the key the Pi offers now only if it is the fingerprint the operator read on the Pi; the
        server writes its own known_hosts (``Enrolment.enrol``, audited)."""
        with self._desk(peer, name) as desk:
            offer = desk.enrolment.host_key_offer(name)
            saved = desk.enrolment.enrol(name, offer, read_on_pi)
        return HostKeyView(offer.address, offer.key_type, offer.fingerprint, str(saved))

    def sync_status(self, peer: Peer, name: str, source: str | None, with_hash: bool) -> SyncStatusView:
        """``CapsuleLinks.sync_status``, read-only: a directory the caller names is read only if its account
        could read all of it (``paths.readable_tree``); None is the capsule's configured ``sync_source``."""
        chosen = None if source is None else readable_tree(peer.uid, source)
        with self._desk(peer, name) as desk:
            status = desk.links.sync_status(name, chosen, with_hash=with_hash)
        last = iso_utc(status.last_sync_utc) if status.last_sync_utc else None
        return SyncStatusView(
            status.missing,
            status.changed,
            len(status.up_to_date),
            status.bytes_pending,
            last,
            status.left_out,
        )

    def sync(self, peer: Peer, name: str, source: str | None, say: Say) -> Done:
        """``CapsuleLinks.sync`` with the server's SSH identity (the operator never holds the Pi's key): the
        upload, its sha256 verification on the Pi and its audit, each file's progress said as it goes."""
        chosen: Path | None = None if source is None else readable_tree(peer.uid, source)
        said: dict[str, float] = {}

        def progress(relative: str, done: int, total: int) -> None:
            now = time.monotonic()
            if done >= total or now - said.get(relative, -PROGRESS_PERIOD_S) >= PROGRESS_PERIOD_S:
                said[relative] = now
                say(f"{name}: {relative}: {done} of {total} bytes sent")

        with self._desk(peer, name, need_operator=True) as desk:
            report = desk.links.sync(name, chosen, progress)
        view = SyncReportView(report.uploaded, len(report.skipped), report.bytes_sent, report.left_out)
        return Done((), True, sync=view)
