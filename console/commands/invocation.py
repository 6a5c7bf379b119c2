"""How to run `drs` again from a fresh shell, for the lines that tell an operator what to type next.

`make demo` installs `drs` into the repository's `.venv`, which a fresh shell does not have on its PATH:
a printed `drs console --replay …` then answered "command not found". The command is named as this
process can prove it runs: plain `drs` when the PATH finds this very installation, else the absolute
path of the `drs` next to this interpreter (works from any directory), else `python -m` with it.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


def drs_command(path: str | None = None) -> str:
    """The words that start this installation's `drs` in a fresh shell whose PATH is ``path`` ($PATH)."""
    installed = Path(sys.executable).parent / "drs"
    if not installed.is_file():
        return f"{sys.executable} -m console.commands.main"
    found = shutil.which("drs", path=os.environ.get("PATH", "") if path is None else path)
    if found is not None and Path(found).resolve() == installed.resolve():
        return "drs"
    return str(installed.absolute())
