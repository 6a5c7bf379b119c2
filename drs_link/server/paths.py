"""Paths a client names are read by the server only if the asking account could have read them itself.

Why: the server runs as its own account and reads files for its clients (the GRIB2 weather of ARM and
FIRE, the directory ``drs sync`` uploads). Opening whatever path a client names would make it a
confused deputy: an operator could name the server's store, its Pi keys or ``server.env`` and have the
server read them (into a prediction's error, or onto the capsule's disk). So every client-named path
is checked against the peer's own rights before anything opens it.

How: there is no ``access(2)`` for another uid (it answers for the caller, here the server), so the
check is the kernel's DAC rule done by hand, from the server's own ``stat`` of each name: the owner
bits when the peer owns it, else the group bits when one of the peer's groups owns it, else the other
bits; every directory on the way (as named, and after links are resolved) must grant search. The
peer's groups come from NSS for the kernel's uid (``getgrouplist``), never from anything the client
sends. ACLs and capabilities are not honoured: a file readable only through an ACL is refused, the
safe direction. Root (uid 0) reads and searches everything, as the kernel lets it.

What it does not close: a name swapped between this check and the read (a rename in a directory the
peer can write) is read as it then is; the server reads the resolved path this check returns, so a
link the peer plants afterwards in one of its own directories is the only route, and ``drs sync``
never follows links inside its source.
"""

from __future__ import annotations

import os
import pwd
import stat
from dataclasses import dataclass
from pathlib import Path

from drs_link.errors import LinkError, RefusedError

_READ, _SEARCH = 4, 1


@dataclass(frozen=True)
class Reader:
    """Who a path is checked for: the kernel's uid, its account and every group NSS lists for it."""

    uid: int
    account: str
    groups: frozenset[int]

    @classmethod
    def of(cls, uid: int) -> Reader:
        try:
            entry = pwd.getpwuid(uid)
        except KeyError:
            raise RefusedError(f"uid {uid} has no account on this host: it may name no file") from None
        return cls(uid, entry.pw_name, frozenset(os.getgrouplist(entry.pw_name, entry.pw_gid)))

    def may(self, info: os.stat_result, wanted: int) -> bool:
        """Whether the permission bits of ``info`` grant ``wanted`` (read 4, search 1) to this reader."""
        if self.uid == 0:
            return True
        mode = stat.S_IMODE(info.st_mode)
        if info.st_uid == self.uid:
            granted = mode >> 6
        elif info.st_gid in self.groups:
            granted = mode >> 3
        else:
            granted = mode
        return granted & wanted == wanted


def _refused(named: str, reader: Reader) -> RefusedError:
    return RefusedError(
        f"{named}: refused: {reader.account} could not read it (the server reads only what the asking "
        "account may: check its mode and every directory above it)"
    )


def _searchable_parents(path: Path, named: str, reader: Reader) -> None:
    for parent in reversed(path.parents):
        try:
            info = parent.stat()
        except OSError:
            raise _refused(named, reader) from None
        if not stat.S_ISDIR(info.st_mode) or not reader.may(info, _SEARCH):
            raise _refused(named, reader)


def readable_path(uid: int, named: str, *, directory: bool = False) -> Path:
    """The resolved path of ``named`` if the account of ``uid`` could read it (a directory: list and
    enter it), else a one-line refusal that names the path and nothing of its content."""
    reader = Reader.of(uid)
    path = Path(named)
    if not path.is_absolute():
        raise RefusedError(f"{named}: name it from / (the server does not share your working directory)")
    _searchable_parents(path, named, reader)
    real = Path(os.path.realpath(path))
    _searchable_parents(real, named, reader)
    try:
        info = real.stat()
    except FileNotFoundError:
        raise LinkError(f"{named} is not a directory" if directory else f"{named}: no such file") from None
    except OSError:
        raise _refused(named, reader) from None
    if directory and not stat.S_ISDIR(info.st_mode):
        raise LinkError(f"{named} is not a directory")
    if not reader.may(info, _READ | _SEARCH if directory else _READ):
        raise _refused(named, reader)
    return real


def readable_tree(uid: int, named: str) -> Path:
    """``readable_path`` for a directory, and every folder and regular file under it that the server
    would read (links are never followed there): one the account could not read refuses the whole."""
    root = readable_path(uid, named, directory=True)
    reader = Reader.of(uid)
    for folder, dirnames, filenames in os.walk(root):
        for name in [*dirnames, *filenames]:
            entry = Path(folder) / name
            try:
                info = entry.lstat()
            except OSError:
                continue  # gone, or unreadable to the server too: the sync leaves it out and says so
            wanted = _READ | _SEARCH if stat.S_ISDIR(info.st_mode) else _READ
            if (stat.S_ISDIR(info.st_mode) or stat.S_ISREG(info.st_mode)) and not reader.may(info, wanted):
                raise _refused(str(Path(named) / entry.relative_to(root)), reader)
    return root
