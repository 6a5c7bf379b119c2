"""How far a test has skipped the wall clock forward, in its own process and in those it starts.

An ARM window, an approval's deadline and a stale link are all judged against the wall clock
(``drs_link.store.utc_now``, which every default clock in ``drs_link`` is). A test that checks what
happens after a deadline must get past it: waiting it out cost 5–15 s of wall clock per test, and a
loaded machine stretched the waits on both sides of the deadline. Skipping moves the time every rule
reads; no rule is bypassed, and FIRE checks its window again against the same, skipped, time.

The skip reaches the processes a test starts (``drs …``, ``drs server``, a console), so it cannot be a
monkeypatch, and it must never be switched on by accident in the field. Ways considered:

* the store's simulated clock (``Store.run_clock``): a row in the shared store, read once when a
  process opens it, so a running ``drs server`` would not see a later skip (re-reading it costs a
  query per reading), and anybody who can write the store would move every process's deadlines;
* a command-line option or a configuration key: part of the operator's interface, one wrong line in a
  config file away from frozen ARM windows;
* an environment variable alone: inherited by everything a shell starts, left over from a debugging
  session.

So the skip is the number of seconds in a file that ``DRS_SKIP_CLOCK`` names, honoured only when all
of these hold, and otherwise ignored (the wall clock, which is the safe direction):

1. ``PYTEST_CURRENT_TEST`` is set too. pytest sets it in the environment of every test it runs, and
   children inherit it; drs never sets it and an operator has no reason to.
2. The file is a regular file of this process's user, in a directory of this user with no access for
   group or others (0700): no other account can move this process's deadlines, and a root
   ``drs server`` never reads a clock another login wrote.
3. The number is finite and not negative: time only skips forward.

The file is read again when it changes (its inode, size or mtime), so a running server sees a skip at
its next reading; the test writes it with ``os.replace`` (``tests.clock.SkipClock``).
"""

from __future__ import annotations

import math
import os
import stat

CLOCK_FILE_ENV = "DRS_SKIP_CLOCK"
TEST_MARKER_ENV = "PYTEST_CURRENT_TEST"

_read: tuple[tuple[int, int, int], float] | None = None
"""The last file read: its (inode, size, mtime) and the seconds in it."""


def skipped_seconds() -> float:
    """Seconds to add to the wall clock: 0 unless a test skipped it (see the module's rules)."""
    path = os.environ.get(CLOCK_FILE_ENV)
    if not path or not os.environ.get(TEST_MARKER_ENV):
        return 0.0
    return _seconds_in(path)


def _seconds_in(path: str) -> float:
    global _read
    euid = os.geteuid()
    try:
        folder = os.stat(os.path.dirname(os.path.abspath(path)))
        info = os.stat(path, follow_symlinks=False)
    except OSError:
        return 0.0
    private_folder = folder.st_uid == euid and not stat.S_IMODE(folder.st_mode) & 0o077
    if not (private_folder and stat.S_ISREG(info.st_mode) and info.st_uid == euid):
        return 0.0
    key = (info.st_ino, info.st_size, info.st_mtime_ns)
    if _read is not None and _read[0] == key:
        return _read[1]
    try:
        with open(path, encoding="ascii") as file:
            seconds = float(file.read().strip())
    except (OSError, ValueError, UnicodeDecodeError):
        return 0.0
    if not math.isfinite(seconds) or seconds < 0:
        return 0.0
    _read = (key, seconds)
    return seconds
