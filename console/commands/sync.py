"""``drs sync``: upload a directory to a capsule's storage mount, verified by sha256 on the Pi.

A client of the operations server (issue #29): the server uploads with its own SSH identity (the
operator never holds the Pi's key), audits under the caller's operator name, and reads the named
directory only if the caller's account could read all of it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import msgspec

from drs_link.config import load_config


def register(subparsers: argparse._SubParsersAction) -> None:
    sync = subparsers.add_parser("sync", help="upload a directory to a capsule's storage mount (verified)")
    sync.add_argument("name")
    sync.add_argument(
        "source", type=Path, metavar="SOURCE_DIR", nargs="?", help="default: the capsule's sync_source"
    )
    sync.add_argument("--status", action="store_true", help="only report what is missing or changed")
    sync.add_argument("--hash", action="store_true", help="with --status: also compare sha256")
    sync.add_argument("--json", action="store_true", help="with --status: machine-readable output")
    sync.set_defaults(func=cmd_sync)


def cmd_sync(args: argparse.Namespace) -> int:
    """The server's ``CapsuleLinks.sync`` (the console's Sync key: the same upload, verification and
    audit), its progress printed as the server says it."""
    from drs_link.server import Client

    with Client.for_config(load_config(args.config)) as client:
        capsule = client.capsule(args.name)
        if args.status:
            status = capsule.sync_status(args.source, with_hash=args.hash)
            if args.json:
                print(json.dumps(msgspec.to_builtins(status), indent=2, sort_keys=True))
            else:
                print(
                    f"{args.name}: {status.up_to_date} up to date, {len(status.missing)} missing, "
                    f"{len(status.changed)} changed, {status.bytes_pending} bytes pending"
                )
            return 0 if not (status.missing or status.changed) else 1
        report = capsule.sync(args.source, lambda line: print(line, flush=True))
    print(
        f"{args.name}: {len(report.uploaded)} files uploaded and verified by sha256 on the Pi, "
        f"{report.skipped} already up to date, {report.bytes_sent} bytes sent"
    )
    if report.left_out:
        print(f"{args.name}: {len(report.left_out)} entries left out: {'; '.join(report.left_out)}")
    return 0
