"""The team the server's tests run with: real accounts in a real group, a directory they can all enter, and
a capsule simulator behind a real sshd that the team's server reaches."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import write_ed25519
from tests.drs_link.conftest import SIM_SCALE, capsule_table
from tests.drs_link.server.team import Server, Team, client_config, drs, server_config
from tests.release_helpers import ROCKBLOCK_PASSWORD_ENV, ROCKBLOCK_TOML

IMEI = "300434060000029"


@pytest.fixture
def team() -> Iterator[Team]:
    tag = f"{os.getpid() % 100000}"
    group = f"drsteam{tag}"
    names = [f"drsal{tag}", f"drsbo{tag}", f"drsma{tag}", f"drsou{tag}"]
    subprocess.run(["groupadd", group], check=True)
    try:
        for name in names[:3]:
            subprocess.run(["useradd", "-M", "-N", "-G", group, "-s", "/usr/sbin/nologin", name], check=True)
        subprocess.run(["useradd", "-M", "-N", "-s", "/usr/sbin/nologin", names[3]], check=True)
        yield Team(group, *names)
    finally:
        for name in names:
            subprocess.run(["userdel", name], check=False, capture_output=True)
        subprocess.run(["groupdel", group], check=False, capture_output=True)


@pytest.fixture
def place() -> Iterator[Path]:
    """A directory every account can enter (pytest's tmp_path is 0700)."""
    path = Path(tempfile.mkdtemp(prefix="drs-team-"))
    path.chmod(0o755)
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def capsule_server(place: Path, team: Team) -> Iterator[tuple[CapsuleSimulator, Server]]:
    """A capsule simulator behind sshd, and the team's server for it (the two-person rule on, a 120 s
    ARM window); the Pi's host key in the server's known_hosts (``place/known_hosts``)."""
    key = place / "keys" / "id_ed25519"
    sim = CapsuleSimulator(authorized_keys=[write_ed25519(key)], clock_scale=SIM_SCALE)
    sim.start()
    try:
        known_hosts = place / "known_hosts"
        known_hosts.write_text(sim.known_hosts_line())
        table = capsule_table(sim, key, known_hosts=str(known_hosts), python="python3", imei=IMEI)
        capsule = "\n".join(f"{k} = {json.dumps(v)}" for k, v in table.items())
        body = f"{ROCKBLOCK_TOML}[console]\nrequire_second_operator = true\narm_window_s = 120.0\n[[capsule]]\n{capsule}\n"
        server = Server(server_config(place, team, body), place, team.group, {ROCKBLOCK_PASSWORD_ENV: "pw"})
        try:
            yield sim, server
        finally:
            server.stop()
    finally:
        sim.stop()


@pytest.fixture
def powered(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> tuple[CapsuleSimulator, Server]:
    """The capsule powered on by the first operator (EL) through the team's server, waiting for Go."""
    code, out = drs(team.alice, client_config(place, team.alice), "capsule", "power-on", "DRS1", "--yes")
    assert code == 0 and "waiting for Go" in out, out
    return capsule_server
