"""End to end against a real OpenSSH sshd on loopback, with fake stock scripts in a temporary tools_dir.

The fake scripts emulate the Pi's hardware with files: ``gpio.log`` records pin writes, ``relay``
appears when the interlock pulse latched it, ``ttyS0.tx`` receives what would go to the
microcontroller, and ``nmea.txt`` is what the microcontroller echoes once powered. Their "sudo
shutdown now" kills this test's own sshd session processes, so the link drops exactly as when the
Pi halts. With ``CI`` set, a missing sshd fails these tests rather than skipping them.
"""

from __future__ import annotations

import fcntl
import importlib.util
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path

import paramiko
import pytest

from drs_link.config import CapsuleConfig, parse_config
from drs_link.errors import RefusedError
from drs_link.link import remote
from drs_link.link.backends import AuthorityState
from drs_link.link.backends.agent import AGENT_SOURCE, AgentBackend
from drs_link.link.backends.stock import StockBackend
from drs_link.link.nmea import format_gga, format_rmc
from drs_link.link.ssh import CapsuleLink, HostKeyError, fingerprint
from drs_link.link.storage import read_storage
from drs_link.link.sync import Syncer
from drs_link.ops.capsule import ReleaseState, ReleaseStateMachine
from drs_link.sim import Firmware, SimClock
from drs_link.sim.keys import generate_ed25519, write_ed25519
from drs_link.store import Store
from tests.ports import free_port

pytestmark = pytest.mark.slow

SSHD = Path("/usr/sbin/sshd")
PYTHON3 = "/usr/bin/python3"


def _require_sshd() -> None:
    if SSHD.is_file() and Path(PYTHON3).is_file() and shutil.which("ssh-keygen"):
        return
    reason = f"OpenSSH server ({SSHD}), {PYTHON3} and ssh-keygen are needed for the real-sshd tests"
    if os.environ.get("CI"):
        pytest.fail(reason + " and CI is set")
    pytest.skip(reason)


@dataclass(frozen=True)
class RealSshd:
    port: int
    pid: int
    root: Path
    client_key: Path
    host_key: paramiko.PKey
    known_hosts: Path


def _wait_for_banner(port: int, proc: subprocess.Popen[bytes], log: Path) -> bool:
    """Until OUR sshd says it listens on ``port`` and answers there. A banner alone could come from another
    sshd (a parallel worker or a second suite) that took the same port between free_port() and our bind;
    ours then fails to bind and exits, and the caller tries another port. The 30 s limit is a readiness
    bound on a loaded machine; the wait ends as soon as sshd answers."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        if f"Server listening on 127.0.0.1 port {port}." not in log.read_text(errors="replace"):
            time.sleep(0.05)
            continue
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1) as conn:
                if conn.recv(64).startswith(b"SSH-2.0-"):
                    return True
        except OSError:
            time.sleep(0.05)
    return False


@pytest.fixture(scope="module")
def sshd(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RealSshd]:
    _require_sshd()
    root = tmp_path_factory.mktemp("sshd")
    root.chmod(0o700)
    _write_fake_pi_commands(root)
    Path("/run/sshd").mkdir(mode=0o755, exist_ok=True)
    subprocess.run(["ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-f", str(root / "host_key")], check=True)
    host_key = paramiko.Ed25519Key.from_private_key_file(str(root / "host_key"))
    client_key = root / "client_key"
    write_ed25519(client_key)
    (root / "authorized_keys").write_text((root / "client_key.pub").read_text())
    (root / "authorized_keys").chmod(0o600)
    user = os.environ.get("USER") or "root"
    for attempt in range(5):
        port = free_port()
        config = root / "sshd_config"
        config.write_text(
            textwrap.dedent(
                f"""\
                Port {port}
                ListenAddress 127.0.0.1
                HostKey {root / "host_key"}
                PidFile {root / "sshd.pid"}
                AuthorizedKeysFile {root / "authorized_keys"}
                PubkeyAuthentication yes
                PasswordAuthentication no
                KbdInteractiveAuthentication no
                UsePAM no
                StrictModes no
                PermitRootLogin prohibit-password
                AllowUsers {user}
                Subsystem sftp internal-sftp
                LogLevel VERBOSE
                SetEnv GPIOZERO_PIN_FACTORY=mock PATH={root / "bin"}:/usr/local/bin:/usr/bin:/bin
                """
            )
        )
        subprocess.run([str(SSHD), "-t", "-f", str(config)], check=True)
        log = root / f"sshd-{attempt}.log"
        proc = subprocess.Popen([str(SSHD), "-D", "-e", "-f", str(config)], stderr=log.open("wb"))
        if _wait_for_banner(port, proc, log):
            break
        proc.kill()
        proc.wait()
    else:
        pytest.fail(f"sshd did not start: {log.read_text()[-2000:]}")
    known_hosts = root / "known_hosts"
    known_hosts.write_text(f"[127.0.0.1]:{port} {host_key.get_name()} {host_key.get_base64()}\n")
    try:
        yield RealSshd(port, proc.pid, root, client_key, host_key, known_hosts)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


KILL_SESSIONS = """
import os, signal
listener = int(open({pidfile!r}).read())
for entry in os.listdir("/proc"):
    if entry.isdigit():
        try:
            fields = open(f"/proc/{{entry}}/stat").read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == listener:
            os.kill(int(entry), signal.SIGKILL)
