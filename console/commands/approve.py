"""`drs approve`: the second operator's side of the two-person rule, from their own login.

A hazardous command sent with ``--await-approval`` waits as pending; the second operator lists what
waits and approves or rejects it here, in their own session. Only what can still be used is listed: a
request whose ARM window closed, whose capsule changed state or whose requester cancelled it is void.
The operations server decides who they are from the kernel (the socket's peer uid), never a name typed
next to the requester's, a config file or an SSH key this process could choose.
"""

from __future__ import annotations

import argparse
import json

from predictor.errors import UsageError


def register(subparsers: argparse._SubParsersAction) -> None:
    approve = subparsers.add_parser(
        "approve",
        help="list hazardous commands waiting for a second operator, or approve/reject one",
        description="Without ID: the requests waiting for approval. With ID: approve it (or --reject it). "
        "Asked of the operations server, which knows the approver's account from the kernel: the approver "
        "must be another account than the requester's (a private server is reached by one account only: "
        "the team's shared server is needed, drs setup server).",
    )
    approve.add_argument("approval_id", nargs="?", type=int, metavar="ID", help="the request to decide")
    approve.add_argument("--reject", action="store_true", help="reject instead of approving")
    approve.add_argument("--reason", default="", help="why (logged; required with --reject)")
    approve.add_argument("--json", action="store_true", help="list as JSON, one object per request")
    approve.set_defaults(func=run_approve)


def run_approve(args: argparse.Namespace) -> int:
    """Through the operations server: it knows this account from the kernel, never from this process."""
    from drs_link.config import load_config
    from drs_link.server import Client

    if args.approval_id is not None and args.reject and not args.reason.strip():
        raise UsageError("--reject needs --reason: the requester is told why")
    with Client.for_config(load_config(args.config)) as client:
        if args.approval_id is None:
            requests = client.approvals.waiting()
            for request in requests:
                if args.json:
                    print(json.dumps({"id": request.id, "capsule": request.capsule, "action": request.action,
                                      "summary": request.summary, "requested_by": request.requested_by,
                                      "login": request.requester_account, "command": request.command,
                                      "expires_utc": request.expires_utc}))  # fmt: skip
                else:
                    print(request.described)
            if not requests and not args.json:
                print("nothing waits for approval")
            return 0
        if args.reject:
            decided = client.approvals.reject(args.approval_id, args.reason)
        else:
            decided = client.approvals.approve(args.approval_id)
    print(decided.described)
    return 0
