"""Who is at this keyboard, as only the kernel or a signature can say: the login the two-person rule counts.

Why: anything a process can set for itself, such as the key file ``$SSH_USER_AUTH`` names, would let
one person approve their own PARACHUTE override by pointing it at a second key. So a login is made of
two things a process cannot choose for itself:

- the OS account of the kernel's real uid (``os.getuid()``), which only login, sshd, su or sudo set;
- an SSH key *proven here*: a fresh random challenge is signed by ``ssh-agent`` (``$SSH_AUTH_SOCK``)
  and the signature verified against the public key written for that person in the configuration's
  ``[[approver]]`` list. A key nobody listed proves nothing; a listed key whose private half is not in
  the agent cannot sign. The proven person's name then is the operator name of the request or approval.

What it cannot do (docs/console.md says it to the operators): root, and anyone who can edit the
configuration or reach another person's agent socket, can act as anyone on their own machine.
"""

from __future__ import annotations

import base64
import hashlib
import os
import pwd
import secrets
import socket
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # paramiko is imported only when there is an agent to ask
    from paramiko.agent import AgentKey

CHALLENGE_PREFIX = b"drs-console approval login v1\0"
"""Domain separation: a signature made here cannot be replayed as an SSH authentication, and one made
for SSH cannot be replayed here (the agent signs these bytes, never a server's session data)."""


@dataclass(frozen=True)
class ProvenKey:
    """A listed approver whose key signed this process's challenge."""

    person: str
    fingerprint: str


def account_name() -> str:
    """The OS account of the real uid: $USER and $LOGNAME are the shell's to set, the uid is not."""
    return pwd.getpwuid(os.getuid()).pw_name


def fingerprint(blob: bytes) -> str:
    """A public key's SHA256 fingerprint as ``ssh-keygen -l`` prints it."""
    return "SHA256:" + base64.b64encode(hashlib.sha256(blob).digest()).decode().rstrip("=")


def key_blob(public_key_line: str) -> bytes | None:
    """The wire blob of an OpenSSH public key line (``ssh-ed25519 AAAA… comment``); None if not one."""
    fields = public_key_line.split()
    if len(fields) < 2:
        return None
    try:
        return base64.b64decode(fields[1], validate=True)
    except ValueError:
        return None


def prove_agent_key(
    approvers: Iterable[tuple[str, str]], environ: Mapping[str, str] = os.environ
) -> ProvenKey | None:
    """The first listed approver (``(name, public key line)``) whose key in the ssh-agent at
    ``$SSH_AUTH_SOCK`` signs a fresh challenge that verifies against the LISTED public key; None when
    there is no agent, no listed key in it, or no valid signature."""
    listed: dict[bytes, str] = {}
    for name, line in approvers:
        blob = key_blob(line)
        if blob is not None:
            listed.setdefault(blob, name)
    path = environ.get("SSH_AUTH_SOCK", "")
    if not listed or not path:
        return None
    import paramiko  # the agent protocol; paid for only when there is an agent and a list to prove against

    agent = paramiko.agent.AgentSSH()  # paramiko.Agent reads only os.environ; this one is given the socket
    conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    conn.settimeout(5.0)
    try:
        conn.connect(path)
        # _connect/_close are paramiko's own way to give AgentSSH a socket; private, so not in its stubs
        agent._connect(conn)  # type: ignore[attr-defined]
        for key in agent.get_keys():
            person = listed.get(key.asbytes())
            if person is not None and _signs(key, key.asbytes()):
                return ProvenKey(person, fingerprint(key.asbytes()))
    except (OSError, paramiko.SSHException):
        return None
    finally:
        agent._close()  # type: ignore[attr-defined]  # private, as _connect above
        conn.close()
    return None


def _signs(agent_key: AgentKey, blob: bytes) -> bool:
    """Whether the agent's key signs a new challenge that verifies with the public key we were given."""
    import paramiko

    challenge = CHALLENGE_PREFIX + secrets.token_bytes(32)
    try:
        public = paramiko.PKey.from_type_string(paramiko.Message(blob).get_text(), blob)
        algorithm = "rsa-sha2-256" if public.get_name() == "ssh-rsa" else None
        signature = agent_key.sign_ssh_data(challenge, algorithm)
        # An AgentKey's signature is the agent's bytes; types-paramiko gives it PKey's Message instead
        return bool(public.verify_ssh_sig(challenge, paramiko.Message(signature)))  # type: ignore[arg-type]
    except (paramiko.SSHException, OSError, ValueError, TypeError):
        return False