"""


def _write_fake_pi_commands(root: Path) -> None:
    """``pinctrl`` (records the alt5 switch) and ``sudo shutdown now`` (drops the link like a halt)."""
    bin_dir = root / "bin"
    bin_dir.mkdir()
    pinctrl = bin_dir / "pinctrl"
    pinctrl.write_text('#!/bin/sh\necho "pinctrl $*" >> "$PWD/pinctrl.log"\n')
    sudo = bin_dir / "sudo"
    sudo.write_text(f"#!{PYTHON3}\n" + KILL_SESSIONS.format(pidfile=str(root / "sshd.pid")))
    for tool in (pinctrl, sudo):
        tool.chmod(0o755)


FAKE_SCRIPTS = {
    "DRS_on.py": """
        import time
        with open("gpio.log", "a") as log:
            for pin, level in ((9, 1), (10, 1), (2, 0)):
                log.write(f"{pin}={level}\\n")
            time.sleep(0.2)
            for pin, level in ((2, 1), (10, 0)):
                log.write(f"{pin}={level}\\n")
            log.write("cleanup\\n14=alt5\\n")
        open("relay", "w").write("latched\\n")
    """,
    "DRS_log_serial.py": """
        import os, time
        time.sleep(0.2)
        if os.path.exists("relay") and not os.path.exists("gone"):
            with open("DRS_serial_log.txt", "ab") as log, open("nmea.txt", "rb") as nmea:
                log.write(nmea.read())
        os.system("tail DRS_serial_log.txt")
    """,
    "DRS_GoGoGo.py": """
        import os, signal, sys, time
        os.system("tail DRS_serial_log.txt")
        with open("ttyS0.tx", "ab") as port:
            port.write(b"GoGoGo\\n")
        print("Dropping in 30 seconds!", flush=True)
        time.sleep(0.3)
        print("Shutting down...", flush=True)
        time.sleep(0.1)
        listener = int(open(sys.argv[1] if len(sys.argv) > 1 else "sshd.pid").read())
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
                except OSError:
                    continue
                if int(fields[1]) == listener:
                    os.kill(int(entry), signal.SIGKILL)
        time.sleep(5)
    """,
}


@pytest.fixture
def capsule(sshd: RealSshd, tmp_path: Path) -> CapsuleConfig:
    tools = tmp_path / "DRS_Python_Tools"
    tools.mkdir()
    for name, body in FAKE_SCRIPTS.items():
        (tools / name).write_text(textwrap.dedent(body))
    (tools / "sshd.pid").write_text((sshd.root / "sshd.pid").read_text())
    now = datetime.now(UTC)
    (tools / "nmea.txt").write_text(
        format_gga(now, 67.8887, 21.0856, 1, 8, 1.1, 30000.0)
        + "\r\n"
        + format_rmc(now, 67.8887, 21.0856)
        + "\r\n"
    )
    mount = tmp_path / "raid1"
    mount.mkdir()
    table = {
        "name": "DRS1",
        "host": "127.0.0.1",
        "port": sshd.port,
        "user": os.environ.get("USER") or "root",
        "identity_file": str(sshd.client_key),
        "known_hosts": str(sshd.known_hosts),
        "tools_dir": str(tools),
        "python": PYTHON3,
        "storage_mount": str(mount),
        "microcontroller_wait_s": 3.0,
        "connect_timeout_s": 5.0,
        "command_timeout_s": 20.0,
    }
    return parse_config({"capsule": [table]}).capsules[0]


def _machine(config: CapsuleConfig, tmp_path: Path, holder: str = "EL@console1") -> ReleaseStateMachine:
    link = CapsuleLink(config)
    return ReleaseStateMachine(
        Store.open(tmp_path / "drs.sqlite"), config, StockBackend(config, link), "EL", holder=holder
    )


def test_power_on_runs_the_stock_script_with_the_interlock_sequence(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    machine = _machine(capsule, tmp_path)
    machine.power_on(confirmed=True)
    tools = Path(capsule.tools_dir)
    assert (tools / "gpio.log").read_text().split() == [
        "9=1",
        "10=1",
        "2=0",
        "2=1",
        "10=0",
        "cleanup",
        "14=alt5",
    ]
    assert (tools / "relay").exists()
    assert (tools / ".drs-release.owner").read_text().split()[0] == "EL@console1"
    report = machine.wait_for_microcontroller()
    assert report.waiting_for_go and report.gnss.has_fix and report.gnss.satellites == 8


def test_status_reads_real_df_of_the_mount(capsule: CapsuleConfig) -> None:
    with CapsuleLink(capsule) as link:
        status = read_storage(link, capsule.storage_mount, capsule.raid_device)
    assert status.usage is not None and status.usage.total_bytes > 0
    real_mount = os.path.realpath(capsule.storage_mount)
    assert real_mount == status.usage.mount or real_mount.startswith(status.usage.mount.rstrip("/") + "/")
    assert status.usage.used_bytes + status.usage.available_bytes <= status.usage.total_bytes
    if not Path("/proc/mdstat").exists():
        assert status.raid is None and status.as_dict()["raid_state"] == "missing"


def test_go_refused_without_power_on_or_with_the_wrong_name_sends_nothing(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    machine = _machine(capsule, tmp_path)
    with pytest.raises(RefusedError):
        machine.confirm("DRS1")
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    with pytest.raises(RefusedError, match="does not name"):
        machine.confirm("DRS2")
    assert not (Path(capsule.tools_dir) / "ttyS0.tx").exists()


def test_confirmed_go_writes_gogogo_and_the_link_drop_is_released_pi_shut_down(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    machine = _machine(capsule, tmp_path)
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    released = machine.go(machine.confirm("DRS1"))
    assert (Path(capsule.tools_dir) / "ttyS0.tx").read_bytes() == b"GoGoGo\n"
    assert released.state is ReleaseState.RELEASED and released.note == "released, Pi shut down"
    with pytest.raises(RefusedError, match="already released"):
        machine.confirm("DRS1")


def test_another_console_is_refused_release_authority_by_the_pi_lock(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    _machine(capsule, tmp_path / "a", holder="EL@console1").power_on(confirmed=True)
    theirs = _machine(capsule, tmp_path / "b", holder="JR@console2")
    with pytest.raises(RefusedError, match="held by EL@console1"):
        theirs.power_on(confirmed=True)


def _reading_under_the_shared_lock(tools: Path) -> bool:
    """Whether an authority query's ``flock -s`` is running in ``tools`` (waiting, while we hold the lock)."""
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                argv = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
                cwd = os.readlink(f"/proc/{entry}/cwd")
            except OSError:
                continue
            if argv[:2] == [b"flock", b"-s"] and cwd == str(tools.resolve()):
                return True
    return False


