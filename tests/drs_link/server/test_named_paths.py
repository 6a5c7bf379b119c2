"""Paths a client names (ARM/FIRE's weather, `drs sync`'s directory) are read by the server only if the
asking account could read them itself: with real accounts, real files and a real shared `drs server`.
Without the check, the server (its own account, or root here) read whatever it was named: its store,
its Pi keys, its secrets."""

from __future__ import annotations

import os
import pwd
import shutil
from pathlib import Path

import pytest

from drs_link.errors import LinkError, RefusedError
from drs_link.server.paths import readable_path, readable_tree
from drs_link.sim import CapsuleSimulator
from tests.drs_link.server.team import Server, Team, client_config, drs, needs_root
from tests.release_helpers import WAIVE_SYNC, write_weather

pytestmark = [needs_root, pytest.mark.slow]


def _own(path: Path, account: str, mode: int, content: bytes | None = None) -> Path:
    """``path`` made ``account``'s with ``mode``: a file of ``content``, else a directory if it is new."""
    if content is not None:
        path.write_bytes(content)
    elif not path.exists():
        path.mkdir()
    entry = pwd.getpwnam(account)
    os.chown(path, entry.pw_uid, entry.pw_gid)
    path.chmod(mode)
    return path


def _uid(account: str) -> int:
    return pwd.getpwnam(account).pw_uid


def test_the_kernels_rule_by_hand_owner_group_other_bits_and_every_directory_above(
    place: Path, team: Team
) -> None:
    alice, bob = _uid(team.alice), _uid(team.bob)
    secret = place / "secret.env"
    secret.write_text("DRS_ROCKBLOCK_PASSWORD=hunter2\n")
    secret.chmod(0o600)  # root's
    with pytest.raises(RefusedError) as refused:
        readable_path(alice, str(secret))
    assert str(refused.value).startswith(f"{secret}: refused: {team.alice} could not read it")
    assert "hunter2" not in str(refused.value)

    mine = _own(place / "mine.grib2", team.alice, 0o600, b"GRIB")
    assert readable_path(alice, str(mine)) == mine
    with pytest.raises(RefusedError):
        readable_path(bob, str(mine))

    shared = place / "team.grib2"
    shared.write_bytes(b"GRIB")
    shutil.chown(shared, group=team.group)
    shared.chmod(0o640)
    assert readable_path(bob, str(shared)) == shared
    with pytest.raises(RefusedError):
        readable_path(_uid(team.outsider), str(shared))
    shared.chmod(0o604)  # the group is denied what others get: the kernel reads the group bits only
    with pytest.raises(RefusedError):
        readable_path(bob, str(shared))
    assert readable_path(_uid(team.outsider), str(shared)) == shared

    closed = place / "closed"
    closed.mkdir(mode=0o700)  # root's: nobody else may search it
    inside = closed / "open.grib2"
    inside.write_bytes(b"GRIB")
    inside.chmod(0o644)
    with pytest.raises(RefusedError):
        readable_path(alice, str(inside))
    with pytest.raises(RefusedError):
        readable_path(alice, str(closed / "absent"))  # nor whether a name exists there

    link = place / "alice-link"
    link.symlink_to(secret)
    with pytest.raises(RefusedError):
        readable_path(alice, str(link))  # a link is judged by what it points at
    with pytest.raises(RefusedError):
        readable_path(alice, "mine.grib2")  # the server does not share the client's working directory
    with pytest.raises(LinkError, match="no such file"):
        readable_path(alice, str(place / "absent.grib2"))


def test_a_directory_is_read_only_if_every_folder_and_file_under_it_is_the_accounts_to_read(
    place: Path, team: Team
) -> None:
    alice = _uid(team.alice)
    payload = _own(place / "payload", team.alice, 0o700)
    _own(payload / "frame.bin", team.alice, 0o600, b"f")
    assert readable_tree(alice, str(payload)) == payload
    planted = payload / "server.key"
    planted.write_bytes(b"KEY")
    planted.chmod(0o600)  # root's, in alice's folder
    with pytest.raises(RefusedError, match=f"^{payload / 'server.key'}: refused: "):
        readable_tree(alice, str(payload))
    planted.unlink()
    (payload / "sub").mkdir(mode=0o700)
    with pytest.raises(RefusedError, match="sub: refused: "):
        readable_tree(alice, str(payload))


def test_arm_refuses_a_weather_file_of_the_server_and_reads_the_operators_own(
    powered: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    alice = client_config(place, team.alice)
    key = place / "keys" / "id_ed25519"  # the server's Pi key: 0600, root's
    for secret in (key, place / "state" / "drs.sqlite"):
        code, out = drs(team.alice, alice, "capsule", "arm", "DRS1", "--weather", str(secret), *WAIVE_SYNC)
        assert code == 1 and out.count("drs: error: ") == 1, out
        [error] = [line for line in out.splitlines() if line.startswith("drs: error: ")]
        assert error.startswith(f"drs: error: {secret}: refused: {team.alice} could not read it"), out
        assert "PRIVATE KEY" not in out and "SQLite" not in out
        assert "ARMED" not in out

    weather = _own(place / "alice-gfs", team.alice, 0o700)
    files = [_own(f, team.alice, 0o600) for f in write_weather(weather)]
    code, out = drs(team.alice, alice, "capsule", "arm", "DRS1", "--weather", *map(str, files), *WAIVE_SYNC)
    assert code == 0 and "DRS1: ARMED (window #1)" in out, out
    assert "Prediction fresh: no data" not in out, "her own files were read"


def test_sync_uploads_the_operators_own_directory_and_refuses_one_she_could_not_read(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    sim, _ = capsule_server
    alice = client_config(place, team.alice)
    code, out = drs(team.alice, alice, "sync", "DRS1", str(place / "state"))
    assert code == 1 and out == (
        f"drs: error: {place / 'state'}: refused: {team.alice} could not read it (the server reads only "
        "what the asking account may: check its mode and every directory above it)\n"
    ), out
    code, out = drs(team.alice, alice, "sync", "DRS1", str(place / "keys"), "--status")
    assert code == 1 and "refused" in out and "id_ed25519" in out and "PRIVATE" not in out, out

    payload = _own(place / "payload", team.alice, 0o700)
    _own(payload / "frame.bin", team.alice, 0o600, b"f" * 70_000)
    code, out = drs(team.alice, alice, "sync", "DRS1", str(payload), "--status")
    assert (code, out) == (1, "DRS1: 0 up to date, 1 missing, 0 changed, 70000 bytes pending\n")
    code, out = drs(team.alice, alice, "sync", "DRS1", str(payload))
    assert code == 0 and "DRS1: frame.bin: 70000 of 70000 bytes sent\n" in out, out
    assert out.endswith(
        "DRS1: 1 files uploaded and verified by sha256 on the Pi, 0 already up to date, 70000 bytes sent\n"
    ), out
    assert (sim.storage_dir / "frame.bin").read_bytes() == b"f" * 70_000
