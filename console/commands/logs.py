"""Logging for every `drs` command: one line per record, UTC time, level, logger, message, then fields.

Fields passed as ``extra={...}`` are written as ``key=value`` (logfmt), so a receiver running for
weeks under systemd can be searched by client, status or IMEI with journalctl and grep, or loaded
by a log shipper, without parsing English. Records go to stderr: stdout stays the command's output.

Libraries' own records (paramiko logs ERROR for a connection reset the link then reports as one
line) are shown only at debug level: below that an operator sees each failure once, in our words.
"""

from __future__ import annotations

import json
import logging
import sys
import time

LEVELS = ("debug", "info", "warning", "error")
OUR_PACKAGES = ("console", "drs_link", "predictor")
_STANDARD = frozenset(logging.LogRecord("", 0, "", 0, "", (), None).__dict__) | {
    "message",
    "asctime",
    "taskName",
}


def _value(value: object) -> str:
    text = str(value)
    if not text or any(c in text for c in ' "=\\') or not text.isprintable():
        return json.dumps(
            text, ensure_ascii=False
        )  # quoted, with newlines and quotes escaped: one record, one line
    return text


class LogfmtFormatter(logging.Formatter):
    """``2026-11-25T06:30:00.123Z INFO drs_link.iridium.webhook: POST … client=… status=200``."""

    converter = staticmethod(time.gmtime)

    def format(self, record: logging.LogRecord) -> str:
        moment = self.formatTime(record, "%Y-%m-%dT%H:%M:%S") + f".{int(record.msecs):03d}Z"
        line = f"{moment} {record.levelname} {record.name}: {record.getMessage()}"
        fields = {k: v for k, v in record.__dict__.items() if k not in _STANDARD and not k.startswith("_")}
        if fields:
            line += " " + " ".join(f"{key}={_value(value)}" for key, value in fields.items())
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


class _DrsHandler(logging.StreamHandler):
    """Ours, so a second `drs` run in one process (the tests) replaces it and leaves others' handlers be.

    It writes to whatever ``sys.stderr`` is when a record comes, as Python's last-resort handler does: a
    stream fixed at the run's start may since have been closed (a test's capture) or replaced.
    """

    @property
    def stream(self) -> object:
        return sys.stderr

    @stream.setter
    def stream(self, _stream: object) -> None:
        """StreamHandler sets it; the property already answers with the current stderr."""


def _ours(record: logging.LogRecord) -> bool:
    return record.name.split(".", 1)[0] in OUR_PACKAGES


def configure_logging(level: int) -> None:
    """Send records at ``level`` and above to stderr (the stream of this moment); libraries' only at debug."""
    root = logging.getLogger()
    for old in [h for h in root.handlers if isinstance(h, _DrsHandler)]:
        root.removeHandler(old)
    handler = _DrsHandler()
    handler.setFormatter(LogfmtFormatter())
    if level > logging.DEBUG:
        handler.addFilter(_ours)
    root.addHandler(handler)
    root.setLevel(level)


def level_from(name: str | None, verbose: int, default: int) -> int:
    """``--log-level`` when given; otherwise each ``-v`` lowers the command's default by one step."""
    if name is not None:
        return int(getattr(logging, name.upper()))
    return max(logging.DEBUG, default - 10 * verbose)
