"""A simulated capsule Pi: an SSH server on loopback that behaves like the flown one.

It serves the console's fixed command templates (recognised by their ``: drs:<label>`` prefix, see
``drs_link.link.remote``) with the behaviour and output of the stock scripts, a GPIO that enforces the
relay interlock, the firmware's state machine, a storage mount with RAID status over SFTP, and
faults a real release can meet: the link dropping after N bytes, slow replies, a wrong host key,
a full disk, no GNSS fix, dead batteries, a unit left in Gone mode. Time runs on a scalable
clock so a test walks through the 23 s boot and the Go script's 9 s in a fraction of a second.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import select
import socket
import struct
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

import paramiko
from paramiko.common import (
    AUTH_FAILED,
    AUTH_SUCCESSFUL,
    OPEN_FAILED_ADMINISTRATIVELY_PROHIBITED,
    OPEN_SUCCEEDED,
)

from drs_link.link import remote
from drs_link.sim.firmware import Firmware, GnssSky
from drs_link.sim.gpio import ENABLE_LOW, SET_INPUT, SUPPLY, FakeGpio
from drs_link.sim.keys import generate_ed25519
from drs_link.sim.sftp import SimSftpServer
from drs_link.skip_clock import skipped_seconds

DEFAULT_CAPACITY = 128 * 1000**3
SLEEP_SLICE_S = 0.05
"""How often a simulated sleep looks at the clock again (wall seconds): a skip ends it this late at most."""


class SimClock:
    """Simulated UTC that runs ``scale`` times faster than the wall clock.

    A skip of the wall clock by a test (``drs_link.skip_clock``) moves it too, ``scale`` times as far,
    as it moves a store's simulated clock (``Store.run_clock``): the simulators, the demo world and every
    process on its store stay at one time while a test gets past a boot, a Go script or a descent."""

    def __init__(self, scale: float = 1.0, start: datetime | None = None) -> None:
        if scale <= 0:
            raise ValueError("clock scale must be positive")
        self.scale = scale
        self._start = start or datetime.now(UTC)
        self._t0 = time.monotonic()
        self._skipped0 = skipped_seconds()

    def now(self) -> datetime:
        elapsed = time.monotonic() - self._t0 + skipped_seconds() - self._skipped0
        return self._start + timedelta(seconds=elapsed * self.scale)

    def sleep(self, sim_seconds: float) -> None:
        """Until simulated time has moved ``sim_seconds`` on (a skip ends it early, as it would end)."""
        until = self.now() + timedelta(seconds=max(0.0, sim_seconds))
        while (left := (until - self.now()).total_seconds()) > 0:
            time.sleep(min(left / self.scale, SLEEP_SLICE_S))


@dataclass
class Faults:
    """Fault injection, changeable while the simulator runs."""

    drop_after_bytes: int | None = None
    drop_on_command: str | None = None
    response_delay_s: float = 0.0
    slow_command: tuple[str, float] | None = None
    """One labelled command answered that many seconds late (the others at once): a Go the Pi still runs."""
    answer_delay_s: float = 0.0
    """Seconds a command's exit status is held back after it ran: the Pi has acted, the console not heard."""
    raid_degraded: bool = False
    corrupt_writes: int = 0
    """The next N uploads are stored with their first byte inverted: a card that keeps other bytes
    than it was given, which only the sha256 on the Pi can catch."""
    _sent: int = field(default=0, repr=False)

    def arm_drop(self, after_bytes: int) -> None:
        self._sent = 0
        self.drop_after_bytes = after_bytes

    def count(self, n: int) -> bool:
        """Count traffic; True (once) when the link must die now, after which reconnecting works."""
        if self.drop_after_bytes is None:
            return False
        self._sent += n
        if self._sent < self.drop_after_bytes:
            return False
        self.drop_after_bytes = None
        return True


