"""Bytes per second the console writes to its terminal (``make bench-bytes``): what an SSH link carries.

Starts ``drs demo --speed 1`` (launch-day pace: the demo's default ×4 ticks every age four times a
second) in a real terminal (tmux, 120×40) and records the terminal's real output stream with ``tmux
pipe-pane``, as a slow link would carry it, in three states an operator sits in:

* the idle fleet screen, once the first predictions are in;
* the release screen of DRS1 with the ARM window open (the countdown ticking);
* recovery during the descent, after FIRE.

``top -d 1`` in the same terminal is the yardstick (issue 17: the idle fleet should write no more).
Each figure is the mean over its window; the README carries them.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DRS = REPO / ".venv" / "bin" / "drs"
TIMEOUT_S = 300.0


class Terminal:
    """One tmux session whose output is piped to a file, byte for byte."""

    def __init__(self, command: str, log: Path) -> None:
        self.session = f"drs-bytes-{uuid.uuid4().hex[:8]}"
        self.log = log
        subprocess.run(
            ["tmux", "new-session", "-d", "-s", self.session, "-x", "120", "-y", "40", command], check=True
        )
        subprocess.run(["tmux", "pipe-pane", "-o", "-t", self.session, f"cat >> {log}"], check=True)

    def screen(self) -> str:
        return subprocess.run(
            ["tmux", "capture-pane", "-p", "-t", self.session], capture_output=True, text=True, check=False
        ).stdout

    def keys(self, *keys: str) -> None:
        for key in keys:
            subprocess.run(["tmux", "send-keys", "-t", self.session, key], check=True)
            time.sleep(0.3)

    def wait_for(self, pattern: str) -> None:
        deadline = time.monotonic() + TIMEOUT_S
        while not re.search(pattern, " ".join(self.screen().split())):
            if time.monotonic() > deadline:
                raise SystemExit(f"console_bytes: {pattern!r} never appeared:\n{self.screen()}")
            time.sleep(0.2)

    def rate(self, seconds: float) -> float:
        """Bytes per second written to the terminal over the next ``seconds``."""
        before = self.log.stat().st_size if self.log.exists() else 0
        time.sleep(seconds)
        return (self.log.stat().st_size - before) / seconds

    def close(self) -> None:
        subprocess.run(["tmux", "kill-session", "-t", self.session], check=False)


def idle_fleet(terminal: Terminal) -> None:
    terminal.wait_for(r"Prediction landing ")


def arm_open(terminal: Terminal) -> None:
    terminal.wait_for(r"UP ")
    terminal.keys("Enter")
    terminal.wait_for(r"Power-on done")
    terminal.keys("s")
    terminal.wait_for(r"✔ GO +Storage sync complete")
    terminal.keys("o")
    terminal.wait_for(r"Software CANNOT switch it off")
    terminal.keys("Tab", "Enter")
    terminal.wait_for(r"Poll: GO")
    terminal.keys("a")
    terminal.wait_for(r"ARMED —")


def recovery_descent(terminal: Terminal) -> None:
    arm_open(terminal)
    terminal.keys("f")
    terminal.wait_for(r"Type the capsule's name \(DRS1\)")
    terminal.keys("DRS1", "Enter", "Enter", "bytes benchmark, one operator", "Enter")
    terminal.wait_for(r"FIRED: Go sent")
    terminal.keys("Escape")
    terminal.wait_for(r"v Recovery")
    terminal.keys("v")
    terminal.wait_for(r"DRS1 recovery")


SCENARIOS: dict[str, tuple[Callable[[Terminal], None], float]] = {
    "idle fleet": (idle_fleet, 60.0),
    "release, ARM open": (arm_open, 20.0),
    "recovery during descent": (recovery_descent, 30.0),
}
"""What to do before measuring, and how long to measure (the ARM window of the demo is 60 s)."""


def measure(command: str, prepare: Callable[[Terminal], None], seconds: float, folder: Path) -> float:
    log = folder / f"{uuid.uuid4().hex}.out"
    terminal = Terminal(command, log)
    try:
        prepare(terminal)
        time.sleep(2.0)  # the transition's own repaint is not the steady state
        return terminal.rate(seconds)
    finally:
        terminal.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--low-bandwidth", action="store_true", help="run the console with --low-bandwidth")
    args = parser.parse_args()
    if shutil.which("tmux") is None:
        print("console_bytes: needs tmux (apt-get install tmux)", file=sys.stderr)
        return 1
    demo = f"{DRS} demo --speed 1" + (" --low-bandwidth" if args.low_bandwidth else "")
    with tempfile.TemporaryDirectory() as folder:
        top = measure("top -d 1", lambda t: t.wait_for(r"load average"), 30.0, Path(folder))
        print(f"top -d 1 (the yardstick): {top / 1000:.2f} kB/s")
        for name, (prepare, seconds) in SCENARIOS.items():
            rate = measure(demo, prepare, seconds, Path(folder))
            print(f"{name}: {rate / 1000:.2f} kB/s ({rate * 8 / 1000:.1f} kbit/s) over {seconds:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
