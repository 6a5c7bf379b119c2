"""This account's private operations server, started on demand as tmux starts its server.

Why: single-operator use and ``make demo`` need no set-up, yet every action still goes through a
server. Its socket sits in a directory only this account can enter (``$XDG_RUNTIME_DIR/drs``, else
``/tmp/drs-<uid>``, made 0700 and refused if anyone else owns it), so only this account reaches it;
that is also why it can never satisfy ``require_second_operator`` (``release.PRIVATE_TWO_PERSON``).
One server per configuration as it now reads (the socket's name is a hash of its file's path and content,
or of every setting when there is no file, so an edited file gets a server that read it; the old one exits
when idle, as every private one does).
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import socket
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

from drs_link.config import Config, default_config_path
from drs_link.errors import ConfigError, LinkError

if TYPE_CHECKING:
    from drs_link.server.desks import PredictorFor
    from drs_link.server.recovery import LiveFor

IDLE_EXIT_S = 300.0
"""A private server with no request for this long exits (``$DRS_SERVER_IDLE_S`` overrides it)."""
START_WAIT_S = 30.0
SERVER_MODULE = "console.commands.main"
"""The ``drs`` entry point, run as ``drs server --private`` (named, not imported: it sits above this room)."""


def runtime_directory() -> Path:
    """A directory only this account can enter, made if need be; refused if another account made it."""
    uid = os.geteuid()
    xdg = os.environ.get("XDG_RUNTIME_DIR", "")
    base = Path(xdg) / "drs" if xdg and _owned_private(Path(xdg), uid) else Path(f"/tmp/drs-{uid}")
    try:
        base.mkdir(mode=0o700, exist_ok=True)
    except OSError as exc:
        raise LinkError(f"cannot make {base} for the private server: {exc.strerror}") from None
    if not _owned_private(base, uid):
        raise ConfigError(
            f"{base} is not this account's alone (owner or mode): the private server's socket cannot go "
            f"there; remove it or set $XDG_RUNTIME_DIR"
        )
    return base


def _owned_private(path: Path, uid: int) -> bool:
    info = path.lstat()
    return stat.S_ISDIR(info.st_mode) and info.st_uid == uid and stat.S_IMODE(info.st_mode) & 0o077 == 0


def config_key(config: Config) -> str:
    """The configuration a private server serves: its file's path and what it said when loaded, or,
    with no file, every setting (the defaults depend on ``$XDG_CONFIG_HOME`` and ``$XDG_DATA_HOME``: one
    key for all of them once had a client with other directories served another's store and told of
    another's missing file)."""
    if config.source is None:
        return f"(no file)\0{default_config_path()}\0{config!r}"
    try:
        content = hashlib.sha256(config.source.read_bytes()).hexdigest()
    except OSError:
        content = "(unreadable)"
    return f"{config.source.resolve()}\0{content}"


def private_socket(config: Config) -> Path:
    where = config_key(config)
    return runtime_directory() / f"server-{hashlib.sha256(where.encode()).hexdigest()[:12]}.sock"


def listening(path: Path) -> bool:
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(str(path))
    except OSError:
        return False
    finally:
        probe.close()
    return True


IN_PROCESS_ENV = "DRS_PRIVATE_SERVER"
"""``thread``: run the private server in a thread of this process instead of its own process (tests that
watch or patch the operations layer from the test's process; a killed ``drs`` then kills its server)."""
_threads: dict[str, Path] = {}


def ensure_private_server(
    config: Config, predictor_for: PredictorFor | None = None, live_for: LiveFor | None = None
) -> Path:
    """The private server's socket, its server started first when none listens."""
    if os.environ.get(IN_PROCESS_ENV) == "thread":
        return _thread_server(config, predictor_for, live_for)
    path = private_socket(config)
    if listening(path):
        return path
    log_path = path.with_suffix(".log")
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one starter at a time; the others find it listening
        if listening(path):
            return path
        idle = os.environ.get("DRS_SERVER_IDLE_S", str(IDLE_EXIT_S))
        argv = [sys.executable, "-m", SERVER_MODULE]
        if config.source is not None:
            argv += ["--config", str(config.source.resolve())]
        argv += ["server", "--private", "--socket", str(path), "--idle-exit", idle]
        with open(log_path, "ab") as log:
            process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                                       start_new_session=True)  # fmt: skip
        deadline = time.monotonic() + START_WAIT_S
        while time.monotonic() < deadline:
            if listening(path):
                return path
            if process.poll() is not None:
                break
            time.sleep(0.05)
    tail = log_path.read_text(errors="replace").strip().splitlines()[-1:] if log_path.exists() else []
    said = tail[0].removeprefix("drs: error: ") if tail else "no output"
    raise LinkError(f"the private operations server did not start: {said} (log: {log_path})")


