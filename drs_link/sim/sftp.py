"""SFTP into the simulated capsule's storage mount (``/mnt/raid1`` backed by a temporary directory).

Only paths under the mount and the tools directory exist, as on a Pi where the console has no
business elsewhere. The
mount has a capacity, so a full disk fails a write the way ext4 does, after the bytes that fit.
"""

from __future__ import annotations

import os
import posixpath
from collections.abc import Callable
from pathlib import Path
from typing import IO, TYPE_CHECKING

import paramiko
from paramiko.sftp import SFTP_FAILURE, SFTP_NO_SUCH_FILE, SFTP_OK, SFTP_PERMISSION_DENIED

if TYPE_CHECKING:
    from typing_extensions import Buffer

    from drs_link.sim.capsule_pi import CapsuleSimulator


def _status(exc: OSError) -> int:
    """The SFTP status for a failed call (an OSError without an errno is a plain failure)."""
    return paramiko.SFTPServer.convert_errno(exc.errno if exc.errno is not None else 0)


class _Handle(paramiko.SFTPHandle):
    readfile: IO[bytes]
    writefile: IO[bytes]
    """The open file paramiko's own read and write use, once ``open`` sets them."""

    def __init__(self, flags: int, sim: CapsuleSimulator, real: Path) -> None:
        super().__init__(flags)
        self.sim = sim
        self.real = real

    def write(self, offset: int, data: Buffer) -> int:
        chunk = bytes(data)
        current = self.real.stat().st_size
        growth = max(0, offset + len(chunk) - current)
        if growth and self.sim.storage_used() + growth > self.sim.capacity_bytes:
            return SFTP_FAILURE
        if offset == 0 and chunk and self.sim.faults.corrupt_writes > 0:
            self.sim.faults.corrupt_writes -= 1
            chunk = bytes([chunk[0] ^ 0xFF]) + chunk[1:]
        return super().write(offset, chunk)

    def stat(self) -> paramiko.SFTPAttributes | int:
        try:
            return paramiko.SFTPAttributes.from_stat(os.stat(self.real))
        except OSError as exc:
            return _status(exc)

    def chattr(self, attr: paramiko.SFTPAttributes) -> int:
        return _apply_attr(self.real, attr)


def _apply_attr(real: Path, attr: paramiko.SFTPAttributes) -> int:
    try:
        if attr.st_mtime is not None:
            os.utime(real, (attr.st_atime or attr.st_mtime, attr.st_mtime))
        if attr.st_mode is not None:
            os.chmod(real, attr.st_mode & 0o7777)
    except OSError as exc:
        return _status(exc)
    return SFTP_OK


class SimSftpServer(paramiko.SFTPServerInterface):
    def __init__(self, server: paramiko.ServerInterface, sim: CapsuleSimulator) -> None:
        super().__init__(server)
        self.sim = sim

    def session_started(self) -> None:
        self.sim.sftp_sessions.started()

    def session_ended(self) -> None:
        self.sim.sftp_sessions.ended()

    def canonicalize(self, path: str) -> str:
        return posixpath.normpath(posixpath.join("/home/pi", path))

    def _real(self, path: str) -> Path | None:
        return self.sim.real_path(self.canonicalize(path))

    def _guard(self, path: str) -> Path:
        real = self._real(path)
        if real is None:
            raise PermissionError(path)
        return real

    def list_folder(self, path: str) -> list[paramiko.SFTPAttributes] | int:
        try:
            real = self._guard(path)
            out = []
            for name in sorted(os.listdir(real)):
                attr = paramiko.SFTPAttributes.from_stat(os.lstat(real / name))
                attr.filename = name
                out.append(attr)
            return out
        except PermissionError:
            return SFTP_PERMISSION_DENIED
        except OSError as exc:
            return _status(exc)

    def stat(self, path: str) -> paramiko.SFTPAttributes | int:
        try:
            return paramiko.SFTPAttributes.from_stat(os.stat(self._guard(path)))
        except PermissionError:
            return SFTP_PERMISSION_DENIED
        except OSError as exc:
            return _status(exc)

    def lstat(self, path: str) -> paramiko.SFTPAttributes | int:
        """The entry itself, a link included, as OpenSSH's sftp-server answers (``stat`` follows it)."""
        try:
            return paramiko.SFTPAttributes.from_stat(os.lstat(self._guard(path)))
        except PermissionError:
            return SFTP_PERMISSION_DENIED
        except OSError as exc:
            return _status(exc)

    def open(self, path: str, flags: int, attr: paramiko.SFTPAttributes) -> _Handle | int:
        try:
            real = self._guard(path)
            fd = os.open(real, flags | getattr(os, "O_BINARY", 0), 0o644)
        except PermissionError:
            return SFTP_PERMISSION_DENIED
        except OSError as exc:
            return _status(exc)
        if flags & os.O_WRONLY:
            mode = "ab" if flags & os.O_APPEND else "wb"
        elif flags & os.O_RDWR:
            mode = "a+b" if flags & os.O_APPEND else "r+b"
        else:
            mode = "rb"
        handle = _Handle(flags, self.sim, real)
        file = os.fdopen(fd, mode)
        handle.readfile = file
        handle.writefile = file
        return handle

    def remove(self, path: str) -> int:
        return self._call(lambda: os.remove(self._guard(path)))

    def rename(self, oldpath: str, newpath: str) -> int:
        def move() -> None:
            new = self._guard(newpath)
            if new.exists():
                raise FileExistsError(newpath)
            os.rename(self._guard(oldpath), new)

        return self._call(move)

    def posix_rename(self, oldpath: str, newpath: str) -> int:
        return self._call(lambda: os.replace(self._guard(oldpath), self._guard(newpath)))

    def mkdir(self, path: str, attr: paramiko.SFTPAttributes) -> int:
        return self._call(lambda: os.mkdir(self._guard(path)))

    def rmdir(self, path: str) -> int:
        return self._call(lambda: os.rmdir(self._guard(path)))

    def chattr(self, path: str, attr: paramiko.SFTPAttributes) -> int:
        try:
            return _apply_attr(self._guard(path), attr)
        except PermissionError:
            return SFTP_PERMISSION_DENIED

    @staticmethod
    def _call(action: Callable[[], object]) -> int:
        try:
            action()
        except PermissionError:
            return SFTP_PERMISSION_DENIED
        except FileNotFoundError:
            return SFTP_NO_SUCH_FILE
        except OSError as exc:
            return _status(exc)
        return SFTP_OK
