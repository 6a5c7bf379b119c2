"""`drs setup shared-store`: one store for several operators' OS accounts, so a second operator
approves from their own account (the two-person rule's strong form, docs/console.md); `drs setup login`:
the login the two-person rule sees for this session, to check before launch day that a key is proven."""

from __future__ import annotations

import argparse
import grp
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    setup = subparsers.add_parser("setup", help="prepare this machine for operations (a shared store)")
    actions = setup.add_subparsers(dest="setup_action", metavar="ACTION", required=True)
    shared = actions.add_parser(
        "shared-store",
        help="let the accounts of one group share a store",
        description="Give DIR (default: the configured [data] dir) to GROUP with mode 2770 and the store "
        "inside it mode 0660, so every member's console and drs approve use one store. Create the group "
        "and add the operators first, as root: groupadd GROUP; usermod -aG GROUP NAME (each operator "
        'logs in again). Then set [data] dir = "DIR" in every operator\'s drs.toml.',
    )
    shared.add_argument("directory", nargs="?", type=Path, metavar="DIR", help="the store's directory")
    shared.add_argument("--group", required=True, help="the operators' group (must exist)")
    shared.set_defaults(func=run_shared_store)
    login = actions.add_parser(
        "login",
        help="show the login the two-person rule sees for this session",
        description="The OS account of this process's real uid and, if ssh-agent ($SSH_AUTH_SOCK) holds "
        "a key of the configuration's [[approver]] list, that key (proven by a signature) and its person.",
    )
    login.set_defaults(func=run_login)


def run_shared_store(args: argparse.Namespace) -> int:
    from drs_link.config import load_config
    from drs_link.store import share_directory

    given = args.directory
    directory = given.expanduser().absolute() if given else load_config(args.config).data.dir
    for line in share_directory(directory, args.group):
        print(line)
    group = grp.getgrnam(args.group)
    members = ", ".join(sorted(group.gr_mem)) or "nobody yet (usermod -aG GROUP NAME, as root)"
    print(f"members of {args.group}: {members}")
    print(f'each operator: [data] dir = "{directory}" in their drs.toml')
    return 0


def run_login(args: argparse.Namespace) -> int:
    import os

    from drs_link.config import load_config
    from drs_link.ops import current_login

    config = load_config(args.config)
    login = current_login()
    if login.person:
        print(f"{login}: acts as {login.person} (key proven by ssh-agent, listed in [[approver]])")
        return 0
    why = (
        "no ssh-agent ($SSH_AUTH_SOCK is not set)"
        if not os.environ.get("SSH_AUTH_SOCK")
        else "no [[approver]] list in the configuration"
        if not config.approvers
        else "the agent holds no key of the [[approver]] list"
    )
    print(f"{login}: the OS account only ({why}); another person must approve from another account")
    return 0