class _FaultySocket:
    """The TCP socket under paramiko's Transport, cut dead when the byte budget runs out."""

    def __init__(self, sock: socket.socket, faults: Faults, on_drop: Callable[[], None]) -> None:
        self._sock = sock
        self._faults = faults
        self._on_drop = on_drop

    def _check(self, n: int) -> None:
        if self._faults.count(n):
            self._on_drop()
            self.close()
            raise OSError("simulated link drop")

    def send(self, data: bytes) -> int:
        n = self._sock.send(data)
        self._check(n)
        return n

    def recv(self, size: int) -> bytes:
        data = self._sock.recv(size)
        self._check(len(data))
        return data

    def settimeout(self, value: float | None) -> None:
        self._sock.settimeout(value)

    def close(self) -> None:
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()

    @property
    def _closed(self) -> bool:
        """paramiko's Transport.stop_thread peeks at this attribute of a real socket."""
        return bool(getattr(self._sock, "_closed", False))

    def getpeername(self) -> object:
        return self._sock.getpeername()

    def fileno(self) -> int:
        return self._sock.fileno()


class _SimTransport(paramiko.Transport):
    """Notes when a channel request was answered, so a command's output never overtakes its reply.

    Without this a fast command (the heartbeat) can close its channel before paramiko has sent
    the exec request's success reply, which the client reports as "Channel closed".
    """

    _CHANNEL_REPLY = (99, 100)  # SSH_MSG_CHANNEL_SUCCESS, SSH_MSG_CHANNEL_FAILURE

    def __init__(self, sock: _FaultySocket) -> None:
        # paramiko drives any object with send/recv/settimeout/close; its stubs name only socket and Channel
        super().__init__(sock)  # type: ignore[arg-type]
        self.replied: dict[int, threading.Event] = {}
        self._replied_lock = threading.Lock()

    def reply_event(self, remote_chanid: int) -> threading.Event:
        with self._replied_lock:
            return self.replied.setdefault(remote_chanid, threading.Event())

    def _send_user_message(self, data: paramiko.Message) -> None:
        super()._send_user_message(data)  # type: ignore[misc]  # private to paramiko, so not in its stubs
        raw = data.asbytes()
        if len(raw) >= 5 and raw[0] in self._CHANNEL_REPLY:
            self.reply_event(struct.unpack(">I", raw[1:5])[0]).set()


class _Server(paramiko.ServerInterface):
    def __init__(self, sim: CapsuleSimulator) -> None:
        self.sim = sim
        self.forwards: dict[int, tuple[str, int]] = {}

    def get_allowed_auths(self, username: str) -> str:
        return "publickey"

    def check_auth_publickey(self, username: str, key: paramiko.PKey) -> int:
        if username == self.sim.user and any(key == k for k in self.sim.authorized_keys):
            return AUTH_SUCCESSFUL
        return AUTH_FAILED

    def check_channel_request(self, kind: str, chanid: int) -> int:
        if kind == "session":
            return OPEN_SUCCEEDED
        return OPEN_FAILED_ADMINISTRATIVELY_PROHIBITED

    def check_channel_direct_tcpip_request(self, chanid: int, origin: tuple, destination: tuple) -> int:
        if destination[0] not in ("127.0.0.1", "localhost"):
            return OPEN_FAILED_ADMINISTRATIVELY_PROHIBITED
        self.forwards[chanid] = ("127.0.0.1", int(destination[1]))
        return OPEN_SUCCEEDED

    def check_channel_exec_request(self, channel: paramiko.Channel, command: bytes) -> bool:
        threading.Thread(
            target=self.sim._serve_command, args=(channel, command.decode("utf-8", "replace")), daemon=True
        ).start()
        return True


class ActiveSessions:
    """How many SFTP sessions the simulated Pi is serving.

    After a link drop the server still writes the packets it had received, as a real sshd does:
    a test that inspects the capsule's files after a drop waits until the session has ended.
    """

    def __init__(self) -> None:
        self._count = 0
        self._changed = threading.Condition()

    def started(self) -> None:
        with self._changed:
            self._count += 1

    def ended(self) -> None:
        with self._changed:
            self._count -= 1
            self._changed.notify_all()

    def wait_idle(self, timeout_s: float = 10.0) -> bool:
        """True once no session is active; False if some still are after ``timeout_s``."""
        with self._changed:
            return self._changed.wait_for(lambda: self._count == 0, timeout=timeout_s)


