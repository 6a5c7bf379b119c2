"""``drs capsule …``: the release steps, scriptable for checklists, each one asked of the operations server.

This process holds no store, link or state machine (issue #29): every verb goes through
``drs_link.server.client``, and the server's refusal comes back as the same one-line error the operations
layer gives (``console.commands.main`` prints it with a non-zero exit); the state machine audits each step
there before this module reports it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import add_two_person_options
from drs_link.config import load_config
from drs_link.errors import RefusedError
from predictor.errors import UsageError

if TYPE_CHECKING:  # the client and its protocol load msgspec: not for --help
    from drs_link.server import Capsule, CapsuleStatus, Client

EXIT_MICROCONTROLLER_SILENT = 3
EXIT_LINK_DOWN = 4

POWER_ON_WARNING = (
    "Power-on pulses the latching relay: the capsule's batteries stay connected until someone presses "
    "the OFF button on the unit. Software cannot switch it off again."
)

WAIVABLE_ITEMS = ("gnss", "sync")
"""``drs_link.ops.WAIVABLE`` (a test holds them equal): that module loads shapely and numpy, and
``drs capsule --help`` must not wait for them."""

TAKE_OVER_WARNING = (
    "Taking over makes {holder} the only console that can power on and release {name}; "
    "the console that held it is refused from now on. The audit log records who, from whom and why."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    capsule = subparsers.add_parser("capsule", help="talk to a capsule's Pi over SSH: status, power-on, go")
    actions = capsule.add_subparsers(dest="capsule_command", metavar="ACTION", required=True)

    status = actions.add_parser("status", help="release state, microcontroller, GNSS fix and storage")
    status.add_argument("name")
    status.add_argument("--json", action="store_true", help="machine-readable output")
    status.set_defaults(func=cmd_status)

    power = actions.add_parser("power-on", help="run DRS_on.py (latches the battery relay)")
    power.add_argument("name")
    power.add_argument("--yes", action="store_true", help="confirm without the interactive prompt")
    power.set_defaults(func=cmd_power_on)

    arm = actions.add_parser(
        "arm", help="poll go/no-go now and, on GO, open the ARM window that `drs capsule go` fires in",
        description="The console's ARM: the same go/no-go items, the same window (console.arm_window_s), one "
        "per capsule across consoles. The window is this account's on this host: `drs capsule go` from it "
        "may FIRE inside it, no console may.",
    )  # fmt: skip
    arm.add_argument("name")
    _poll_options(arm)
    arm.set_defaults(func=cmd_arm)

    disarm = actions.add_parser("disarm", help="close the capsule's ARM window, whoever holds it (audited)")
    disarm.add_argument("name")
    disarm.set_defaults(func=cmd_disarm)

    go = actions.add_parser(
        "go", help="FIRE: run DRS_GoGoGo.py inside the ARM window of `drs capsule arm` (the console's rules)"
    )
    go.add_argument("name")
    go.add_argument("--confirm", metavar="NAME", required=True, help="repeat the capsule's name to confirm")
    _poll_options(go)
    add_two_person_options(go, "", "; the approval ends with the ARM window")
    go.set_defaults(func=cmd_go)

    reset = actions.add_parser("reset", help="after recovery: allow a new release of this capsule")
    reset.add_argument("name")
    reset.add_argument("--confirm", metavar="NAME", required=True, help="repeat the capsule's name")
    reset.set_defaults(func=cmd_reset)

    released = actions.add_parser(
        "released",
        help="settle an unverified Go as released, on evidence (the Pi is down, the reports show the fall)",
    )
    released.add_argument("name")
    released.add_argument("--evidence", metavar="TEXT", required=True, help="what shows it left (audit log)")
    released.add_argument("--confirm", metavar="NAME", required=True, help="repeat the capsule's name")
    released.set_defaults(func=cmd_released)

    authority = actions.add_parser(
        "authority", help="who holds the release authority on the Pi; take it over or give it up"
    )
    authority.add_argument("name")
    authority.add_argument(
        "--take-over", action="store_true", help="make this console the holder (needs --reason and the name)"
    )
    authority.add_argument("--release", action="store_true", help="give up this console's own authority")
    authority.add_argument("--reason", default="", help="why, for the audit log (required with --take-over)")
    authority.add_argument(
        "--confirm", metavar="NAME", help="with --take-over: the capsule's name, instead of typing it"
    )
    add_two_person_options(authority, "with --take-over", "")
    authority.set_defaults(func=cmd_authority)

    enrol = actions.add_parser("enrol", help="show the Pi's host key fingerprint; save it once compared")
    enrol.add_argument("name")
    enrol.add_argument("--fingerprint", metavar="SHA256", help="the fingerprint read on the Pi itself")
    enrol.set_defaults(func=cmd_enrol)

    bench = actions.add_parser("bench", help="measure link overhead and sync speed against a local simulator")
    bench.add_argument("--mb", type=float, default=32.0, help="size of the synced test file (MiB)")
    bench.add_argument("--rounds", type=int, default=20, help="heartbeat round trips to time")
    bench.set_defaults(func=cmd_bench)


def _poll_options(parser: argparse.ArgumentParser) -> None:
    """What the go/no-go poll needs from a terminal: waivers, and the weather to predict the landing from."""
    parser.add_argument(
        "--waive", metavar="ITEM=REASON", action="append", default=[],
        help=f"waive a NO-GO item ({', '.join(WAIVABLE_ITEMS)}) with a reason (logged); "
        "the same to arm and go",
    )  # fmt: skip
    parser.add_argument(
        "--weather",
        type=Path,
        nargs="+",
        metavar="GRIB2",
        help="GFS files for the landing prediction go/no-go checks (without: 'Prediction fresh: no data')",
    )


def _waivers(texts: list[str]) -> list[tuple[str, str]]:
    waivers = []
    for text in texts:
        item, _, reason = text.partition("=")
        if not item.strip() or not reason.strip():
            raise UsageError(
                f"--waive {text!r}: write ITEM=REASON, e.g. --waive gnss='no fix, dropping anyway'"
            )
        waivers.append((item.strip(), reason.strip()))
    return waivers


def _client(args: argparse.Namespace) -> Client:
    """The operations server of this account's configuration (``drs_link.server``): it acts, not this process."""
    from console.commands.server import predictor_for
    from drs_link.server import Client

    return Client.for_config(load_config(args.config), predictor_for)


