"""Clocks a test sets and advances: the code under test must only ever ask them the time."""

from __future__ import annotations

import os
import shlex
from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.skip_clock import CLOCK_FILE_ENV, TEST_MARKER_ENV, skipped_seconds


class ManualClock:
    def __init__(self, now: datetime) -> None:
        self.now = now

    def __call__(self) -> datetime:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += timedelta(seconds=seconds)


class SkipClock:
    """The wall clock of this test's process and every process it starts, skipped forward on demand.

    ``drs_link.skip_clock`` honours the file only under pytest, in a 0700 directory of this user; the
    environment variable is set for the test's own process (``monkeypatch``) and so inherited by every
    ``drs`` and ``drs server`` it starts from then on (a private server started before it is not)."""

    def __init__(self, directory: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        directory.chmod(0o700)
        self.path = directory / "skipped-seconds"
        self.seconds = 0.0
        self._write()
        monkeypatch.setenv(CLOCK_FILE_ENV, str(self.path))

    def skip(self, seconds: float) -> None:
        """Move every reading of the wall clock ``seconds`` forward, at once and for good."""
        if seconds <= 0:
            raise ValueError("the clock only skips forward")
        self.seconds += seconds
        self._write()
        assert skipped_seconds() == self.seconds, "drs_link.skip_clock refused the test's clock file"

    def skipper(self, step_s: float, most_s: float) -> Callable[[], None]:
        """A function that skips ``step_s`` a call, ``most_s`` in all: for a wait that only time ends (a
        boot, a Go script, a descent), called between two looks at what is waited for."""
        left = [most_s]

        def skip() -> None:
            step = min(step_s, left[0])
            if step > 0:
                left[0] -= step
                self.skip(step)

        return skip

    def shell_assignments(self) -> str:
        """The variables as shell words, for a command another program starts in an environment of its own
        (tmux starts a session's command in its server's)."""
        return " ".join(
            f"{name}={shlex.quote(os.environ[name])}" for name in (CLOCK_FILE_ENV, TEST_MARKER_ENV)
        )

    def _write(self) -> None:
        spare = self.path.with_name(self.path.name + ".new")
        spare.write_text(repr(self.seconds), encoding="ascii")
        os.replace(spare, self.path)
