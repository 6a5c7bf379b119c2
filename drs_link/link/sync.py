"""Getting the flight data onto the capsule's RAID1 mount over SFTP, and knowing that it arrived.

A file counts as synced only after the Pi has flushed it and its own sha256 matches ours; until
then it lives under a temporary name, so a dropped link or a full card can never leave a
half-written file where a complete one is expected. An interrupted upload resumes from the
bytes already on the Pi (the final hash catches a bad prefix, which is then re-sent whole).
"""

from __future__ import annotations

import hashlib
import os
import posixpath
import stat
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import paramiko

from drs_link.errors import LinkError
from drs_link.link import remote
from drs_link.link.ssh import CapsuleLink, CommandResult
from drs_link.link.storage import read_storage
from drs_link.store import Store, iso_utc, parse_iso_utc, utc_now

PARTIAL_SUFFIX = ".drs-partial"
CHUNK = 256 * 1024

_DDL = """
CREATE TABLE IF NOT EXISTS sync_files (
    capsule TEXT NOT NULL,
    path TEXT NOT NULL,
    size INTEGER NOT NULL,
    mtime INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    verified_at TEXT NOT NULL,
    PRIMARY KEY (capsule, path)
);
"""


@dataclass(frozen=True)
class LocalFile:
    relative: str
    path: Path
    size: int
    mtime: int


@dataclass(frozen=True)
class SyncStatus:
    missing: tuple[str, ...]
    changed: tuple[str, ...]
    up_to_date: tuple[str, ...]
    bytes_pending: int
    last_sync_utc: datetime | None
    left_out: tuple[str, ...] = ()
    """Entries of the source that are not uploaded, each ``path (why)``: links, FIFOs, unreadable folders."""

    def as_dict(self) -> dict[str, object]:
        return {
            "missing": list(self.missing),
            "changed": list(self.changed),
            "up_to_date": len(self.up_to_date),
            "bytes_pending": self.bytes_pending,
            "last_sync_utc": iso_utc(self.last_sync_utc) if self.last_sync_utc else None,
            "left_out": list(self.left_out),
        }


@dataclass(frozen=True)
class SyncReport:
    uploaded: tuple[str, ...]
    skipped: tuple[str, ...]
    bytes_sent: int
    left_out: tuple[str, ...] = ()
    """As ``SyncStatus.left_out``: said by count and name, never dropped without a word."""


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(CHUNK), b""):
            digest.update(block)
    return digest.hexdigest()


def local_files(source: Path) -> list[LocalFile]:
    return scan_source(source)[0]


def scan_source(source: Path) -> tuple[list[LocalFile], list[str]]:
    """The regular files under ``source``, and every entry left out with the reason (``path (why)``).

    Why links are not followed: the RAID is dropped from the balloon, and a file link's target (anything
    on this laptop) was uploaded in its place; directory links, loops, FIFOs and sockets were skipped
    without a word ("2 files uploaded" while 6 entries were left out).
    """
    if not source.is_dir():
        raise LinkError(f"{source} is not a directory")
    files: list[LocalFile] = []
    left_out: list[str] = []

    def unreadable(exc: OSError) -> None:
        where = Path(exc.filename).relative_to(source).as_posix() if exc.filename else "?"
        left_out.append(f"{where}/ (cannot be read: {exc.strerror or exc})")

    for dirpath, dirnames, filenames in os.walk(source, onerror=unreadable):
        folder = Path(dirpath)
        for name in sorted(dirnames):
            if (folder / name).is_symlink():
                dirnames.remove(name)
                link = (folder / name).relative_to(source).as_posix()
                left_out.append(f"{link}/ (a directory link, not followed)")
        dirnames.sort()
        for name in sorted(filenames):
            path = folder / name
            relative = path.relative_to(source).as_posix()
            try:
                info = path.lstat()
            except OSError as exc:
                left_out.append(f"{relative} (cannot be read: {exc.strerror or exc})")
                continue
            if name.endswith(PARTIAL_SUFFIX):
                left_out.append(f"{relative} (a partial upload's name)")
            elif stat.S_ISLNK(info.st_mode):
                left_out.append(f"{relative} (a link, not followed: its target would be uploaded)")
            elif not stat.S_ISREG(info.st_mode):
                left_out.append(f"{relative} (not a regular file: a FIFO, socket or device)")
            else:
                files.append(LocalFile(relative, path, info.st_size, int(info.st_mtime)))
    return files, left_out


