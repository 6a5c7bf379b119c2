"""``drs sync``: upload a directory to a capsule's storage mount, verified by sha256 on the Pi.

Not yet a client of the operations server (issue #29): it opens ``Operations`` in this process, so in
shared use it needs the store and the Pi's key, which only the server holds (docs/console.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

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
    """``Operations.sync`` (the console's Sync key: the same upload, verification and audit), with bars."""
    from rich.progress import BarColumn, DownloadColumn, Progress, TaskID, TextColumn, TransferSpeedColumn

    from drs_link.ops import Operations, cli_holder

    config = load_config(args.config)
    config.capsule(args.name)
    ops = Operations.open(config, holder=cli_holder())
    try:
        if args.status:
            status = ops.sync_status(args.name, args.source, with_hash=args.hash)
            if args.json:
                print(json.dumps(status.as_dict(), indent=2, sort_keys=True))
            else:
                print(
                    f"{args.name}: {len(status.up_to_date)} up to date, {len(status.missing)} missing, "
                    f"{len(status.changed)} changed, {status.bytes_pending} bytes pending"
                )
            return 0 if not (status.missing or status.changed) else 1
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            DownloadColumn(),
            TransferSpeedColumn(),
            transient=True,
        ) as progress:
            tasks: dict[str, TaskID] = {}

            def on_progress(relative: str, done: int, total: int) -> None:
                if relative not in tasks:
                    tasks[relative] = progress.add_task(relative, total=total)
                progress.update(tasks[relative], completed=done)

            report = ops.sync(args.name, args.source, on_progress)
    finally:
        ops.close()
    print(
        f"{args.name}: {len(report.uploaded)} files uploaded and verified by sha256 on the Pi, "
        f"{len(report.skipped)} already up to date, {report.bytes_sent} bytes sent"
    )
    if report.left_out:
        print(f"{args.name}: {len(report.left_out)} entries left out: {'; '.join(report.left_out)}")
    return 0
