"""Who is on the other end of a connection, as the kernel says it: the server's only source of identity.

Why: every rule that needs "another person" was once judged from something the first person could
write (a list of approvers' keys in a config file, a row of a group-writable store). A Unix socket's peer
credentials (``SO_PEERCRED``) are filled in by the kernel from the connecting process; no client can
choose them. The uid is mapped to an operator only through the server's OWN configuration, which only
the server's account and root may write (``check_own_file``): a client's configuration, and anything
a client says about itself, count for nothing.
"""

from __future__ import annotations

import os
import socket
import stat
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from drs_link.config import Config
from drs_link.errors import ConfigError, RefusedError
from drs_link.store import account_of

Mode = Literal["private", "shared"]
_CREDENTIALS = struct.Struct("3i")
"""``struct ucred``: pid, uid, gid."""


@dataclass(frozen=True)
class Peer:
    """One connected operator: the kernel's uid, its account, and the operator name it acts under."""

    uid: int
    account: str
    operator: str


def peer_uid(connection: socket.socket) -> int:
    """The uid of the process at the other end of a Unix stream socket, from the kernel."""
    raw = connection.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, _CREDENTIALS.size)
    return int(_CREDENTIALS.unpack(raw)[1])


class Roster:
    """The server's map from a connection's uid to an operator.

    Shared: the ``[[operator]]`` list of the server's configuration, nobody else (root included, unless
    listed). Private: only the account the server runs as, under its ``[operator] name``.
    """

    def __init__(self, config: Config, mode: Mode, own_uid: int | None = None) -> None:
        self.mode = mode
        self.own_uid = os.geteuid() if own_uid is None else own_uid
        self.operators = {o.account: o.name for o in config.operators}
        self.own_name = config.operator.name
        if mode == "shared" and not self.operators:
            raise ConfigError(
                f"{config.where()}: a shared server needs its [[operator]] list "
                '([[operator]] account = "alice" name = "EL", one per person)'
            )

    def peer(self, uid: int) -> Peer:
        account = account_of(uid)
        if self.mode == "private":
            if uid != self.own_uid:  # the socket's 0700 directory already keeps others out
                raise RefusedError(
                    f"this private server belongs to {account_of(self.own_uid)}, not {account}"
                )
            return Peer(uid, account, self.own_name)  # no name: the services refuse what must be audited
        name = self.operators.get(account)
        if name is None:
            raise RefusedError(
                f"the account {account} (uid {uid}) is not an operator of this server: "
                "its administrator lists it in the server's [[operator]] table"
            )
        return Peer(uid, account, name)


def check_own_file(path: Path, what: str = "configuration") -> None:
    """Refuse a file that someone other than this account or root could have written: the server's
    configuration decides who each uid is, so it must be as safe as the server itself."""
    try:
        info = path.stat()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the server's {what}: {exc.strerror}") from None
    me = os.geteuid()
    if info.st_uid not in (me, 0):
        raise ConfigError(
            f"{path}: the server's {what} belongs to {account_of(info.st_uid)}; it must belong to "
            f"{'root' if me == 0 else account_of(me) + ' or root'} (chown {account_of(me)} {path})"
        )
    if stat.S_IMODE(info.st_mode) & (stat.S_IWGRP | stat.S_IWOTH):
        raise ConfigError(
            f"{path}: the server's {what} is writable by its group or others "
            f"(mode {stat.S_IMODE(info.st_mode):04o}); chmod go-w {path}"
        )


def check_state_directory(directory: Path) -> None:
    """A shared server's store must sit where no operator can reach it (the OS refuses their writes)."""
    try:
        info = directory.stat()
    except FileNotFoundError:
        return  # Store.open makes it 0700
    if stat.S_IMODE(info.st_mode) & 0o077 or info.st_uid != os.geteuid():
        raise ConfigError(
            f"{directory}: a shared server's data directory must be its own, mode 0700 "
            f"(it is {account_of(info.st_uid)}'s, mode {stat.S_IMODE(info.st_mode):04o}): operators must "
            "not be able to write the store; drs setup server makes it so"
        )
