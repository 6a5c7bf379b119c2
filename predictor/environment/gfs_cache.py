"""Upkeep of the GFS download cache: how fetches and prunes share it, and what a prune may remove.

Why: every fetched cycle stays on disk, and on a field laptop the disk fills across a campaign; a full
disk on launch day is exactly when nothing may fail. So a prune must free space without ever taking
what a flight may still need:

- a cycle inside the keep window. A cycle's age counts from its nominal time or from its latest
  download, whichever is later, so a past cycle fetched today for a post-flight analysis is as safe
  as today's forecast;
- a cycle a fetch is working on. Every fetch holds a shared ``flock`` on ``.fetching.lock`` in its
  cycle directory for as long as it works on it (retries and backoff included). A prune removes a
  cycle only under an exclusive lock taken without waiting, so it skips a busy cycle, and a fetch
  that starts meanwhile waits for the removal and then starts again in a fresh directory. A partial
  download (``.part``) written to in the last 15 minutes also keeps its cycle, whoever writes it
  (a program that does not take the lock).

Cube-cache entries (``predictor.environment.weather``) built from a removed cycle can never be hit again and go
with it, and so does every entry whose weather files are already gone or were downloaded again.
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING

from predictor.errors import WeatherError

if TYPE_CHECKING:
    from predictor.environment.weather import CubeCacheEntry

LOCK_NAME = ".fetching.lock"
PART_SUFFIX = ".part"
ACTIVE_PART_AGE = timedelta(minutes=15)
"""A partial download written to more recently than this belongs to a fetch that may still run."""
SIZE_ONLY_KEEP = timedelta(days=2)
"""The keep window of a prune by size alone: the cycles of the last two days are never removed."""
LOW_SPACE_BYTES = 1_000_000_000
"""Below this much free space a fetch warns: a few full-resolution runs would not fit."""

_MAX_KEEP_DAYS = 36500
_DATE_DIR = re.compile(r"^gfs\.(\d{8})$")
_HOUR_DIR = re.compile(r"^(\d{2})$")


def cycle_directory(root: Path, cycle: datetime) -> Path:
    """Where the files of one cycle live (one subdirectory per region below it)."""
    return root / f"gfs.{cycle:%Y%m%d}" / f"{cycle:%H}"


@contextmanager
def fetching(cycle_dir: Path) -> Iterator[None]:
    """Hold the cycle against prunes while downloading into it; any number of fetches may share it."""
    lock_path = cycle_dir / LOCK_NAME
    while True:
        cycle_dir.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH)
            held = os.fstat(fd).st_ino == os.stat(lock_path).st_ino
        except FileNotFoundError:
            held = False
        except BaseException:
            os.close(fd)
            raise
        if held:
            break
        os.close(fd)  # a prune removed the cycle while this fetch waited: start in a fresh directory
    try:
        yield
    finally:
        os.close(fd)


@dataclass(frozen=True)
class CachedCycle:
    """One cycle directory of the download cache."""

    path: Path
    cycle: datetime
    size_bytes: int
    files: int
    last_write: datetime | None
    """The latest modification of any file in it; None when it holds no file."""
    active_part: bool
    """It holds a partial download written to within ``ACTIVE_PART_AGE`` of the scan."""

    @property
    def name(self) -> str:
        return f"{self.path.parent.name}/{self.path.name}"

    @property
    def age_reference(self) -> datetime:
        """Nominal time or latest download, whichever is later: what the keep window is measured on."""
        return max(self.cycle, self.last_write) if self.last_write else self.cycle


def scan_gfs_cache(root: Path, now: datetime) -> tuple[list[CachedCycle], int]:
    """The cycle directories under ``root``, and the bytes of everything else there (left alone)."""
    cycles = []
    other_bytes = 0
    for date_dir in sorted(root.iterdir()):
        date_match = _DATE_DIR.match(date_dir.name)
        if date_match is None or not date_dir.is_dir() or date_dir.is_symlink():
            other_bytes += _tree_bytes(date_dir)
            continue
        for hour_dir in sorted(date_dir.iterdir()):
            cycle = _cycle_of(date_match.group(1), hour_dir)
            if cycle is None:
                other_bytes += _tree_bytes(hour_dir)
                continue
            cycles.append(_scan_cycle(hour_dir, cycle, now))
    return cycles, other_bytes


def _cycle_of(date_text: str, hour_dir: Path) -> datetime | None:
    hour_match = _HOUR_DIR.match(hour_dir.name)
    if hour_match is None or not hour_dir.is_dir() or hour_dir.is_symlink():
        return None
    try:
        return datetime.strptime(date_text + hour_match.group(1), "%Y%m%d%H").replace(tzinfo=UTC)
    except ValueError:
        return None


def _scan_cycle(path: Path, cycle: datetime, now: datetime) -> CachedCycle:
    size = 0
    files = 0
    latest: float | None = None
    active_part = False
    for folder, _, names in os.walk(path):
        for name in names:
            try:
                stat = os.lstat(os.path.join(folder, name))
            except FileNotFoundError:
                continue  # a fetch renamed its partial file since the listing
            size += stat.st_size
            if name == LOCK_NAME:
                continue  # created by fetches and prunes alike: not a download
            files += 1
            latest = stat.st_mtime if latest is None else max(latest, stat.st_mtime)
            written = datetime.fromtimestamp(stat.st_mtime, UTC)
            active_part |= name.endswith(PART_SUFFIX) and now - written < ACTIVE_PART_AGE
    return CachedCycle(
        path=path,
        cycle=cycle,
        size_bytes=size,
        files=files,
        last_write=datetime.fromtimestamp(latest, UTC) if latest is not None else None,
        active_part=active_part,
    )


def _tree_bytes(path: Path) -> int:
    if path.is_symlink() or not path.is_dir():
        try:
            return path.lstat().st_size
        except FileNotFoundError:
            return 0
    total = 0
    for folder, _, names in os.walk(path):
        for name in names:
            try:
                total += os.lstat(os.path.join(folder, name)).st_size
            except FileNotFoundError:
                continue
    return total


@dataclass
class PruneResult:
    """What a prune removed (or, in a dry run, would remove) and what it had to leave."""

    dry_run: bool
    keep_from: datetime
    """Cycles whose age reference is at or after this are inside the keep window."""
    removed: list[CachedCycle] = field(default_factory=list)
    skipped: list[tuple[CachedCycle, str]] = field(default_factory=list)
    """Cycles the rules would remove but that are busy or could not be removed, with the reason."""
    removed_entries: list[CubeCacheEntry] = field(default_factory=list)
    failed_entries: list[tuple[CubeCacheEntry, str]] = field(default_factory=list)
    kept: list[CachedCycle] = field(default_factory=list)
    bytes_before: int = 0
    bytes_after: int = 0

    @property
    def freed_bytes(self) -> int:
        return self.bytes_before - self.bytes_after


def prune(
    root: Path,
    cube_cache: Path,
    *,
    keep_days: float | None,
    max_bytes: int | None,
    dry_run: bool = False,
    now: datetime | None = None,
) -> PruneResult:
    """Remove cycles older than ``keep_days``, then the oldest until both caches hold ≤ ``max_bytes``.

    The keep window is ``keep_days``, or ``SIZE_ONLY_KEEP`` when only a size is given; nothing inside
    it is removed, so a size that cannot be reached without it is left exceeded. Cube-cache entries
    that no load can hit any more are removed in any case.
    """
    if keep_days is None and max_bytes is None:
        raise WeatherError("say what to prune: --keep-days N, --max-gb X, or both")
    if keep_days is not None and not (0.0 <= keep_days <= _MAX_KEEP_DAYS):
        raise WeatherError(f"--keep-days must be between 0 and {_MAX_KEEP_DAYS} days, not {keep_days:g}")
    if max_bytes is not None and max_bytes <= 0:
        raise WeatherError(f"the size limit must be more than 0 bytes, not {max_bytes}")
    if not root.is_dir():
        what = "is not a directory" if root.exists() else "does not exist"
        raise WeatherError(f"GFS cache directory {root} {what} (see --dir; nothing to prune)")
    if cube_cache.exists() and not cube_cache.is_dir():
        raise WeatherError(f"weather cache directory {cube_cache} is not a directory (see --cache-dir)")
    root = root.resolve()
    now = now or datetime.now(UTC)
    window = timedelta(days=keep_days) if keep_days is not None else SIZE_ONLY_KEEP
    result = PruneResult(dry_run=dry_run, keep_from=now - window)

    from predictor.environment.weather import (
        cube_cache_entries,  # the GRIB reader: loaded by a prune, not by --help
    )

    try:
        cycles, other_bytes = scan_gfs_cache(root, now)
        entries = cube_cache_entries(cube_cache)
    except OSError as exc:
        raise WeatherError(f"cannot read the weather caches: {exc.filename}: {exc.strerror or exc}") from exc
    result.bytes_before = other_bytes + sum(c.size_bytes for c in cycles) + sum(e.size_bytes for e in entries)
    remaining = result.bytes_before
    remaining -= _remove_entries(result, [e for e in entries if not e.current])
    live = [e for e in entries if e.current]

    candidates = sorted(
        (c for c in cycles if c.age_reference < result.keep_from), key=lambda c: (c.age_reference, c.cycle)
    )
    result.kept = [c for c in cycles if c.age_reference >= result.keep_from]
    for cycle in candidates:
        if keep_days is None and max_bytes is not None and remaining <= max_bytes:
            result.kept.append(cycle)
            continue
        reason = _busy_reason(cycle) if dry_run else _remove_cycle(cycle)
        if reason is not None:
            result.skipped.append((cycle, reason))
            continue
        result.removed.append(cycle)
        remaining -= cycle.size_bytes
        derived = [e for e in live if _built_from(e, cycle.path)]
        live = [e for e in live if e not in derived]
        remaining -= _remove_entries(result, derived)
        if not dry_run:
            _remove_if_empty(cycle.path.parent)
    result.kept.sort(key=lambda c: c.cycle)
    result.bytes_after = remaining
    return result


def _built_from(entry: CubeCacheEntry, cycle_dir: Path) -> bool:
    resolved = cycle_dir.resolve()
    return any(source.is_relative_to(resolved) for source in entry.sources)


def _remove_entries(result: PruneResult, entries: Sequence[CubeCacheEntry]) -> int:
    """Remove (or, in a dry run, count) cube-cache entries; the bytes freed."""
    freed = 0
    for entry in entries:
        if not result.dry_run:
            try:
                entry.path.unlink(missing_ok=True)
            except OSError as exc:
                result.failed_entries.append((entry, exc.strerror or str(exc)))
                continue
        result.removed_entries.append(entry)
        freed += entry.size_bytes
    return freed


def _busy_reason(cycle: CachedCycle) -> str | None:
    """Why a cycle must stay although the rules would remove it; None when it may go."""
    if cycle.active_part:
        return f"a partial download in it was written to in the last {_minutes(ACTIVE_PART_AGE)} minutes"
    try:
        fd = os.open(cycle.path / LOCK_NAME, os.O_RDONLY)
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"cannot check for a fetch in progress: {exc.strerror or exc}"
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return "a fetch is in progress"
    finally:
        os.close(fd)
    return None


def _remove_cycle(cycle: CachedCycle) -> str | None:
    """Remove the cycle under an exclusive lock; why not, or None when it is gone."""
    if cycle.active_part:
        return _busy_reason(cycle)
    try:
        fd = os.open(cycle.path / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        return f"cannot lock it: {exc.strerror or exc}"
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return "a fetch is in progress"
    try:
        shutil.rmtree(cycle.path)
    except OSError as exc:
        return f"could not remove all of it: {exc.strerror or exc}"
    finally:
        os.close(fd)
    return None


def _remove_if_empty(date_dir: Path) -> None:
    try:
        date_dir.rmdir()
    except OSError:
        pass  # another cycle of that day is still there, or a fetch just created one


def _minutes(span: timedelta) -> int:
    return int(span.total_seconds() // 60)


def free_space_warning(directory: Path, minimum_bytes: int = LOW_SPACE_BYTES) -> str | None:
    """A warning when the disk that ``directory`` is (or will be) on has less than ``minimum_bytes`` free."""
    existing = directory.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        free = shutil.disk_usage(existing).free
    except OSError:
        return None  # no disk to ask about: the download itself will say what is wrong
    if free >= minimum_bytes:
        return None
    return (
        f"only {free / 1e9:.2f} GB free on the disk holding {directory}; "
        "`drs weather prune --keep-days 7` removes older cycles"
    )
