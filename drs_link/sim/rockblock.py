"""A RockBLOCK gateway and a DRS capsule's Iridium side, simulated on loopback for tests and the demo.

The Iridium network cannot exist here, so this stands in for it and behaves like the real thing,
failures included: the MT endpoint answers ``OK,<id>`` or each documented ``FAILED`` code, can be
told to answer slowly or reset the connection, queues MTs per IMEI and hands out one per session;
the capsule builds byte-exact MO reports and applies downloaded MTs with the firmware's own rules
(``drs_link.iridium.commands``), including the ±14 min PARACHUTE test and silent loss of bad commands.
"""

from __future__ import annotations

import functools
import json
import math
import socket
import struct
import threading
import time
import urllib.error
import urllib.request
from collections import deque
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlencode

import jwt
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa

from drs_link.iridium import GnssFix, MtEffect, apply_mt, format_mo

MAX_MT_BYTES_GATEWAY = 270
MT_PATH = "/rockblock/MT"


@dataclass(frozen=True)
class Scripted:
    """How the gateway treats the next MT request: ``ok``, ``failed`` (with code), ``slow``, ``reset``."""

    action: str
    code: int = 0
    delay_s: float = 0.0


@dataclass
class ReceivedMt:
    form: dict[str, str]
    path: str
    answered: str


class _MtHandler(BaseHTTPRequestHandler):
    server: _GatewayHttpServer

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the stdlib's signature
        """Silent: request lines on stderr would clutter test output and the demo screen."""

    def do_POST(self) -> None:  # noqa: N802 - the stdlib's name
        length = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(length).decode("ascii", "replace")
        form = {key: values[0] for key, values in parse_qs(body, keep_blank_values=True).items()}
        gateway = self.server.gateway
        scripted = gateway.next_script()
        if scripted.action == "reset":
            gateway.record(ReceivedMt(form, self.path, "reset"))
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            self.close_connection = True
            self.connection.close()
            return
        if scripted.action == "failed":
            answer = f"FAILED,{scripted.code},Scripted failure"
        else:
            answer = gateway.queue_mt(form)
        gateway.record(ReceivedMt(form, self.path, answer))
        if scripted.action == "slow":
            time.sleep(scripted.delay_s)
        encoded = answer.encode("ascii")
        try:
            self.send_response(200)
            self.send_header("Content-Type", "text/plain")
            self.send_header("Content-Length", str(len(encoded)))
            self.end_headers()
            self.wfile.write(encoded)
        except OSError:
            self.close_connection = True


class _GatewayHttpServer(ThreadingHTTPServer):
    daemon_threads = True
    gateway: SimulatedRockblock


class SimulatedRockblock:
    """The gateway: MT endpoint on 127.0.0.1, per-IMEI MT queues, one MT handed out per session."""

    def __init__(
        self,
        username: str = "drs-demo",
        password: str = "demo-secret",
        imeis: tuple[str, ...] = (),
        port: int = 0,
    ) -> None:
        self.username = username
        self.password = password
        self.imeis = set(imeis)
        self.requests: list[ReceivedMt] = []
        self.queues: dict[str, deque[bytes]] = {}
        self._script: deque[Scripted] = deque()
        self._lock = threading.Lock()
        self._next_mt_id = 4114651
        self._server = _GatewayHttpServer(("127.0.0.1", port), _MtHandler)
        self._server.gateway = self
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_address[1]}{MT_PATH}"

    def start(self) -> SimulatedRockblock:
        self._thread = threading.Thread(
            target=self._server.serve_forever, args=(0.05,), name="sim-rockblock", daemon=True
        )
        self._thread.start()
        return self

    def stop(self) -> None:
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5)
            self._thread = None
        self._server.server_close()

    def __enter__(self) -> SimulatedRockblock:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def script(self, *behaviour: Scripted) -> None:
        """Queue how the next requests are answered; after these, requests are handled normally."""
        with self._lock:
            self._script.extend(behaviour)

    def next_script(self) -> Scripted:
        with self._lock:
            return self._script.popleft() if self._script else Scripted("ok")

    def record(self, received: ReceivedMt) -> None:
        with self._lock:
            self.requests.append(received)

    def queue_mt(self, form: dict[str, str]) -> str:
        """Validate like the real gateway and queue the MT; returns the reply body."""
        if form.get("username") != self.username or form.get("password") != self.password:
            return "FAILED,10,Invalid login credentials"
        imei = form.get("imei", "")
        if self.imeis and imei not in self.imeis:
            return "FAILED,11,No RockBLOCK with this IMEI found on your account"
        data = form.get("data", "")
        if not data:
            return "FAILED,16,No data"
        try:
            payload = bytes.fromhex(data)
        except ValueError:
            return "FAILED,14,Could not decode hex data"
        if len(payload) > MAX_MT_BYTES_GATEWAY:
            return "FAILED,15,Data too long"
        with self._lock:
            queue = self.queues.setdefault(imei, deque())
            if form.get("flush") == "yes":
                queue.clear()
            queue.append(payload)
            self._next_mt_id += 1
            return f"OK,{self._next_mt_id}"

    def download(self, imei: str) -> bytes | None:
        """The modem's SBD session fetches at most one MT, which then leaves the queue for good."""
        with self._lock:
            queue = self.queues.get(imei)
            return queue.popleft() if queue else None


