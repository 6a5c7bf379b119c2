"""`drs mt …` and `drs mo …`: the Iridium side from a terminal.

`mt send/status/resolve` and `mo health/export` are clients of the operations server, which holds the
store and the gateway's password; this only collects arguments, prints their typed answers and turns
refusals into one-line errors (console/commands/main.py prints LinkError as ``drs: error: …``).
`mo serve/import/parse` are the MO receiver, which faces the internet and writes reports only: it opens
the store itself and stays apart from the server (issue #29 item 7).
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import add_two_person_options, text_or_stdin
from console.commands.stopping import stop_signals
from drs_link.config import load_config
from drs_link.errors import LinkError
from drs_link.iridium import LISTED  # drs_link.ops's copies load pyproj
from drs_link.store import Store
from predictor.errors import UsageError

if TYPE_CHECKING:  # the webhook loads jwt: not for --help
    from drs_link.iridium import StoredReport

_IMEI_RE = re.compile(r"\d{15}")
log = logging.getLogger(__name__)


def register(subparsers: argparse._SubParsersAction) -> None:
    mt = subparsers.add_parser("mt", help="commands to a capsule over Iridium (RockBLOCK MT)")
    mt_actions = mt.add_subparsers(dest="mt_action", metavar="ACTION", required=True)
    send = mt_actions.add_parser("send", help="compose one MT; --dry-run shows it, --confirm NAME queues it")
    send.add_argument("name", help="capsule name from the configuration")
    for command in LISTED:
        send.add_argument(command.flag, **command.option)
    send.add_argument("--accept-midnight", action="store_true", help="allow a PARACHUTE window across 00:00Z")
    send.add_argument("--flush", action="store_true", help="empty the gateway's MT queue first (hazardous)")
    send.add_argument("--dry-run", action="store_true", help="print the exact text and hex; send nothing")
    send.add_argument("--confirm", metavar="NAME", help="the capsule's name again: required for a real send")
    add_two_person_options(send, "PARACHUTE", "")
    send.add_argument(
        "--override-landed",
        metavar="REASON",
        help="PARACHUTE without landed evidence in the reports: why (needs a second operator or a waiver)",
    )
    send.set_defaults(func=_mt_send)
    status = mt_actions.add_parser("status", help="the lifecycle of this capsule's commands")
    status.add_argument("name")
    status.add_argument("--json", action="store_true", help="print JSON")
    status.set_defaults(func=_mt_status)
    resolve = mt_actions.add_parser(
        "resolve", help="record what the RockBLOCK portal shows for a command whose delivery is unknown"
    )
    resolve.add_argument("name", help="capsule name from the configuration")
    resolve.add_argument(
        "command_id", type=int, metavar="MT_LOCAL_ID", help="the MT number `drs mt status` shows"
    )
    outcome = resolve.add_mutually_exclusive_group(required=True)
    outcome.add_argument(
        "--queued", type=int, metavar="GATEWAY_ID", help="the portal shows it queued with this id"
    )
    outcome.add_argument(
        "--not-sent", action="store_true", help="the portal shows it never reached the gateway"
    )
    resolve.add_argument("--note", default="", metavar="TEXT", help="what you saw, kept in the audit log")
    resolve.set_defaults(func=_mt_resolve)

    mo = subparsers.add_parser("mo", help="capsule reports over Iridium (RockBLOCK MO)")
    mo_actions = mo.add_subparsers(dest="mo_action", metavar="ACTION", required=True)
    parse = mo_actions.add_parser("parse", help="decode one report given as the gateway's hex")
    parse.add_argument("hex", type=text_or_stdin("HEX"), help="the report's hex; - reads standard input")
    parse.add_argument("--json", action="store_true", help="print JSON")
    parse.set_defaults(func=_mo_parse)
    serve = mo_actions.add_parser("serve", help="receive the gateway's webhook deliveries ([mo] config)")
    serve.add_argument("--host", help="override mo.listen_host")
    serve.add_argument("--port", type=int, help="override mo.listen_port (0: any free port)")
    serve.set_defaults(func=_mo_serve, log_default=logging.INFO)  # a service: its access log is its record
    importer = mo_actions.add_parser(
        "import", help="store saved SBD attachments (RockBLOCK or Iridium-direct file names)"
    )
    importer.add_argument("files", nargs="+", type=Path)
    importer.set_defaults(func=_mo_import)
    bench = mo_actions.add_parser("bench", help="measure webhook store+answer latency and parser speed")
    bench.add_argument("--posts", type=int, default=200, help="deliveries POSTed one at a time (default 200)")
    bench.add_argument(
        "--clients", type=int, default=20, help="clients POSTing at once in the burst (default 20)"
    )
    bench.add_argument(
        "--per-client", type=int, default=50, help="deliveries each burst client POSTs (default 50)"
    )
    bench.set_defaults(func=_mo_bench)
    health = mo_actions.add_parser("health", help="battery, resets, gaps and spacing from the reports")
    health.add_argument("name")
    health.add_argument("--json", action="store_true", help="print JSON")
    health.set_defaults(func=_mo_health)
    export = mo_actions.add_parser("export", help="the stored position fixes as a canonical track CSV")
    export.add_argument("name", nargs="?", help="capsule name from the configuration")
    export.add_argument("--imei", help="a modem's IMEI instead of a configured capsule's name")
    export.add_argument("--out", type=Path, required=True, metavar="TRACK.csv")
    export.add_argument("--force", action="store_true", help="replace an existing --out file")
    export.set_defaults(func=_mo_export)


def _mt_send(args: argparse.Namespace) -> int:
    """Through the operations server, which alone holds the gateway's password: it composes, shows, gates
    (``IridiumOps.send_mt``: the landed gate, the two-person rule, the approval) and queues."""
    from drs_link.server import PROTOCOL, Client, MtSendRequest, Second

    options = {c.dest: getattr(args, c.dest) for c in LISTED if getattr(args, c.dest) is not None}
    request = MtSendRequest(
        PROTOCOL, options, args.confirm, args.dry_run, args.flush, args.accept_midnight, args.override_landed,
        Second(args.second_operator, args.single_operator_waiver, args.await_approval),
    )  # fmt: skip
    with Client.for_config(load_config(args.config)) as client:
        done = client.iridium.send_mt(args.name, request, lambda line: print(line, flush=True))
    for line in done.lines:
        print(line)
    return 0 if done.ok else 1


def _mt_status(args: argparse.Namespace) -> int:
    """Asked of the operations server, which moves the MTs on from the reports it holds."""
    import msgspec

    from drs_link.server import Client

    with Client.for_config(load_config(args.config)) as client:
        status = client.iridium.mt_status(args.name)
    if args.json:
        print(json.dumps(msgspec.to_builtins(status), indent=2))
        return 0
    for command in status.commands:
        requested = command.requested_utc[:19].replace("T", " ")  # the store's ISO time, to the second
        print(f"MT {command.id} {requested}Z {command.text} {command.state}: {command.detail}")
    return 0


def _mt_resolve(args: argparse.Namespace) -> int:
    """Through the operations server, which audits the resolution under the caller's operator name."""
    from drs_link.server import Client

    with Client.for_config(load_config(args.config)) as client:
        commands = client.iridium.resolve_mt(
            args.name, args.command_id, None if args.not_sent else args.queued, args.note
        )
    for command in commands:
        print(f"MT {command.id} {command.text}: {command.state}: {command.detail}")
    return 0


