"""Whole-process latency a person feels at the console (``make bench-console``).

Starts ``drs demo`` in a real terminal (tmux, 120×40), as an operator would, and reads the screen
every 50 ms: the time from launch to the first screen, and from the first screen to DRS1's first
predicted landing in the fleet view. Warm means the numba cache and the demo weather already exist
(the first run of a machine fills them); the figure is the median of the runs.
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
import sys
import time
import uuid
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DRS = REPO / ".venv" / "bin" / "drs"
RUNS = 5
TIMEOUT_S = 300.0


def screen(session: str) -> str:
    return subprocess.run(
        ["tmux", "capture-pane", "-p", "-t", session], capture_output=True, text=True, check=False
    ).stdout


def one_run() -> tuple[float, float]:
    session = f"drs-latency-{uuid.uuid4().hex[:8]}"
    start = time.monotonic()
    subprocess.run(
        ["tmux", "new-session", "-d", "-s", session, "-x", "120", "-y", "40", f"{DRS} demo"], check=True
    )
    try:
        first_screen = first_prediction = None
        while time.monotonic() - start < TIMEOUT_S:
            shown = screen(session)
            now = time.monotonic() - start
            if first_screen is None and "DRS3" in shown:
                first_screen = now
            if first_screen is not None and "Prediction landing " in " ".join(shown.split()):
                first_prediction = now
                break
            time.sleep(0.05)
        if first_screen is None or first_prediction is None:
            raise SystemExit(f"console_latency: no prediction within {TIMEOUT_S:.0f} s:\n{screen(session)}")
        return first_screen, first_prediction - first_screen
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], check=False)


def main() -> int:
    if shutil.which("tmux") is None:
        print("console_latency: needs tmux (apt-get install tmux)", file=sys.stderr)
        return 1
    keeper = f"drs-latency-keeper-{uuid.uuid4().hex[:8]}"  # one tmux server for every run
    subprocess.run(["tmux", "new-session", "-d", "-s", keeper, "sleep 3600"], check=True)
    try:
        one_run()  # the numba cache and the demo weather, once
        runs = [one_run() for _ in range(RUNS)]
    finally:
        subprocess.run(["tmux", "kill-session", "-t", keeper], check=False)
    screens, predictions = zip(*runs, strict=True)
    print(f"drs demo, warm, 120×40, {RUNS} runs:")
    print(
        f"  launch → first screen:              median {statistics.median(screens):.2f} s "
        f"(min {min(screens):.2f}, max {max(screens):.2f})"
    )
    print(
        f"  first screen → first prediction:    median {statistics.median(predictions):.2f} s "
        f"(min {min(predictions):.2f}, max {max(predictions):.2f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
