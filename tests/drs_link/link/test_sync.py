"""Sync over SFTP to the simulated capsule: verified uploads, resume, full disk, dropped link."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError
from drs_link.link.ssh import CapsuleLink
from drs_link.link.storage import read_storage
from drs_link.link.sync import PARTIAL_SUFFIX, Syncer
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store

pytestmark = pytest.mark.slow


def _source(tmp_path: Path, sizes: dict[str, int]) -> Path:
    source = tmp_path / "flight-data"
    for index, (name, size) in enumerate(sizes.items()):
        path = source / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(os.urandom(size))
        os.utime(path, (1_700_000_000 + index, 1_700_000_000 + index))
    return source


def _syncer(tmp_path: Path, config: CapsuleConfig) -> tuple[Syncer, CapsuleLink]:
    link = CapsuleLink(config)
    return Syncer(Store.open(tmp_path / "drs.sqlite"), link, config.name, config.storage_mount), link


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_sync_uploads_missing_files_verified_and_then_reports_up_to_date(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    source = _source(tmp_path, {"a.bin": 300_000, "maps/b.bin": 1000, "empty.txt": 0})
    syncer, link = _syncer(tmp_path, sim_config(sim))
    before = syncer.status(source)
    assert sorted(before.missing) == ["a.bin", "empty.txt", "maps/b.bin"] and before.bytes_pending == 301_000
    report = syncer.sync(source)
    assert sorted(report.uploaded) == ["a.bin", "empty.txt", "maps/b.bin"] and report.bytes_sent == 301_000
    for name in ("a.bin", "maps/b.bin", "empty.txt"):
        assert _digest(sim.storage_dir / name) == _digest(source / name)
    after = syncer.status(source, with_hash=True)
    assert after.missing == () and after.changed == () and after.bytes_pending == 0
    assert after.last_sync_utc is not None
    assert not list(sim.storage_dir.rglob(f"*{PARTIAL_SUFFIX}"))
    link.close()


def test_changed_file_is_detected_by_size_and_mtime_and_resent(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    source = _source(tmp_path, {"a.bin": 5000, "b.bin": 5000})
    syncer, _ = _syncer(tmp_path, sim_config(sim))
    syncer.sync(source)
    (source / "b.bin").write_bytes(os.urandom(5001))
    status = syncer.status(source)
    assert status.changed == ("b.bin",) and status.bytes_pending == 5001
    assert syncer.sync(source).uploaded == ("b.bin",)


def test_same_size_and_mtime_but_different_content_needs_the_hash_check(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    source = _source(tmp_path, {"a.bin": 4096})
    syncer, _ = _syncer(tmp_path, sim_config(sim))
    syncer.sync(source)
    stat = (source / "a.bin").stat()
    (source / "a.bin").write_bytes(os.urandom(4096))
    os.utime(source / "a.bin", (stat.st_atime, stat.st_mtime))
    assert syncer.status(source).changed == ()
    assert syncer.status(source, with_hash=True).changed == ("a.bin",)


def test_dropped_link_mid_file_keeps_verified_files_and_resumes_the_partial_one(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    source = _source(tmp_path, {"1-first.bin": 20_000, "2-big.bin": 2_000_000})
    syncer, _ = _syncer(tmp_path, sim_config(sim))

    def drop_during_second(relative: str) -> None:
        sim.faults.arm_drop(after_bytes=600_000)

    with pytest.raises(LinkError, match="link dropped while sending 2-big.bin"):
        syncer.sync(source, on_verified=drop_during_second)
    assert _digest(sim.storage_dir / "1-first.bin") == _digest(source / "1-first.bin")
    assert not (sim.storage_dir / "2-big.bin").exists()
    assert sim.sftp_sessions.wait_idle(), "the simulated Pi is still serving the dropped session"
    partial = sim.storage_dir / f"2-big.bin{PARTIAL_SUFFIX}"
    already = partial.stat().st_size
    assert 0 < already < 2_000_000
    report = syncer.sync(source)
    assert report.uploaded == ("2-big.bin",) and report.bytes_sent == 2_000_000 - already
    assert _digest(sim.storage_dir / "2-big.bin") == _digest(source / "2-big.bin")


def test_not_enough_space_is_refused_before_sending_anything(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim(capacity_bytes=50_000)
    source = _source(tmp_path, {"big.bin": 80_000})
    syncer, _ = _syncer(tmp_path, sim_config(sim))
    with pytest.raises(LinkError, match="50000 bytes free but 80000 are to be sent; nothing was uploaded"):
        syncer.sync(source)
    assert list(sim.storage_dir.iterdir()) == []


def test_disk_filling_up_mid_sync_is_reported_and_verified_files_survive(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim(capacity_bytes=1_000_000)
    source = _source(tmp_path, {"1.bin": 300_000, "2.bin": 300_000})
    syncer, _ = _syncer(tmp_path, sim_config(sim))

    def another_writer_fills_the_card(relative: str) -> None:
        (sim.storage_dir / "someone-else.bin").write_bytes(b"\0" * 600_000)

    with pytest.raises(LinkError, match="is full while sending 2.bin"):
        syncer.sync(source, on_verified=another_writer_fills_the_card)
    assert _digest(sim.storage_dir / "1.bin") == _digest(source / "1.bin")
    assert not (sim.storage_dir / "2.bin").exists()


def test_a_file_the_card_stores_wrong_is_sent_again_and_then_verified(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    sim.faults.corrupt_writes = 1
    source = _source(tmp_path, {"a.bin": 100_000})
    syncer, link = _syncer(tmp_path, sim_config(sim))
    report = syncer.sync(source)
    link.close()
    assert report.uploaded == ("a.bin",) and report.bytes_sent == 200_000
    assert _digest(sim.storage_dir / "a.bin") == _digest(source / "a.bin")


def test_a_file_stored_wrong_twice_is_refused_and_never_counted_as_synced(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    """Without the sha256 comparison on the Pi this corrupt copy would be renamed into place as synced."""
    sim = make_sim()
    sim.faults.corrupt_writes = 2
    source = _source(tmp_path, {"a.bin": 100_000})
    syncer, link = _syncer(tmp_path, sim_config(sim))
    with pytest.raises(LinkError, match="a.bin: the Pi's sha256 does not match after re-sending"):
        syncer.sync(source)
    assert not (sim.storage_dir / "a.bin").exists()
    assert syncer.status(source).missing == ("a.bin",)
    link.close()


def test_storage_status_reports_usage_and_a_degraded_mirror(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim(capacity_bytes=10_000_000)
    (sim.storage_dir / "x.bin").write_bytes(b"\0" * 1_000_000)
    with CapsuleLink(sim_config(sim)) as link:
        healthy = read_storage(link, "/mnt/raid1", "/dev/md0")
        sim.faults.raid_degraded = True
        degraded = read_storage(link, "/mnt/raid1", "/dev/md0")
    assert healthy.usage is not None and healthy.usage.used_bytes == 1_000_000
    assert healthy.raid is not None and healthy.raid.state == "healthy"
    assert (
        degraded.raid is not None and degraded.raid.state == "degraded" and degraded.raid.member_map == "UUU_"
    )


def test_missing_source_directory_is_a_clear_error(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    syncer, _ = _syncer(tmp_path, sim_config(make_sim()))
    with pytest.raises(LinkError, match="is not a directory"):
        syncer.status(tmp_path / "nope")


def test_links_fifos_and_loops_in_the_source_are_left_out_by_name_and_never_followed(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    """#24 item 11: a file link's target (anything on the laptop) was uploaded to the RAID dropped from the
    balloon, and directory links, loops and FIFOs were skipped without a word."""
    sim = make_sim()
    source = _source(tmp_path, {"frames.bin": 2000})
    secret = tmp_path / "laptop-secret.txt"
    secret.write_text("not for the capsule")
    (source / "secret-link.txt").symlink_to(secret)
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "inside.bin").write_bytes(b"x" * 10)
    (source / "folder-link").symlink_to(tmp_path / "elsewhere")
    (source / "loop").symlink_to(source / "loop")
    os.mkfifo(source / "pipe")
    syncer, link = _syncer(tmp_path, sim_config(sim))
    report = syncer.sync(source)
    assert report.uploaded == ("frames.bin",)
    assert sorted(entry.split(" (")[0] for entry in report.left_out) == [
        "folder-link/",
        "loop",
        "pipe",
        "secret-link.txt",
    ]
    assert all("(" in entry and entry.endswith(")") for entry in report.left_out)
    on_pi = sorted(p.relative_to(sim.storage_dir).as_posix() for p in sim.storage_dir.rglob("*"))
    assert on_pi == ["frames.bin"]
    assert not any(
        b"not for the capsule" in p.read_bytes() for p in sim.storage_dir.rglob("*") if p.is_file()
    )
    link.close()


def test_a_planted_partial_link_or_directory_link_on_the_pi_never_writes_outside_the_mount(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    outside = tmp_path / "outside-the-mount"
    outside.mkdir()
    victim = outside / "victim.bin"
    victim.write_bytes(b"keep me")
    (sim.storage_dir / f"a.bin{PARTIAL_SUFFIX}").symlink_to(victim)
    (sim.storage_dir / "maps").symlink_to(outside)
    source = _source(tmp_path, {"a.bin": 3000, "maps/b.bin": 1000})
    syncer, link = _syncer(tmp_path, sim_config(sim))
    with pytest.raises(LinkError, match=r"maps on the Pi is a link; refusing to write maps/b.bin through it"):
        syncer.sync(source)
    assert victim.read_bytes() == b"keep me" and sorted(p.name for p in outside.iterdir()) == ["victim.bin"]
    assert _digest(sim.storage_dir / "a.bin") == _digest(source / "a.bin")
    assert not (sim.storage_dir / "a.bin").is_symlink()
    link.close()
