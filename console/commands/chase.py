"""``drs chase``: put the capsules on the chase team's chasemapper, from what the operations server holds.

The console does this itself when ``[chase] udp`` is set; this command is for a second laptop, a
machine without the console, or a check before the flight (``--once`` sends one round, prints it and
exits). It prints every packet it sends, so a team sees what their chasemapper should show.
"""

from __future__ import annotations

import argparse
import json
import sys

from console.commands.argparser import udp_target
from console.commands.stopping import stop_signals
from drs_link.config import load_config
from predictor.errors import UsageError


def register(subparsers: argparse._SubParsersAction) -> None:
    chase = subparsers.add_parser(
        "chase",
        help="send the capsules (and their predicted landings) to chasemapper as Horus UDP",
        description="Ask the operations server and send, for each capsule with a position, a Horus UDP PAYLOAD_SUMMARY "
        "(and NAME_LAND at a live predicted landing) to chasemapper, every 10 s.",
    )
    chase.add_argument(
        "--udp",
        type=udp_target,
        metavar="HOST:PORT",
        help="where chasemapper listens (default [chase] udp), e.g. 255.255.255.255:55672",
    )
    chase.add_argument("--once", action="store_true", help="send one round, print it and exit")
    chase.set_defaults(func=cmd_chase)


def cmd_chase(args: argparse.Namespace) -> int:
    from drs_link.feeds import CHASE_PERIOD_S, ChaseSender
    from drs_link.server import Client

    config = load_config(args.config)
    target = args.udp or config.chase.udp
    if not target:
        raise UsageError("drs chase needs --udp HOST:PORT or [chase] udp in the configuration")
    sender = ChaseSender(target, "--udp" if args.udp else "chase.udp")
    client = Client.for_config(config)
    every = "once" if args.once else f"every {CHASE_PERIOD_S:g} s"
    try:
        with stop_signals() as wait_for_stop:
            # Said only once SIGTERM is blocked for sigwait: a supervisor (or a test) that stops the
            # process as soon as it reads this line finds it stopping between rounds, never killed.
            print(
                f"drs chase: sending to udp {sender.target} {every} from the operations server at {client.socket_path}",
                file=sys.stderr,
                flush=True,
            )
            while True:
                points = client.chase.points()
                sender.send(points)
                for point in points:
                    print(json.dumps(point.packet()), flush=True)
                if not points:
                    print("drs chase: no capsule has a position yet", file=sys.stderr, flush=True)
                if args.once:
                    return 0
                stop = wait_for_stop(CHASE_PERIOD_S)  # the round is sent whole; a stop ends the wait
                if stop is not None:
                    print(f"drs chase: {stop}: stopped between rounds", file=sys.stderr, flush=True)
                    return 0
    finally:
        sender.close()
        client.close()
