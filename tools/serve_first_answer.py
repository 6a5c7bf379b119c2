"""How long chasemapper waits for its first answer after ``drs serve predictor`` says it is ready
(``make bench-serve``; #31 item 3: 9.2-21.6 s on main, chasemapper gives up after 10 s).

Each run starts a fresh server process on 2024-05-01's DEMO files written as GRIB2 (``--weather``, a
fresh weather cache, so the files are decoded at start as after a new forecast), waits for the ready
line, then times one chasemapper-shaped whole flight over loopback, and ``/health``. It also reports the
start itself (process start to ready line). Figures: median and max of ``RUNS`` runs.
"""

from __future__ import annotations

import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from datetime import UTC, datetime
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DRS = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / ".venv" / "bin" / "drs"
"""The drs to time: this checkout's, or another's given as the argument (a baseline)."""
RUNS = 5
LAUNCH = datetime(2024, 5, 1, 6, tzinfo=UTC)
QUERY = {"launch_latitude": 52.2, "launch_longitude": 359.6, "launch_altitude": 0,
         "launch_datetime": LAUNCH.isoformat(), "ascent_rate": 5.0, "descent_rate": 5.0,
         "burst_altitude": 30000.0, "profile": "standard_profile"}  # fmt: skip


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def one_run(weather: list[Path]) -> tuple[float, float]:
    port = free_port()
    with tempfile.TemporaryDirectory() as cache:
        began = time.monotonic()
        server = subprocess.Popen([str(DRS), "serve", "predictor", "--port", str(port), "--weather",
                                   *map(str, weather), "--cache-dir", cache],
                                  stderr=subprocess.PIPE, text=True)  # fmt: skip
        try:
            assert server.stderr is not None
            for line in server.stderr:
                if "Tawhiri v1 API at" in line:
                    break
            ready = time.monotonic()
            url = f"http://127.0.0.1:{port}/api/v1/?{urllib.parse.urlencode(QUERY)}"
            with urllib.request.urlopen(url, timeout=60) as response:
                json.loads(response.read())
            first = time.monotonic() - ready
        finally:
            server.terminate()
            server.wait(timeout=60)
    return ready - began, first


def main() -> int:
    from predictor.environment.demo_weather import demo_weather_files

    with tempfile.TemporaryDirectory() as files:
        weather = demo_weather_files(52.2, -0.4, LAUNCH, cache_dir=files)
        runs = [one_run(weather) for _ in range(RUNS)]
    starts, firsts = zip(*runs, strict=True)
    print(f"start to ready line: median {statistics.median(starts):.2f} s, max {max(starts):.2f} s")
    print(f"ready line to first answer: median {1000 * statistics.median(firsts):.0f} ms, "
          f"max {1000 * max(firsts):.0f} ms ({RUNS} runs)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