def test_authority_query_waits_for_the_lock_so_it_never_reads_a_half_written_owner_file(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    machine = _machine(capsule, tmp_path)
    assert machine.authority().state is AuthorityState.FREE
    machine.power_on(confirmed=True)
    tools = Path(capsule.tools_dir)
    owner = tools / remote.AUTHORITY_OWNER
    holder, lease_end = owner.read_text().split()
    status = machine.authority()
    assert (status.holder, status.lease_end_s, status.state) == (holder, int(lease_end), AuthorityState.HELD)
    assert 0 < status.seconds_left <= capsule.authority_lease_s
    with ThreadPoolExecutor(1) as pool, (tools / remote.AUTHORITY_LOCK).open("a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        owner.write_text("JR@cons")
        reading = pool.submit(machine.authority)
        deadline = time.monotonic() + 10
        while not _reading_under_the_shared_lock(tools):
            assert time.monotonic() < deadline and not reading.done(), "the query did not wait for the lock"
            time.sleep(0.02)
        owner.write_text(f"JR@console2 {int(lease_end) + 60}\n")
        fcntl.flock(lock, fcntl.LOCK_UN)
        seen = reading.result(timeout=20)
    assert (seen.holder, seen.lease_end_s) == ("JR@console2", int(lease_end) + 60)
    owner.write_text(f"JR@console2 {seen.pi_time_s - 1}\n")
    assert machine.authority().state is AuthorityState.EXPIRED


def test_take_over_on_a_real_shell_is_a_compare_and_set_under_the_lock(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    first = _machine(capsule, tmp_path / "a", holder="EL@console1")
    first.power_on(confirmed=True)
    slow = _machine(capsule, tmp_path / "b", holder="JR@backup")
    fast = _machine(capsule, tmp_path / "c", holder="AB@spare")
    stale = slow.authority()
    taken = fast.take_over(fast.authority(), "DRS1", "console1 is down")
    tools = Path(capsule.tools_dir)
    owner = tools / remote.AUTHORITY_OWNER
    assert owner.read_text().split() == ["AB@spare", str(taken.lease_end_s)]
    assert taken.seconds_left == int(capsule.authority_lease_s)
    with pytest.raises(RefusedError, match="changed since it was shown") as refused:
        slow.take_over(stale, "DRS1", "console1 is down")
    assert "held by EL@console1" in str(refused.value) and "now held by AB@spare" in str(refused.value)
    assert owner.read_text().split() == ["AB@spare", str(taken.lease_end_s)]
    assert first.wait_for_microcontroller().waiting_for_go
    with pytest.raises(RefusedError, match="held by AB@spare"):
        first.go(first.confirm("DRS1"))
    assert not (tools / "ttyS0.tx").exists()
    with pytest.raises(RefusedError, match="belongs to AB@spare"):
        first.release_authority()
    assert fast.release_authority("done").holder == "AB@spare"
    assert owner.read_text() == "" and fast.authority().state is AuthorityState.FREE


def test_wrong_host_key_is_refused(capsule: CapsuleConfig, sshd: RealSshd, tmp_path: Path) -> None:
    impostor = generate_ed25519()
    known_hosts = tmp_path / "known_hosts"
    known_hosts.write_text(f"[127.0.0.1]:{sshd.port} {impostor.get_name()} {impostor.get_base64()}\n")
    config = parse_config(
        {
            "capsule": [
                {
                    "name": "DRS1",
                    "host": "127.0.0.1",
                    "port": sshd.port,
                    "user": capsule.user,
                    "identity_file": str(sshd.client_key),
                    "known_hosts": str(known_hosts),
                }
            ]
        }
    ).capsules[0]
    with pytest.raises(HostKeyError, match="CHANGED") as refused:
        CapsuleLink(config).connect()
    assert fingerprint(sshd.host_key) in str(refused.value)


def test_sync_over_real_sftp_is_verified_by_sha256sum_on_the_server(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    source = tmp_path / "payload"
    (source / "sub").mkdir(parents=True)
    (source / "sub" / "a.bin").write_bytes(os.urandom(200_000))
    link = CapsuleLink(capsule)
    syncer = Syncer(Store.open(tmp_path / "drs.sqlite"), link, capsule.name, capsule.storage_mount)
    report = syncer.sync(source)
    link.close()
    assert report.uploaded == ("sub/a.bin",)
    assert (Path(capsule.storage_mount) / "sub" / "a.bin").read_bytes() == (
        source / "sub" / "a.bin"
    ).read_bytes()


def test_sync_verifies_files_whose_names_gnu_sha256sum_would_escape(
    capsule: CapsuleConfig, tmp_path: Path
) -> None:
    """Given a name with a backslash or a newline, GNU sha256sum starts its line with ``\\``: such a
    file never verified, the sync gave up after sending it twice, and every later file stayed unsent."""
    names = ["back\\slash.bin", "new\nline.bin", "z-after.bin"]
    source = tmp_path / "payload"
    source.mkdir()
    for name in names:
        (source / name).write_bytes(os.urandom(50_000))
    link = CapsuleLink(capsule)
    syncer = Syncer(Store.open(tmp_path / "drs.sqlite"), link, capsule.name, capsule.storage_mount)
    report = syncer.sync(source)
    after = syncer.status(source, with_hash=True)
    link.close()
    assert sorted(report.uploaded) == sorted(names) and report.bytes_sent == 150_000
    for name in names:
        assert (Path(capsule.storage_mount) / name).read_bytes() == (source / name).read_bytes()
    assert after.missing == () and after.changed == ()


def _kill_sessions_of(listener_pid: int) -> None:
    """SIGKILL this test's own sshd session processes (children of our listener), by pid."""
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == listener_pid:
                os.kill(int(entry), signal.SIGKILL)


def test_killing_the_session_mid_command_is_a_link_drop(capsule: CapsuleConfig, sshd: RealSshd) -> None:
    link = CapsuleLink(capsule)
    assert link.heartbeat()
    (Path(capsule.tools_dir) / "DRS_log_serial.py").write_text("import time\ntime.sleep(30)\n")
    killer = threading.Timer(0.5, _kill_sessions_of, args=(sshd.pid,))
    killer.start()
    started = time.monotonic()
    result = link.run(remote.read_serial(capsule.tools_dir, capsule.python, 0), timeout_s=10)
    killer.join()
    assert result.link_dropped and result.exit_status is None and time.monotonic() - started < 5
    link.close()


class PtyMicrocontroller:
    """The firmware model on the master side of a pseudo-terminal; the agent opens the slave."""

    def __init__(self, clock_scale: float = 40.0) -> None:
        self.clock = SimClock(clock_scale)
        self.firmware = Firmware()
        self.master, slave = os.openpty()
        self.device = os.ttyname(slave)
        self._slave = slave
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self.firmware.relay_latched(self.clock.now())
        self._thread.start()

    def _run(self) -> None:
        last = self.clock.now()
        while not self._stop.is_set():
            readable, _, _ = select.select([self.master], [], [], 0.02)
            now = self.clock.now()
            if readable:
                try:
                    self.firmware.receive_from_pi(os.read(self.master, 1024), now)
                except OSError:
                    return
            for line in self.firmware.output_between(last, now):
                os.write(self.master, line.encode() + b"\r\n")
            last = now

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self.master)
        os.close(self._slave)


@pytest.fixture
def agent_capsule(capsule: CapsuleConfig) -> Iterator[tuple[CapsuleConfig, PtyMicrocontroller]]:
    if importlib.util.find_spec("gpiozero") is None or importlib.util.find_spec("serial") is None:
        pytest.fail("gpiozero and pyserial are dependencies of the project: reinstall it")
    mcu = PtyMicrocontroller()
    config = replace(capsule, backend="agent", agent_python=sys.executable, serial_device=mcu.device)
    try:
        yield config, mcu
    finally:
        pidfile = Path(capsule.tools_dir) / "drs_agent_logger.pid"
        if pidfile.exists():
            try:
                os.kill(int(pidfile.read_text()), signal.SIGTERM)
            except (OSError, ValueError):
                pass
        mcu.stop()


def test_agent_script_on_a_real_sshd_pulses_the_pins_logs_nmea_and_reads_the_go_ack(
    agent_capsule: tuple[CapsuleConfig, PtyMicrocontroller], tmp_path: Path
) -> None:
    config, mcu = agent_capsule
    link = CapsuleLink(config)
    machine = ReleaseStateMachine(
        Store.open(tmp_path / "drs.sqlite"), config, AgentBackend(config, link), "EL"
    )
    machine.power_on(confirmed=True)
    mcu.start()
    tools = Path(config.tools_dir)
    assert (tools / "drs_agent.py").read_bytes() == AGENT_SOURCE.read_bytes()
    assert (tools / "pinctrl.log").read_text().split() == ["pinctrl", "set", "14", "a5"]
    report = machine.wait_for_microcontroller()
    assert report.waiting_for_go and report.gnss.has_fix
    stamped = (tools / "drs_agent_nmea.log").read_text().splitlines()[0]
    assert stamped.split(" ", 1)[0].endswith("Z") and "$GPGGA" in stamped
    released = machine.go(machine.confirm("DRS1"))
    assert released.state is ReleaseState.RELEASED and released.note == "released, Pi shut down"
    assert mcu.firmware.go_at is not None
    assert machine.store.audit("DRS1")[-1].detail["firmware_acknowledged"] is True  # type: ignore[index]
    assert "Dropping in 30 seconds!" in (tools / "DRS_serial_log.txt").read_text()