@dataclass
class MoDelivery:
    """One MO as the gateway delivers it to a webhook."""

    imei: str
    serial: int
    momsn: int
    payload: bytes
    transmit_time: datetime
    iridium_latitude: float
    iridium_longitude: float
    iridium_cep: float

    def fields(self) -> dict[str, str]:
        return {
            "imei": self.imei,
            "device_type": "ROCKBLOCK",
            "serial": str(self.serial),
            "momsn": str(self.momsn),
            "transmit_time": self.transmit_time.strftime("%y-%m-%d %H:%M:%S"),
            "iridium_latitude": f"{self.iridium_latitude:.4f}",
            "iridium_longitude": f"{self.iridium_longitude:.4f}",
            "iridium_cep": f"{self.iridium_cep:.1f}",
            "data": self.payload.hex(),
        }


def generate_test_keys() -> tuple[str, str]:
    """A fresh RS256 key pair (private PEM, public PEM) standing in for Ground Control's signing key."""
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    private = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    ).decode("ascii")
    public = (
        key.public_key()
        .public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
        .decode("ascii")
    )
    return private, public


def post_mo(
    receiver_url: str,
    delivery: MoDelivery,
    as_json: bool = False,
    jwt_private_key: str | None = None,
    timeout_s: float = 5.0,
) -> int:
    """POST one MO like the gateway (HTTP_POST form or HTTP_JSON), optionally with an RS256 ``JWT``."""
    return post_body(receiver_url, *mo_body(delivery, as_json, jwt_private_key), timeout_s=timeout_s)


def mo_body(
    delivery: MoDelivery, as_json: bool = False, jwt_private_key: str | None = None
) -> tuple[bytes, str]:
    """The body and Content-Type the gateway would POST for ``delivery``, signed when a key is given."""
    fields: dict[str, str] = delivery.fields()
    if jwt_private_key is not None:
        fields["JWT"] = jwt.encode(
            {"iss": "Rock 7", **fields}, _signing_key(jwt_private_key), algorithm="RS256"
        )
    if as_json:
        return json.dumps(fields).encode(), "application/json"
    return urlencode(fields).encode(), "application/x-www-form-urlencoded"


@functools.lru_cache(maxsize=4)
def _signing_key(pem: str) -> rsa.RSAPrivateKey:
    """Loaded once: given the PEM, PyJWT loads and validates the RSA key on every call, 38 ms a post."""
    key = serialization.load_pem_private_key(pem.encode("ascii"), password=None)
    assert isinstance(key, rsa.RSAPrivateKey)
    return key


def post_body(receiver_url: str, body: bytes, content_type: str, timeout_s: float = 5.0) -> int:
    """One POST as the gateway makes it; the HTTP status (an error status is returned, not raised)."""
    request = urllib.request.Request(receiver_url, data=body, headers={"Content-Type": content_type})
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as response:
            return int(response.status)
    except urllib.error.HTTPError as exc:
        return int(exc.code)


