"""Every shell command the console sends to a capsule's Pi, as fixed templates.

Nothing an operator types reaches the Pi's shell unquoted: each template takes typed values and
``shlex.quote``s every one. Each command starts with a no-op label (``: drs:power-on 'arg' …;``)
that the shell ignores; it names the step in sshd logs and lets the capsule simulator recognise
the command and its arguments without re-implementing a shell.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass

SERIAL_LOG_NAME = "DRS_serial_log.txt"
# Relative to tools_dir (every stock-script command runs there): one lock per capsule, owned by pi.
AUTHORITY_LOCK = ".drs-release.lock"
AUTHORITY_OWNER = ".drs-release.owner"
LOG_OFFSET_MARKER = "drs-log-offset"
MAX_LOG_BYTES = 65536
HOLDER_RE = re.compile(r"^[A-Za-z0-9@._:+-]{1,96}$")
_EPOCH_RE = re.compile(r"^[0-9]{1,11}$")

EXIT_AUTHORITY_HELD = 75
EXIT_AUTHORITY_CHANGED = 76
EXIT_NO_AUTHORITY = 77
EXIT_NO_TOOLS = 66
AUTHORITY_MARKER = "drs-authority"
_NO_AUTHORITY_MESSAGE = "echo 'drs: this console holds no release authority: run power-on first'"


@dataclass(frozen=True)
class RemoteCommand:
    label: str
    args: tuple[str, ...]
    script: str

    @property
    def text(self) -> str:
        words = [":", f"drs:{self.label}", *(shlex.quote(a) for a in self.args)]
        return f"{' '.join(words)}; {self.script}"


def parse_label(text: str) -> tuple[str, tuple[str, ...]] | None:
    """The label and arguments of a command built here, or None for anything else.

    The label part ends at the first ``; `` whose prefix is exactly a sequence of quoted words, so
    a ``;`` inside a quoted argument can never end it early.
    """
    start = 0
    while (end := text.find("; ", start)) >= 0:
        prefix = text[:end]
        start = end + 1
        try:
            words = shlex.split(prefix)
        except ValueError:
            continue
        if " ".join([*words[:2], *(shlex.quote(w) for w in words[2:])]) != prefix:
            continue
        if len(words) < 2 or words[0] != ":" or not words[1].startswith("drs:"):
            return None
        return words[1].removeprefix("drs:"), tuple(words[2:])
    return None


def check_holder(holder: str) -> str:
    if not HOLDER_RE.match(holder):
        raise ValueError(f"release-authority holder {holder!r} must match {HOLDER_RE.pattern}")
    return holder


def _read_owner(shared: bool = False) -> str:
    """Lock fd 9 and read the owner file into ``held_by`` and ``lease_end`` (epoch s), ``now`` likewise.

    Every reader and writer of the owner file holds this ``flock``, so none ever sees it half
    written; readers share it. A lease end that is not a number reads as 0 (expired), so a damaged
    owner file can never hold the authority forever.
    """
    lock, owner = (shlex.quote(x) for x in (AUTHORITY_LOCK, AUTHORITY_OWNER))
    mode = "-s " if shared else ""
    return (
        f"exec 9>>{lock} || exit {EXIT_AUTHORITY_HELD}; "
        f"flock {mode}-w 5 9 || "
        f"{{ echo 'drs: the release-authority lock is busy' >&2; exit {EXIT_AUTHORITY_HELD}; }}; "
        f"now=$(date +%s); held_by=''; lease_end=0; "
        f"if [ -s {owner} ]; then read -r held_by lease_end < {owner}; fi; "
        f"case $lease_end in ''|*[!0-9]*) lease_end=0;; esac"
    )


_REPORT_OWNER = f'printf \'%s %s %s %s\\n\' {AUTHORITY_MARKER} "$now" "$lease_end" "$held_by"'


def _authority_prelude(holder: str) -> str:
    """Take the Pi-side lock that makes the power-on → go window exclusive to one console.

    ``flock`` makes the check-and-set of the owner file atomic; the owner file (holder and lease
    expiry) is what persists between the separate SSH commands of one release.
    """
    return (
        f"{_read_owner()}; "
        f'if [ -n "$held_by" ] && [ "$held_by" != {shlex.quote(holder)} ] && [ "$lease_end" -gt "$now" ]; then '
        f'echo "drs: release authority is held by $held_by" >&2; exit {EXIT_AUTHORITY_HELD}; fi'
    )


def _claim_authority(tools_dir: str, holder: str, lease_s: int) -> str:
    """Enter tools_dir and take (or renew) the release authority for ``lease_s`` seconds."""
    check_holder(holder)
    q = shlex.quote
    return (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; "
        f"{_authority_prelude(holder)}; "
        f"echo {q(holder)} $((now + {lease_s})) > {q(AUTHORITY_OWNER)}"
    )


def power_on(tools_dir: str, python: str, holder: str, lease_s: float) -> RemoteCommand:
    lease = int(lease_s)
    q = shlex.quote
    script = (
        f"{_claim_authority(tools_dir, holder, lease)}; "
        f"echo {LOG_OFFSET_MARKER} $(stat -c %s {q(SERIAL_LOG_NAME)} 2>/dev/null || echo 0); "
        f"{q(python)} DRS_on.py"
    )
    return RemoteCommand("power-on", (tools_dir, python, holder, str(lease)), script)


def log_offset(power_on_output: str) -> int:
    """Where the serial log ended before power-on (the ``drs-log-offset N`` line), 0 if absent.

    Reading NMEA from that offset on shows only what the microcontroller said since this power-on.
    """
    offset = 0
    for line in power_on_output.splitlines():
        if line.startswith(LOG_OFFSET_MARKER + " "):
            offset = int(line.split()[1])
    return offset


def read_serial(tools_dir: str, python: str, offset: int) -> RemoteCommand:
    """Capture NMEA with the stock logger, then print what the log gained since ``offset``."""
    q = shlex.quote
    start = max(int(offset), 0) + 1
    script = (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; "
        f"{q(python)} DRS_log_serial.py > /dev/null || exit $?; "
        f"tail -c +{start} {q(SERIAL_LOG_NAME)} 2>/dev/null | tail -c {MAX_LOG_BYTES}"
    )
    return RemoteCommand("read-serial", (tools_dir, python, str(int(offset))), script)


def _as_holder(tools_dir: str, holder: str, command: str) -> str:
    """Enter tools_dir and run ``command`` only if ``holder`` holds the release authority (with the lock
    on fd 9 kept open until the command ends): the one guard every Go runs behind."""
    check_holder(holder)
    q = shlex.quote
    return (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; "
        f"{_authority_prelude(holder)}; "
        f'if [ "$held_by" != {q(holder)} ]; then '
        f"{_NO_AUTHORITY_MESSAGE} >&2; exit {EXIT_NO_AUTHORITY}; fi; "
        f"{command}"
    )


def go(tools_dir: str, python: str, holder: str) -> RemoteCommand:
    """Run the stock Go script while holding the authority lock (fd 9 stays open until shutdown)."""
    script = _as_holder(tools_dir, holder, f"{shlex.quote(python)} DRS_GoGoGo.py")
    return RemoteCommand("go", (tools_dir, python, holder), script)


def authority(tools_dir: str) -> RemoteCommand:
    """Print who holds the release authority (one ``drs-authority`` line); changes nothing."""
    script = (
        f"cd {shlex.quote(tools_dir)} || exit {EXIT_NO_TOOLS}; {_read_owner(shared=True)}; {_REPORT_OWNER}"
    )
    return RemoteCommand("authority", (tools_dir,), script)


def authority_take_over(
    tools_dir: str, holder: str, expected_holder: str, expected_lease_end: int, lease_s: float
) -> RemoteCommand:
    """Make ``holder`` the owner for a fresh lease, only if the owner file still says what the operator saw.

    The comparison and the write happen under one exclusive ``flock``, so a console that renewed or
    took over in between is never overwritten. ``expected_holder`` is "" when the authority was
    free. On a mismatch the current owner is printed and the command exits ``EXIT_AUTHORITY_CHANGED``.
    """
    check_holder(holder)
    if expected_holder:
        check_holder(expected_holder)
    expected_end, lease = int(expected_lease_end), int(lease_s)
    if expected_end < 0 or lease <= 0:
        raise ValueError(f"lease end {expected_end} must not be negative, lease {lease} s must be positive")
    q = shlex.quote
    script = (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; "
        f"{_read_owner()}; "
        f'if [ "$held_by" != {q(expected_holder)} ] || [ "$lease_end" -ne {expected_end} ]; then '
        f"{_REPORT_OWNER}; echo 'drs: the release authority changed since it was shown' >&2; "
        f"exit {EXIT_AUTHORITY_CHANGED}; fi; "
        f"held_by={q(holder)}; lease_end=$((now + {lease})); "
        f'echo "$held_by $lease_end" > {q(AUTHORITY_OWNER)} || exit 1; '
        f"{_REPORT_OWNER}"
    )
    return RemoteCommand(
        "authority-take-over", (tools_dir, holder, expected_holder, str(expected_end), str(lease)), script
    )


def authority_release(tools_dir: str, holder: str) -> RemoteCommand:
    """Give up ``holder``'s release authority; prints the owner as it was, refuses another console's."""
    check_holder(holder)
    q = shlex.quote
    script = (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; "
        f"{_read_owner()}; "
        f'if [ -n "$held_by" ] && [ "$held_by" != {q(holder)} ]; then '
        f'echo "drs: the release authority belongs to $held_by, not to this console" >&2; '
        f"exit {EXIT_AUTHORITY_HELD}; fi; "
        f"{_REPORT_OWNER}; "
        f'if [ -n "$held_by" ]; then : > {q(AUTHORITY_OWNER)} || exit 1; fi'
    )
    return RemoteCommand("authority-release", (tools_dir, holder), script)


def authority_report(output: str) -> tuple[int, int, str] | None:
    """The Pi's clock, the lease end (both epoch s) and the holder ("" when free), from the marker line.

    None when the output carries no well-formed marker line (not this command's output).
    """
    for line in output.splitlines():
        words = line.split()
        if words[:1] == [AUTHORITY_MARKER] and len(words) in (3, 4) and all(map(_EPOCH_RE.match, words[1:3])):
            return int(words[1]), int(words[2]), words[3] if len(words) == 4 else ""
    return None


AGENT_NAME = "drs_agent.py"
EXIT_AGENT_NO_ACK = 3


def agent_power_on(
    tools_dir: str, python: str, holder: str, lease_s: float, serial_device: str
) -> RemoteCommand:
    lease = int(lease_s)
    q = shlex.quote
    script = (
        f"{_claim_authority(tools_dir, holder, lease)}; "
        f"{q(python)} {AGENT_NAME} power-on --serial {q(serial_device)}"
    )
    return RemoteCommand("agent-power-on", (tools_dir, python, holder, str(lease), serial_device), script)


def agent_read(tools_dir: str, python: str, offset: int) -> RemoteCommand:
    q = shlex.quote
    script = (
        f"cd {q(tools_dir)} || exit {EXIT_NO_TOOLS}; {q(python)} {AGENT_NAME} read --offset {int(offset)}"
    )
    return RemoteCommand("agent-read", (tools_dir, python, str(int(offset))), script)


def agent_go(tools_dir: str, python: str, holder: str, serial_device: str) -> RemoteCommand:
    q = shlex.quote
    script = _as_holder(tools_dir, holder, f"{q(python)} {AGENT_NAME} go --serial {q(serial_device)}")
    return RemoteCommand("agent-go", (tools_dir, python, holder, serial_device), script)


def storage_report(mount: str) -> RemoteCommand:
    q = shlex.quote
    script = f"df -P -B1 -- {q(mount)}; echo '--mdstat--'; cat /proc/mdstat"
    return RemoteCommand("storage", (mount,), script)


def verify_file(path: str) -> RemoteCommand:
    """Flush the uploaded file to the card, then hash what is actually stored.

    The file is hashed from standard input, so the line is always ``<digest>  -``: given the name,
    GNU sha256sum escapes one that holds a backslash or a newline and starts the line with ``\\``,
    and such a file never verified.
    """
    q = shlex.quote
    script = f"sync -- {q(path)} && sha256sum < {q(path)}"
    return RemoteCommand("verify", (path,), script)


def hash_file(path: str) -> RemoteCommand:
    q = shlex.quote
    return RemoteCommand("hash", (path,), f"sha256sum < {q(path)}")


_SHA256_LINE_RE = re.compile(r"([0-9a-f]{64})  -\n?")


def sha256_of(output: str) -> str | None:
    """The digest ``verify_file`` or ``hash_file`` printed, or None when the output is anything else."""
    match = _SHA256_LINE_RE.fullmatch(output)
    return match.group(1) if match else None


def heartbeat() -> RemoteCommand:
    return RemoteCommand("heartbeat", (), "true")
