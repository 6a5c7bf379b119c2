"""The operations client: every face's one way to act, with verbs and typed values (as Yamcs' client).

``Client.for_config(config)`` reaches the team's shared server (``[server] socket``) or, with none
configured, this account's private server, started on demand (``private``). Verbs:
``client.capsule("DRS1").arm(…)``, ``.fire(…)``, ``.disarm()``, ``.status()``, ``.power_on()``,
``.reset(name)``, ``.released(name, evidence)``, ``.authority()``, ``.take_over(…)``,
``.release_authority(reason)``, ``.host_key()``/``.enrol(fingerprint)``, ``.sync(source)``/``.sync_status(…)``, ``client.iridium.send_mt(…)``,
``.mt_status(name)``, ``.resolve_mt(…)``, ``.health(name)``, ``.track(…)``,
``client.recovery(name, …)``, ``client.chase.points()``/``.keep(landing)``, ``client.approvals.waiting()``/``.approve(id)``/``.reject(id, reason)``, ``client.events()``
for views, and ``client.telemetry_stream()`` for the capsules' telemetry (``.poll()`` for one poll now).
A console's desk (waivers, checklists, history, its session, the views it draws, a PARACHUTE plan) is
``drs_link.server.desk.Desk(client)``: its answers are the operations layer's values.

Why the standard library's ``http.client`` for the verbs: a ``drs`` command is one blocking request,
and a plain socket keeps ``drs …`` from paying for an event loop and aiohttp's import (the CLI's
start-up is measured); the WebSocket of ``events`` imports aiohttp only when a view subscribes. A
refusal comes back as the same exception type the operations layer raised.
"""

from __future__ import annotations

import contextlib
import http.client
import socket
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import msgspec

from drs_link.config import Config
from drs_link.errors import ConfigError, LinkError, RefusedError, StoreError
from drs_link.feeds import ChasePoint, KeptLanding
from drs_link.server.protocol import (
    PROTOCOL,
    ROOT,
    ApprovalView,
    ArmRequest,
    ArmState,
    AuthoritySeen,
    AuthorityView,
    CapsuleStatus,
    DecideRequest,
    DisarmRequest,
    Done,
    EnrolRequest,
    Event,
    Failure,
    FireRequest,
    HealthView,
    Hello,
    HostKeyView,
    KeepLandingRequest,
    MtSendRequest,
    MtStatus,
    MtView,
    Pending,
    PowerOnRequest,
    ReasonRequest,
    RecoveryReadout,
    RecoveryRequest,
    ReleasedRequest,
    ReleaseView,
    ResolveMtRequest,
    Said,
    Second,
    SyncReportView,
    SyncRequest,
    SyncStatusRequest,
    SyncStatusView,
    TakeOverRequest,
    TelemetryBatch,
    TrackCsv,
    TrackRequest,
    TypedNameRequest,
    Waive,
    decode_step,
    encode,
)
from predictor.errors import UsageError

if TYPE_CHECKING:
    from drs_link.ops import TelemetryRecord
    from drs_link.server.desks import PredictorFor
    from drs_link.server.recovery import LiveFor

T = TypeVar("T")
Say = Callable[[str], None]
TIMEOUT_S = 600.0
"""The longest a verb waits for its answer: a FIRE waiting for another account's approval (the
request itself expires after ``APPROVAL_TTL_S``)."""
_ERRORS: dict[str, type[Exception]] = {
    "refused": RefusedError, "config": ConfigError, "store": StoreError, "usage": UsageError,
    "link": LinkError, "protocol": LinkError, "identity": RefusedError,
}  # fmt: skip


def raise_failure(failure: Failure) -> None:
    raise _ERRORS.get(failure.kind, LinkError)(failure.error)


class _UnixConnection(http.client.HTTPConnection):
    def __init__(self, path: Path, timeout: float) -> None:
        super().__init__("drs-server", timeout=timeout)
        self.path = path

    def connect(self) -> None:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(self.timeout)
        try:
            sock.connect(str(self.path))
        except OSError:
            sock.close()
            raise
        self.sock = sock