@dataclass
class SimulatedCapsule:
    """The DRS's Gone-mode Iridium side: one MO per cycle and at most one MT downloaded with it."""

    imei: str
    rb_source: int
    interval_min: int = 2
    """INTERVAL in flash: what the alarm is re-armed with when it next fires."""
    armed_spacing_min: int = 2
    """Minutes to the next cycle: armed when this cycle's alarm fired, before any MT of its session."""
    rb_destination: int = 0
    sounder_on: bool = True
    vbat: float = 8.9
    iteration: int = 0
    momsn: int = 0
    parachute_open: bool = False
    effects: list[MtEffect] = field(default_factory=list)

    def next_cycle(self, alarm: datetime) -> datetime:
        """When the cycle after the one whose alarm fired at ``alarm`` starts (after its ``session``).

        The firmware re-arms the alarm as it fires, before the session downloads an MT
        (drs_protocol.md 3.5, 3.8): a new INTERVAL spaces the cycle after next, never the next one.
        """
        return alarm + timedelta(minutes=self.armed_spacing_min)

    def session(
        self,
        gateway: SimulatedRockblock,
        fix: GnssFix | None,
        transmit_time: datetime,
        iridium_position: tuple[float, float, float] = (0.0, 0.0, 100.0),
    ) -> MoDelivery:
        """Send this cycle's report and apply the MT downloaded in the same session."""
        self.armed_spacing_min = self.interval_min
        payload = format_mo(fix, self.vbat, self.iteration, self.rb_destination, self.rb_source)
        delivery = MoDelivery(
            self.imei, self.rb_source, self.momsn, payload, transmit_time, *iridium_position
        )
        self.momsn = (self.momsn + 1) % 65536
        self.iteration += 1
        mt = gateway.download(self.imei)
        if mt is not None:
            effect = apply_mt(mt, fix)
            self.effects.append(effect)
            if effect.interval is not None:
                self.interval_min = effect.interval
            if effect.rb_source is not None:
                self.rb_source = effect.rb_source
            if effect.rb_destination is not None:
                self.rb_destination = effect.rb_destination
            if effect.sounder is not None:
                self.sounder_on = effect.sounder
            self.parachute_open = self.parachute_open or effect.parachute_opens
        return delivery


@dataclass(frozen=True)
class SimulatedDescent:
    """Where a capsule is, falling under its parachute from release and then lying still, for the demo.

    The fall speed grows with height as 1/sqrt(air density) (scale height 7.2 km, so speed ∝
    exp(h/14.4 km)); that closed form gives h(t) = -2H ln(exp(-h0/2H) + v0 t / 2H). The wind
    drifts it at a constant velocity until it lands.
    """

    release: datetime
    lat: float
    lon: float
    release_alt_m: float = 30000.0
    ground_alt_m: float = 500.0
    sea_level_speed_ms: float = 4.0
    drift_east_ms: float = 8.0
    drift_north_ms: float = 3.0
    scale_height_m: float = 7200.0

    def _altitude(self, seconds: float) -> float:
        two_h = 2 * self.scale_height_m
        inner = math.exp(-self.release_alt_m / two_h) + self.sea_level_speed_ms * seconds / two_h
        return max(-two_h * math.log(inner), self.ground_alt_m)

    @property
    def landing_time(self) -> datetime:
        two_h = 2 * self.scale_height_m
        seconds = (
            (math.exp(-self.ground_alt_m / two_h) - math.exp(-self.release_alt_m / two_h))
            * two_h
            / self.sea_level_speed_ms
        )
        return self.release + timedelta(seconds=seconds)

    def fix(self, moment: datetime, sats: int = 9, hdop: float = 1.1) -> GnssFix:
        flying = min(
            (moment - self.release).total_seconds(), (self.landing_time - self.release).total_seconds()
        )
        flying = max(flying, 0.0)
        metres_per_degree = 111_320.0
        lat = self.lat + self.drift_north_ms * flying / metres_per_degree
        lon = self.lon + self.drift_east_ms * flying / (metres_per_degree * math.cos(math.radians(self.lat)))
        airborne = moment < self.landing_time
        speed = math.hypot(self.drift_east_ms, self.drift_north_ms) if airborne else 0.0
        course = math.degrees(math.atan2(self.drift_east_ms, self.drift_north_ms)) % 360 if airborne else 0.0
        return GnssFix(moment, lat, lon, self._altitude(flying), speed, course, hdop, sats)
