"""A real ``drs server --private`` process for the server benchmarks (``make bench-fanout``,
``make bench-telemetry``): a fresh configuration with one capsule nobody listens for, in a temporary
directory, the process ended with the ``with``."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


class ServerDidNotStart(Exception):
    """The server's first line was not its ready line."""


@contextlib.contextmanager
def private_server() -> Iterator[tuple[Path, Path]]:
    """The running server's configuration file and socket."""
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        config_path = root / "drs.toml"
        config_path.write_text(f'[operator]\nname = "EL"\n[data]\ndir = "{root / "data"}"\n'
                               '[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\n')  # fmt: skip
        socket_path = root / "drs.sock"
        server = subprocess.Popen(
            [sys.executable, "-m", "console.commands.main", "--config", str(config_path), "server", "--private",
             "--socket", str(socket_path)],
            stdout=subprocess.PIPE, text=True, cwd=REPO,
        )  # fmt: skip
        try:
            assert server.stdout is not None
            ready = server.stdout.readline()
            if "listening" not in ready:
                raise ServerDidNotStart(f"the server did not start: {ready!r}")
            yield config_path, socket_path
        finally:
            server.terminate()
            server.wait(timeout=30)


def p99(sorted_ms: list[float]) -> float:
    return sorted_ms[min(len(sorted_ms) - 1, int(0.99 * len(sorted_ms)))]
