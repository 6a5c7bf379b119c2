"""The SSH link to one capsule's Pi (paramiko), safe to drive from a worker thread.

Release depends on talking to the right Pi, so host keys are only ever checked against the
configured known_hosts: an unknown or changed key is refused with its SHA256 fingerprint for
out-of-band comparison and is never added. Every wait is bounded (paramiko's own
``recv_exit_status`` is not), keepalives hold NAT state, and a cheap heartbeat command detects a
dead peer, which keepalives cannot. The link dropping mid-command is reported as data
(``CommandResult.link_dropped``) because after Go it is the expected outcome.
"""

from __future__ import annotations

import base64
import hashlib
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import paramiko

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError
from drs_link.link import remote

KEEPALIVE_S = 15
HEARTBEAT_TIMEOUT_S = 5.0
POLL_S = 0.05
# paramiko reports -1 when a channel closed without the server sending an exit status.
_NO_EXIT_STATUS = -1


class HostKeyError(LinkError):
    """The capsule's host key is unknown or changed: the connection was refused."""


class LinkDownError(LinkError):
    """The capsule cannot be reached, or the link died during a command."""


@dataclass(frozen=True)
class CommandResult:
    exit_status: int | None
    stdout: str
    stderr: str
    link_dropped: bool
    timed_out: bool = False

    @property
    def ok(self) -> bool:
        return self.exit_status == 0


def fingerprint(key: paramiko.PKey) -> str:
    """OpenSSH's ``SHA256:…`` form, the one an operator can compare with ``ssh-keygen -lf``."""
    digest = hashlib.sha256(key.asbytes()).digest()
    return "SHA256:" + base64.b64encode(digest).decode().rstrip("=")


def known_hosts_name(host: str, port: int) -> str:
    return host if port == 22 else f"[{host}]:{port}"


def parse_jump_host(spec: str, default_user: str) -> tuple[str, str, int]:
    """``[user@]host[:port]`` → (user, host, port)."""
    user, _, rest = spec.rpartition("@")
    host, _, port_text = rest.partition(":")
    if not host:
        raise LinkError(f"jump_host {spec!r}: expected [user@]host[:port]")
    try:
        port = int(port_text) if port_text else 22
    except ValueError:
        raise LinkError(f"jump_host {spec!r}: port {port_text!r} is not a number") from None
    if not 1 <= port <= 65535:
        raise LinkError(f"jump_host {spec!r}: port {port} is not a TCP port")
    return user or default_user, host, port


class _RefuseUnknownHost(paramiko.MissingHostKeyPolicy):
    def missing_host_key(self, client: paramiko.SSHClient, hostname: str, key: paramiko.PKey) -> None:
        raise HostKeyError(
            f"host key of {hostname} is not in the known_hosts file: refusing to connect "
            f"(offered {key.get_name()} {fingerprint(key)}; compare it out of band, then enrol the capsule)"
        )


