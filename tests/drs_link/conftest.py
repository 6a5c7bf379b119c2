"""Fixtures for the capsule link: a client key, simulated capsules, and configs pointing at them."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import paramiko
import pytest

from drs_link.config import CapsuleConfig, parse_config
from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import write_ed25519

# 23 s of firmware boot and the Go script's 9 s take well under a second at this speed.
SIM_SCALE = 40.0


@pytest.fixture
def client_key(tmp_path: Path) -> tuple[Path, paramiko.PKey]:
    path = tmp_path / "keys" / "id_ed25519"
    return path, write_ed25519(path)


@pytest.fixture
def make_sim(client_key: tuple[Path, paramiko.PKey]) -> Iterator[Callable[..., CapsuleSimulator]]:
    started: list[CapsuleSimulator] = []

    def start(**kwargs: Any) -> CapsuleSimulator:
        kwargs.setdefault("authorized_keys", [client_key[1]])
        kwargs.setdefault("clock_scale", SIM_SCALE)
        sim = CapsuleSimulator(**kwargs)
        sim.start()
        started.append(sim)
        return sim

    yield start
    for sim in started:
        sim.stop()


def capsule_table(sim: CapsuleSimulator, key_path: Path, **overrides: Any) -> dict[str, Any]:
    table = {
        "name": sim.name,
        "host": "127.0.0.1",
        "port": sim.port,
        "identity_file": str(key_path),
        "connect_timeout_s": 5.0,
        "command_timeout_s": 20.0,
    }
    return {**table, **overrides}


@pytest.fixture
def sim_config(tmp_path: Path, client_key: tuple[Path, paramiko.PKey]) -> Callable[..., CapsuleConfig]:
    """A capsule config for a running simulator, its host key enrolled in a fresh known_hosts."""

    def build(sim: CapsuleSimulator, **overrides: Any) -> CapsuleConfig:
        known_hosts = tmp_path / f"known_hosts_{sim.name}"
        known_hosts.write_text(sim.known_hosts_line())
        overrides.setdefault("known_hosts", str(known_hosts))
        table = capsule_table(sim, client_key[0], **overrides)
        return parse_config({"capsule": [table]}).capsules[0]

    return build
