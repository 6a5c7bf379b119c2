"""Long runs show progress on a terminal and nothing when piped: `drs plan` in a pseudo-terminal and in a
pipe, and the helper itself on both kinds of stream."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import time
from pathlib import Path

from console.commands.progress import progress, while_saying
from tests.console.commands.test_cli_plan import args, grib_files  # noqa: F401  (the fixture, by name)

DRS = "import sys, console.commands.main as c; sys.exit(c.main())"


def in_a_terminal(argv: list[str]) -> tuple[int, str]:
    """Run ``drs argv`` with stdout and stderr on a pseudo-terminal; its exit code and all it wrote."""
    leader, follower = pty.openpty()
    child = subprocess.Popen(
        [sys.executable, "-c", DRS, *argv], stdin=subprocess.DEVNULL, stdout=follower, stderr=follower,
        env={**os.environ, "TERM": "xterm-256color", "COLUMNS": "120"},
    )  # fmt: skip
    os.close(follower)
    said = bytearray()
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        try:
            chunk = os.read(leader, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        said += chunk
    os.close(leader)
    return child.wait(timeout=30), said.decode("utf-8", "replace")


def test_drs_plan_shows_its_stages_on_a_terminal_and_nothing_in_a_pipe(
    grib_files: list[Path],  # noqa: F811
    tmp_path: Path,
) -> None:
    code, shown = in_a_terminal(args(grib_files, tmp_path))
    assert code == 0, shown
    assert "loading weather (3 files)" in shown and "sweeping the release times" in shown
    piped = subprocess.run(
        [sys.executable, "-c", DRS, *args(grib_files, tmp_path)], capture_output=True, text=True, timeout=120
    )
    assert piped.returncode == 0, piped.stderr
    assert "loading weather" not in piped.stderr + piped.stdout and "\x1b[" not in piped.stderr


def test_the_helper_draws_only_on_a_terminal_and_never_when_quiet(tmp_path: Path) -> None:
    leader, follower = pty.openpty()
    with os.fdopen(follower, "w") as terminal, progress(stream=terminal) as tell:
        assert while_saying(tell, "counting sheep", lambda: 42) == 42
        tell("flights", 1, 3)
    assert b"counting sheep" in os.read(leader, 65536)
    os.close(leader)
    with open(tmp_path / "log", "w") as file, progress(stream=file) as tell:
        tell("flights", 1, 3)
    assert (tmp_path / "log").read_text() == ""
    leader, follower = pty.openpty()
    with os.fdopen(follower, "w") as terminal, progress(quiet=True, stream=terminal) as tell:
        tell("flights", 1, 3)
    os.set_blocking(leader, False)
    try:
        written = os.read(leader, 65536)
    except OSError:  # EIO or EAGAIN: the terminal was closed with nothing written to it
        written = b""
    os.close(leader)
    assert written == b""