class Client:
    """One connection to an operations server (kept open between verbs)."""

    def __init__(self, socket_path: Path, timeout_s: float = TIMEOUT_S) -> None:
        self.socket_path = socket_path
        self._conn = _UnixConnection(socket_path, timeout_s)
        self.iridium = Iridium(self)
        self.approvals = Approvals(self)
        self.chase = Chase(self)

    @classmethod
    def for_config(
        cls, config: Config, predictor_for: PredictorFor | None = None, live_for: LiveFor | None = None
    ) -> Client:
        """The team's server (``[server] socket``), else this account's private one (started if need be;
        ``predictor_for`` and ``live_for`` only reach one run in this process, ``private.IN_PROCESS_ENV``)."""
        if config.server.socket:
            return cls(Path(config.server.socket).expanduser())
        from drs_link.server.private import ensure_private_server

        return cls(ensure_private_server(config, predictor_for, live_for))

    def close(self) -> None:
        self._conn.close()

    def abort(self) -> None:
        """Cut the connection from another thread (a console's cancel): the verb waiting on it fails, and
        the server withdraws the approval request that action waited on."""
        sock = self._conn.sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def capsule(self, name: str) -> Capsule:
        return Capsule(self, name)

    def recovery(self, name: str, request: RecoveryRequest) -> RecoveryReadout:
        """Where a capsule is (``drs recovery``), read by the server from the reports it holds; the GPX,
        KML and descent asked for come back for this process to write or draw."""
        return self.call("POST", f"/recovery/{name}", request, RecoveryReadout)

    def hello(self) -> Hello:
        return self.call("GET", "/hello", None, Hello)

    # The wire ------------------------------------------------------------------------------------

    def _send(self, method: str, path: str, body: object | None) -> http.client.HTTPResponse:
        payload = None if body is None else encode(body)
        headers = {"Content-Type": "application/json"} if payload is not None else {}
        try:
            self._conn.request(method, ROOT + path, body=payload, headers=headers)
            return self._conn.getresponse()
        except (ConnectionRefusedError, FileNotFoundError):
            self._conn.close()
            raise LinkError(
                f"no operations server listens at {self.socket_path} (is drs-server running? "
                "systemctl status drs-server)"
            ) from None
        except PermissionError:
            self._conn.close()
            raise LinkError(
                f"{self.socket_path}: permission denied: this account is not in the server's group "
                "(usermod -aG GROUP ACCOUNT, as root, then log in again)"
            ) from None
        except (OSError, http.client.HTTPException) as exc:
            self._conn.close()
            raise LinkError(f"the operations server at {self.socket_path} did not answer: {exc}") from None

    def call(self, method: str, path: str, body: object | None, kind: type[T]) -> T:
        response = self._send(method, path, body)
        with self._reading():
            raw = response.read()
        if response.status != 200:
            raise_failure(_failure(raw))
        try:
            return msgspec.json.decode(raw, type=kind)
        except msgspec.MsgspecError as exc:
            raise LinkError(
                f"the operations server's answer to {method} {path} does not parse: {exc}"
            ) from None

    @contextlib.contextmanager
    def _reading(self) -> Iterator[None]:
        """An answer that breaks off or stalls while it is read is a ``LinkError`` like one never sent: a
        console's worker says those, where a bare ``TimeoutError`` or ``IncompleteRead`` went unsaid."""
        try:
            yield
        except (OSError, http.client.HTTPException) as exc:
            self._conn.close()
            raise LinkError(
                f"the operations server at {self.socket_path} broke off its answer: {exc!r}"
            ) from None

    def steps(
        self, path: str, body: object, say: Say, on_pending: Callable[[Pending], None] | None = None
    ) -> Done:
        """A long action: print its steps as they come (``say``; the approval request it waits on to
        ``on_pending`` when given, a console's notice); its ``Done``, or its failure raised."""
        response = self._send("POST", path, body)
        if response.status != 200:
            with self._reading():
                raw = response.read()
            raise_failure(_failure(raw))
        while True:
            with self._reading():
                line = response.readline()
            if not line:
                self._conn.close()
                raise LinkError("the operations server ended the answer before the action did (did it stop?)")
            try:
                step = decode_step(line)
            except msgspec.MsgspecError as exc:
                self._conn.close()
                raise LinkError(f"the operations server's step of {path} does not parse: {exc}") from None
            if isinstance(step, Pending) and on_pending is not None:
                on_pending(step)
            elif isinstance(step, Said | Pending):
                say(step.line)
            elif isinstance(step, Failure):
                self._drain(response)
                raise_failure(step)
            else:
                self._drain(response)
                return step

    def _drain(self, response: http.client.HTTPResponse) -> None:
        """Read an answer's end after its last step, so the connection serves the next verb. The step came
        whole, so an end that breaks off or stalls (the server stopping) changes nothing it said: the
        connection is closed and the step stands, where a bare ``IncompleteRead`` read as the action failing."""
        try:
            response.read()
        except (OSError, http.client.HTTPException):
            self._conn.close()

    def events(self) -> Iterator[Event]:
        """Each change of release state, ARM windows and waiting approvals, as the server pushes it."""
        import asyncio
        import queue
        import threading

        found: queue.Queue[Event | BaseException | None] = queue.Queue()

        async def listen() -> None:
            async for event in self.event_stream():
                found.put(event)
            found.put(None)

        def run() -> None:
            try:
                asyncio.run(listen())
            except BaseException as exc:  # noqa: BLE001 - handed to the reader
                found.put(exc)

        threading.Thread(target=run, daemon=True, name="drs-events").start()
        while True:
            item = found.get()
            if item is None:
                return
            if isinstance(item, BaseException):
                raise LinkError(f"the event stream of {self.socket_path} failed: {item}")
            yield item

    async def event_stream(self) -> AsyncIterator[Event]:
        """``events`` in the caller's event loop (a console's): cancelled with the task that reads it."""
        import aiohttp

        connector = aiohttp.UnixConnector(path=str(self.socket_path))
        try:
            async with aiohttp.ClientSession(connector=connector) as session:
                async with session.ws_connect(f"http://drs-server{ROOT}/events") as ws:
                    async for message in ws:
                        if message.type is aiohttp.WSMsgType.BINARY:
                            yield msgspec.json.decode(message.data, type=Event)
        except aiohttp.ClientError as exc:
            raise LinkError(f"the event stream of {self.socket_path} failed: {exc}") from None

    async def telemetry_stream(self) -> AsyncIterator[list[TelemetryRecord]]:
        """The capsules' telemetry as the server polls it (``/v1/telemetry``): first the latest of each
        kind per capsule, then each new batch; in the caller's event loop, cancelled with its task."""
        import aiohttp

        connector = aiohttp.UnixConnector(path=str(self.socket_path))
        try:
            async with aiohttp.ClientSession(connector=connector) as session:
                async with session.ws_connect(f"http://drs-server{ROOT}/telemetry") as ws:
                    async for message in ws:
                        if message.type is aiohttp.WSMsgType.BINARY:
                            yield records_of(msgspec.json.decode(message.data, type=TelemetryBatch))
        except aiohttp.ClientError as exc:
            raise LinkError(f"the telemetry stream of {self.socket_path} failed: {exc}") from None


