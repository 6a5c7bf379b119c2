"""A flight team on one ground machine, for the server's tests: real Unix accounts and a real `drs server`.

Accounts and a group are made with useradd/groupadd (root; the tests skip without it, CI is root). The
server runs as a real process (`python -m console.commands.main server`), as root, with its store in a
0700 directory of its own. Each operator's `drs` runs in a fork of this process that drops to the
operator's uid, gid and groups: this machine's Python lives under /root, which other accounts cannot
enter, so a fresh interpreter could not start as them (tests/drs_link/test_shared_store.py does the
same); the kernel's checks (the socket's mode, SO_PEERCRED, the store's directory) are the same in a fork.
"""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

import console.commands.approve  # noqa: F401 - every module a fork needs, imported before it drops root
import console.commands.capsule  # noqa: F401
import console.commands.iridium  # noqa: F401
import drs_link.server.client  # noqa: F401
import drs_link.server.private  # noqa: F401
from console.commands.main import main
from drs_link.server.client import Client
from drs_link.server.private import listening

needs_root = pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("useradd") is None,
    reason="creates OS accounts with useradd/groupadd, which needs root (CI runs as root)",
)


@dataclass(frozen=True)
class Team:
    group: str
    alice: str
    bob: str
    mallory: str
    """In the group, so the socket lets her in, but in no [[operator]] table."""
    outsider: str
    """Not in the group."""


def server_config(place: Path, team: Team, body: str) -> Path:
    """The server's own configuration: root's, 0644, naming who each account is."""
    path = place / "server.toml"
    state = place / "state"
    state.mkdir(mode=0o700)
    path.write_text(
        f'[data]\ndir = "{state}"\n'
        f'[[operator]]\naccount = "{team.alice}"\nname = "EL"\n'
        f'[[operator]]\naccount = "{team.bob}"\nname = "JM"\n{body}'
    )
    path.chmod(0o644)
    return path


def client_config(place: Path, account: str, extra: str = "") -> Path:
    """An operator's own drs.toml: it names the server's socket, and whatever else it likes."""
    path = place / f"{account}.toml"
    path.write_text(
        f'[operator]\nname = "{account}"\n[server]\nsocket = "{place / "run" / "drs.sock"}"\n{extra}'
    )
    path.chmod(0o644)
    return path


class Server:
    """`drs server` as a real process, shared, its socket 0660 to the team's group."""

    def __init__(self, config: Path, place: Path, group: str, env: dict[str, str] | None = None) -> None:
        run = place / "run"
        run.mkdir(mode=0o755, exist_ok=True)
        self.socket = run / "drs.sock"
        self.log = place / "server.log"
        argv = [sys.executable, "-m", "console.commands.main", "--config", str(config), "server",
                "--socket", str(self.socket), "--group", group]  # fmt: skip
        with open(self.log, "ab") as log:
            self.process = subprocess.Popen(argv, stdout=log, stderr=log, env={**os.environ, **(env or {})})
        deadline = time.monotonic() + 30.0
        while not listening(self.socket):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"the server did not start: {self.log.read_text()}")
            time.sleep(0.05)

    def client(self) -> Client:
        return Client(self.socket)

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=30)


def as_account(user: str, work: Callable[[], int]) -> tuple[int, str]:
    """Run ``work`` in a child with ``user``'s uid, gid and groups; its exit code and output."""
    return Forked(user, work).result()


class Forked:
    """``work`` running as ``user`` in a child process, for a command that waits (``--await-approval``)."""

    def __init__(self, user: str, work: Callable[[], int]) -> None:
        read_end, write_end = os.pipe()
        self.pid = os.fork()
        if self.pid == 0:  # the child: never returns into pytest
            code = 70
            try:
                os.close(read_end)
                out = os.fdopen(write_end, "w", buffering=1)
                sys.stdout = sys.stderr = out
                account = pwd.getpwnam(user)
                os.setgroups(os.getgrouplist(user, account.pw_gid))
                os.setgid(account.pw_gid)
                os.setuid(account.pw_uid)
                code = work()
                out.flush()
            except BaseException as exc:  # noqa: BLE001 - reported to the parent, which fails the test
                print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
            finally:
                os._exit(code)
        os.close(write_end)
        self.pipe = os.fdopen(read_end)

    def readline(self) -> str:
        return self.pipe.readline()

    def result(self) -> tuple[int, str]:
        output = self.pipe.read()
        self.pipe.close()
        _, status = os.waitpid(self.pid, 0)
        return os.waitstatus_to_exitcode(status), output


def drs(user: str, config: Path, *argv: str) -> tuple[int, str]:
    """`drs --config CONFIG argv` as ``user``."""
    return as_account(user, lambda: main(["--config", str(config), *argv]))


def drs_waiting(user: str, config: Path, *argv: str) -> Forked:
    return Forked(user, lambda: main(["--config", str(config), *argv]))
