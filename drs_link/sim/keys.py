"""Ed25519 keys for simulated capsules and test clients (paramiko cannot generate Ed25519 itself)."""

from __future__ import annotations

import io
import os
from pathlib import Path

import paramiko
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey


def _openssh_pem() -> str:
    return (
        Ed25519PrivateKey.generate()
        .private_bytes(
            serialization.Encoding.PEM, serialization.PrivateFormat.OpenSSH, serialization.NoEncryption()
        )
        .decode()
    )


def generate_ed25519() -> paramiko.Ed25519Key:
    return paramiko.Ed25519Key.from_private_key(io.StringIO(_openssh_pem()))


def write_ed25519(path: Path) -> paramiko.Ed25519Key:
    """A new key pair on disk (private 0600, ``.pub`` beside it), as ssh-keygen would leave it."""
    pem = _openssh_pem()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as handle:
        handle.write(pem)
    key = paramiko.Ed25519Key.from_private_key(io.StringIO(pem))
    path.with_name(path.name + ".pub").write_text(f"{key.get_name()} {key.get_base64()} drs-sim\n")
    return key