def absolute(paths: tuple[str, ...]) -> tuple[str, ...]:
    """Paths as this process names them: the server does not share its working directory."""
    return tuple(str(Path(p).absolute()) for p in paths)


def records_of(batch: TelemetryBatch) -> list[TelemetryRecord]:
    """The records of a batch, each checked by the recording format's parser (imported here: a ``drs``
    command that never reads telemetry does not pay for the operations layer's import)."""
    from drs_link.ops import TelemetryRecord

    return [TelemetryRecord.from_json(line, "the server's telemetry") for line in batch.records]


def _failure(raw: bytes) -> Failure:
    try:
        return msgspec.json.decode(raw, type=Failure)
    except msgspec.MsgspecError:
        return Failure("protocol", f"the server answered {raw[:200]!r}")


@dataclass(frozen=True)
class Capsule:
    """One capsule's release verbs."""

    client: Client
    name: str

    def arm(self, waivers: tuple[tuple[str, str], ...] = (), weather: tuple[str, ...] = (),
            say: Say = print, held_waivers: bool = False) -> ArmState:  # fmt: skip
        """``held_waivers``: judged with the waivers this account holds at the server (a console's)."""
        request = ArmRequest(
            PROTOCOL, tuple(Waive(i, r) for i, r in waivers), absolute(weather), held_waivers
        )
        done = self.client.steps(f"/capsules/{self.name}/arm", request, say)
        assert done.arm is not None
        return done.arm

    def fire(
        self,
        typed_name: str,
        waivers: tuple[tuple[str, str], ...] = (),
        weather: tuple[str, ...] = (),
        second: Second | None = None,
        say: Say = print,
        on_pending: Callable[[Pending], None] | None = None,
        held_waivers: bool = False,
    ) -> Done:
        waived = tuple(Waive(i, r) for i, r in waivers)
        request = FireRequest(
            PROTOCOL, typed_name, waived, absolute(weather), second or Second(), held_waivers
        )
        return self.client.steps(f"/capsules/{self.name}/fire", request, say, on_pending)

    def disarm(self, reason: str = "operator disarmed (drs capsule disarm)") -> ArmState:
        return self.client.call(
            "POST", f"/capsules/{self.name}/disarm", DisarmRequest(PROTOCOL, reason), ArmState
        )

    def poll(self) -> list[TelemetryRecord]:
        """Poll the capsule now (link, release state, GNSS, storage, sync); every console following the
        telemetry is sent the records too."""
        return records_of(self.client.call("POST", f"/capsules/{self.name}/poll", None, TelemetryBatch))

    def status(self) -> CapsuleStatus:
        """Release record, link, storage, microcontroller and GNSS, read now (read-only)."""
        return self.client.call("GET", f"/capsules/{self.name}/status", None, CapsuleStatus)

    def power_on(self, confirmed: bool = True, say: Say = print) -> Done:
        """Latch the battery relay (software cannot unlatch it: confirm first), then wait for the
        microcontroller's NMEA; ``ok`` when it waits for Go. Not confirmed: refused and audited."""
        request = PowerOnRequest(PROTOCOL, confirmed)
        return self.client.steps(f"/capsules/{self.name}/power-on", request, say)

    def reset(self, typed_name: str) -> ReleaseView:
        """After recovery: ARM possible again (waivers and approvals void)."""
        request = TypedNameRequest(PROTOCOL, typed_name)
        return self.client.call("POST", f"/capsules/{self.name}/reset", request, ReleaseView)

    def released(self, typed_name: str, evidence: str) -> ReleaseView:
        """Settle an unverified Go as released on the operator's evidence (written to the audit)."""
        request = ReleasedRequest(PROTOCOL, typed_name, evidence)
        return self.client.call("POST", f"/capsules/{self.name}/released", request, ReleaseView)

    def authority(self) -> AuthorityView:
        """Who holds the release authority on the Pi now."""
        return self.client.call("GET", f"/capsules/{self.name}/authority", None, AuthorityView)

    def check_take_over(self, reason: str) -> AuthorityView:
        """A take-over that can never be right is refused now, before the name is asked; else who holds
        the authority, to show the operator (and hand back as ``seen``)."""
        request = ReasonRequest(PROTOCOL, reason)
        return self.client.call(
            "POST", f"/capsules/{self.name}/authority/check-take-over", request, AuthorityView
        )

    def take_over(
        self,
        seen: AuthoritySeen,
        typed_name: str,
        reason: str,
        second: Second | None = None,
        say: Say = print,
    ) -> Done:
        """Take over from what the operator was shown (``seen``); the two-person rule as FIRE meets it."""
        request = TakeOverRequest(PROTOCOL, seen, typed_name, reason, second or Second())
        return self.client.steps(f"/capsules/{self.name}/authority/take-over", request, say)

    def release_authority(self, reason: str = "") -> AuthorityView:
        """Give up this operator's release authority; what was given up (free if it held none)."""
        request = ReasonRequest(PROTOCOL, reason)
        return self.client.call("POST", f"/capsules/{self.name}/authority/release", request, AuthorityView)

    def sync(self, source: Path | None = None, say: Say = print) -> SyncReportView:
        """Upload ``source`` (None: the capsule's ``sync_source``) with the server's SSH identity, each file
        verified by sha256 on the Pi; the server reads only what this account could read."""
        request = SyncRequest(PROTOCOL, None if source is None else str(source.absolute()))
        done = self.client.steps(f"/capsules/{self.name}/sync", request, say)
        assert done.sync is not None
        return done.sync

    def sync_status(self, source: Path | None = None, with_hash: bool = False) -> SyncStatusView:
        """What an upload would send (read-only; ``with_hash`` compares sha256 on the Pi too)."""
        request = SyncStatusRequest(PROTOCOL, None if source is None else str(source.absolute()), with_hash)
        return self.client.call("POST", f"/capsules/{self.name}/sync/status", request, SyncStatusView)

    def host_key(self) -> HostKeyView:
        """The host key the Pi offers now, for the operator to compare with the one read on the Pi."""
        return self.client.call("GET", f"/capsules/{self.name}/host-key", None, HostKeyView)

    def enrol(self, fingerprint: str) -> HostKeyView:
        """Trust the Pi's key if it is ``fingerprint`` (read on the Pi itself); the server saves it."""
        request = EnrolRequest(PROTOCOL, fingerprint)
        return self.client.call("POST", f"/capsules/{self.name}/host-key", request, HostKeyView)


