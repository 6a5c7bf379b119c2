"""`drs demo` in a real terminal (tmux), driven by keys through a release and recovery of one capsule.

Everything is the shipped path: the `drs` entry point, the SSH simulators, the simulated RockBLOCK
posting webhooks to the console's receiver, predictions on demo weather. Only what a person sees
(capture-pane) is asserted. The demo runs at 60× so the ~45 min descent takes under a minute.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from drs_link.store import Store
from tests.clock import SkipClock

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
TMUX = shutil.which("tmux") or "/usr/bin/tmux"


class Terminal:
    def __init__(self, session: str) -> None:
        self.session = session

    def keys(self, *keys: str, pause_s: float = 0.25) -> None:
        """One key (or literal text) at a time, as a person types: bursts can merge into one read."""
        for key in keys:
            subprocess.run([TMUX, "send-keys", "-t", self.session, key], check=True)
            time.sleep(pause_s)

    def back_to_fleet(self) -> None:
        """Escape, then wait until the fleet is shown before anything else is typed.

        A key sent while the app is busy can arrive in the same read as the ESC before it, and a
        terminal reads ESC + key as Alt+key: both would be lost. Only the fleet's footer offers
        `v Recovery`.
        """
        self.keys("Escape")
        self.wait_for("v Recovery")

    def press_until(self, key: str, text: str, attempts: int, timeout_s: float) -> str:
        """Press ``key`` until ``text`` shows, as an operator presses again after nothing happened; the
        screen once it does. ``attempts`` presses that each waited ``timeout_s`` in vain are a failure."""
        for _ in range(attempts):
            self.keys(key)
            try:
                return self.wait_for(text, timeout_s=timeout_s)
            except AssertionError:
                continue
        raise AssertionError(f"{key} pressed {attempts} times, {text!r} never appeared:\n{self.screen()}")

    def screen(self) -> str:
        return subprocess.run(
            [TMUX, "capture-pane", "-p", "-t", self.session], check=True, capture_output=True, text=True
        ).stdout

    def wait_for(self, text: str, timeout_s: float = 120.0, skip: Callable[[], None] | None = None) -> str:
        return self.wait_for_match(re.escape(text), timeout_s, skip)

    def wait_for_match(
        self, pattern: str, timeout_s: float = 120.0, skip: Callable[[], None] | None = None
    ) -> str:
        """The screen once ``pattern`` (a regular expression) matches it; column spacing is layout's business.

        ``skip``: called between two looks at the screen, to move the demo's clock on (``SkipClock``)
        where only time stands between the screen and the state (a boot, a Go script, a descent)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            shown = self.screen()
            if re.search(pattern, shown):
                return shown
            if skip is not None:
                skip()
            time.sleep(0.2)
        raise AssertionError(f"{pattern!r} never appeared; the terminal shows:\n{self.screen()}")

    def wait_for_absence(self, pattern: str, timeout_s: float = 30.0) -> None:
        """Until ``pattern`` is off the screen (a notice timing out), so the next match is a new one."""
        deadline = time.monotonic() + timeout_s
        while re.search(pattern, self.screen()):
            if time.monotonic() > deadline:
                raise AssertionError(f"{pattern!r} stayed on screen:\n{self.screen()}")
            time.sleep(0.2)


def queue_parachute(terminal: Terminal, attempts: int = 6) -> str:
    """Queue PARACHUTE as an operator does at 60×: plan, confirm, and plan again when refused.

    The plan's queue-before deadline is at most one report interval ahead (2 min: 2 s at 60×) and is
    checked again at submit, so typing the confirmation can outlast it. The product then refuses
    ("…passed while the dialog was open; plan the time again"), which is the behaviour this test must
    not mistake for a failure; six refusals in a row would be.
    """
    refusal = r"PARACHUTE refused"  # a notice; the dialog itself may say a late send "will be refused"
    for _ in range(attempts):
        terminal.wait_for_absence(refusal)
        terminal.keys("c")
        shown = terminal.wait_for_match(rf"Type the capsule's name \(DRS1\)|{refusal}")
        if re.search(refusal, shown):
            continue
        terminal.keys("DRS1", "Enter", "Enter", "alone at the landing site", "Enter", pause_s=0.15)
        shown = terminal.wait_for_match(rf"delivered\?|{refusal}")
        if "delivered?" in shown:
            return shown
    raise AssertionError(f"PARACHUTE was refused {attempts} times in a row:\n{terminal.screen()}")


