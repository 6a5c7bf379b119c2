"""Where an export goes: a file, or standard output when the path is ``-``.

``-`` lets an export feed a pipe (``drs predict --geojson - | ogr2ogr ...``) as Unix tools do. Only
one output can own standard output at a time, and the human summary then moves to standard error
so that the piped document stays parseable.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from predictor.errors import PredictorError, UsageError

STDOUT = "-"
EXPORT_MODE = 0o640
"""Exports are created for the owner and its group, never for everyone: a track or a landing says where
a capsule lies. The umask may take more away, never add."""


def is_stdout(path: str | Path | bool | None) -> bool:
    return isinstance(path, str | Path) and str(path) == STDOUT


def piped(**outputs: str | Path | bool | None) -> bool:
    """Whether an output file option (name → value) is ``-``, so the summary must go to standard error.

    A ``True`` value is an option that prints its document to standard output (``--json``): it
    claims standard output too, and two claimants would interleave, so that is refused.
    """
    claims = [name for name, value in outputs.items() if value is True or is_stdout(value)]
    if len(claims) > 1:
        options = " and ".join(f"--{name}" for name in claims)
        raise UsageError(f"{options} all ask for standard output: only one output can be '-'")
    return any(is_stdout(value) for value in outputs.values())


def write_text(path: str | Path, text: str, what: str) -> Path:
    """Write ``text`` to ``path`` (created ``EXPORT_MODE``), or to standard output when ``path`` is ``-``."""
    out = Path(path)
    if is_stdout(path):
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        sys.stdout.flush()
        return out
    try:
        with os.fdopen(
            os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, EXPORT_MODE), "w", encoding="utf-8"
        ) as f:
            f.write(text)
    except OSError as exc:
        raise PredictorError(f"cannot write the {what} file {out}: {exc.strerror or exc}") from None
    return out