def _remote_tree(
    sftp: paramiko.SFTPClient, directory: str, prefix: str = ""
) -> dict[str, paramiko.SFTPAttributes]:
    """Every regular file under ``directory``, by path relative to it (a missing mount is empty)."""
    found: dict[str, paramiko.SFTPAttributes] = {}
    try:
        entries = sftp.listdir_attr(directory)
    except FileNotFoundError:
        return found
    for entry in entries:
        relative = f"{prefix}{entry.filename}"
        if entry.st_mode is not None and stat.S_ISDIR(entry.st_mode):
            found.update(_remote_tree(sftp, posixpath.join(directory, entry.filename), relative + "/"))
        else:
            found[relative] = entry
    return found


class Syncer:
    def __init__(
        self, store: Store, link: CapsuleLink, capsule_name: str, mount: str, raid_device: str = "/dev/md0"
    ) -> None:
        self.store = store
        self.link = link
        self.capsule = capsule_name
        self.mount = mount.rstrip("/")
        self.raid_device = raid_device
        store.ensure_schema(_DDL)

    def _remote_path(self, relative: str) -> str:
        return posixpath.join(self.mount, relative)

    def status(self, source: Path, with_hash: bool = False) -> SyncStatus:
        """Missing and changed files by size+mtime; ``with_hash`` also compares sha256 computed on the Pi."""
        files, left_out = scan_source(source)
        sftp = self.link.sftp()
        try:
            remote_files = _remote_tree(sftp, self.mount)
        except OSError as exc:
            raise LinkError(f"{self.capsule}: cannot list {self.mount}: {exc}") from None
        finally:
            sftp.close()
        missing, changed, current = [], [], []
        pending = 0
        for item in files:
            attr = remote_files.get(item.relative)
            if attr is None:
                missing.append(item.relative)
                pending += item.size
            elif (
                attr.st_size != item.size
                or int(attr.st_mtime or 0) != item.mtime
                or (with_hash and self._pi_sha256(item.relative) != sha256_file(item.path))
            ):
                changed.append(item.relative)
                pending += item.size
            else:
                current.append(item.relative)
        rows = self.store.query(
            "SELECT MAX(verified_at) AS last FROM sync_files WHERE capsule = ?", (self.capsule,)
        )
        last = parse_iso_utc(rows[0]["last"]) if rows and rows[0]["last"] else None
        return SyncStatus(tuple(missing), tuple(changed), tuple(current), pending, last, tuple(left_out))

    def sync(
        self,
        source: Path,
        on_progress: Callable[[str, int, int], None] | None = None,
        on_verified: Callable[[str], None] | None = None,
    ) -> SyncReport:
        """Push every missing or changed file; each is durable in the store before the next starts."""
        status = self.status(source)
        todo = set(status.missing) | set(status.changed)
        files = [f for f in local_files(source) if f.relative in todo]
        needed = sum(f.size for f in files)
        storage = read_storage(self.link, self.mount, self.raid_device)
        if storage.usage is not None and storage.usage.available_bytes < needed:
            raise LinkError(
                f"{self.capsule}: {self.mount} has {storage.usage.available_bytes} bytes free but "
                f"{needed} are to be sent; nothing was uploaded"
            )
        uploaded: list[str] = []
        sent = 0
        for item in files:
            sent += self._upload(item, on_progress)
            uploaded.append(item.relative)
            if on_verified is not None:
                on_verified(item.relative)
        return SyncReport(tuple(uploaded), tuple(status.up_to_date), sent, status.left_out)

    def _upload(self, item: LocalFile, on_progress: Callable[[str, int, int], None] | None) -> int:
        final = self._remote_path(item.relative)
        partial = final + PARTIAL_SUFFIX
        digest = sha256_file(item.path)
        sftp = self.link.sftp()
        try:
            self._refuse_links(sftp, item.relative)
            self._make_dirs(sftp, posixpath.dirname(item.relative))
            sent = self._send(sftp, item, partial, on_progress)
            verified = self._remote_sha256(partial)
            if verified != digest:
                sftp.remove(partial)
                sent += self._send(sftp, item, partial, on_progress)
                verified = self._remote_sha256(partial)
                if verified != digest:
                    raise LinkError(
                        f"{self.capsule}: {item.relative}: the Pi's sha256 does not match after re-sending"
                    )
            sftp.utime(partial, (item.mtime, item.mtime))
            sftp.posix_rename(partial, final)
        except OSError as exc:
            raise self._explain(item, exc) from None
        except (EOFError, paramiko.SSHException):
            self.link.close()
            raise LinkError(
                f"{self.capsule}: the link dropped while sending {item.relative}; "
                "files already verified are safe, run sync again to resume"
            ) from None
        finally:
            try:
                sftp.close()
            except (OSError, EOFError):
                pass
        self.store.write(
            "INSERT OR REPLACE INTO sync_files (capsule, path, size, mtime, sha256, verified_at)"
            " VALUES (?, ?, ?, ?, ?, ?)",
            (self.capsule, item.relative, item.size, item.mtime, digest, iso_utc(utc_now())),
        )
        return sent

    def _explain(self, item: LocalFile, exc: OSError) -> LinkError:
        if not self.link.connected:
            return LinkError(
                f"{self.capsule}: the link dropped while sending {item.relative}; "
                "files already verified are safe, run sync again to resume"
            )
        try:
            storage = read_storage(self.link, self.mount, self.raid_device)
        except LinkError:
            storage = None
        if storage and storage.usage and storage.usage.available_bytes < item.size:
            return LinkError(
                f"{self.capsule}: {self.mount} is full while sending {item.relative} "
                f"({storage.usage.available_bytes} bytes free); files already verified are safe"
            )
        return LinkError(f"{self.capsule}: cannot write {item.relative} on the Pi: {exc}")

    def _refuse_links(self, sftp: paramiko.SFTPClient, relative: str) -> None:
        """No write goes through a link on the Pi: a planted ``x.drs-partial`` link or directory link once
        had the upload write outside the mount. A stale partial link is removed (the link, not its target);
        a link among the folders is refused, as the operator must see who planted it."""
        path = self.mount
        for part in [p for p in posixpath.dirname(relative).split("/") if p]:
            path = posixpath.join(path, part)
            mode = self._lmode(sftp, path)
            if mode is not None and stat.S_ISLNK(mode):
                raise LinkError(
                    f"{self.capsule}: {path} on the Pi is a link; refusing to write {relative} through it"
                )
        partial = self._remote_path(relative) + PARTIAL_SUFFIX
        mode = self._lmode(sftp, partial)
        if mode is not None and stat.S_ISLNK(mode):
            sftp.remove(partial)
        elif mode is not None and not stat.S_ISREG(mode):
            raise LinkError(
                f"{self.capsule}: {partial} on the Pi is not a file; remove it to upload {relative}"
            )

    @staticmethod
    def _lmode(sftp: paramiko.SFTPClient, path: str) -> int | None:
        try:
            return sftp.lstat(path).st_mode
        except FileNotFoundError:
            return None

    def _make_dirs(self, sftp: paramiko.SFTPClient, relative_dir: str) -> None:
        """Create the file's directories below the mount (the mount itself must already exist)."""
        path = self.mount
        for part in [p for p in relative_dir.split("/") if p]:
            path = posixpath.join(path, part)
            try:
                sftp.stat(path)
            except FileNotFoundError:
                sftp.mkdir(path)

    def _send(
        self,
        sftp: paramiko.SFTPClient,
        item: LocalFile,
        partial: str,
        on_progress: Callable[[str, int, int], None] | None,
    ) -> int:
        """Append to the partial file from where it stopped; returns the bytes sent now."""
        try:
            offset = sftp.lstat(partial).st_size or 0
        except FileNotFoundError:
            offset = 0
        if offset > item.size:
            sftp.remove(partial)
            offset = 0
        sent = 0
        with item.path.open("rb") as source, sftp.open(partial, "ab" if offset else "wb") as target:
            target.set_pipelined(True)
            source.seek(offset)
            done = offset
            for block in iter(lambda: source.read(CHUNK), b""):
                target.write(block)
                done += len(block)
                sent += len(block)
                if on_progress is not None:
                    on_progress(item.relative, done, item.size)
        stored = sftp.stat(partial).st_size
        if stored != item.size:
            # Pipelined writes report a refused write (a full card) only as a short file.
            raise OSError(f"the Pi stored {stored} of {item.size} bytes")
        return sent

    def _pi_sha256(self, relative: str) -> str:
        """The hash of what the Pi actually stores, for ``status --hash``."""
        path = self._remote_path(relative)
        return self._digest(self.link.run(remote.hash_file(path)), f"cannot hash {path} on the Pi")

    def _remote_sha256(self, path: str) -> str:
        result = self.link.run(remote.verify_file(path))
        if result.link_dropped:
            raise LinkError(f"{self.capsule}: the link dropped while verifying {path}")
        return self._digest(result, f"cannot verify {path} on the Pi")

    def _digest(self, result: CommandResult, failure: str) -> str:
        """The digest of a ``<digest>  -`` line, or a refusal that says what the Pi said instead."""
        digest = remote.sha256_of(result.stdout) if result.ok else None
        if digest is None:
            said = result.stderr.strip() or result.stdout.strip()[:200] or "no output"
            raise LinkError(f"{self.capsule}: {failure}: {said}")
        return digest