def _mo_parse(args: argparse.Namespace) -> int:
    from drs_link.iridium import parse_hex  # not drs_link.ops: one hex string, no store, 5x lighter

    result = parse_hex(args.hex)
    if args.json:
        print(json.dumps(result.as_dict(), indent=2))
        return 0 if result.accepted else 1
    if result.report is None:
        raise LinkError(f"not a DRS report: {result.reason}")
    report = result.report
    if report.fix is None:
        print("fix: none (19700101000000): use the Iridium position and CEP of the delivery")
    else:
        fix = report.fix
        print(
            f"fix: {fix.time:%Y-%m-%d %H:%M:%S}Z {fix.lat:.6f},{fix.lon:.6f} alt {fix.alt_m} m "
            f"speed {fix.speed_ms} m/s course {fix.course_deg}° hdop {fix.hdop} sats {fix.sats}"
        )
    print(f"battery: {report.vbat:.2f} V  iteration: {report.iteration}")
    if report.forwarding:
        print(f"forwarding: to RockBLOCK {report.rb_destination}, from {report.rb_source}")
    return 0


def _mo_serve(args: argparse.Namespace) -> int:
    from drs_link.iridium import MoHttpServer, MoReceiver, ReportStore, lifecycle as lc

    # not OperatorOps: the webhook must start whatever the console's files say
    config = load_config(args.config)
    store = Store.open(config.store_path)
    mo_config = config.mo
    if args.host is not None or args.port is not None:
        mo_config = replace(
            mo_config,
            listen_host=args.host if args.host is not None else mo_config.listen_host,
            listen_port=args.port if args.port is not None else mo_config.listen_port,
        )
    reports = ReportStore(store)
    life = lc.CommandLifecycle(store, config.operator.name)

    def after_answer(stored: StoredReport) -> None:
        report = stored.report
        if report is None:
            what = f"rejected: {stored.parsed.reason}"
        elif report.fix is None:
            what = f"no fix, battery {report.vbat:.2f} V"
        else:
            fix = report.fix
            what = f"{fix.lat:.5f},{fix.lon:.5f} {fix.alt_m} m at {fix.time:%H:%M:%S}Z"
            what += f", battery {report.vbat:.2f} V"
        print(f"MO {stored.delivery.imei} #{stored.delivery.momsn}: {what}", flush=True)
        for command in life.observe_store(reports, stored.delivery.imei):
            print(f"MT {command.id} {command.text}: {command.state}", flush=True)

    with stop_signals() as wait_for_stop:
        try:
            server = MoHttpServer(MoReceiver(reports, mo_config, after_answer)).start()
        except OSError as exc:
            raise LinkError(
                f"cannot listen on {mo_config.listen_host}:{mo_config.listen_port}: {exc.strerror}"
            ) from None
        print(
            f"listening on {server.url} (Ctrl-C or SIGTERM stops it, after answering what has arrived)",
            flush=True,
        )
        log.info("listening", extra={"url": server.url, "trusted_proxy": mo_config.trusted_proxy or "none"})
        log.info("stopping", extra={"signal": wait_for_stop(None)})
        unanswered = server.stop()
    log.info("stopped", extra={"unanswered": unanswered})
    return 0


