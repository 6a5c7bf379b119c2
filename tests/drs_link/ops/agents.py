"""Real OpenSSH keys and a real ssh-agent for the login tests: ssh-keygen makes the keys, the ssh-agent
binary holds them and ssh-add loads them, exactly as an operator's session would."""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def ssh_key(directory: Path, name: str) -> Path:
    """A new ed25519 key pair made by ssh-keygen; the private key's path (the public key is beside it)."""
    key = directory / name
    subprocess.run(["ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-C", name, "-f", str(key)], check=True)
    return key


def public_line(key: Path) -> str:
    return key.with_name(key.name + ".pub").read_text().strip()


def printed_fingerprint(key: Path) -> str:
    """The fingerprint as ssh-keygen itself prints it, to compare ours against."""
    out = subprocess.run(
        ["ssh-keygen", "-l", "-E", "sha256", "-f", str(key)], check=True, capture_output=True, text=True
    ).stdout
    return out.split()[1]


def approver_tables(**people: Path) -> str:
    """``[[approver]]`` TOML for ``name=key`` pairs."""
    return "".join(
        f'[[approver]]\nname = "{name}"\nkey = "{public_line(key)}"\n' for name, key in people.items()
    )


@contextmanager
def ssh_agent(directory: Path, *keys: Path) -> Iterator[str]:
    """An ssh-agent process holding ``keys``; yields its socket path (the value of SSH_AUTH_SOCK)."""
    directory.mkdir(parents=True, exist_ok=True)
    sock = directory / f"agent.{len(list(directory.glob('agent.*')))}.sock"
    agent = subprocess.Popen(
        ["ssh-agent", "-D", "-a", str(sock)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 10.0
        while not sock.exists():
            if time.monotonic() > deadline or agent.poll() is not None:
                raise RuntimeError("ssh-agent did not start")
            time.sleep(0.02)
        for key in keys:
            subprocess.run(
                ["ssh-add", "-q", str(key)],
                check=True,
                capture_output=True,
                env={**os.environ, "SSH_AUTH_SOCK": str(sock)},
            )
        yield str(sock)
    finally:
        agent.kill()
        agent.wait(timeout=10)
