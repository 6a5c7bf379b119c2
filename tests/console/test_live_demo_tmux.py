"""`drs demo --live` in a real terminal (tmux), started from another directory as a newcomer would: the LIVE
console from the file it wrote, through ARM, FIRE and the first Iridium report of the descent."""

from __future__ import annotations

import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from console.live_demo import PASSWORD_FILE
from tests.console.test_end_to_end_tmux import REPO, TMUX, Terminal, arm_drs1

pytestmark = pytest.mark.slow


@pytest.fixture
def terminal(tmp_path: Path, tmux_server: None) -> Iterator[Terminal]:
    session = f"drs-live-{uuid.uuid4().hex[:8]}"
    command = f"cd {tmp_path} && TMPDIR={tmp_path} {REPO / '.venv' / 'bin' / 'drs'} demo --live; sleep 30"
    subprocess.run([TMUX, "new-session", "-d", "-s", session, "-x", "120", "-y", "40", command], check=True)
    try:
        yield Terminal(session)
    finally:
        subprocess.run([TMUX, "kill-session", "-t", session], check=False)


def test_a_newcomer_rehearses_arm_fire_and_sees_the_descents_reports(
    terminal: Terminal, tmp_path: Path
) -> None:
    arm_drs1(terminal, mode="LIVE")
    assert "DEMO" not in terminal.screen()
    terminal.keys("f")
    terminal.wait_for("Type the capsule's name (DRS1)")
    terminal.keys("DRS1", "Enter", "Enter", "rehearsal, one operator", "Enter")
    terminal.wait_for("FIRED: Go sent", timeout_s=60)
    terminal.back_to_fleet()
    terminal.keys("v")
    terminal.wait_for("DRS1 recovery")
    terminal.wait_for_match(r"Last report: .*VBAT", timeout_s=240)  # the first report of the descent
    [config] = tmp_path.glob("drs-live-demo-*/drs.toml")
    assert str(config.parent) in config.read_text() and (config.parent / PASSWORD_FILE).exists()