@pytest.fixture
def terminal(tmp_path: Path, tmux_server: None, skip_clock: SkipClock) -> Iterator[Terminal]:
    """``drs demo --speed 60`` on this test's skip clock (``SkipClock``)."""
    session = f"drs-e2e-{uuid.uuid4().hex[:8]}"
    log = tmp_path / "after-exit.txt"
    command = (
        f"cd {REPO} && TMPDIR={tmp_path} {skip_clock.shell_assignments()} .venv/bin/drs demo --speed 60; "
        f"echo EXITED $? > {log}; sleep 30"
    )
    subprocess.run([TMUX, "new-session", "-d", "-s", session, "-x", "120", "-y", "40", command], check=True)
    try:
        yield Terminal(session)
    finally:
        subprocess.run([TMUX, "kill-session", "-t", session], check=False)


def arm_drs1(terminal: Terminal, mode: str = "DEMO", booting: Callable[[], None] | None = None) -> None:
    """From the start of the demo (``drs demo --live``: mode LIVE) to DRS1's open ARM window, by keys;
    ``booting`` is called while the capsule boots (a skip of the clock, ``SkipClock.skipper``)."""
    terminal.wait_for("DRS3", timeout_s=180)
    terminal.wait_for(mode)  # the title line can be painted after the fleet's rows (seen once)
    terminal.wait_for("UP ")
    terminal.keys("Enter")
    terminal.wait_for("Release day (2/4) — DRS1")
    terminal.wait_for("Power-on done")
    terminal.keys("s")
    terminal.wait_for_match(r"✔ GO +Storage sync complete")
    terminal.keys("o")
    terminal.wait_for("Software CANNOT switch it off")
    terminal.keys("Tab", "Enter")
    terminal.wait_for("NMEA arriving")
    terminal.wait_for("Poll: GO", skip=booting)
    terminal.keys("f")
    assert "Type the capsule's name" not in terminal.screen()
    arm(terminal)


def arm(terminal: Terminal) -> None:
    """Press ARM as an operator does, again after a refusal. At 60× the poll's 20 s freshness limits are
    a third of a real second: on a starved machine (a loaded CI) a poll goes stale between two looks and
    ARM is refused or the window closes, as it must; five refusals in a row would be a failure."""
    terminal.press_until("a", "ARMED —", attempts=5, timeout_s=20.0)


def fire(terminal: Terminal, attempts: int = 4) -> None:
    """FIRE from an open window, typing the name; when the window closed first (a stale poll at 60×,
    ``arm``), ARM again and FIRE again."""
    for _ in range(attempts):
        terminal.keys("f")
        shown = terminal.wait_for_match(r"Type the capsule's name \(DRS1\)|○ DISARMED")
        if "Type the capsule's name" in shown:
            terminal.keys("DRS1", "Enter", "Enter", "end-to-end test, one operator", "Enter")
            shown = terminal.wait_for_match(r"FIRED: Go sent|○ DISARMED")
            if "FIRED: Go sent" in shown:
                return
        time.sleep(2.0)  # a FIRED painted just after the window's close is not a refusal
        if "FIRED: Go sent" in terminal.screen():
            return
        if "○ DISARMED" in terminal.screen():
            arm(terminal)
    raise AssertionError(f"FIRE did not go in {attempts} tries:\n{terminal.screen()}")


