"""`drs approve`: the second operator's side of the two-person rule, from their own login.

A hazardous command sent with ``--await-approval`` waits as pending; the second operator lists what
waits and approves or rejects it here, in their own session. Only what can still be used is listed: a
request whose ARM window closed, whose capsule changed state or whose requester cancelled it is void.
The login (OS account, SSH key) decides who they are, not a name typed next to the requester's.
"""

from __future__ import annotations

import argparse
import json

from drs_link.errors import ConfigError
from drs_link.ops import ApprovalBook
from predictor.errors import UsageError


def register(subparsers: argparse._SubParsersAction) -> None:
    approve = subparsers.add_parser(
        "approve",
        help="list hazardous commands waiting for a second operator, or approve/reject one",
        description="Without ID: the requests waiting for approval. With ID: approve it (or --reject it). "
        "The approver must be another login than the requester: another OS account, or another "
        "person's key of the [[approver]] list, proven by a signature from ssh-agent ($SSH_AUTH_SOCK).",
    )
    approve.add_argument("approval_id", nargs="?", type=int, metavar="ID", help="the request to decide")
    approve.add_argument("--reject", action="store_true", help="reject instead of approving")
    approve.add_argument("--reason", default="", help="why (logged; required with --reject)")
    approve.add_argument("--json", action="store_true", help="list as JSON, one object per request")
    approve.set_defaults(func=run_approve)


def run_approve(args: argparse.Namespace) -> int:
    from drs_link.config import load_config
    from drs_link.ops import current_login

    config = load_config(args.config)
    book = ApprovalBook.open(config.store_path)
    if args.approval_id is None:
        requests = book.open_requests()
        for request in requests:
            if args.json:
                print(json.dumps({"id": request.id, "capsule": request.capsule, "action": request.action,
                                  "summary": request.summary, "requested_by": request.requested_by,
                                  "login": str(request.requester), "command": request.command,
                                  "expires_utc": request.expires_utc.isoformat(),
                                  "brief": request.for_approver(book.clock())[1:]}))  # fmt: skip
            else:
                print("\n".join(request.for_approver(book.clock())))
        if not requests and not args.json:
            print("nothing waits for approval")
        return 0
    if not config.operator.name:
        raise ConfigError("operator.name: set [operator] name; every approval is audited with it")
    if args.reject and not args.reason.strip():
        raise UsageError("--reject needs --reason: the requester is told why")
    decided = book.decide(
        args.approval_id, config.operator.name, current_login(), not args.reject, args.reason
    )
    print(decided.describe(book.clock()))
    return 0
