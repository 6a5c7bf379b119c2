"""The login of the two-person rule is the kernel's uid or a key proven by a signature, never a variable.

Real parts: keys made by ssh-keygen, the ssh-agent binary holding them (ssh-add), and `drs approve` run
as a separate process, as the second operator would run it. The forged case is the one issue #23 found:
``SSH_USER_AUTH`` pointed at a second key made a second earlier.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from drs_link.config import load_config
from drs_link.errors import ConfigError
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.ops.identity import account_name, prove_agent_key
from drs_link.store import Store
from tests.drs_link.ops.agents import approver_tables, printed_fingerprint, public_line, ssh_agent, ssh_key

CHILD = "import sys; from console.commands.main import main; sys.exit(main(sys.argv[1:]))"
SUMMARY = "[PARACHUTE=01:19]"


def config(tmp_path: Path, operator: str, approvers: str = "") -> Path:
    """One person's configuration on the shared store (each person has their own file and name)."""
    path = tmp_path / f"{operator}.toml"
    path.write_text(f'[operator]\nname = "{operator}"\n[data]\ndir = "{tmp_path / "data"}"\n{approvers}')
    return path


def clean_env(**extra: str) -> dict[str, str]:
    """This environment without any login hint, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("SSH_AUTH_SOCK", "SSH_USER_AUTH")}
    return {**env, **extra}


def drs_approve(config_file: Path, env: dict[str, str], *argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", CHILD, "--config", str(config_file), "approve", *argv],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def request_as(config_file: Path, env: dict[str, str]) -> int:
    """A PARACHUTE approval request made by this process with the login ``env`` gives it."""
    load_config(config_file)
    book = ApprovalBook(Store.open(tmp_store(config_file)))
    return book.request("DRS1", "parachute", SUMMARY, "EL", current_login(env)).id


def tmp_store(config_file: Path) -> Path:
    return load_config(config_file).store_path


@pytest.fixture
def keys(tmp_path: Path) -> dict[str, Path]:
    return {name: ssh_key(tmp_path, name) for name in ("el", "bob", "stranger")}


def test_a_forged_ssh_user_auth_is_not_another_login(tmp_path: Path, keys: dict[str, Path]) -> None:
    """Key A requests, key B (made by ssh-keygen a moment before) is named in SSH_USER_AUTH to approve:
    before this rule the approval went through; now the approver is the same login and is refused."""
    forged = {}
    for name in ("el", "bob"):
        forged[name] = tmp_path / f"{name}.auth"
        forged[name].write_text("publickey " + public_line(keys[name]) + "\n")
    approvers = approver_tables(EL=keys["el"], Bob=keys["bob"])
    request = request_as(config(tmp_path, "EL", approvers), clean_env(SSH_USER_AUTH=str(forged["el"])))
    approving = drs_approve(
        config(tmp_path, "Bob", approvers), clean_env(SSH_USER_AUTH=str(forged["bob"])), str(request)
    )
    assert approving.returncode == 1, approving.stdout
    assert (
        f"approval #{request} refused: the same login ({account_name()}) that requested it"
        in approving.stderr
    )
    assert current_login(clean_env(SSH_USER_AUTH=str(forged["bob"]))) == Login(account_name())


def test_the_same_uid_without_a_proven_key_is_not_a_second_login(
    tmp_path: Path, keys: dict[str, Path]
) -> None:
    approvers = approver_tables(EL=keys["el"], Bob=keys["bob"])
    bob_config = config(tmp_path, "Bob", approvers)
    with ssh_agent(tmp_path / "el-agent", keys["el"]) as el_sock:
        request = request_as(config(tmp_path, "EL", approvers), clean_env(SSH_AUTH_SOCK=el_sock))
        with ssh_agent(tmp_path / "stranger-agent", keys["stranger"]) as stranger_sock:
            attempts = {
                "no agent": clean_env(),
                "a dead agent socket": clean_env(SSH_AUTH_SOCK=str(tmp_path / "gone.sock")),
                "an agent with a key nobody listed": clean_env(SSH_AUTH_SOCK=stranger_sock),
                "the requester's own agent": clean_env(SSH_AUTH_SOCK=el_sock),
            }
            for what, env in attempts.items():
                approving = drs_approve(bob_config, env, str(request))
                assert approving.returncode == 1, what
                assert "that requested it cannot approve it" in approving.stderr, what
    assert ApprovalBook(Store.open(tmp_path / "data" / "drs.sqlite")).get(request).state == "pending"


def test_the_agent_proof_checks_the_listed_key_and_the_signature(
    tmp_path: Path, keys: dict[str, Path]
) -> None:
    listed = [("EL", public_line(keys["el"])), ("Bob", public_line(keys["bob"]))]
    with ssh_agent(tmp_path / "agent", keys["stranger"], keys["bob"]) as sock:
        proven = prove_agent_key(listed, {"SSH_AUTH_SOCK": sock})
        assert proven is not None and proven.person == "Bob"
        assert proven.fingerprint == printed_fingerprint(keys["bob"])
        assert prove_agent_key(listed[:1], {"SSH_AUTH_SOCK": sock}) is None, "EL's private key is not in it"
        assert prove_agent_key([], {"SSH_AUTH_SOCK": sock}) is None, "no list, nothing proven"
    assert prove_agent_key(listed, {}) is None


def test_an_approver_entry_that_is_not_a_public_key_names_itself(tmp_path: Path) -> None:
    path = tmp_path / "drs.toml"
    path.write_text('[[approver]]\nname = "Bob"\nkey = "SHA256:abc"\n')
    with pytest.raises(ConfigError, match=r"approver\[0\]\.key: must be an OpenSSH public key line"):
        load_config(path)
    path.write_text('[[approver]]\nname = "Bob"\n')
    with pytest.raises(ConfigError, match=r"approver\[0\]\.key: required key is missing"):
        load_config(path)


def test_drs_setup_login_says_which_login_the_rule_sees(tmp_path: Path, keys: dict[str, Path]) -> None:
    approvers = approver_tables(EL=keys["el"])
    el_config = config(tmp_path, "EL", approvers)

    def setup_login(env: dict[str, str]) -> str:
        done = subprocess.run(
            [sys.executable, "-c", CHILD, "--config", str(el_config), "setup", "login"],
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        return done.stdout.strip()

    assert setup_login(clean_env()) == (
        f"{account_name()}: the OS account only (no ssh-agent ($SSH_AUTH_SOCK is not set)); another person "
        "must approve from another account"
    )
    with ssh_agent(tmp_path / "agent", keys["el"]) as sock:
        assert setup_login(clean_env(SSH_AUTH_SOCK=sock)) == (
            f"{account_name()} (key {printed_fingerprint(keys['el'])}): acts as EL (key proven by ssh-agent, "
            "listed in [[approver]])"
        )
    with ssh_agent(tmp_path / "stranger-agent", keys["stranger"]) as sock:
        assert "the agent holds no key of the [[approver]] list" in setup_login(clean_env(SSH_AUTH_SOCK=sock))
