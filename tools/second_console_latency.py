"""How soon a console shows what another process wrote to the server's store (``make bench-consoles``).

A console runs (headless, Textual's test driver) on a store; another process, as a second console
would, writes an audit row through ``drs_link.store`` and prints when it committed. The figure is the
time from that commit to the first console's notice naming it, over ten writes (issue 17: ≤ 1 s).
"""

from __future__ import annotations

import asyncio
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from tests.console.test_sessions import live_console  # noqa: E402 - the repository's own console setup

WRITES = 10
OTHER = (
    "import sys, time; from drs_link.config import load_config; from drs_link.store import Store; "
    "c = load_config(sys.argv[1]); Store.open(c.store_path).append_audit('JM', 'DRS2', 'waiver', 'granted', "
    "{'write': int(sys.argv[2])}); print(time.time())"
)


async def measure(folder: Path) -> list[float]:
    app = live_console(folder)
    config = folder / "other.toml"
    config.write_text(f'[operator]\nname = "JM"\n[data]\ndir = "{folder / "data"}"\n'
                      '[[capsule]]\nname = "DRS2"\nhost = "127.0.0.1"\nport = 9\n')  # fmt: skip
    latencies = []
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(1.0)
        for write in range(WRITES):
            out = subprocess.run([sys.executable, "-c", OTHER, str(config), str(write)],
                                 capture_output=True, text=True, check=True).stdout  # fmt: skip
            committed = float(out.strip())
            while sum("waiver granted — JM" in n.message for n in app._notifications) <= write:
                await pilot.pause(0.01)
            latencies.append(time.time() - committed)
        await pilot.press("q", "tab", "enter")
    return latencies


def main() -> int:
    with tempfile.TemporaryDirectory() as folder:
        latencies = asyncio.run(measure(Path(folder)))
    print(
        f"a second process's write shown on the console: median {statistics.median(latencies):.2f} s, "
        f"max {max(latencies):.2f} s over {len(latencies)} writes"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