class CapsuleSimulator:
    """Start with ``start()`` (returns the port) or as a context manager; ``stop()`` ends everything."""

    def __init__(
        self,
        name: str = "DRS1",
        authorized_keys: list[paramiko.PKey] | None = None,
        host_key: paramiko.PKey | None = None,
        clock_scale: float = 1.0,
        user: str = "pi",
        tools_dir: str = "/home/pi/DRS_Python_Tools",
        storage_mount: str = "/mnt/raid1",
        capacity_bytes: int = DEFAULT_CAPACITY,
        sky: GnssSky | None = None,
        gone: bool = False,
        battery: bool = True,
        workdir: Path | None = None,
    ) -> None:
        self.name = name
        self.user = user
        self.tools_dir = tools_dir
        self.storage_mount = storage_mount
        self.capacity_bytes = capacity_bytes
        self.clock = SimClock(clock_scale)
        self.host_key = host_key or generate_ed25519()
        self.authorized_keys = list(authorized_keys or [])
        self.faults = Faults()
        self.firmware = Firmware(sky, gone=gone, battery=battery)
        self.gpio = FakeGpio(self.firmware, self.clock.now)
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        if workdir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix=f"drs-sim-{name}-")
            workdir = Path(self._tmp.name)
        root = workdir
        self.storage_dir = root / "raid1"
        self.tools_path = root / "tools"
        self.storage_dir.mkdir(parents=True, exist_ok=True)
        self.tools_path.mkdir(parents=True, exist_ok=True)
        self.authority: tuple[str, datetime] | None = None
        self.shut_down = False
        self.agent_logging_since: datetime | None = None
        self.commands: list[str] = []
        self._listener: socket.socket | None = None
        self._transports: list[paramiko.Transport] = []
        self.sftp_sessions = ActiveSessions()
        self._lock = threading.Lock()
        self._authority_lock = threading.Lock()
        self.port = 0

    # Lifecycle --------------------------------------------------------------------------------

    def start(self) -> int:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", self.port))
        listener.listen(16)
        self._listener = listener
        self.port = listener.getsockname()[1]
        threading.Thread(target=self._accept_loop, name=f"sim-{self.name}", daemon=True).start()
        return self.port

    def stop(self) -> None:
        self._close_everything()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> CapsuleSimulator:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _close_everything(self) -> None:
        if self._listener is not None:
            try:
                self._listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            try:
                self._listener.close()
            except OSError:
                pass
            self._listener = None
        with self._lock:
            transports, self._transports = self._transports, []
        for transport in transports:
            transport.close()

    def drop_link(self) -> None:
        """Cut every connection at once (the gondola Wi-Fi going away); new ones still accepted."""
        with self._lock:
            transports, self._transports = self._transports, []
        for transport in transports:
            transport.close()

    def press_off_button(self) -> None:
        """Reset the latching relay (the only way: a physical button with the Pi powered)."""
        self.gpio.relay_latched = False
        self.firmware.relay_reset(self.clock.now())

    def known_hosts_line(self, host: str = "127.0.0.1") -> str:
        return f"[{host}]:{self.port} {self.host_key.get_name()} {self.host_key.get_base64()}\n"

    def _accept_loop(self) -> None:
        listener = self._listener
        while listener is not None and self._listener is listener:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            threading.Thread(target=self._serve_connection, args=(conn,), daemon=True).start()

    def _serve_connection(self, conn: socket.socket) -> None:
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        holder: list[paramiko.Transport] = []

        def drop() -> None:
            for t in holder:
                t.close()

        sock = _FaultySocket(conn, self.faults, drop)
        transport = _SimTransport(sock)
        holder.append(transport)
        transport.add_server_key(self.host_key)
        transport.set_subsystem_handler("sftp", paramiko.SFTPServer, SimSftpServer, self)
        with self._lock:
            self._transports.append(transport)
        server = _Server(self)
        try:
            transport.start_server(server=server)
        except (paramiko.SSHException, OSError, EOFError):
            transport.close()
            return
        while transport.is_active():
            channel = transport.accept(timeout=0.5)
            if channel is not None and channel.get_id() in server.forwards:
                destination = server.forwards.pop(channel.get_id())
                threading.Thread(target=_forward, args=(channel, destination), daemon=True).start()

    # Storage ----------------------------------------------------------------------------------

    def storage_used(self) -> int:
        total = 0
        for dirpath, _, files in os.walk(self.storage_dir):
            for name in files:
                try:
                    total += os.lstat(os.path.join(dirpath, name)).st_size
                except OSError:
                    pass
        return total

    def _df(self) -> str:
        used = self.storage_used()
        avail = max(self.capacity_bytes - used, 0)
        pct = -(-used * 100 // self.capacity_bytes) if self.capacity_bytes else 100
        return (
            "Filesystem        1-blocks       Used  Available Capacity Mounted on\n"
            f"/dev/md0 {self.capacity_bytes} {used} {avail} {pct}% {self.storage_mount}\n"
        )

    def _mdstat(self) -> str:
        members = "[4/3] [UUU_]" if self.faults.raid_degraded else "[4/4] [UUUU]"
        failed = "sdd1[3](F)" if self.faults.raid_degraded else "sdd1[3]"
        return (
            "Personalities : [raid1] \n"
            f"md0 : active raid1 {failed} sdc1[2] sdb1[1] sda1[0]\n"
            f"      124967936 blocks super 1.2 {members}\n"
            "      bitmap: 0/1 pages [0KB], 65536KB chunk\n\n"
            "unused devices: <none>\n"
        )

    # Commands ---------------------------------------------------------------------------------

    def _serve_command(self, channel: paramiko.Channel, command: str) -> None:
        self.commands.append(command)
        transport = channel.get_transport()
        if isinstance(transport, _SimTransport):
            transport.reply_event(channel.remote_chanid).wait(5.0)
        if self.faults.response_delay_s:
            time.sleep(self.faults.response_delay_s)
        parsed = remote.parse_label(command)
        slow = self.faults.slow_command
        if parsed is not None and slow is not None and parsed[0] == slow[0]:
            time.sleep(slow[1])
        if parsed is not None and parsed[0] == self.faults.drop_on_command:
            self.faults.drop_on_command = None
            self.drop_link()
            return
        out = _Output(channel)
        status: int | None
        try:
            if parsed is None:
                out.err(
                    f"sh: 1: {command.split()[0] if command.split() else ''}: not found on the simulator\n"
                )
                status = 127
            else:
                label, args = parsed
                handler = getattr(self, "_cmd_" + label.replace("-", "_"), None)
                status = handler(out, *args) if handler else 127
        except _PiShutdown:
            return
        except (OSError, EOFError, paramiko.SSHException):
            return
        if status is not None:
            time.sleep(self.faults.answer_delay_s)
            try:
                channel.send_exit_status(status)
                channel.shutdown_write()
                channel.close()
            except (OSError, EOFError, paramiko.SSHException):
                pass

    def _cmd_heartbeat(self, out: _Output) -> int:
        return 0

    def _cd_tools(self, out: _Output, tools_dir: str) -> int | None:
        if tools_dir != self.tools_dir:
            out.err(f"sh: 1: cd: can't cd to {tools_dir}\n")
            return remote.EXIT_NO_TOOLS
        return None

    def _check_tools(self, out: _Output, tools_dir: str, python: str) -> int | None:
        if (failed := self._cd_tools(out, tools_dir)) is not None:
            return failed
        if python not in ("python", "python2", "python3", "/usr/bin/python"):
            out.err(f"sh: 1: {python}: not found\n")
            return 127
        return None

    def _pi_seconds(self) -> int:
        """``date +%s`` on the Pi: the owner file counts in whole epoch seconds."""
        return int(self.clock.now().timestamp())

    def _owner(self) -> tuple[str, int]:
        """The owner file as ``remote._read_owner`` reads it: holder ("" when free) and lease end."""
        if self.authority is None:
            return "", 0
        held_by, until = self.authority
        return held_by, int(until.timestamp())

    def _report_owner(self, out: _Output) -> None:
        held_by, lease_end = self._owner()
        out.write(f"{remote.AUTHORITY_MARKER} {self._pi_seconds()} {lease_end} {held_by}\n")

    def _take_authority(self, out: _Output, holder: str) -> str | None:
        """The owner-file check of ``remote._authority_prelude``; returns the current holder or exits."""
        held_by, lease_end = self._owner()
        if not held_by:
            return None
        if held_by != holder and lease_end > self._pi_seconds():
            out.err(f"drs: release authority is held by {held_by}\n")
            raise _Exit(remote.EXIT_AUTHORITY_HELD)
        return held_by

    def _claim_authority(self, out: _Output, holder: str, lease: str) -> int | None:
        """Take or renew the release authority for ``lease`` seconds (call under the lock).

        Returns the exit status refusing the command when another console holds it.
        """
        try:
            self._take_authority(out, holder)
        except _Exit as exit_:
            return exit_.status
        self._write_owner(holder, int(lease))
        return None

    def _write_owner(self, holder: str, lease_s: int) -> None:
        self.authority = (holder, datetime.fromtimestamp(self._pi_seconds() + lease_s, UTC))

    def _cmd_authority(self, out: _Output, tools_dir: str) -> int:
        if (failed := self._cd_tools(out, tools_dir)) is not None:
            return failed
        with self._authority_lock:
            self._report_owner(out)
        return 0

    def _cmd_authority_take_over(
        self, out: _Output, tools_dir: str, holder: str, expected_holder: str, expected_end: str, lease: str
    ) -> int:
        """Compare-and-set of the owner file: only if it still says what the operator was shown."""
        if (failed := self._cd_tools(out, tools_dir)) is not None:
            return failed
        with self._authority_lock:
            if self._owner() != (expected_holder, int(expected_end)):
                self._report_owner(out)
                out.err("drs: the release authority changed since it was shown\n")
                return remote.EXIT_AUTHORITY_CHANGED
            self._write_owner(holder, int(lease))
            self._report_owner(out)
        return 0

    def _cmd_authority_release(self, out: _Output, tools_dir: str, holder: str) -> int:
        if (failed := self._cd_tools(out, tools_dir)) is not None:
            return failed
        with self._authority_lock:
            held_by, _ = self._owner()
            if held_by and held_by != holder:
                out.err(f"drs: the release authority belongs to {held_by}, not to this console\n")
                return remote.EXIT_AUTHORITY_HELD
            self._report_owner(out)
            self.authority = None
        return 0

    def _cmd_power_on(self, out: _Output, tools_dir: str, python: str, holder: str, lease: str) -> int:
        failed = self._check_tools(out, tools_dir, python)
        if failed is not None:
            return failed
        with self._authority_lock:
            refused = self._claim_authority(out, holder, lease)
            if refused is not None:
                return refused
            out.write(f"{remote.LOG_OFFSET_MARKER} {self._log_size()}\n")
            self._drs_on()
        return 0

    def _drs_on(self) -> None:
        """DRS_on.py: BCM9=1, BCM10=1, BCM2=0, hold 2 s, BCM2=1, BCM10=0, cleanup, TX to alt5."""
        self.gpio.output(SUPPLY, 1)
        self.gpio.output(SET_INPUT, 1)
        self.gpio.output(ENABLE_LOW, 0)
        self.clock.sleep(2.0)
        self.gpio.output(ENABLE_LOW, 1)
        self.gpio.output(SET_INPUT, 0)
        self.gpio.cleanup()
        self.gpio.set_tx_mode("alt5")

    @property
    def serial_log(self) -> Path:
        return self.tools_path / remote.SERIAL_LOG_NAME

    def _log_size(self) -> int:
        return self.serial_log.stat().st_size if self.serial_log.exists() else 0

    def _capture(self, seconds: float) -> None:
        """The stock logger: readline for ``seconds`` and append raw bytes (CRLF from println)."""
        start = self.clock.now()
        self.clock.sleep(seconds)
        lines = self.firmware.output_between(start, self.clock.now())
        with self.serial_log.open("ab") as log:
            for line in lines:
                log.write(line.encode("ascii") + b"\r\n")

    def _tail(self) -> str:
        if not self.serial_log.exists():
            return ""
        lines = self.serial_log.read_bytes().decode("ascii", "replace").splitlines(keepends=True)
        return "".join(lines[-10:])

    def _cmd_read_serial(self, out: _Output, tools_dir: str, python: str, offset: str) -> int:
        failed = self._check_tools(out, tools_dir, python)
        if failed is not None:
            return failed
        self._capture(5.0)
        data = self.serial_log.read_bytes()[int(offset) :] if self.serial_log.exists() else b""
        out.write(data[-remote.MAX_LOG_BYTES :].decode("ascii", "replace"))
        return 0

    def _refuse_without_authority(self, out: _Output, holder: str) -> int | None:
        """The exit status refusing Go unless ``holder`` holds the release authority (call under the lock)."""
        try:
            held_by = self._take_authority(out, holder)
        except _Exit as exit_:
            return exit_.status
        if held_by != holder:
            out.err("drs: this console holds no release authority: run power-on first\n")
            return remote.EXIT_NO_AUTHORITY
        return None

    def _cmd_go(self, out: _Output, tools_dir: str, python: str, holder: str) -> int:
        failed = self._check_tools(out, tools_dir, python)
        if failed is not None:
            return failed
        with self._authority_lock:
            refused = self._refuse_without_authority(out, holder)
            if refused is not None:
                return refused
            self._gogogo(out)
        return 0

    def _gogogo(self, out: _Output) -> None:
        """DRS_GoGoGo.py at HEAD: alt5, log 3 s, tail, write GoGoGo, 5 s, Shutting down, 1 s, halt."""
        self.gpio.set_tx_mode("alt5")
        self.clock.sleep(0.1)
        self._capture(3.0)
        out.write(self._tail())
        if self.gpio.tx_mode == "alt5":
            self.firmware.receive_from_pi(b"GoGoGo\n", self.clock.now())
        out.write("Dropping in 30 seconds!\n")
        self.clock.sleep(5.0)
        out.write("Shutting down...\n")
        self.clock.sleep(1.0)
        self.shut_down = True
        self._close_everything()
        raise _PiShutdown

    def _cmd_storage(self, out: _Output, mount: str) -> int:
        if mount != self.storage_mount:
            out.err(f"df: {mount}: No such file or directory\n")
            return 1
        out.write(self._df() + "--mdstat--\n" + self._mdstat())
        return 0

    def _cmd_hash(self, out: _Output, path: str) -> int:
        return self._cmd_verify(out, path)

    def _cmd_verify(self, out: _Output, path: str) -> int:
        real = self.real_path(path)
        if real is None:
            out.err(f"sha256sum: {path}: Permission denied\n")
            return 1
        if not real.is_file():
            out.err(f"sha256sum: {path}: No such file or directory\n")
            return 1
        digest = hashlib.sha256(real.read_bytes()).hexdigest()
        out.write(f"{digest}  -\n")  # GNU sha256sum reading standard input (drs_link.link.remote.verify_file)
        return 0

    # The agent backend (drs_link/link/backends/pi_agent.py as it behaves on a Pi) --------------------

    def _agent_ready(self, out: _Output, tools_dir: str, python: str) -> int | None:
        failed = self._check_tools(out, tools_dir, python)
        if failed is not None:
            return failed
        if not (self.tools_path / remote.AGENT_NAME).is_file():
            out.err(f"{python}: can't open file '{tools_dir}/{remote.AGENT_NAME}': [Errno 2] No such file\n")
            return 2
        return None

    @property
    def agent_log(self) -> Path:
        return self.tools_path / "drs_agent_nmea.log"

    def _agent_flush_log(self) -> None:
        """The continuous logger: everything the firmware sent since the last look, timestamped."""
        if self.agent_logging_since is None:
            return
        now = self.clock.now()
        lines = self.firmware.output_between(self.agent_logging_since, now)
        self.agent_logging_since = now
        stamp = now.isoformat(timespec="milliseconds").replace("+00:00", "Z")
        with self.agent_log.open("a") as log:
            for line in lines:
                log.write(f"{stamp} {line}\n")

    def _cmd_agent_power_on(
        self, out: _Output, tools_dir: str, python: str, holder: str, lease: str, serial: str
    ) -> int:
        failed = self._agent_ready(out, tools_dir, python)
        if failed is not None:
            return failed
        with self._authority_lock:
            refused = self._claim_authority(out, holder, lease)
            if refused is not None:
                return refused
            size = self.agent_log.stat().st_size if self.agent_log.exists() else 0
            out.write(f"{remote.LOG_OFFSET_MARKER} {size}\n")
            self._drs_on()
            out.write("gpio 9=1\ngpio 10=1\ngpio 2=0\ngpio 2=1\ngpio 10=0\ngpio released\ngpio 14=alt5\n")
            if self.agent_logging_since is None:
                self.agent_logging_since = self.clock.now()
            out.write("logger started\n")
        return 0

    def _cmd_agent_read(self, out: _Output, tools_dir: str, python: str, offset: str) -> int:
        failed = self._agent_ready(out, tools_dir, python)
        if failed is not None:
            return failed
        self._agent_flush_log()
        data = self.agent_log.read_bytes()[int(offset) :] if self.agent_log.exists() else b""
        out.write(data[-remote.MAX_LOG_BYTES :].decode("ascii", "replace"))
        return 0

    def _cmd_agent_go(self, out: _Output, tools_dir: str, python: str, holder: str, serial: str) -> int:
        failed = self._agent_ready(out, tools_dir, python)
        if failed is not None:
            return failed
        with self._authority_lock:
            refused = self._refuse_without_authority(out, holder)
            if refused is not None:
                return refused
            self._agent_flush_log()
            self.agent_logging_since = None
            self.gpio.set_tx_mode("alt5")
            for attempt in (1, 2):
                sent_at = self.clock.now()
                self.firmware.receive_from_pi(b"\nGoGoGo\n", sent_at)
                out.write(f"GoGoGo written (attempt {attempt})\n")
                self.clock.sleep(2.0)
                if "Dropping in 30 seconds!" in self.firmware.output_between(sent_at, self.clock.now()):
                    break
            else:
                out.write("NO ACK from the microcontroller; the Pi stays up\n")
                return remote.EXIT_AGENT_NO_ACK
            out.write("ACK Dropping in 30 seconds!\nShutting down...\n")
            self.clock.sleep(1.0)
            self.shut_down = True
            self._close_everything()
            raise _PiShutdown

    def real_path(self, virtual: str) -> Path | None:
        """Where a Pi path lives in the simulator: only the mount and the tools directory exist."""
        for prefix, real in ((self.storage_mount, self.storage_dir), (self.tools_dir, self.tools_path)):
            prefix = prefix.rstrip("/")
            if virtual == prefix or virtual.startswith(prefix + "/"):
                return real / virtual[len(prefix) :].lstrip("/")
        return None


class _Exit(Exception):
    def __init__(self, status: int) -> None:
        self.status = status


class _PiShutdown(Exception):
    """``sudo shutdown now``: the connection dies without an exit status."""


class _Output:
    def __init__(self, channel: paramiko.Channel) -> None:
        self.channel = channel

    def write(self, text: str) -> None:
        if text:
            self.channel.sendall(text.encode())

    def err(self, text: str) -> None:
        self.channel.sendall_stderr(text.encode())


def _forward(channel: paramiko.Channel, destination: tuple[str, int]) -> None:
    """The jump-host role (the flight computer): pipe a direct-tcpip channel to a loopback port."""
    try:
        upstream = socket.create_connection(destination, timeout=5)
    except OSError:
        channel.close()
        return
    try:
        while True:
            watched: list[paramiko.Channel | socket.socket] = [channel, upstream]
            readable, _, _ = select.select(watched, [], [], 0.5)
            if channel in readable:
                data = channel.recv(32768)
                if not data:
                    break
                upstream.sendall(data)
            if upstream in readable:
                data = upstream.recv(32768)
                if not data:
                    break
                channel.sendall(data)
            if channel.closed:
                break
    except OSError:
        pass
    finally:
        upstream.close()
        # The client may have dropped the whole connection first: closing a channel on a dead transport
        # raises EOFError from paramiko's packetizer, and there is nothing left to tell.
        with contextlib.suppress(EOFError, OSError):
            channel.close()
