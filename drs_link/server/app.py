"""``drs server``: the one process that holds the store, the capsule links and the gateway credentials.

Why aiohttp: HTTP request/response for verbs and a WebSocket for pushed views, both on a Unix socket
(aiohttp's handler on connections the server accepts itself, ``OperationsServer.accept``), from one
well-kept library with an asyncio server; the kernel's peer credentials of each connection are read from its socket
(``peers.peer_uid``). Each operator action runs in a worker
thread over ``drs_link.ops`` (blocking SSH, SQLite, HTTP), and a long one (FIRE, an MT) answers with
a stream of typed steps, so the requester's connection stays open while another account approves; when
it drops, its waiting request is withdrawn.

A request is read whole (at most ``MAX_BODY_BYTES``), decoded against its type, checked for the
protocol version, and only then acted on; a malformed, oversized or unknown message gets one
``Failure`` and changes nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import grp
import logging
import os
import signal
import socket
import threading
import time
import weakref
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime
from pathlib import Path
from typing import Any, TypeVar

import msgspec
from aiohttp import WSCloseCode, WSMsgType, web

from drs_link.config import Config
from drs_link.errors import ConfigError, LinkError, RefusedError, StoreError
from drs_link.ops import Approval, TelemetryRecord
from drs_link.server.approvals import ApprovalService
from drs_link.server.capsules import CapsuleService
from drs_link.server.chase import ChaseService
from drs_link.server.checklists import ChecklistService
from drs_link.server.desks import Desks, PredictorFor
from drs_link.server.history import HistoryService
from drs_link.server.iridium import IridiumService
from drs_link.server.peers import Mode, Peer, Roster, check_own_file, check_state_directory, peer_uid
from drs_link.server.protocol import (
    MAX_BODY_BYTES,
    MAX_RECOVERY_BYTES,
    PROTOCOL,
    ROOT,
    ArmRequest,
    DecideRequest,
    DisarmRequest,
    Done,
    EnrolRequest,
    Event,
    Failure,
    FireRequest,
    Hello,
    HistoryRequest,
    ItemRequest,
    KeepLandingRequest,
    MtSendRequest,
    Pending,
    PlanRequest,
    PowerOnRequest,
    ReasonRequest,
    RecoveryRequest,
    ReleasedRequest,
    Request,
    ResolveMtRequest,
    Said,
    SessionLossRequest,
    Step,
    StepRequest,
    SyncRequest,
    SyncStatusRequest,
    TakeOverRequest,
    TelemetryBatch,
    TrackRequest,
    TypedNameRequest,
    WaiveRequest,
    encode,
)
from drs_link.server.recovery import LiveFor, RecoveryService
from drs_link.server.release import ReleaseService
from drs_link.server.telemetry import Periods, TelemetryService
from drs_link.server.views import ViewService
from drs_link.server.waivers import WaiverService
from drs_link.store import Store
from predictor.errors import UsageError

log = logging.getLogger(__name__)
R = TypeVar("R", bound=Request)
EVENT_PERIOD_S = 0.25
"""How often the event stream looks for a change to push."""
WITHDRAWN_DROPPED = "withdrawn: the requester's connection closed while it waited"
WITHDRAWN_STOPPED = "withdrawn: the operations server stopped while it waited; ask again"
"""Why a request nobody waits for any more was withdrawn: said to the requester and in the audit, where
"cancelled by" its requester would name an act they never did."""
PEER = web.RequestKey("peer", Peer)
"""Who the kernel says sent a request (``SO_PEERCRED``), set before any route runs; a typed key, so
every route reads a ``Peer``."""
LISTEN_BACKLOG = 128
"""Connections the kernel holds for the server before it accepts them (aiohttp's own default)."""
STOP_GRACE_S = 3.0
"""How long a stopping server lets a request in flight finish before it cancels it and closes its
connection (its client's ``LinkError``): a read answers in milliseconds, and an action's approval
request is withdrawn first, so what is left is work that would hold the stop (a store locked by another
process, a link that stalls); the worker thread finishes it, nobody waits for it."""
_STATUS = {
    "refused": 409,
    "config": 400,
    "usage": 400,
    "protocol": 400,
    "identity": 403,
    "link": 502,
    "store": 500,
}


def failure(kind: str, error: str) -> web.Response:
    body = encode(Failure(kind, error))  # type: ignore[arg-type]
    return web.Response(status=_STATUS[kind], body=body, content_type="application/json")


def failure_of(exc: BaseException) -> Failure:
    kinds: list[tuple[type[BaseException], str]] = [
        (RefusedError, "refused"), (ConfigError, "config"), (StoreError, "store"), (UsageError, "usage"),
        (LinkError, "link"),
    ]  # fmt: skip
    for kind_of, kind in kinds:
        if isinstance(exc, kind_of):
            return Failure(kind, str(exc))  # type: ignore[arg-type]
    log.exception("unexpected error", exc_info=exc)
    return Failure("link", f"the server failed: {type(exc).__name__}: {exc}")


class ServerStopping(RefusedError):
    """The server is ending and its worker pool takes no more work."""


class OperationsServer:
    def __init__(
        self,
        config: Config,
        mode: Mode,
        socket_path: Path,
        *,
        group: str | None = None,
        idle_exit_s: float | None = None,
        predictor_for: PredictorFor | None = None,
        environ: dict[str, str] | None = None,
        live_for: LiveFor | None = None,
        clock: Callable[[], datetime] | None = None,
        poll_period_s: float | None = None,
    ) -> None:
        """``poll_period_s``: how often the telemetry polls each capsule, in real seconds (default: by the
        store's time scale, ``telemetry.Periods``)."""
        if config.source is not None:
            check_own_file(config.source)
        if mode == "shared":
            check_state_directory(config.store_path.parent)
        self.config = config
        self.mode = mode
        self.socket_path = socket_path
        self.group = group
        self.idle_exit_s = idle_exit_s
        self.roster = Roster(config, mode)
        self.store = Store.open(config.store_path)
        self.desks = Desks(config, self.store, environ, clock)
        self.waivers = WaiverService(self.desks)
        self.checklists = ChecklistService(self.desks)
        self.history = HistoryService(self.desks)
        self.views = ViewService(self.desks, self.waivers, self.checklists)
        self.release = ReleaseService(self.desks, mode, self.waivers, predictor_for)
        self.iridium = IridiumService(self.desks, mode)
        self.capsules = CapsuleService(self.desks, mode)
        self.approvals = ApprovalService(self.store, self.desks.clock)
        self.recovery = RecoveryService(self.desks, live_for)
        self.chase = ChaseService(self.desks)
        self.pool = ThreadPoolExecutor(max_workers=32, thread_name_prefix="drs-server")
        self.feed = TelemetryService(
            self.desks.server_desk, [c.name for c in config.capsules],
            Periods.at_scale(self.store.scale, poll_period_s), self.blocking,
        )  # fmt: skip
        """The capsules' telemetry, polled once for every console that follows ``/v1/telemetry``."""
        self.busy = 0
        self.last_active = time.monotonic()
        self.stopping = asyncio.Event()
        self.held: dict[int, tuple[Peer, Approval]] = {}
        """Requests a connection waits on: withdrawn if it drops, or when the server stops."""
        self.changes = asyncio.Event()
        """Set (then replaced) whenever a request may have changed what the event streams show: each
        stream wakes at once instead of at its next look (``EVENT_PERIOD_S``), which stays for what the
        server did not do itself (an MO report, an ARM window running out). Loop thread only."""
        self.streams: set[web.WebSocketResponse] = set()
        """Open event streams, closed first when the server stops (their handlers then end before the
        worker pool does, instead of asking a pool that was shut down)."""
        self.connections: weakref.WeakSet[asyncio.Transport] = weakref.WeakSet()
        """Every connection made (``accept``): the stop closes each before the loop ends."""
        self.accepting: set[asyncio.Task[None]] = set()
        """Connections accepted and not yet made: the stop waits for them (``accept``)."""

    # Plumbing ------------------------------------------------------------------------------------

    async def blocking(self, work: Callable[[], Any]) -> Any:
        return await self.worker(work)

    def worker(self, work: Callable[[], Any]) -> asyncio.Future[Any]:
        """``work`` on the worker pool; refused as ``ServerStopping`` once the pool takes no more.

        Why: a pool shut down by the stop, or by the interpreter's exit (a server in a thread of a process
        that is ending), raises a bare ``RuntimeError: cannot schedule new futures``. A handler that asks
        then is one the server is ending under: its client is told so in one line, and nothing is logged
        as an unexpected error."""
        try:
            return asyncio.get_running_loop().run_in_executor(self.pool, work)
        except RuntimeError:
            raise ServerStopping("the operations server is stopping: ask again when it is back") from None

    def peer(self, request: web.Request) -> Peer:
        sock = request.transport.get_extra_info("socket") if request.transport else None
        if sock is None:
            raise RefusedError("no connection to read the caller from")
        return self.roster.peer(peer_uid(sock))

    async def body(self, request: web.Request, kind: type[R]) -> R:
        raw = await request.read()
        try:
            decoded = msgspec.json.decode(raw, type=kind)
        except msgspec.ValidationError as exc:
            raise _ProtocolError(f"malformed {kind.__name__}: {exc}") from None
        except msgspec.DecodeError as exc:
            raise _ProtocolError(f"not JSON: {exc}") from None
        if decoded.protocol != PROTOCOL:
            raise _ProtocolError(
                f"the client speaks protocol {decoded.protocol}, this server {PROTOCOL}: use one drs version"
            )
        return decoded

    @web.middleware
    async def guard(
        self, request: web.Request, handler: Callable[[web.Request], Awaitable[web.StreamResponse]]
    ) -> web.StreamResponse:
        """Every request: who it is from (the kernel), then its errors as one typed ``Failure``."""
        self.busy += 1
        self.last_active = time.monotonic()
        try:
            if not request.path.startswith(ROOT + "/"):
                return failure(
                    "protocol", f"{request.path}: this server speaks protocol {PROTOCOL} ({ROOT}/…)"
                )
            try:
                request[PEER] = self.peer(request)
            except (RefusedError, ConfigError) as exc:
                return failure("identity", str(exc))
            return await handler(request)
        except web.HTTPRequestEntityTooLarge:
            most = MAX_RECOVERY_BYTES if request.path.startswith(f"{ROOT}/recovery/") else MAX_BODY_BYTES
            return failure("protocol", f"the request is larger than {most} bytes: refused unread")
        except web.HTTPException as exc:
            return failure("protocol", f"{request.method} {request.path}: {exc.reason}")
        except _ProtocolError as exc:
            return failure("protocol", str(exc))
        except Exception as exc:  # noqa: BLE001 - every error reaches the operator as one line
            found = failure_of(exc)
            return failure(found.kind, found.error)
        finally:
            self.busy -= 1
            self.last_active = time.monotonic()
            if request.method != "GET":
                self.changed()

    async def stream(
        self, request: web.Request, work: Callable[[Callable[[str], None], Callable[[Approval], None]], Done]
    ) -> web.StreamResponse:
        """Run ``work(say, on_pending)`` in a worker and stream its steps; a dropped client withdraws the
        approval request it waited on (the action is then refused and nothing is sent)."""
        peer = request[PEER]
        loop = asyncio.get_running_loop()
        steps: asyncio.Queue[Step | None] = asyncio.Queue()
        waiting: list[Approval] = []
        dropped = threading.Event()
        """Set before the requests held for a dropped client are withdrawn (as ``stopping`` is before the
        stop withdraws them): a request its worker asks for after that withdrawal sees it and is withdrawn at
        once, instead of waiting pending, its action with it, for an approval nobody watches."""

        def post(step: Step, changed: bool = True) -> None:
            """Hand a step to the stream; once a stop past its grace has ended the loop nobody reads it, and
            the worker goes on to finish its action (``STOP_GRACE_S``) instead of dying on a closed loop."""
            with contextlib.suppress(RuntimeError):  # "Event loop is closed"
                loop.call_soon_threadsafe(steps.put_nowait, step)
                if changed:  # each step may have moved a window or a request on
                    loop.call_soon_threadsafe(self.changed)

        def say(line: str) -> None:
            post(Said(line))

        def on_pending(approval: Approval) -> None:
            waiting.append(approval)
            self.held[approval.id] = (peer, approval)
            self.approvals.requested(peer, approval)
            if self.stopping.is_set() or dropped.is_set():  # held after the withdrawal: refused, unstreamed
                self.withdraw([approval], WITHDRAWN_STOPPED if self.stopping.is_set() else WITHDRAWN_DROPPED)
                return
            text = (f"approval #{approval.id}: waiting for another account to run `drs approve {approval.id}` "
                    f"(expires {approval.expires_utc:%H:%M:%S}Z)")  # fmt: skip
            post(Pending(approval.id, text))

        def run() -> None:
            try:
                end: Step = work(say, on_pending)
            except Exception as exc:  # noqa: BLE001 - the stream's last step says what went wrong
                end = failure_of(exc)
            post(end, changed=False)

        response = web.StreamResponse(headers={"Content-Type": "application/x-ndjson"})
        await response.prepare(request)
        job = self.worker(run)
        while True:
            try:
                step = await asyncio.wait_for(steps.get(), timeout=0.25)
            except TimeoutError:
                if request.transport is None or request.transport.is_closing():
                    dropped.set()
                    await self.blocking(lambda: self.withdraw(waiting, WITHDRAWN_DROPPED))
                    await job
                    return response
                continue
            with contextlib.suppress(ConnectionError):
                await response.write(encode(step) + b"\n")
            if isinstance(step, Done | Failure):
                break
        await job
        for approval in waiting:
            self.held.pop(approval.id, None)
        with contextlib.suppress(ConnectionError):
            await response.write_eof()
        return response

    def withdraw(self, requests: list[Approval], why: str) -> None:
        """Cancel requests whose requester is gone (its connection, or the server), saying ``why``: the
        action waiting on each is then refused and sends nothing."""
        for approval in requests:
            peer = self.held.pop(approval.id, (None, None))[0]
            with contextlib.suppress(RefusedError):
                self.approvals.book.cancel(
                    approval.id, peer.operator if peer else "drs server", approval.requester, why
                )

    # Routes ---------------------------------------------------------------------------------------

    async def hello(self, request: web.Request) -> web.Response:
        peer = request[PEER]
        hello = Hello(
            PROTOCOL, self.mode, peer.uid, peer.account, peer.operator,
            self.config.console.require_second_operator, tuple(c.name for c in self.config.capsules),
        )  # fmt: skip
        return json_response(hello)

    async def arm(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, ArmRequest)
        name = request.match_info["name"]
        return await self.stream(
            request, lambda say, _: Done((), True, self.release.arm(request[PEER], name, body, say))
        )

    async def disarm(self, request: web.Request) -> web.Response:
        body = await self.body(request, DisarmRequest)
        name = request.match_info["name"]
        state = await self.blocking(lambda: self.release.disarm(request[PEER], name, body.reason))
        return json_response(state)

    async def fire(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, FireRequest)
        name = request.match_info["name"]
        return await self.stream(
            request,
            lambda say, pending: Done(tuple(self.release.fire(request[PEER], name, body, say, pending))),
        )

    async def send_mt(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, MtSendRequest)
        name = request.match_info["name"]
        return await self.stream(
            request, lambda say, pending: self.iridium.send_mt(request[PEER], name, body, say, pending)
        )

    async def mt_status(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.iridium.mt_status(request[PEER], name)))

    async def resolve_mt(self, request: web.Request) -> web.Response:
        body = await self.body(request, ResolveMtRequest)
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.iridium.resolve_mt(request[PEER], name, body)))

    async def health(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.iridium.health(request[PEER], name)))

    async def track(self, request: web.Request) -> web.Response:
        body = await self.body(request, TrackRequest)
        return json_response(await self.blocking(lambda: self.iridium.track(request[PEER], body)))

    async def recovery_readout(self, request: web.Request) -> web.Response:
        """The one request that carries a track (the operator's predicted one): read up to its own limit."""
        body = await self.body(request.clone(client_max_size=MAX_RECOVERY_BYTES), RecoveryRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.recovery.readout(request[PEER], name, body))
        return json_response(view)

    async def chase_points(self, request: web.Request) -> web.Response:
        return json_response(await self.blocking(self.chase.points))

    async def keep_landing(self, request: web.Request) -> web.Response:
        body = await self.body(request, KeepLandingRequest)
        await self.blocking(lambda: self.chase.keep(body.landing))
        return json_response(None)

    # The capsule's other steps (``capsules``): each one request, a power-on and a take-over streamed.

    async def status(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.capsules.status(request[PEER], name)))

    async def power_on(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, PowerOnRequest)
        name = request.match_info["name"]
        return await self.stream(
            request, lambda say, _: self.capsules.power_on(request[PEER], name, body.confirmed, say)
        )

    async def reset(self, request: web.Request) -> web.Response:
        body = await self.body(request, TypedNameRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.capsules.reset(request[PEER], name, body.typed_name))
        self.waivers.void(view.capsule)
        return json_response(view)

    async def released(self, request: web.Request) -> web.Response:
        body = await self.body(request, ReleasedRequest)
        name = request.match_info["name"]
        view = await self.blocking(
            lambda: self.capsules.released(request[PEER], name, body.typed_name, body.evidence)
        )
        return json_response(view)

    async def authority(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.capsules.authority(request[PEER], name)))

    async def check_take_over(self, request: web.Request) -> web.Response:
        body = await self.body(request, ReasonRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.capsules.check_take_over(request[PEER], name, body.reason))
        return json_response(view)

    async def take_over(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, TakeOverRequest)
        name = request.match_info["name"]
        return await self.stream(
            request, lambda say, pending: self.capsules.take_over(request[PEER], name, body, say, pending)
        )

    async def release_authority(self, request: web.Request) -> web.Response:
        body = await self.body(request, ReasonRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.capsules.release_authority(request[PEER], name, body.reason))
        return json_response(view)

    async def sync(self, request: web.Request) -> web.StreamResponse:
        body = await self.body(request, SyncRequest)
        name = request.match_info["name"]
        return await self.stream(
            request, lambda say, _: self.capsules.sync(request[PEER], name, body.source, say)
        )

    async def sync_status(self, request: web.Request) -> web.Response:
        body = await self.body(request, SyncStatusRequest)
        name = request.match_info["name"]
        view = await self.blocking(
            lambda: self.capsules.sync_status(request[PEER], name, body.source, body.with_hash)
        )
        return json_response(view)

    async def host_key(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.capsules.host_key_offer(request[PEER], name)))

    async def enrol(self, request: web.Request) -> web.Response:
        body = await self.body(request, EnrolRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.capsules.enrol(request[PEER], name, body.fingerprint))
        return json_response(view)

    # A console's desk (``desk``): its waivers, the checklists, the audit, its session, the views it draws.

    async def desk(self, request: web.Request) -> web.Response:
        return json_response(await self.blocking(lambda: self.views.desk(request[PEER])))

    async def waive(self, request: web.Request) -> web.Response:
        body = await self.body(request, WaiveRequest)
        name = request.match_info["name"]
        held = await self.blocking(lambda: self.waivers.waive(request[PEER], name, body.item, body.reason))
        return json_response(held)

    async def withdraw_waiver(self, request: web.Request) -> web.Response:
        body = await self.body(request, ItemRequest)
        name = request.match_info["name"]
        return json_response(
            await self.blocking(lambda: self.waivers.withdraw(request[PEER], name, body.item))
        )

    async def held_waivers(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.waivers.held(request[PEER], name)))

    async def checklist_step(self, request: web.Request) -> web.Response:
        body = await self.body(request, StepRequest)
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.checklists.step(request[PEER], name, body)))

    async def audit(self, request: web.Request) -> web.Response:
        body = await self.body(request, HistoryRequest)
        return json_response(await self.blocking(lambda: self.history.read(request[PEER], body)))

    async def session_start(self, request: web.Request) -> web.Response:
        await self.body(request, HistoryRequest)
        return json_response(await self.blocking(lambda: self.history.started(request[PEER])))

    async def session_lost(self, request: web.Request) -> web.Response:
        body = await self.body(request, SessionLossRequest)
        return json_response(await self.blocking(lambda: self.history.lost(request[PEER], body)))

    async def recovery_view(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.views.recovery(request[PEER], name)))

    async def iridium_view(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.views.iridium(request[PEER], name)))

    async def plan_parachute(self, request: web.Request) -> web.Response:
        body = await self.body(request, PlanRequest)
        name = request.match_info["name"]
        view = await self.blocking(lambda: self.iridium.plan_parachute(request[PEER], name, body.requested))
        return json_response(view)

    async def landed(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        return json_response(await self.blocking(lambda: self.iridium.landed(request[PEER], name)))

    async def waiting(self, request: web.Request) -> web.Response:
        return json_response(await self.blocking(self.approvals.waiting))

    async def decide(self, request: web.Request) -> web.Response:
        body = await self.body(request, DecideRequest)
        try:
            approval_id = int(request.match_info["approval"])
        except ValueError:
            raise _ProtocolError(f"{request.match_info['approval']!r} is not an approval number") from None
        view = await self.blocking(
            lambda: self.approvals.decide(request[PEER], approval_id, body.approve, body.reason)
        )
        return json_response(view)

    async def events(self, request: web.Request) -> web.WebSocketResponse:
        """Push an ``Event`` whenever what it shows changed; a client that sends anything is told this
        stream is one-way and closed (nothing it sends is acted on)."""
        ws = web.WebSocketResponse(heartbeat=10.0)
        await ws.prepare(request)
        self.streams.add(ws)
        last = b""
        reader = asyncio.ensure_future(ws.receive())
        try:
            while not ws.closed and not self.stopping.is_set():
                changes = self.changes  # taken before the look: a change made during it wakes the next wait
                try:
                    event = encode(await self.blocking(lambda: self.event(request[PEER])))
                except ServerStopping:
                    break  # the stream ends for its client like any stop's (the pool takes no more)
                if event != last:
                    try:
                        await ws.send_bytes(event)
                    except ConnectionError:
                        break  # closed while it looked: the console went away, or the server stops
                    last = event
                woken = asyncio.ensure_future(changes.wait())
                try:
                    done, _ = await asyncio.wait(
                        {reader, woken}, timeout=EVENT_PERIOD_S, return_when=asyncio.FIRST_COMPLETED
                    )
                finally:
                    woken.cancel()
                if reader in done:
                    message = reader.result()
                    if message.type in (WSMsgType.TEXT, WSMsgType.BINARY):
                        with contextlib.suppress(ConnectionError):
                            await ws.send_bytes(
                                encode(Failure("protocol", "the event stream takes no messages"))
                            )
                    await ws.close()
                    break
                self.last_active = time.monotonic()
        finally:
            reader.cancel()
            self.streams.discard(ws)
        return ws

    async def poll(self, request: web.Request) -> web.Response:
        """A poll now (a console's refresh key), answered and pushed to every telemetry subscriber."""
        name = request.match_info["name"]
        records: list[TelemetryRecord] = await self.blocking(
            lambda: self.desks.server_desk().links.poll(name)
        )
        self.feed.publish(records)
        return json_response(batch_of(records))

    async def telemetry(self, request: web.Request) -> web.WebSocketResponse:
        """Push the snapshot (the latest of each kind per capsule), then each new batch as the server
        polls it; like ``events``, a client that sends anything is told the stream is one-way and closed."""
        ws = web.WebSocketResponse(heartbeat=10.0)
        await ws.prepare(request)
        self.streams.add(ws)
        subscription = self.feed.subscribe()
        reader = asyncio.ensure_future(ws.receive())
        try:
            while not ws.closed and not self.stopping.is_set():
                batch = asyncio.ensure_future(subscription.next())
                try:
                    done, _ = await asyncio.wait({reader, batch}, return_when=asyncio.FIRST_COMPLETED)
                finally:
                    batch.cancel()
                if batch in done:
                    try:
                        await ws.send_bytes(encode(batch_of(batch.result())))
                    except ConnectionError:
                        break  # the console went away: its reader ends the same way
                    self.last_active = time.monotonic()
                if reader in done:
                    message = reader.result()
                    if message.type in (WSMsgType.TEXT, WSMsgType.BINARY):
                        with contextlib.suppress(ConnectionError):
                            await ws.send_bytes(
                                encode(Failure("protocol", "the telemetry stream takes no messages"))
                            )
                    await ws.close()
                    break
        finally:
            reader.cancel()
            self.feed.unsubscribe(subscription)
            self.streams.discard(ws)
        return ws

    def changed(self) -> None:
        """Wake every event stream now (``changes``)."""
        self.changes.set()
        self.changes = asyncio.Event()

    def event(self, peer: Peer) -> Event:
        """What a subscriber sees: every capsule's release state and ARM window (whose, from its account)
        and the approvals that wait."""
        desk = self.desks.any_desk()
        release, armed = {}, {}
        if desk is not None:
            for name, capsule in desk.state.capsules.items():
                release[name] = capsule.machine.record().state.value
                window = capsule.arming.windows.latest(name)
                armed[name] = window.state if window is not None else "none"
        return Event(
            release,
            armed,
            tuple(self.approvals.waiting()),
            self.release.arm_states(peer),
            self.views.newest_id(),
        )

    # Running --------------------------------------------------------------------------------------

    def application(self) -> web.Application:
        app = web.Application(middlewares=[self.guard], client_max_size=MAX_BODY_BYTES)
        app.router.add_get(f"{ROOT}/hello", self.hello)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/arm", self.arm)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/disarm", self.disarm)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/fire", self.fire)
        app.router.add_get(f"{ROOT}/capsules/{{name}}/status", self.status)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/power-on", self.power_on)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/reset", self.reset)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/released", self.released)
        app.router.add_get(f"{ROOT}/capsules/{{name}}/authority", self.authority)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/authority/check-take-over", self.check_take_over)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/authority/take-over", self.take_over)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/authority/release", self.release_authority)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/sync", self.sync)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/sync/status", self.sync_status)
        app.router.add_get(f"{ROOT}/capsules/{{name}}/host-key", self.host_key)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/host-key", self.enrol)
        app.router.add_post(f"{ROOT}/iridium/{{name}}/mt", self.send_mt)
        app.router.add_get(f"{ROOT}/iridium/{{name}}/mt", self.mt_status)
        app.router.add_post(f"{ROOT}/iridium/{{name}}/mt/resolve", self.resolve_mt)
        app.router.add_get(f"{ROOT}/iridium/{{name}}/health", self.health)
        app.router.add_post(f"{ROOT}/iridium/track", self.track)
        app.router.add_post(f"{ROOT}/recovery/{{name}}", self.recovery_readout)
        app.router.add_get(f"{ROOT}/chase/points", self.chase_points)
        app.router.add_post(f"{ROOT}/chase/landing", self.keep_landing)
        app.router.add_get(f"{ROOT}/desk", self.desk)
        app.router.add_get(f"{ROOT}/capsules/{{name}}/waivers", self.held_waivers)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/waivers", self.waive)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/waivers/withdraw", self.withdraw_waiver)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/checklist", self.checklist_step)
        app.router.add_post(f"{ROOT}/audit", self.audit)
        app.router.add_post(f"{ROOT}/session/start", self.session_start)
        app.router.add_post(f"{ROOT}/session/lost", self.session_lost)
        app.router.add_get(f"{ROOT}/views/{{name}}/recovery", self.recovery_view)
        app.router.add_get(f"{ROOT}/views/{{name}}/iridium", self.iridium_view)
        app.router.add_post(f"{ROOT}/iridium/{{name}}/parachute-plan", self.plan_parachute)
        app.router.add_get(f"{ROOT}/iridium/{{name}}/landed", self.landed)
        app.router.add_get(f"{ROOT}/approvals", self.waiting)
        app.router.add_post(f"{ROOT}/approvals/{{approval}}", self.decide)
        app.router.add_get(f"{ROOT}/events", self.events)
        app.router.add_post(f"{ROOT}/capsules/{{name}}/poll", self.poll)
        app.router.add_get(f"{ROOT}/telemetry", self.telemetry)
        return app

    async def run(self, ready: Callable[[str], None] = print) -> None:
        claim_socket(self.socket_path)
        runner = web.AppRunner(
            self.application(), access_log=None, handle_signals=False, shutdown_timeout=STOP_GRACE_S
        )
        await runner.setup()
        listening = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        old = os.umask(0o177 if self.mode == "private" else 0o117)
        try:
            listening.bind(str(self.socket_path))
        finally:
            os.umask(old)
        listening.listen(LISTEN_BACKLOG)
        listening.setblocking(False)
        if self.group is not None:
            os.chown(self.socket_path, -1, grp.getgrnam(self.group).gr_gid)
        self.socket_path.chmod(0o600 if self.mode == "private" else 0o660)
        handler = runner.server
        assert handler is not None  # made by setup
        loop = asyncio.get_running_loop()
        loop.add_reader(listening, self.accept, listening, handler)
        if threading.current_thread() is threading.main_thread():  # a private server in a thread has none
            for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
                loop.add_signal_handler(sig, self.stopping.set)
        who = ", ".join(f"{o.account} as {o.name}" for o in self.config.operators) or self.roster.own_name
        ready(
            f"drs server ({self.mode}, protocol {PROTOCOL}): listening on {self.socket_path}; operators: {who}"
        )
        try:
            while not self.stopping.is_set():
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self.stopping.wait(), timeout=1.0)
                if self.idle_exit_s is not None and self.busy == 0:
                    if time.monotonic() - self.last_active > self.idle_exit_s:
                        ready(f"drs server: idle for {self.idle_exit_s:.0f} s: exiting")
                        break
        finally:
            await self.stop(listening, runner)

    def accept(self, listening: socket.socket, handler: web.Server) -> None:
        """Take every connection waiting on the listening socket, each made into aiohttp's handler.

        Why not ``loop.create_unix_server`` (nor aiohttp's ``UnixSite``, which uses it): on Python 3.11
        a connection accepted in the loop turn before its ``Server.close()`` is made a turn later, fails
        the closed server's ``assert self._sockets is not None`` (``Server._attach``), and the error is
        dropped; its socket was left in a reference cycle, open until a garbage collection, neither
        answered nor closed, and its client waited its whole timeout (600 s). Here every accepted
        socket becomes a connection the stop waits for (``accepting``) and closes (``connections``)."""
        while True:
            try:
                conn, _ = listening.accept()
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionAbortedError:
                continue
            except OSError as exc:  # out of file descriptors: listen again in a second, as asyncio does
                log.warning("drs server: cannot accept a connection: %s", exc)
                loop = asyncio.get_running_loop()
                loop.remove_reader(listening)
                loop.call_later(1.0, self.listen_again, listening, handler)
                return
            task = asyncio.get_running_loop().create_task(self.connect(conn, handler))
            self.accepting.add(task)
            task.add_done_callback(self.accepting.discard)

    def listen_again(self, listening: socket.socket, handler: web.Server) -> None:
        """Accept again after a pause (``accept``), unless the server began to stop meanwhile: its listening
        socket is closed, and adding it back failed in the loop ("Invalid file descriptor: -1")."""
        if not self.stopping.is_set():
            asyncio.get_running_loop().add_reader(listening, self.accept, listening, handler)

    async def connect(self, conn: socket.socket, handler: web.Server) -> None:
        try:
            transport, _ = await asyncio.get_running_loop().connect_accepted_socket(handler, conn)
        except OSError:  # the client went away before its connection was made
            conn.close()
            return
        self.connections.add(transport)

    async def stop(self, listening: socket.socket, runner: web.AppRunner) -> None:
        """End every connection before the loop and the worker pool end, in this order: accept nothing more;
        end the event streams and the telemetry; withdraw the approval requests held (the actions waiting on
        them are refused and send nothing); let aiohttp answer each request in flight within
        ``STOP_GRACE_S``, then cancel it; close every connection still open. A handler still running
        when the pool was shut down asked it for a worker (``RuntimeError: cannot schedule new futures
        after shutdown``); one left open when the loop ended was never answered (``accept``)."""
        self.stopping.set()
        asyncio.get_running_loop().remove_reader(listening)
        listening.close()
        for ws in list(self.streams):
            await ws.close(code=WSCloseCode.GOING_AWAY, message=b"the operations server is stopping")
        await self.feed.stop()
        await self.blocking(
            lambda: self.withdraw([a for _, a in list(self.held.values())], WITHDRAWN_STOPPED)
        )
        await asyncio.gather(*self.accepting)  # every accepted connection made: aiohttp's shutdown sees it
        await runner.cleanup()
        for transport in list(self.connections):
            transport.abort()  # one whose answer its client does not read is closed, not flushed
        await asyncio.sleep(0)  # an aborted connection's socket closes in the next loop turn
        with contextlib.suppress(FileNotFoundError):
            self.socket_path.unlink()
        self.desks.close()
        self.pool.shutdown(wait=False, cancel_futures=True)


class _ProtocolError(Exception):
    """A request that is not a valid message of this protocol: refused before it is acted on."""


def batch_of(records: list[TelemetryRecord]) -> TelemetryBatch:
    return TelemetryBatch(tuple(record.to_json() for record in records))


def json_response(value: object) -> web.Response:
    return web.Response(body=encode(value), content_type="application/json")


def claim_socket(path: Path) -> None:
    """Take over a stale socket file (a server that died), never a live server's."""
    if not path.exists():
        return
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(str(path))
    except OSError:
        path.unlink()
        return
    finally:
        probe.close()
    raise LinkError(f"{path}: an operations server already listens there")