def test_a_capsule_is_released_and_recovered_in_the_demo(
    terminal: Terminal, tmp_path: Path, skip_clock: SkipClock
) -> None:
    arm_drs1(terminal)
    fire(terminal)
    terminal.back_to_fleet()
    terminal.wait_for("RELEASED")
    terminal.keys("v")
    terminal.wait_for("DRS1 recovery")
    # The descent (~45 min, 45 s at 60×) is skipped through at 1 s (a minute of the demo) a look.
    shown = terminal.wait_for("Landed ", timeout_s=240, skip=skip_clock.skipper(1.0, 120.0))
    assert "from the team" in shown
    terminal.keys("i")
    terminal.wait_for("Reports (MO)")
    shown = queue_parachute(terminal)
    assert "[PARACHUTE=" in shown
    terminal.keys("Escape")
    terminal.wait_for("Phone: DRS1 on ground")
    terminal.keys("e")
    terminal.wait_for("DRS1-recovery-")
    terminal.back_to_fleet()
    terminal.keys("h")
    terminal.wait_for("released, Pi shut")
    # The search box has the focus: ↓ moves to the entries, where q quits. ↓'s binding runs once the key
    # has bubbled back to the app, so a q typed before that still reaches the search box (CI under load,
    # 2026-12-03). The footer offers `e Export` only once the entries have the focus: the search box
    # would take the e. Once (a quiet fresh clone, 2026-12-03 evening) a ↓ left the search box focused
    # for 120 s, cause not found; an operator presses ↓ again, and so does this test.
    terminal.press_until("Down", "e Export", attempts=5, timeout_s=15.0)
    terminal.keys("q")
    terminal.wait_for("Quit the DRS console?")
    terminal.keys("Tab", "Enter")
    deadline = time.monotonic() + 20
    while not (tmp_path / "after-exit.txt").exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert (tmp_path / "after-exit.txt").read_text().strip() == "EXITED 0"
    exports = list(tmp_path.glob("drs-demo-*/exports/DRS1-recovery-*.gpx"))
    assert len(exports) == 1 and "<trkpt" in exports[0].read_text()
    store = Store.open(next(tmp_path.glob("drs-demo-*/data/drs.sqlite")))
    audit = [(a.action, a.result) for a in store.audit("DRS1")]
    assert ("fire", "authorised") in audit and ("mt.queued", "queued") in audit
    assert [r for r in store.audit("DRS1", text="single_operator_waiver") if r.action == "fire"]


def test_a_dropped_terminal_disarms_on_the_record(terminal: Terminal, tmp_path: Path) -> None:
    # The SSH session dies under the console: the terminal hangs up (SIGHUP), nobody is there to ask.
    arm_drs1(terminal)
    subprocess.run([TMUX, "kill-session", "-t", terminal.session], check=True)
    store = Store.open(next(tmp_path.glob("drs-demo-*/data/drs.sqlite")))
    deadline = time.monotonic() + 30
    while not [a for a in store.audit() if a.action == "session.lost"] and time.monotonic() < deadline:
        time.sleep(0.2)
    [lost] = [a for a in store.audit() if a.action == "session.lost"]
    assert lost.detail == {"signal": "SIGHUP", "disarmed": ["DRS1"], "go_in_flight": []}
    assert ("disarm", "session lost (SIGHUP)") in [(a.action, a.result) for a in store.audit("DRS1")]
    deadline = time.monotonic() + 30
    while holders(store.path) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not holders(store.path), "the console ended: nothing holds its store any more"


def holders(path: Path) -> list[int]:
    """Processes other than this one with ``path`` open (Linux /proc)."""
    found = []
    for fd_dir in Path("/proc").glob("[0-9]*/fd"):
        if fd_dir.parent.name == str(os.getpid()):
            continue
        try:
            if any(os.readlink(fd) == str(path) for fd in fd_dir.iterdir()):
                found.append(int(fd_dir.parent.name))
        except OSError:
            continue
    return found
