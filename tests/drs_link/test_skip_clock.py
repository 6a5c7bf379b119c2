"""A test skips the wall clock of the processes it starts, and nothing else can (``drs_link.skip_clock``).

Each reading is taken in a real child process, as `drs` and `drs server` take theirs; the child's wall
clock is compared with this process's own, read before and after, so a loaded machine only widens the
interval the reading must fall in."""

from __future__ import annotations

import os
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.skip_clock import CLOCK_FILE_ENV, TEST_MARKER_ENV
from tests.clock import SkipClock

READ_ONCE = "from drs_link.store import utc_now; print(utc_now().isoformat())"
READ_EACH_LINE = (
    "import sys\nfrom drs_link.store import utc_now\n"
    "print('ready', flush=True)\n"
    "for _ in sys.stdin:\n    print(utc_now().isoformat(), flush=True)\n"
)


def child_reading(env: dict[str, str] | None = None) -> tuple[datetime, datetime, datetime]:
    """(wall before, the child's utc_now, wall after)."""
    before = datetime.now(UTC)
    out = subprocess.run([sys.executable, "-c", READ_ONCE], check=True, capture_output=True, text=True,
                         env=env if env is not None else dict(os.environ)).stdout  # fmt: skip
    return before, datetime.fromisoformat(out.strip()), datetime.now(UTC)


def skipped_by(seconds: float, reading: tuple[datetime, datetime, datetime]) -> bool:
    before, theirs, after = reading
    return before + timedelta(seconds=seconds) <= theirs <= after + timedelta(seconds=seconds)


def test_a_child_reads_the_wall_clock_skipped_and_a_running_one_sees_a_later_skip(
    skip_clock: SkipClock,
) -> None:
    assert skipped_by(0, child_reading())
    skip_clock.skip(3600)
    assert skipped_by(3600, child_reading())
    running = subprocess.Popen([sys.executable, "-c", READ_EACH_LINE], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)  # fmt: skip
    assert running.stdin is not None and running.stdout is not None
    try:
        assert running.stdout.readline() == "ready\n"
        for more in (0.0, 120.0, 0.5):
            if more:
                skip_clock.skip(more)
            before = datetime.now(UTC)
            running.stdin.write("now?\n")
            running.stdin.flush()
            theirs = datetime.fromisoformat(running.stdout.readline().strip())
            assert skipped_by(skip_clock.seconds, (before, theirs, datetime.now(UTC)))
    finally:
        running.stdin.close()
        running.wait(timeout=60)


def test_without_pytests_marker_the_clock_file_is_ignored(skip_clock: SkipClock) -> None:
    """In the field nobody sets PYTEST_CURRENT_TEST: a DRS_SKIP_CLOCK left in a shell changes nothing."""
    skip_clock.skip(3600)
    env = {name: value for name, value in os.environ.items() if name != TEST_MARKER_ENV}
    assert env[CLOCK_FILE_ENV] == str(skip_clock.path)
    assert skipped_by(0, child_reading(env))


def test_a_clock_file_others_can_reach_or_another_account_wrote_is_ignored(skip_clock: SkipClock) -> None:
    skip_clock.skip(3600)
    folder = skip_clock.path.parent
    folder.chmod(0o750)
    assert skipped_by(0, child_reading()), "a directory the group can enter"
    folder.chmod(0o700)
    assert skipped_by(3600, child_reading())
    if os.geteuid() != 0:
        pytest.skip("giving the file to another account needs root")
    os.chown(skip_clock.path, 65534, 65534)
    assert skipped_by(0, child_reading()), "a file another account owns"


@pytest.mark.parametrize("text", ["-60", "nan", "inf", "soon", ""])
def test_a_clock_file_that_would_turn_time_back_or_is_no_number_is_ignored(
    skip_clock: SkipClock, text: str
) -> None:
    skip_clock.skip(3600)
    skip_clock.path.write_text(text)
    assert skipped_by(0, child_reading())


def test_a_link_to_a_clock_file_is_ignored(skip_clock: SkipClock, tmp_path: Path) -> None:
    """The named file itself must be the user's regular file, not a link to someone else's number."""
    skip_clock.skip(3600)
    link = skip_clock.path.with_name("link")
    link.symlink_to(skip_clock.path)
    env = {**os.environ, CLOCK_FILE_ENV: str(link)}
    assert skipped_by(0, child_reading(env))
