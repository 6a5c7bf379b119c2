"""``python -m drs_link.sim``: run simulated capsules on loopback for the demo or by hand.

Prints, per capsule, the ``[[capsule]]`` table to paste into drs.toml and writes the host keys
to the given known_hosts file, so the console connects with full host-key verification.
"""

from __future__ import annotations

import argparse
import base64
import binascii
import signal
import sys
import threading
from pathlib import Path

import paramiko

from drs_link.sim.capsule_pi import CapsuleSimulator
from drs_link.sim.firmware import GnssSky


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m drs_link.sim", description=__doc__.splitlines()[0])
    parser.add_argument("--name", action="append", default=None, help="capsule name (repeat for several)")
    parser.add_argument("--authorized-key", type=Path, required=True, help="client public key file (.pub)")
    parser.add_argument("--known-hosts", type=Path, required=True, help="known_hosts file to write")
    parser.add_argument("--scale", type=float, default=1.0, help="simulated seconds per real second")
    parser.add_argument("--no-fix", action="store_true", help="GNSS tracks satellites but has no fix")
    args = parser.parse_args(argv)
    try:
        key_type, key_data = args.authorized_key.read_text().split()[:2]
        client_key = paramiko.PKey.from_type_string(key_type, base64.b64decode(key_data))
    except (OSError, ValueError, binascii.Error, paramiko.SSHException) as exc:
        print(f"simulator: error: cannot read {args.authorized_key}: {exc}", file=sys.stderr)
        return 2
    sims = []
    lines = []
    for name in args.name or ["DRS1"]:
        sim = CapsuleSimulator(name, [client_key], clock_scale=args.scale, sky=GnssSky(fix=not args.no_fix))
        port = sim.start()
        sims.append(sim)
        lines.append(sim.known_hosts_line())
        identity = str(args.authorized_key).removesuffix(".pub")
        print(
            f'[[capsule]]\nname = "{name}"\nhost = "127.0.0.1"\nport = {port}\n'
            f'identity_file = "{identity}"\nknown_hosts = "{args.known_hosts}"\npython = "python3"\n'
        )
    args.known_hosts.parent.mkdir(parents=True, exist_ok=True)
    args.known_hosts.write_text("".join(lines))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())  # before the ready line: a stop after it is clean
    print("simulators running; Ctrl-C stops them", flush=True)
    try:
        stop.wait()
    except KeyboardInterrupt:
        pass
    for sim in sims:
        sim.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
