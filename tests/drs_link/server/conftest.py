"""The team the server's tests run with: real accounts in a real group, and a directory they can all enter."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.drs_link.server.team import Team


@pytest.fixture
def team() -> Iterator[Team]:
    tag = f"{os.getpid() % 100000}"
    group = f"drsteam{tag}"
    names = [f"drsal{tag}", f"drsbo{tag}", f"drsma{tag}", f"drsou{tag}"]
    subprocess.run(["groupadd", group], check=True)
    try:
        for name in names[:3]:
            subprocess.run(["useradd", "-M", "-N", "-G", group, "-s", "/usr/sbin/nologin", name], check=True)
        subprocess.run(["useradd", "-M", "-N", "-s", "/usr/sbin/nologin", names[3]], check=True)
        yield Team(group, *names)
    finally:
        for name in names:
            subprocess.run(["userdel", name], check=False, capture_output=True)
        subprocess.run(["groupdel", group], check=False, capture_output=True)


@pytest.fixture
def place() -> Iterator[Path]:
    """A directory every account can enter (pytest's tmp_path is 0700)."""
    path = Path(tempfile.mkdtemp(prefix="drs-team-"))
    path.chmod(0o755)
    yield path
    shutil.rmtree(path, ignore_errors=True)