def _mo_import(args: argparse.Namespace) -> int:
    from drs_link.iridium import ReportStore, import_files  # not OperatorOps: as `mo serve`

    store = Store.open(load_config(args.config).store_path)
    outcomes = import_files(args.files, ReportStore(store))
    for outcome in outcomes:
        print(f"{outcome.path}: {outcome.status}: {outcome.message}")
    return 1 if any(o.status == "error" for o in outcomes) else 0


def _mo_export(args: argparse.Namespace) -> int:
    """The server reads the fixes it holds; this process writes them where its operator chose, so the file
    is the operator's own (issue #29 item 6)."""
    from drs_link.exports import write_export
    from drs_link.server import Client

    if (args.name is None) == (args.imei is None):
        raise UsageError("give either a capsule NAME or --imei IMEI, not both or neither")
    if args.imei is not None and not _IMEI_RE.fullmatch(args.imei):
        raise UsageError(f"--imei {args.imei!r}: an IMEI is 15 digits")
    if str(args.out) != "-" and args.out.exists() and not args.force:  # before the server reads anything
        raise LinkError(
            f"--out {args.out}: the file exists; choose another name or add --force to replace it"
        )
    with Client.for_config(load_config(args.config)) as client:
        track = client.iridium.track(args.name, args.imei)
    write_export(track.csv, args.out, overwrite=args.force)
    print(
        f"wrote {args.out}: {track.fixes} fixes of {track.who}; skipped {track.without_fix} report(s) "
        f"without a fix and {track.rejected} rejected",
        file=sys.stderr if str(args.out) == "-" else sys.stdout,
    )
    return 0


def _mo_bench(args: argparse.Namespace) -> int:
    from drs_link.sim import mo_bench

    for option, value, most in (("--posts", args.posts, 10_000), ("--clients", args.clients, 200),
                                ("--per-client", args.per_client, 10_000)):  # fmt: skip
        if not 1 <= value <= most:
            raise UsageError(f"{option} must be from 1 to {most}")
    for line in mo_bench.run_bench(args.posts, args.clients, args.per_client).lines():
        print(line)
    return 0


def _mo_health(args: argparse.Namespace) -> int:
    """Judged by the operations server from the reports it holds; printed here from its typed answer."""
    from drs_link.server import Client, iso_utc

    with Client.for_config(load_config(args.config)) as client:
        health = client.iridium.health(args.name)
    if args.json:
        document = {
            "capsule": health.capsule, "imei": health.imei, "reports": health.reports,
            "last_report_utc": iso_utc(health.last_report) if health.last_report else None,
            "last_vbat": health.last_vbat,
            "findings": [{"kind": f.kind, "report_id": f.report_id, "message": f.message} for f in health.findings],
        }  # fmt: skip
        print(json.dumps(document, indent=2))
        return 0
    last = f"{health.last_report:%Y-%m-%d %H:%M:%S}Z" if health.last_report else "never"
    vbat = f"{health.last_vbat:.2f} V" if health.last_vbat is not None else "unknown"
    print(f"{health.capsule}: {health.reports} reports, last {last}, battery {vbat}")
    for finding in health.findings:
        print(f"{finding.kind}: {finding.message}")
    return 0
