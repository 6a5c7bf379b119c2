"""`drs setup server --group G`: the systemd unit of the team's operations server, and what to do next."""

from __future__ import annotations

import grp
import os
from pathlib import Path

import pytest

from console.commands.main import main


def test_the_unit_runs_the_server_as_its_own_account_with_its_store_its_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    group = grp.getgrgid(os.getgid()).gr_name
    assert main(["setup", "server", "--group", group, "--unit-dir", str(tmp_path)]) == 0
    unit = (tmp_path / "drs-server.service").read_text()
    assert f"--socket /run/drs/drs.sock --group {group}" in unit and "User=drs-server" in unit
    assert "StateDirectoryMode=0700" in unit and "UMask=0077" in unit and "NoNewPrivileges=yes" in unit
    assert "PrivateUsers" not in unit, "in a user namespace every caller's uid would read as nobody"
    assert "CacheDirectory=drs-server" in unit and "Environment=NUMBA_CACHE_DIR=/var/cache/drs-server" in unit
    out = capsys.readouterr().out
    assert "useradd --system" in out and "systemctl daemon-reload && systemctl enable --now drs-server" in out


def test_a_group_that_does_not_exist_is_named_with_how_to_make_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["setup", "server", "--group", "no-such-drs-team", "--unit-dir", str(tmp_path)]) == 1
    assert capsys.readouterr().err.strip() == (
        "drs: error: group 'no-such-drs-team' does not exist: as root, `groupadd no-such-drs-team`"
    )
    assert not (tmp_path / "drs-server.service").exists()