def _load_known_hosts(path: Path) -> paramiko.HostKeys:
    if not path.is_file():
        raise HostKeyError(f"known_hosts file {path} does not exist: enrol the capsule's host key first")
    try:
        return paramiko.HostKeys(str(path))
    except OSError as exc:
        raise HostKeyError(f"known_hosts file {path} cannot be read: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - paramiko's parser raises InvalidHostKey, ValueError, UnicodeDecodeError…
        raise HostKeyError(
            f"known_hosts file {path} is damaged ({type(exc).__name__}: {exc}); fix that line or enrol the "
            "capsule again (drs capsule enrol)"
        ) from None


class CapsuleLink:
    """One SSH connection to one capsule, used by one worker at a time (an internal lock enforces it)."""

    def __init__(
        self,
        capsule: CapsuleConfig,
        sleep: Callable[[float], None] = time.sleep,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.capsule = capsule
        self._sleep = sleep
        self._monotonic = monotonic
        self._client: paramiko.SSHClient | None = None
        self._jump: paramiko.SSHClient | None = None
        self._lock = threading.RLock()

    def __enter__(self) -> CapsuleLink:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        transport = self._client.get_transport() if self._client else None
        return bool(transport and transport.is_active())

    def _new_client(self, known_hosts: paramiko.HostKeys) -> paramiko.SSHClient:
        client = paramiko.SSHClient()
        for hostname, keys in known_hosts.items():
            for key_type, key in keys.items():
                client.get_host_keys().add(hostname, key_type, key)
        client.set_missing_host_key_policy(_RefuseUnknownHost())
        return client

    def _open(
        self,
        client: paramiko.SSHClient,
        host: str,
        port: int,
        user: str,
        sock: paramiko.Channel | None = None,
    ) -> None:
        c = self.capsule
        key_file = str(c.identity_file) if c.identity_file else None
        timeout = c.connect_timeout_s
        try:
            client.connect(
                host,
                port=port,
                username=user,
                key_filename=key_file,
                allow_agent=key_file is None,
                look_for_keys=key_file is None,
                timeout=timeout,
                banner_timeout=timeout,
                auth_timeout=timeout,
                channel_timeout=timeout,
                sock=sock,
            )
        except HostKeyError:
            raise
        except paramiko.BadHostKeyException as exc:
            raise HostKeyError(
                f"host key of {known_hosts_name(host, port)} has CHANGED: refusing to connect "
                f"(offered {exc.key.get_name()} {fingerprint(exc.key)}, "
                f"known_hosts has {fingerprint(exc.expected_key)}); this may be the wrong Pi or an attack"
            ) from None
        except paramiko.AuthenticationException as exc:
            raise LinkError(f"{user}@{host}:{port}: authentication failed ({exc})") from None
        except FileNotFoundError as exc:
            raise LinkError(f"identity_file cannot be read: {exc}") from None
        except (OSError, EOFError, paramiko.SSHException) as exc:
            raise LinkDownError(f"cannot reach {user}@{host}:{port}: {exc or type(exc).__name__}") from None
        transport = client.get_transport()
        if transport is not None and isinstance(transport.sock, socket.socket):
            # Small request/reply commands otherwise wait ~40 ms on Nagle + delayed ACK.
            transport.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def connect(self) -> None:
        """Open the connection (through the jump host when configured); host keys always verified."""
        with self._lock:
            self.close()
            c = self.capsule
            known = _load_known_hosts(c.known_hosts)
            sock = None
            if c.jump_host:
                user, host, port = parse_jump_host(c.jump_host, c.user)
                self._jump = self._new_client(known)
                self._open(self._jump, host, port, user)
                transport = self._jump.get_transport()
                assert transport is not None
                try:
                    sock = transport.open_channel(
                        "direct-tcpip", (c.host, c.port), ("127.0.0.1", 0), timeout=c.connect_timeout_s
                    )
                except (OSError, EOFError, paramiko.SSHException) as exc:
                    self.close()
                    raise LinkDownError(f"jump host {host} cannot reach {c.host}:{c.port}: {exc}") from None
            self._client = self._new_client(known)
            try:
                self._open(self._client, c.host, c.port, c.user, sock=sock)
            except LinkError:
                self.close()
                raise
            transport = self._client.get_transport()
            if transport is not None:
                transport.set_keepalive(KEEPALIVE_S)

    def connect_with_retry(
        self, attempts: int = 4, first_delay_s: float = 0.5, max_delay_s: float = 8.0
    ) -> None:
        """Reconnect with exponential backoff; a host-key or authentication refusal is never retried."""
        delay = first_delay_s
        for attempt in range(1, attempts + 1):
            try:
                self.connect()
                return
            except LinkDownError:
                if attempt == attempts:
                    raise
                self._sleep(delay)
                delay = min(delay * 2, max_delay_s)

    def ensure_connected(self) -> None:
        if not self.connected:
            self.connect_with_retry()

    def run(
        self,
        command: remote.RemoteCommand,
        timeout_s: float | None = None,
        on_stdout: Callable[[str], None] | None = None,
    ) -> CommandResult:
        """Run one template; output is drained while waiting so a full window can never hang us."""
        with self._lock:
            timeout = timeout_s if timeout_s is not None else self.capsule.command_timeout_s
            channel, transport = self._open_session(command)
            try:
                channel.settimeout(POLL_S)
                channel.exec_command(command.text)
            except (OSError, EOFError, paramiko.SSHException) as exc:
                self.close()
                raise LinkDownError(f"{self.capsule.name}: cannot start {command.label}: {exc}") from None
            return self._collect(channel, transport, timeout, on_stdout)

    def _open_session(self, command: remote.RemoteCommand) -> tuple[paramiko.Channel, paramiko.Transport]:
        """A session channel; a link found dead here is reconnected once, since nothing has run yet."""
        for attempt in (1, 2):
            self.ensure_connected()
            assert self._client is not None
            transport = self._client.get_transport()
            try:
                assert transport is not None
                return transport.open_session(timeout=self.capsule.connect_timeout_s), transport
            except (OSError, EOFError, paramiko.SSHException) as exc:
                self.close()
                if attempt == 2:
                    raise LinkDownError(f"{self.capsule.name}: cannot start {command.label}: {exc}") from None
        raise AssertionError("unreachable")

    def _collect(
        self,
        channel: paramiko.Channel,
        transport: paramiko.Transport,
        timeout: float,
        on_stdout: Callable[[str], None] | None,
    ) -> CommandResult:
        deadline = self._monotonic() + timeout
        out, err = bytearray(), bytearray()
        pending = b""
        while True:
            progressed = False
            while channel.recv_ready():
                chunk = channel.recv(32768)
                if not chunk:
                    break
                out += chunk
                progressed = True
                if on_stdout is not None:
                    pending += chunk
                    *lines, pending = pending.split(b"\n")
                    for line in lines:
                        on_stdout(line.decode("utf-8", errors="replace"))
            while channel.recv_stderr_ready():
                err += channel.recv_stderr(32768)
                progressed = True
            if channel.exit_status_ready() and not channel.recv_ready() and not channel.recv_stderr_ready():
                status = channel.recv_exit_status()
                channel.close()
                if status != _NO_EXIT_STATUS:
                    return CommandResult(
                        status, out.decode(errors="replace"), err.decode(errors="replace"), False
                    )
                self.close()
                return CommandResult(None, out.decode(errors="replace"), err.decode(errors="replace"), True)
            if channel.closed or not transport.is_active():
                while channel.recv_ready():
                    out += channel.recv(32768)
                self.close()
                return CommandResult(None, out.decode(errors="replace"), err.decode(errors="replace"), True)
            if self._monotonic() > deadline:
                channel.close()
                return CommandResult(
                    None, out.decode(errors="replace"), err.decode(errors="replace"), False, timed_out=True
                )
            if not progressed:
                channel.status_event.wait(POLL_S)

    def heartbeat(self, timeout_s: float = HEARTBEAT_TIMEOUT_S) -> bool:
        """True when the Pi answered a no-op command in time: the dead-peer check keepalives lack."""
        try:
            return self.run(remote.heartbeat(), timeout_s=timeout_s).ok
        except LinkError:
            return False

    def sftp(self) -> paramiko.SFTPClient:
        with self._lock:
            self.ensure_connected()
            assert self._client is not None
            try:
                sftp = self._client.open_sftp()
            except (OSError, EOFError, paramiko.SSHException) as exc:
                self.close()
                raise LinkDownError(f"{self.capsule.name}: cannot open SFTP: {exc}") from None
            channel = sftp.get_channel()
            if channel is not None:
                channel.settimeout(self.capsule.command_timeout_s)
            return sftp

    def close(self) -> None:
        """Close the connection. Lock-free on purpose: another thread may call it to abort a command
        in flight, which then returns with ``link_dropped``."""
        clients, self._client, self._jump = (self._client, self._jump), None, None
        for client in clients:
            if client is not None:
                try:
                    client.close()
                except (OSError, EOFError, paramiko.SSHException):
                    pass


def scan_host_key(host: str, port: int, timeout_s: float = 10.0) -> paramiko.PKey:
    """Fetch a server's host key without authenticating, for the operator to compare and enrol."""
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        raise LinkDownError(f"cannot reach {host}:{port}: {exc}") from None
    transport = paramiko.Transport(sock)
    try:
        transport.start_client(timeout=timeout_s)
        key = transport.get_remote_server_key()
    except (OSError, EOFError, paramiko.SSHException) as exc:
        raise LinkDownError(f"{host}:{port}: SSH handshake failed: {exc}") from None
    finally:
        transport.close()
    return key


def enrol_host_key(known_hosts: Path, host: str, port: int, key: paramiko.PKey) -> None:
    """Append (or replace) the capsule's entry in the console's own known_hosts file."""
    known_hosts.parent.mkdir(parents=True, exist_ok=True)
    keys = paramiko.HostKeys(str(known_hosts)) if known_hosts.exists() else paramiko.HostKeys()
    name = known_hosts_name(host, port)
    if name in keys:
        del keys[name]
    keys.add(name, key.get_name(), key)
    keys.save(str(known_hosts))
    known_hosts.chmod(0o600)