def _thread_server(config: Config, predictor_for: PredictorFor | None, live_for: LiveFor | None) -> Path:
    """The private server in a daemon thread of this process: the same server, socket and identity check."""
    path = private_socket(config).with_name(f"server-{os.getpid()}-{len(_threads)}.sock")
    key = config_key(config)
    if key in _threads and listening(_threads[key]):
        return _threads[key]
    import asyncio

    from drs_link.server.app import OperationsServer

    server = OperationsServer(config, "private", path, predictor_for=predictor_for, live_for=live_for)
    failed: list[BaseException] = []

    def run() -> None:
        try:
            asyncio.run(server.run(lambda line: None))
        except BaseException as exc:  # noqa: BLE001 - said by the caller below
            failed.append(exc)

    threading.Thread(target=run, daemon=True, name="drs-private-server").start()
    deadline = time.monotonic() + START_WAIT_S
    while not listening(path):
        if failed or time.monotonic() > deadline:
            raise LinkError(
                f"the private operations server did not start: {failed[0] if failed else 'timeout'}"
            )
        time.sleep(0.01)
    _threads[key] = path
    return path


class InProcessServer:
    """A private server in a thread of this process, stopped with ``stop``: the demo's, whose world (the
    store, the simulators, the gateway password) lives in this process too and ends with it."""

    def __init__(
        self, config: Config, predictor_for: PredictorFor | None = None, environ: dict[str, str] | None = None,
        clock: Callable[[], datetime] | None = None, poll_period_s: float | None = None,
    ) -> None:  # fmt: skip
        """``poll_period_s``: the demo's pace of telemetry polls (``OperationsServer``)."""
        import asyncio

        from drs_link.server.app import OperationsServer

        self.socket = private_socket(config).with_name(f"server-{os.getpid()}-{id(self):x}.sock")
        self.server = OperationsServer(config, "private", self.socket, predictor_for=predictor_for,
                                       environ=environ, clock=clock, poll_period_s=poll_period_s)  # fmt: skip
        self._loop: asyncio.AbstractEventLoop | None = None
        failed: list[BaseException] = []

        async def serve() -> None:
            self._loop = asyncio.get_running_loop()
            await self.server.run(lambda line: None)

        def run() -> None:
            try:
                asyncio.run(serve())
            except BaseException as exc:  # noqa: BLE001 - said by the caller below
                failed.append(exc)

        self._thread = threading.Thread(target=run, daemon=True, name="drs-private-server")
        self._thread.start()
        deadline = time.monotonic() + START_WAIT_S
        while not listening(self.socket):
            if failed or time.monotonic() > deadline:
                raise LinkError(
                    f"the private operations server did not start: {failed[0] if failed else 'timeout'}"
                )
            time.sleep(0.01)

    def stop(self) -> None:
        """End the server and wait for its thread: a request in flight is answered if it ends within
        ``app.STOP_GRACE_S``, else its connection is closed (``OperationsServer.stop``)."""
        if self._loop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self.server.stopping.set)
        self._thread.join(timeout=START_WAIT_S)
