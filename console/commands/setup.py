"""`drs setup server`: the team's operations server as a systemd unit of its own account, and what to run
next, so that operators share one store and one rule by connecting to it (docs/console.md)."""

from __future__ import annotations

import argparse
import grp
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    setup = subparsers.add_parser("setup", help="prepare this machine for operations (the team's server)")
    actions = setup.add_subparsers(dest="setup_action", metavar="ACTION", required=True)
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