def cmd_arm(args: argparse.Namespace) -> int:
    """ARM through the server (``Release.arm`` there): the console's go/no-go and one window per capsule."""
    waivers = tuple(_waivers(args.waive))
    with _client(args) as client:
        state = client.capsule(args.name).arm(waivers, tuple(map(str, args.weather or ())), _step)
    print(
        f"{args.name}: ARMED (window #{state.window}) until {state.until_utc}, "
        f"{state.remaining_s:.0f} s: run `drs capsule go {args.name} --confirm {args.name}` within it"
    )
    return 0


def cmd_disarm(args: argparse.Namespace) -> int:
    with _client(args) as client:
        state = client.capsule(args.name).disarm()
    reason = f" ({state.reason})" if state.reason else ""
    print(f"{args.name}: {state.state}{reason}")
    return 0


def cmd_status(args: argparse.Namespace) -> int:
    """Read by the server, which holds the capsule's link; exit 4 when the Pi is unreachable (and not released)."""
    import msgspec

    with _client(args) as client:
        status = client.capsule(args.name).status()
    if args.json:
        print(json.dumps(msgspec.to_builtins(status), indent=2, sort_keys=True))
    else:
        _print_status(args.name, status)
    return 0 if status.link.up or status.release.state == "released" else EXIT_LINK_DOWN


def _print_status(name: str, status: CapsuleStatus) -> None:
    release, link, storage = status.release, status.link, status.storage
    print(f"{name}: {release.state}" + (f" ({release.note})" if release.note else ""))
    print(f"  link: {'up' if link.up else 'DOWN'}" + (f" - {link.error}" if link.error else ""))
    if storage is not None and storage.total_bytes and storage.used_bytes is not None:
        used = storage.used_bytes / storage.total_bytes
        print(
            f"  storage: {storage.mount} {used:.1%} used, {storage.available_bytes} bytes free; "
            f"RAID {storage.raid_state} {storage.raid_members or ''}"
        )
    if status.microcontroller is not None:
        print(f"  microcontroller: {status.microcontroller.diagnosis}")
    gnss = status.gnss
    if gnss is not None and gnss.nmea_seen:
        age = f"{gnss.age_s:.0f} s old" if gnss.age_s is not None else "age unknown"
        position = (
            f"{gnss.latitude:.5f}, {gnss.longitude:.5f}"
            if gnss.latitude is not None and gnss.longitude is not None
            else "no position"
        )
        print(
            f"  GNSS: {gnss.fix_quality_name}, {gnss.satellites} sats, HDOP {gnss.hdop}, "
            f"{position}, {age} ({gnss.sentences_malformed} malformed, "
            f"{gnss.sentences_bad_checksum} bad checksum)"
        )
        if gnss.date_problem:
            print(f"  GNSS warning: {gnss.date_problem}")


def cmd_power_on(args: argparse.Namespace) -> int:
    """Through the server (``CapsuleLinks.power_on`` there, as the console's Power key: the checklist step, a
    disarm, void approvals), confirmed here first: the relay cannot be switched off by software."""
    print(POWER_ON_WARNING)
    confirmed = args.yes
    if not confirmed:
        if not sys.stdin.isatty():
            raise RefusedError(
                f"{args.name}: power-on refused: pass --yes, or run it in a terminal to confirm"
            )
        try:
            typed = input(f"Type the capsule name ({args.name}) to power it on: ")
        except EOFError:
            typed = ""
        confirmed = typed.strip() == args.name
    with _client(args) as client:
        done = client.capsule(args.name).power_on(confirmed, _step)
    for line in done.lines:
        print(line)
    return 0 if done.ok else EXIT_MICROCONTROLLER_SILENT


