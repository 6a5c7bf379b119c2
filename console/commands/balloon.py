"""``drs balloon watch``: on launch day, prove the configured balloon feed delivers positions before relying on it.

It prints every accepted fix and every rejected line with its reason, so a team sees at once a
wrong port, a wrong format or a sender without a fix, and exits non-zero with a one-line summary
if no position arrives in time. With ``--json`` each of those is one JSON object per line, flushed
as it happens, so a script can follow the feed (``| jq``) while it runs.
"""

from __future__ import annotations

import argparse
import json
import queue
import time
from datetime import UTC, datetime
from typing import Any

from drs_link.config import load_config
from drs_link.errors import LinkError
from drs_link.feeds import BalloonFeed, BalloonFix, FeedStatus, Rejection


def register(subparsers: argparse._SubParsersAction) -> None:
    balloon = subparsers.add_parser("balloon", help="the balloon's position from a ground-station feed")
    actions = balloon.add_subparsers(dest="balloon_command", metavar="ACTION", required=True)
    watch = actions.add_parser("watch", help="print what the configured [balloon_feed] delivers, to check it")
    watch.add_argument("--count", type=_positive_int, default=5, help="exit 0 after this many fixes (5)")
    watch.add_argument(
        "--timeout",
        type=_positive_float,
        default=30.0,
        help="fail if no fix arrives for this many seconds (30)",
    )
    watch.add_argument(
        "--json", action="store_true", help="one JSON object per line: fixes, rejections, the source"
    )
    watch.set_defaults(func=cmd_watch)


def cmd_watch(args: argparse.Namespace) -> int:
    from drs_link.ops import (
        iso_utc,  # here, not at the top: drs_link.ops's values load pyproj, not for --help
    )

    config = load_config(args.config)
    outcomes: queue.Queue[BalloonFix | Rejection] = queue.Queue()
    feed = BalloonFeed(config.balloon_feed, clock=lambda: datetime.now(UTC), listener=outcomes.put)
    feed.start()
    say = _json_line if args.json else _text_line
    say({"event": "watching", "source": feed.source})
    try:
        accepted = 0
        deadline = time.monotonic() + args.timeout
        while accepted < args.count:
            try:
                outcome = outcomes.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise LinkError(quiet_message(feed.status(), args.timeout, accepted, args.count)) from None
            if isinstance(outcome, BalloonFix):
                accepted += 1
                deadline = time.monotonic() + args.timeout
                say({"event": "fix", "time_utc": iso_utc(outcome.time), "lat": outcome.lat, "lon": outcome.lon,
                     "alt_m": outcome.alt_m, "format": outcome.format, "callsign": outcome.callsign})  # fmt: skip
            else:
                say(
                    {
                        "event": "rejected",
                        "reason": outcome.reason,
                        "detail": outcome.detail,
                        "line": outcome.line,
                    }
                )
    finally:
        feed.stop()
    status = feed.status()
    if status.out_of_order:
        say({"event": "out_of_order", "dropped": status.out_of_order})
    return 0


def _json_line(event: dict[str, Any]) -> None:
    print(json.dumps(event, ensure_ascii=False), flush=True)


def _text_line(event: dict[str, Any]) -> None:
    """The same events as ``--json``, as a person reads them."""
    kind = event["event"]
    if kind == "watching":
        text = f"watching the balloon feed from {event['source']}"
    elif kind == "fix":
        text = f"{event['time_utc']}  {event['lat']:9.5f} {event['lon']:10.5f}  {event['alt_m']:7.0f} m  {event['format']}"
    elif kind == "rejected":
        text = f"rejected: {event['detail']}  [{event['line']}]"
    else:
        text = f"({event['dropped']} out-of-order fixes dropped)"
    print(text, flush=True)


def quiet_message(status: FeedStatus, timeout_s: float, accepted: int, wanted: int) -> str:
    """One line saying what did arrive, so the team knows whether to look at the sender or the network."""
    seen: list[str] = []
    if accepted:
        seen.append(f"{accepted} of {wanted} fixes before that")
    if status.rejected:
        if len(status.reasons) == 1:
            reasons = status.reasons[0][0]
        else:
            reasons = ", ".join(f"{reason} ×{count}" for reason, count in status.reasons)
        seen.append(f"{_lines(status.rejected)} rejected: {reasons}")
    if status.ignored:
        seen.append(f"{_lines(status.ignored)} without a position ignored")
    if status.out_of_order:
        seen.append(f"{status.out_of_order} out-of-order fixes dropped")
    if not seen:
        seen.append("nothing received")
    if status.last_error:
        seen.append(f"last error: {status.last_error}")
    return f"no balloon position from {status.source} in {timeout_s:g} s ({'; '.join(seen)})"


def _lines(count: int) -> str:
    return f"{count} line" if count == 1 else f"{count} lines"


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text} must be a positive number of seconds")
    return value
