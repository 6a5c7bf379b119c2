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
    server = actions.add_parser(
        "server",
        help="write the systemd unit of the team's operations server (drs server) and say what to do next",
        description="Writes drs-server.service: the server runs as its own account, its socket in /run/drs "
        "(mode 0660, group GROUP), its store in /var/lib/drs-server (0700, the account's alone), its "
        "configuration /etc/drs/server.toml (root's, 0644, with the [[operator]] list). Prints the "
        "commands that make the account and start it.",
    )
    server.add_argument("--group", required=True, help="the operators' group: its members may connect")
    server.add_argument(
        "--account", default="drs-server", help="the server's own account (default drs-server)"
    )
    server.add_argument(
        "--unit-dir", type=Path, default=Path("/etc/systemd/system"), help="where to write the unit"
    )
    server.set_defaults(func=run_setup_server)


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


SERVER_UNIT = """[Unit]
Description=DRS operations server (drs server): the one process that acts on the capsules and the gateway
Wants=network-online.target
After=network-online.target

[Service]
User={account}
Group={group}
Environment=DRS_CONFIG=/etc/drs/server.toml
EnvironmentFile=-/etc/drs/server.env
ExecStart={drs} server --socket /run/drs/drs.sock --group {group}
Restart=on-failure
RestartSec=5
TimeoutStopSec=150
RuntimeDirectory=drs
RuntimeDirectoryMode=0750
StateDirectory=drs-server
StateDirectoryMode=0700
CacheDirectory=drs-server
CacheDirectoryMode=0700
Environment=NUMBA_CACHE_DIR=/var/cache/drs-server
UMask=0077
NoNewPrivileges=yes
ProtectSystem=strict
ProtectHome=yes
PrivateTmp=yes
PrivateDevices=yes
ProtectHostname=yes
ProtectClock=yes
ProtectKernelTunables=yes
ProtectKernelModules=yes
ProtectKernelLogs=yes
ProtectControlGroups=yes
ProtectProc=invisible
ProcSubset=pid
RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX
RestrictNamespaces=yes
RestrictRealtime=yes
RestrictSUIDSGID=yes
LockPersonality=yes
RemoveIPC=yes
CapabilityBoundingSet=
AmbientCapabilities=
SystemCallArchitectures=native
SystemCallFilter=@system-service
SystemCallErrorNumber=EPERM
DevicePolicy=closed
MemoryMax=2G

[Install]
WantedBy=multi-user.target
"""
"""Hardened as the MO receiver's unit (docs/iridium.md), less what the server needs: SSH to the capsules
and HTTPS to RockBLOCK (so no IPAddressDeny), numba's compiled predictions (no MemoryDenyWriteExecute),
and the callers' real uids (no PrivateUsers: in a user namespace every operator would be "nobody").
numba keeps the compiled predictor in the unit's own cache directory: the installation is read-only and the
account has no home, and a cache in the private /tmp would be compiled again (tens of seconds) at each start."""


def run_setup_server(args: argparse.Namespace) -> int:
    import shutil
    import sys

    from drs_link.errors import ConfigError, LinkError

    try:
        grp.getgrnam(args.group)
    except KeyError:
        raise ConfigError(f"group {args.group!r} does not exist: as root, `groupadd {args.group}`") from None
    drs = shutil.which("drs") or f"{sys.executable} -m console.commands.main"
    unit = args.unit_dir / "drs-server.service"
    try:
        unit.write_text(SERVER_UNIT.format(account=args.account, group=args.group, drs=drs))
    except OSError as exc:
        raise LinkError(f"cannot write {unit}: {exc.strerror} (run it as root)") from None
    print(f"wrote {unit}: drs server as {args.account}, socket /run/drs/drs.sock (0660, group {args.group}),")
    print("  store in /var/lib/drs-server (0700: no operator can write it), config /etc/drs/server.toml")
    print("next, as root:")
    print(f"  useradd --system --no-create-home --shell /usr/sbin/nologin --gid {args.group} {args.account}")
    print('  install -d -m 0755 /etc/drs; edit /etc/drs/server.toml: [data] dir = "/var/lib/drs-server",')
    print('    one [[operator]] account = "…" name = "…" per person, [[capsule]], [rockblock], [console]')
    print("  chown root:root /etc/drs/server.toml; chmod 0644 /etc/drs/server.toml")
    print(
        "  the RockBLOCK password and the Pi keys: /etc/drs/server.env (0600) and files only the account reads"
    )
    print("  systemctl daemon-reload && systemctl enable --now drs-server")
    print('each operator: [server] socket = "/run/drs/drs.sock" in their own drs.toml')
    return 0