def _step(line: str) -> None:
    """A progress line, flushed at once: Go takes about 12 s and used to print nothing until the end."""
    print(line, flush=True)


def cmd_go(args: argparse.Namespace) -> int:
    """FIRE through the server (``Release.fire`` there): inside the ARM window, on a poll that still says
    GO with the values ARM saw, with the typed name and the two-person rule; else nothing reaches the Pi.
    An unverified Go is finished instead (``Release.finish_go``)."""
    from drs_link.server import Second

    second = Second(args.second_operator, args.single_operator_waiver, args.await_approval)
    with _client(args) as client:
        done = client.capsule(args.name).fire(
            args.confirm, tuple(_waivers(args.waive)), tuple(map(str, args.weather or ())), second, _step
        )
    for line in done.lines:
        print(line)
    return 0


def cmd_authority(args: argparse.Namespace) -> int:
    if args.take_over and args.release:
        raise UsageError(f"{args.name}: authority: --take-over and --release cannot be combined")
    if args.confirm is not None and not args.take_over:
        raise UsageError(f"{args.name}: authority: --confirm only confirms --take-over")
    if args.await_approval and not args.take_over:
        raise UsageError(f"{args.name}: authority: --await-approval is for --take-over")
    with _client(args) as client:
        capsule = client.capsule(args.name)
        if args.take_over:
            return _take_over(args, capsule)
        if args.release:
            given_up = capsule.release_authority(args.reason)
            if given_up.seen.holder is None:
                print(f"{args.name}: this console held no release authority: it is free")
            else:
                print(f"{args.name}: release authority given up; it was {given_up.described}")
            return 0
        seen = capsule.authority()
    print(f"{args.name}: release authority {seen.described}{' (this console)' if seen.mine else ''}")
    return 0


def _take_over(args: argparse.Namespace, capsule: Capsule) -> int:
    """The take-over is the server's (``Release.take_over``: the two-person rule, the approval, the
    Pi's check); this shows who holds it now and asks for the name."""
    from drs_link.server import Second

    seen = capsule.check_take_over(args.reason)
    if args.confirm is None and not sys.stdin.isatty():
        raise RefusedError(
            f"{args.name}: take-over refused: pass --confirm {args.name}, or run it in a terminal to confirm"
        )
    print(f"{args.name}: release authority {seen.described}{' (this console)' if seen.mine else ''}")
    typed = args.confirm
    if typed is None:
        print(TAKE_OVER_WARNING.format(name=args.name, holder=seen.this_console))
        try:
            typed = input(f"Type the capsule name ({args.name}) to take over its release authority: ").strip()
        except EOFError:
            typed = ""
    second = Second(args.second_operator, args.single_operator_waiver, args.await_approval)
    done = capsule.take_over(seen.seen, typed, args.reason, second, _step)
    for line in done.lines:
        print(line)
    return 0


def cmd_released(args: argparse.Namespace) -> int:
    with _client(args) as client:
        record = client.capsule(args.name).released(args.confirm, args.evidence)
    print(f"{args.name}: {record.note}")
    return 0


def cmd_reset(args: argparse.Namespace) -> int:
    """Through the server (``CapsuleLinks.reset``, as the console's reset key): ARM possible again, waivers
    and approvals void."""
    with _client(args) as client:
        client.capsule(args.name).reset(args.confirm)
    print(f"{args.name}: reset to idle")
    return 0


def cmd_enrol(args: argparse.Namespace) -> int:
    """The Pi's host key, offered and then trusted by the server, which writes its own known_hosts."""
    with _client(args) as client:
        capsule = client.capsule(args.name)
        offer = capsule.host_key()
        print(f"{offer.address} offers {offer.key_type} {offer.fingerprint}")
        if args.fingerprint is None:
            print(
                "Compare it with `ssh-keygen -lf /etc/ssh/ssh_host_ed25519_key.pub` on the Pi, then re-run "
                f"with --fingerprint {offer.fingerprint}"
            )
            return 1
        saved = capsule.enrol(args.fingerprint)
    print(f"{args.name}: host key saved to {saved.saved_to}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    if args.mb <= 0 or args.rounds < 1:
        raise UsageError("bench: --mb must be positive and --rounds at least 1")
    from drs_link.sim import capsule_bench

    result = capsule_bench.run_bench(sync_mb=args.mb, rounds=args.rounds)
    print(f"SSH connect + host-key check (median): {result.connect_ms_median:.1f} ms")
    print(
        f"heartbeat round trip: median {result.heartbeat_ms_median:.1f} ms, "
        f"p95 {result.heartbeat_ms_p95:.1f} ms"
    )
    print(f"sync {result.sync_mb:.0f} MiB incl. sha256 on the Pi: {result.sync_mb_per_s:.1f} MiB/s")
    print(
        f"power-on -> NMEA -> Go -> Pi shut down: {result.release_sim_s:.1f} s simulated "
        f"({result.release_wall_s:.2f} s wall at clock x{result.clock_scale:.0f})"
    )
    return 0
