"""An export the operator asked for, written where they chose: atomically, and never over a file by mistake.

Its own small module because the process that writes it is the operator's own (``drs mo export``, a
client of the operations server: the server returns the content, so the file belongs to whoever asked,
issue #29 item 6), while the content comes from rooms a client may not import.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from drs_link.errors import LinkError
from predictor.geofiles import EXPORT_MODE


def write_export(text: str, path: Path, overwrite: bool = False) -> None:
    """``text`` to ``path`` (``-``: standard output), through a ``.part`` file replaced at the end, so a
    failed export leaves any earlier file untouched; an existing file is replaced only with ``overwrite``:
    an export must never silently destroy a track someone saved under the same name."""
    if str(path) == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
        return
    if path.exists() and not overwrite:
        raise LinkError(f"--out {path}: the file exists; choose another name or add --force to replace it")
    if not path.parent.is_dir():
        raise LinkError(f"--out {path}: the directory {path.parent} does not exist")
    temporary = path.with_name(f".{path.name}.part")
    try:
        temporary.unlink(missing_ok=True)
        descriptor = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, EXPORT_MODE)
        with os.fdopen(descriptor, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        os.replace(temporary, path)
    except OSError as exc:
        temporary.unlink(missing_ok=True)
        raise LinkError(f"--out {path}: cannot write ({exc.strerror})") from None
