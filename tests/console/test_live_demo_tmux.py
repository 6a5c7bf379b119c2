"""`drs demo --live` in a real terminal (tmux), started from another directory as a newcomer would: the LIVE
console from the file it wrote, through ARM, FIRE and the first Iridium report of the descent."""

from __future__ import annotations

import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from console.live_demo import PASSWORD_FILE
from tests.clock import SkipClock
from tests.console.test_end_to_end_tmux import REPO, TMUX, Terminal, arm_drs1

pytestmark = pytest.mark.slow


@pytest.fixture
def terminal(tmp_path: Path, tmux_server: None, skip_clock: SkipClock) -> Iterator[Terminal]:
    """The demo on this test's skip clock: the boot, the Go script and the descent run at the real pace,
    and the test skips through them instead of waiting them out (~80 s of the test's 90 s)."""
    session = f"drs-live-{uuid.uuid4().hex[:8]}"
    drs = REPO / ".venv" / "bin" / "drs"
    command = (
        f"cd {tmp_path} && TMPDIR={tmp_path} {skip_clock.shell_assignments()} {drs} demo --live; sleep 30"
    )
    subprocess.run([TMUX, "new-session", "-d", "-s", session, "-x", "120", "-y", "40", command], check=True)
    try:
        yield Terminal(session)
    finally:
        subprocess.run([TMUX, "kill-session", "-t", session], check=False)


def test_a_newcomer_rehearses_arm_fire_and_sees_the_descents_reports(
    terminal: Terminal, tmp_path: Path, skip_clock: SkipClock
) -> None:
    arm_drs1(terminal, mode="LIVE", booting=skip_clock.skipper(5.0, 30.0))
    assert "DEMO" not in terminal.screen()
    terminal.keys("f")
    terminal.wait_for("Type the capsule's name (DRS1)")
    terminal.keys("DRS1", "Enter", "Enter", "rehearsal, one operator", "Enter")
    # Only once FIRE has passed its checks (the poll it reads would be stale after a skip) and the Go
    # script runs: its window is FIRING then, which a skip of 15 s in all leaves far from stale.
    terminal.wait_for_match(r"FIRING: Go is being sent|FIRED: Go sent", timeout_s=60)
    terminal.wait_for("FIRED: Go sent", timeout_s=60, skip=skip_clock.skipper(1.0, 15.0))
    terminal.back_to_fleet()
    terminal.keys("v")
    terminal.wait_for("DRS1 recovery")
    terminal.wait_for_match(  # the first report of the descent
        r"Last report: .*VBAT", timeout_s=240, skip=skip_clock.skipper(5.0, 600.0)
    )
    [config] = tmp_path.glob("drs-live-demo-*/drs.toml")
    assert str(config.parent) in config.read_text() and (config.parent / PASSWORD_FILE).exists()
