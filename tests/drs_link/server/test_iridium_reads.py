"""`drs mo health`, `drs mo export` and `drs recovery` through a real shared `drs server`, from an account that cannot open
the store (it lives in the server's 0700 directory): the server reads the reports and answers in typed
values, and an export's file is written by the operator's own process, so it is theirs (issue #29 item 6)."""

from __future__ import annotations

import json
import os
import pwd
import stat
from datetime import timedelta
from pathlib import Path

import pytest

from console.commands.main import main
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store
from predictor.geofiles import EXPORT_MODE
from tests.drs_link.iridium.helpers import T0, fix_at
from tests.drs_link.server.conftest import IMEI
from tests.drs_link.server.team import Server, Team, as_account, client_config, drs, needs_root

pytestmark = [needs_root, pytest.mark.slow]


def test_health_and_export_are_read_by_the_server_and_the_export_is_the_operators_file(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    store = Store.open(place / "state" / "drs.sqlite")  # what the receiver stored (it runs as root here)
    try:
        reports = ReportStore(store)
        for i in range(4):
            moment = T0 + timedelta(minutes=2 * i)
            fix = None if i == 2 else fix_at(moment, alt=3000 - 1000 * i)
            reports.add(Delivery(IMEI, i, format_mo(fix, 8.9, i).hex(), "test", moment))
    finally:
        store.close()
    alice = client_config(place, team.alice)
    code, out = drs(team.alice, alice, "mo", "health", "DRS1")
    assert code == 0 and out.startswith("DRS1: 4 reports, last 2026-07-01 10:06:07Z, battery 8.90 V\n"), out
    code, out = drs(team.alice, alice, "mo", "health", "DRS1", "--json")
    assert code == 0 and '"last_report_utc": "2026-07-01T10:06:07.000Z"' in out, out

    home = place / "alice"
    home.mkdir()
    account = pwd.getpwnam(team.alice)
    os.chown(home, account.pw_uid, account.pw_gid)
    home.chmod(0o700)
    out_file = home / "drs1.csv"
    code, out = drs(team.alice, alice, "mo", "export", "DRS1", "--out", str(out_file))
    assert (code, out) == (
        0,
        f"wrote {out_file}: 3 fixes of DRS1; skipped 1 report(s) without a fix and 0 rejected\n",
    )
    info = out_file.stat()
    assert (info.st_uid, stat.S_IMODE(info.st_mode)) == (account.pw_uid, EXPORT_MODE)
    assert out_file.read_text().splitlines()[0] == "time,lat,lon,alt_m,pressure_pa,speed_mps"
    assert len(out_file.read_text().splitlines()) == 4
    code, out = drs(team.alice, alice, "mo", "export", "DRS1", "--out", str(out_file))
    assert code == 1 and "the file exists; choose another name or add --force" in out, out

    gpx = home / "drs1.gpx"
    code, out = drs(
        team.alice, alice, "recovery", "DRS1", "--from", "46.49,6.60", "--gpx", str(gpx), "--json"
    )
    assert code == 0 and f"wrote {gpx}\n" in out, out
    document = json.loads(out[out.index("{") :])
    assert document["capsule"] == "DRS1" and document["from"] == {"lat": 46.49, "lon": 6.6}
    assert document["last_fix"]["alt_m"] == 0.0 and round(document["distance_m"] / 100) == 11
    assert gpx.stat().st_uid == account.pw_uid and "DRS1 measured" in gpx.read_text()
    secret = place / "keys" / "id_ed25519"
    code, out = drs(
        team.alice, alice, "recovery", "DRS1", "--map", str(home / "map.png"), "--weather", str(secret)
    )
    assert code == 1 and out == (
        f"drs: error: {secret}: refused: {team.alice} could not read it (the server reads only what the "
        "asking account may: check its mode and every directory above it)\n"
    ), out
    assert not (home / "map.png").exists()


def test_an_operator_whose_own_directories_she_cannot_enter_still_asks_the_server(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team,
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
) -> None:  # fmt: skip
    """Her $HOME and $XDG_* name another account's 0700 directory (a ``sudo -E``): looking for the store's
    old place raised EACCES before any command ran, though this one never opens a store of hers."""
    locked = tmp_path / "root-only"  # tmp_path is 0700, root's
    for name in ("HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME"):
        monkeypatch.setenv(name, str(locked / name.lower()))
    (locked / "xdg_data_home" / "drs").mkdir(parents=True)
    (locked / "xdg_data_home" / "drs" / "drs.sqlite").touch()
    code, out = drs(team.alice, client_config(place, team.alice), "mo", "health", "DRS1")
    assert code == 0 and out.startswith("DRS1: 0 reports"), out


def test_an_operator_whose_configuration_directory_she_cannot_enter_is_told_so_not_given_the_defaults(
    team: Team, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A file may be behind it: running on the defaults would show no capsules and another store, like lost data."""
    locked = tmp_path / "root-only"  # tmp_path is 0700, root's
    (locked / "drs").mkdir(parents=True)
    (locked / "drs" / "drs.toml").write_text('[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\n')
    monkeypatch.setenv("XDG_CONFIG_HOME", str(locked))
    monkeypatch.delenv("DRS_CONFIG", raising=False)
    code, out = as_account(team.alice, lambda: main(["mo", "health", "DRS1"]))
    assert code != 0, out
    assert f"{locked / 'drs' / 'drs.toml'}: cannot read: Permission denied" in out, out
    assert "--config" in out and "Traceback" not in out and "PermissionError" not in out, out