@dataclass(frozen=True)
class Iridium:
    client: Client

    def send_mt(
        self, name: str, request: MtSendRequest, say: Say = print,
        on_pending: Callable[[Pending], None] | None = None,
    ) -> Done:  # fmt: skip
        return self.client.steps(f"/iridium/{name}/mt", request, say, on_pending)

    def mt_status(self, name: str) -> MtStatus:
        """The capsule's MTs, once the reports moved them on (delivered, applied), oldest first."""
        return self.client.call("GET", f"/iridium/{name}/mt", None, MtStatus)

    def resolve_mt(self, name: str, command_id: int, gateway_id: int | None, note: str = "") -> list[MtView]:
        """Record what the RockBLOCK portal shows for an MT whose delivery is unknown: queued as
        ``gateway_id``, or (None) never sent. The resolved MT first, then every other that changed."""
        request = ResolveMtRequest(PROTOCOL, command_id, gateway_id, note)
        return self.client.call("POST", f"/iridium/{name}/mt/resolve", request, list[MtView])

    def health(self, name: str) -> HealthView:
        """Battery, resets, gaps and spacing, judged from the reports the server holds."""
        return self.client.call("GET", f"/iridium/{name}/health", None, HealthView)

    def track(self, capsule: str | None = None, imei: str | None = None) -> TrackCsv:
        """The stored fixes of a capsule (or a modem by IMEI) as the canonical track CSV's text, for
        this process to write (``drs_link.exports.write_export``): the file is then the operator's own."""
        return self.client.call("POST", "/iridium/track", TrackRequest(PROTOCOL, capsule, imei), TrackCsv)


@dataclass(frozen=True)
class Approvals:
    client: Client

    def waiting(self) -> list[ApprovalView]:
        return self.client.call("GET", "/approvals", None, list[ApprovalView])

    def approve(self, approval_id: int) -> ApprovalView:
        return self.client.call(
            "POST", f"/approvals/{approval_id}", DecideRequest(PROTOCOL, True), ApprovalView
        )

    def reject(self, approval_id: int, reason: str) -> ApprovalView:
        request = DecideRequest(PROTOCOL, False, reason)
        return self.client.call("POST", f"/approvals/{approval_id}", request, ApprovalView)


@dataclass(frozen=True)
class Chase:
    client: Client

    def points(self) -> list[ChasePoint]:
        """What chasemapper should show now: each capsule's newest fix and its recent landing's marker."""
        return self.client.call("GET", "/chase/points", None, list[ChasePoint])

    def keep(self, landing: KeptLanding) -> None:
        """Record this console's newest landing of a capsule, for every ``drs chase`` to send."""
        self.client.call("POST", "/chase/landing", KeepLandingRequest(PROTOCOL, landing), type(None))
