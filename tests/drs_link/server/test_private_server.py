"""An account's private operations server: started on demand by the first `drs` that acts, reached by
that account alone (a 0700 directory), honest that it cannot meet the two-person rule, gone when idle."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from console.commands.main import main
from drs_link.config import load_config
from drs_link.server.client import Client
from drs_link.server.private import listening, private_socket
from drs_link.store import account_of


def test_a_private_server_starts_on_demand_says_it_cannot_meet_the_rule_and_exits_when_idle(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DRS_SERVER_IDLE_S", "2")
    monkeypatch.delenv("DRS_PRIVATE_SERVER", raising=False)
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "EL"\n[data]\ndir = "{tmp_path / "data"}"\n[console]\nrequire_second_operator = true\n'
        '[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\n'
    )
    socket_path = private_socket(load_config(config))
    assert not listening(socket_path)
    argv = ["--config", str(config), "capsule", "go", "DRS1", "--confirm", "DRS1", "--await-approval"]
    assert main(argv) == 1
    assert capsys.readouterr().err.strip() == (
        f"drs: error: require_second_operator needs a second account, and only {account_of(os.geteuid())} reaches this private "
        "server: run the team's shared server (drs setup server --group GROUP, docs/console.md) and set "
        "[server] socket in each operator's drs.toml"
    )
    assert listening(socket_path), "started on demand"
    assert stat.S_IMODE(socket_path.parent.stat().st_mode) == 0o700
    assert stat.S_IMODE(socket_path.stat().st_mode) == 0o600
    assert main(["--config", str(config), "approve"]) == 0
    assert capsys.readouterr().out.strip() == "nothing waits for approval"
    deadline = time.monotonic() + 15.0
    while listening(socket_path):
        assert time.monotonic() < deadline, "the idle private server did not exit"
        time.sleep(0.2)
    assert not socket_path.exists()


def test_the_event_stream_pushes_each_capsules_release_and_arm_state(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DRS_PRIVATE_SERVER", "thread")
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "EL"\n[data]\ndir = "{tmp_path / "data"}"\n'
        '[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\n'
    )
    assert main(["--config", str(config), "capsule", "disarm", "DRS1"]) == 0
    with Client.for_config(load_config(config)) as client:
        event = next(iter(client.events()))
    assert event.release == {"DRS1": "idle"} and event.armed == {"DRS1": "none"} and event.approvals == ()


def test_two_environments_without_a_file_get_two_private_servers_each_serving_its_own_defaults(
    tmp_path: Path,
) -> None:
    """One account, two environments with no configuration file (other ``$XDG_CONFIG_HOME`` and
    ``$XDG_DATA_HOME``): each `drs` is served by a private server that read its own defaults. One key for
    every "no file" once had the second told of the first's missing file, and served from its store."""
    runtime = tmp_path / "run"
    runtime.mkdir(mode=0o700)
    told = []
    for name in ("first", "second"):
        env = {k: v for k, v in os.environ.items() if k not in ("DRS_CONFIG", "DRS_PRIVATE_SERVER")}
        env.update(HOME=str(tmp_path / name), XDG_CONFIG_HOME=str(tmp_path / name / "config"),
                   XDG_DATA_HOME=str(tmp_path / name / "data"), XDG_RUNTIME_DIR=str(runtime),
                   DRS_SERVER_IDLE_S="60")  # fmt: skip
        done = subprocess.run([sys.executable, "-m", "console.commands.main", "mo", "health", "DRS1"],
                              env=env, capture_output=True, text=True, timeout=120)  # fmt: skip
        told.append(done.stderr)
    for name, said in zip(("first", "second"), told, strict=True):
        assert f"no configuration file at {tmp_path / name / 'config' / 'drs' / 'drs.toml'} " in said, said
